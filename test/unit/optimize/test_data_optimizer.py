"""The data-driven gait step: learned cycle, trust region, bounds, uncertainty, refusals."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.optimize.data import (
    DataOptimizeConfig,
    LearnedCycle,
    LearnedModel,
    _ridge_factor,
    align_to_model,
    reframe,
    shape_frame,
    learn_model,
    motion_miss,
    optimize_from_data,
    trust_used,
)
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.effects import apply_effects
from suds_ros.core.physics.gait import constraint_violations, gait_limits, half_wave_free, nominal_gait, time_shifted
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import make_system


@pytest.fixture(scope="module")
def purcell() -> tuple[object, LearnedModel]:
    system = make_system("purcell3")
    rec = simulate(system, SimConfig(cycles=15, seed=1))
    return system, learn_model(rec)


def test_learned_cycle_is_periodic_and_predicts_the_nominal_speed(purcell: tuple[object, LearnedModel]) -> None:
    system, model = purcell
    gait = align_to_model(model, nominal_gait(system))  # type: ignore[arg-type]
    ev = LearnedCycle(model, 1.0, 1)
    assert ev.steps == 100 and ev.h == pytest.approx(model.dt)
    res = ev.steady_of(gait.to_vector())
    rp_end, _, _ = ev.cycle(gait.to_vector()[None], res.r_p)
    np.testing.assert_allclose(rp_end, res.r_p, atol=1e-8)
    true = evaluate_gait(system, gait)["speed"]  # type: ignore[arg-type]
    predicted = float(np.hypot(*res.g_c[0, :2]))
    assert predicted == pytest.approx(true, rel=0.2)
    # a gait shifted by half a cycle leaves the data: the model no longer predicts the same motion
    far = ev.steady_of(time_shifted(gait, 0.5).to_vector())
    assert abs(float(np.hypot(*far.g_c[0, :2])) - predicted) > 0.2 * predicted


def test_a_cycle_along_prescribed_passive_shapes(purcell: tuple[object, LearnedModel]) -> None:
    system, model = purcell
    x = align_to_model(model, nominal_gait(system)).to_vector()  # type: ignore[arg-type]
    ev = LearnedCycle(model, 1.0, 1)
    res = ev.steady_of(x)
    own: list[np.ndarray] = []
    _, pose, _ = ev.cycle(x[None], res.r_p, passives=own)
    assert len(own) == ev.steps
    shapes = np.stack([res.r_p, *own])  # (steps + 1, 1, np)
    # along its own passive shapes the model moves as in its own cycle; rp0 is not used
    rp_end, prescribed, _ = ev.cycle(x[None], np.full_like(res.r_p, 9.0), passive=shapes)
    np.testing.assert_allclose(rp_end, shapes[-1])
    np.testing.assert_allclose(prescribed, pose, rtol=1e-3, atol=1e-9)
    # other passive shapes move it otherwise
    _, moved, _ = ev.cycle(x[None], None, passive=shapes + 0.3)
    assert np.max(np.abs(moved - pose)) > 1e-3 * np.max(np.abs(pose))
    with pytest.raises(SudsDataError, match="`passive`"):
        ev.cycle(x[None], None, passive=shapes[1:])


def test_a_cycle_that_blows_up_is_refused_quietly(purcell: tuple[object, LearnedModel]) -> None:
    import warnings

    system, model = purcell
    x = align_to_model(model, nominal_gait(system)).to_vector()  # type: ignore[arg-type]
    ev = LearnedCycle(model, 1.0, 1, coef=model.coef * 1e150)  # a draw far off
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's overflow warnings would raise here instead
        with pytest.raises(SudsDataError, match="NaN or Inf"):  # the state left the numbers: refused
            ev.cycle(x[None], ev.start_state())
        with pytest.raises(SudsDataError, match="NaN or Inf"):
            ev.steady_of(x)


def test_the_shape_frame_turns_the_recorded_yaw_by_the_joint_angles_it_follows() -> None:
    """``shape_frame``: the weights w with which yaw + r·w swings least; ``reframe`` turns the pose by them and
    leaves its position; ``learn_model`` fits in that frame by default, in the recorded one with ``frame="pose"``.
    """
    system = make_system("purcell3")
    rec = simulate(system, SimConfig(cycles=5, seed=2))
    w = shape_frame([rec])

    def swing(r: object) -> float:  # rms of the unwrapped yaw about its straight-line trend
        yaw = np.unwrap(r.pose[:, 2])  # type: ignore[attr-defined]
        t = r.pose_t - r.pose_t[0]  # type: ignore[attr-defined]
        return float(np.std(yaw - np.polyval(np.polyfit(t, yaw, 1), t)))

    new = reframe(rec, w)
    assert swing(new) < 0.1 * swing(rec), (swing(new), swing(rec))
    np.testing.assert_array_equal(new.pose[:, :2], rec.pose[:, :2])
    np.testing.assert_allclose(np.angle(np.exp(1j * (new.pose[:, 2] - rec.pose[:, 2] - rec.r @ w))), 0, atol=1e-12)
    # two stretches: one offset and turn each, one set of weights (the same robot)
    two = shape_frame([rec.slice(0, 250), rec.slice(250, rec.n_samples)])
    np.testing.assert_allclose(two, w, rtol=0.05)
    model = learn_model(rec)
    np.testing.assert_allclose(model.frame_weights, w)
    assert model.in_frame(rec).pose[5, 2] == new.pose[5, 2]
    plain = learn_model(rec, frame="pose")
    assert plain.frame_weights is None and plain.in_frame(rec) is rec
    with pytest.raises(SudsConfigError, match="`frame`"):
        learn_model(rec, frame="head")


def test_draws_whose_cycle_blows_up_are_left_out_of_the_steps_spread(
        purcell: tuple[object, LearnedModel], monkeypatch: pytest.MonkeyPatch) -> None:
    system, model = purcell
    wild = LearnedModel.draw
    calls = {"n": 0}

    def every_other_far_off(self: LearnedModel, rng: np.random.Generator) -> np.ndarray:
        calls["n"] += 1
        coef = wild(self, rng)
        return coef * 1e150 if calls["n"] % 2 else coef

    monkeypatch.setattr(LearnedModel, "draw", every_other_far_off)
    res = optimize_from_data(model, DataOptimizeConfig(draws=8, seed=0), limits=gait_limits(system),
                             start=nominal_gait(system))  # type: ignore[arg-type]
    assert calls["n"] == 8 and len(res.draws) == 4  # the blown-up half left out, not raised


def test_the_draws_count_the_ridge_fits_effective_parameters() -> None:
    rng = np.random.default_rng(3)
    X = rng.standard_normal((30, 50))  # more coefficients than rows, as random shape features on a few cycles
    G = X.T @ X
    for ridge in (1e-3, 1e-1):
        lam = ridge * np.mean(np.diag(G))
        hat = X @ np.linalg.solve(G + lam * np.eye(50), X.T)
        chol, dof = _ridge_factor(G, ridge)
        assert dof == pytest.approx(np.trace(hat), rel=1e-9) and dof < 30
        np.testing.assert_allclose(chol @ chol.T, G + lam * np.eye(50), atol=1e-9 * lam)
    assert _ridge_factor(G[:20, :20] + np.eye(20), 0.0)[1] == pytest.approx(20.0)  # no ridge: all of them
    assert _ridge_factor(-np.eye(3), 0.0) == (None, 3.0)  # no factor: all count


def test_step_stays_in_bounds_and_trust_region_and_does_not_hurt(purcell: tuple[object, LearnedModel]) -> None:
    system, model = purcell
    limits = gait_limits(system)  # type: ignore[arg-type]
    start = nominal_gait(system)  # type: ignore[arg-type]
    res = optimize_from_data(model, DataOptimizeConfig(draws=6, min_gain_sigmas=0.0), limits=limits, start=start)
    assert constraint_violations(res.gait, limits) == []
    assert res.trust_used <= 2.0 * 1.01 and res.step_taken
    assert res.value >= res.recorded_value
    assert res.value_std is not None and res.value_std > 0 and res.gain_std is not None and len(res.draws) == 6
    true_new = evaluate_gait(system, res.gait)["speed"]  # type: ignore[arg-type]
    true_old = evaluate_gait(system, start)["speed"]  # type: ignore[arg-type]
    assert true_new >= true_old * 0.99
    # a gain within the draws' spread is not trusted: the start gait comes back
    gated = optimize_from_data(model, DataOptimizeConfig(draws=6, min_gain_sigmas=1e3), limits=limits, start=start)
    assert not gated.step_taken and "below 1000 σ" in gated.message and gated.value == gated.recorded_value
    small = optimize_from_data(model, DataOptimizeConfig(trust=0.3, draws=0), limits=limits, start=start)
    radius = max(0.3, trust_used(model, small.recorded) * 1.001)  # widened to hold the start
    assert small.trust_radius == pytest.approx(radius) and small.value_std is None
    assert trust_used(model, small.gait) <= radius * 1.01


def test_shift_and_alignment_recover_the_model_phase(purcell: tuple[object, LearnedModel]) -> None:
    system, model = purcell
    g = nominal_gait(system).from_vector(nominal_gait(system).to_vector(2) + 0.1, 2)  # type: ignore[arg-type]
    s = np.linspace(0, 1, 17)
    np.testing.assert_allclose(time_shifted(g, 0.3).at_phase(s), g.at_phase(s + 0.3), atol=1e-12)
    a = align_to_model(model, g)
    b = align_to_model(model, time_shifted(g, 0.37))
    np.testing.assert_allclose(a.at_phase(s), b.at_phase(s), atol=0.02)


def test_refusals(purcell: tuple[object, LearnedModel]) -> None:
    system, model = purcell
    with pytest.raises(SudsConfigError, match="efficiency: no learned torque model") as exc:
        optimize_from_data(model, DataOptimizeConfig(objective="efficiency"))
    assert exc.value.code == "unsupported_objective"
    with pytest.raises(SudsConfigError, match="`trust`: expected > 0, got 0"):
        DataOptimizeConfig(trust=0.0)
    with pytest.raises(SudsConfigError, match="`gait`: joints"):
        align_to_model(model, nominal_gait(make_system("swimmer9")))


def test_a_half_wave_step_moves_only_the_odd_harmonics(purcell: tuple[object, LearnedModel]) -> None:
    system, model = purcell
    limits = gait_limits(system)  # type: ignore[arg-type]
    nom = nominal_gait(system)  # type: ignore[arg-type]
    start = nom.from_vector(nom.to_vector(3), 3)
    np.testing.assert_array_equal(half_wave_free(2, 3), [1, 3, 4, 6, 8, 10, 11, 13])
    cfg = DataOptimizeConfig(order=3, draws=0, trust_centre="start")
    free = optimize_from_data(model, cfg, limits=limits, start=start)
    half = optimize_from_data(model, dataclasses.replace(cfg, half_wave=True), limits=limits, start=start)
    assert free.step_taken and half.step_taken
    assert not free.gait.is_half_wave(atol=1e-6)  # left free, the step uses the even harmonics too
    assert half.gait.is_half_wave(atol=0.0) and constraint_violations(half.gait, limits) == []
    assert trust_used(model, half.gait, half.recorded) <= 2.0 * 1.01 and half.value > half.recorded_value
    assert abs(evaluate_gait(system, half.gait)["rotation"]) < 1e-9  # type: ignore[arg-type]
    with pytest.raises(SudsConfigError, match="`half_wave`: expected False for the turn objective"):
        DataOptimizeConfig(objective="turn", half_wave=True)


def test_a_step_whose_own_steady_state_is_no_better_is_not_taken(
        purcell: tuple[object, LearnedModel], monkeypatch: pytest.MonkeyPatch) -> None:
    """The search scores each gait from the last gait's steady state; a learned map may have more than one, and
    the step is confirmed from the recorded gait's: here every gait but the recorded one is made to go nowhere."""
    system, model = purcell
    start = nominal_gait(system)  # type: ignore[arg-type]
    limits = gait_limits(system)  # type: ignore[arg-type]
    cfg = DataOptimizeConfig(draws=0)
    assert optimize_from_data(model, cfg, limits=limits, start=start).step_taken
    steady = LearnedCycle.steady
    seen: list[bytes] = []

    def other_orbit(self: LearnedCycle, X: np.ndarray, rp: np.ndarray) -> object:
        out = steady(self, X, rp)
        if not seen:  # the first steady state asked for is the recorded gait's
            seen.append(X.tobytes())
        if X.tobytes() != seen[0]:  # not the recorded gait: a steady state that goes nowhere
            out[0].g_c[...] = 0.0
        return out

    monkeypatch.setattr(LearnedCycle, "steady", other_orbit)
    res = optimize_from_data(model, cfg, limits=limits, start=start)
    assert not res.step_taken and res.value == res.recorded_value and "not above the recorded" in res.message


def test_trust_region_centred_on_the_start(purcell: tuple[object, LearnedModel]) -> None:
    system, model = purcell
    limits = gait_limits(system)  # type: ignore[arg-type]
    start = nominal_gait(system)  # type: ignore[arg-type]
    cfg = DataOptimizeConfig(trust=0.3, draws=0, trust_centre="start")
    res = optimize_from_data(model, cfg, limits=limits, start=start)
    assert res.trust_radius == pytest.approx(0.3)  # the start is the centre: no widening
    assert trust_used(model, res.recorded, res.recorded) == pytest.approx(0.0, abs=1e-12)
    assert trust_used(model, res.gait, res.recorded) <= 0.3 * 1.01
    with pytest.raises(SudsConfigError, match="`trust_centre`: expected 'template' or 'start', got 'x'"):
        DataOptimizeConfig(trust_centre="x")


def test_a_recorded_gait_off_the_straight_course_is_brought_back_first() -> None:
    """A bent spring makes the recorded gait curve past the rotation bound: the step then goes for the bound,
    though the straight gait it finds is predicted slower (before, no step was taken: 'no better gait')."""
    from suds_ros.core.physics.effects import apply_effects
    from suds_ros.core.physics.rft import RFTChain

    system = make_system("purcell3")
    bent = RFTChain(apply_effects(system.model, [{"name": "spring_rest_offset", "joint": "joint_2",  # type: ignore
                                                  "offset": 0.9}])[0])
    rec = simulate(bent, SimConfig(cycles=15, seed=2))
    model = learn_model(rec)
    start = nominal_gait(system)
    cfg = DataOptimizeConfig(trust=2.0, draws=0, trust_centre="start", max_rotation=0.025)
    res = optimize_from_data(model, cfg, limits=gait_limits(system), start=start)
    assert abs(res.recorded_values["rotation"]) > 0.025  # the model sees the curve
    assert res.step_taken and "breaks the side bound" in res.message
    assert abs(res.values["rotation"]) < abs(res.recorded_values["rotation"])
    # and on the bent robot itself the proposed gait curves less than the recorded one
    assert abs(evaluate_gait(bent, res.gait)["rotation"]) < abs(evaluate_gait(bent, start)["rotation"])


def test_stretches_with_a_pose_stream_of_their_own_are_learnt_together() -> None:
    """A live robot's pose comes at its own rate: several stretches of it (re-runs, rejected candidates) are
    fitted together, each on its own pose intervals, and the model predicts as that of one stretch does (in the
    recorded frame: the pose intervals' bookkeeping); the shape frame found from the two stretches is the one
    found from the whole, and its models predict alike too (within the fits' scatter: 4 % at 120 Hz)."""
    from suds_ros.core.physics.lab import LabConditions, simulate_lab

    system = make_system("purcell3")
    gait = nominal_gait(system)
    for hz in (50.0, 120.0):
        rec = simulate_lab(system, SimConfig(cycles=12, seed=2), LabConditions(pose_hz=hz, pose_phase=0.0037))
        half = rec.n_samples // 2
        for frame, rel in (("pose", 0.03), ("shape", 0.05)):
            both = learn_model([rec.slice(0, half), rec.slice(half, rec.n_samples)], frame=frame)
            whole = learn_model(rec, frame=frame)
            speeds = [float(np.hypot(*LearnedCycle(m, 1.0, 1).steady_of(align_to_model(m, gait).to_vector())
                                     .g_c[0, :2])) for m in (both, whole)]
            assert speeds[0] == pytest.approx(speeds[1], rel=rel), (hz, frame, speeds)
        np.testing.assert_allclose(both.frame_weights, whole.frame_weights, rtol=0.01)


def test_motion_miss_tells_the_modelled_robot_from_a_changed_one(purcell: tuple[object, LearnedModel]) -> None:
    """Held-out cycles of the robot the model was fitted on (another seed of the perturbation) are predicted along
    their own shapes to a few per cent; the same gait on the robot with its spring 3× stiffer is not."""
    system, model = purcell
    same = motion_miss(model, simulate(system, SimConfig(cycles=5, seed=7)))  # type: ignore[arg-type]
    assert same.cycles >= 4 and same.translation < 0.1 and same.rotation < 0.05
    effects = [{"name": "stiffness_to_drag_error", "scale": 3.0}]
    stiff = RFTChain(apply_effects(system.model, effects)[0])  # type: ignore[attr-defined]
    changed = motion_miss(model, simulate(stiff, SimConfig(cycles=5, seed=7)))
    assert changed.translation > 0.5 and changed.translation_sigmas > 1.0
    assert same.size() < 0.1 < 0.5 < changed.size()
    assert changed.size(1e9) == 0.0  # nothing counts when no miss is over that many standard errors
    with pytest.raises(SudsDataError, match="at least 2 whole gait cycles"):
        motion_miss(model, simulate(system, SimConfig(cycles=5, seed=7)).slice(0, 150))  # type: ignore[arg-type]
    with pytest.raises(SudsConfigError, match="`model`"):
        motion_miss(dataclasses.replace(model, identifier=None), simulate(system, SimConfig(cycles=3, seed=7)))


def test_a_broken_down_slsqp_restarts_from_the_best_feasible_point_it_visited(
        purcell: tuple[object, LearnedModel], monkeypatch: pytest.MonkeyPatch) -> None:
    """SLSQP can stop with "Inequality constraints incompatible" after it has found better feasible gaits
    (swimmer9, a pooled model at 72 % of the limit): its last iterate is not the answer, and "no gain" is
    wrong; the step restarts from the best feasible point visited, and keeps that point if the restart
    breaks down too."""
    import scipy.optimize

    import suds_ros.core.optimize.data as data_mod

    system, model = purcell
    limits, start = gait_limits(system), nominal_gait(system)  # type: ignore[arg-type]
    cfg = DataOptimizeConfig(draws=0)
    good = optimize_from_data(model, cfg, limits=limits, start=start)
    assert good.step_taken
    x_good = good.gait.to_vector(cfg.order)
    starts = []

    def broken(fun, z0, **kwargs):  # type: ignore[no-untyped-def]
        starts.append(np.array(z0))
        fun(z0)
        fun(x_good)  # a better feasible gait on the way ...
        fun(z0 + 5.0)  # ... then far outside, where it breaks down
        return scipy.optimize.OptimizeResult(x=z0 + 5.0, success=False, nit=3,
                                             message="Inequality constraints incompatible")

    monkeypatch.setattr(data_mod, "minimize", broken)
    res = optimize_from_data(model, cfg, limits=limits, start=start)
    assert len(starts) == 2 and np.array_equal(starts[1], x_good)
    assert res.step_taken and "restarted from the best feasible point" in res.message
    assert "that point taken" in res.message
    np.testing.assert_allclose(res.gait.to_vector(cfg.order), x_good, atol=1e-12)
    assert res.value == pytest.approx(good.value, rel=1e-9)


def test_the_body_channels_fitted_on_pose_intervals_are_drawn_from_their_own_normal_equations() -> None:
    """With motion capture at its own rate the body velocity is fitted on the pose stream's intervals (the
    averaged design W·A), the other channels on the shape grid: each channel's draws scatter as its own fit's
    covariance s²_c (AᵀA + λI)⁻¹ says.  (They used to take the shape grid's factor for every channel: at a
    47 Hz pose stream that made the body channels' draws, and so the predicted speed's σ, too narrow.)"""
    from suds_ros.core.physics.lab import LabConditions, simulate_lab

    system = make_system("purcell3")
    rec = simulate_lab(system, SimConfig(cycles=10, seed=4), LabConditions(pose_hz=47.0, pose_phase=0.003))
    model = learn_model(rec, frame="pose")
    reg = model.identifier.regressor_
    assert model.avg_columns == (0, 1, 2) and model.chol_avg is not None and model.has_draws

    def covariance(xtx: np.ndarray) -> np.ndarray:
        lam = reg.config.ridge * float(np.mean(np.diag(xtx)))
        return np.linalg.inv(xtx + lam * np.eye(xtx.shape[0]))

    v = np.random.default_rng(0).standard_normal(model.coef.shape[0])  # a linear functional of the coefficients
    rng = np.random.default_rng(1)
    draws = np.stack([model.draw(rng) for _ in range(3000)])  # (draws, p, c)
    for c in model.avg_columns:
        own = model.resid_std[c] ** 2 * v @ covariance(reg.normal_avg_.xtx) @ v
        grid = model.resid_std[c] ** 2 * v @ covariance(reg.normal_.xtx) @ v
        assert np.var(draws[:, :, c] @ v) == pytest.approx(own, rel=0.12), c
        assert own > 1.5 * grid, c  # the shape grid's factor would be far too narrow here
    assert not dataclasses.replace(model, chol_avg=None).has_draws
    with pytest.raises(SudsConfigError, match="covariance"):
        dataclasses.replace(model, chol_avg=None).draw(rng)


def test_a_recording_with_pose_on_the_shape_grid_has_no_averaged_channels(purcell: tuple[object, LearnedModel]) -> None:
    _, model = purcell
    assert model.avg_columns == () and model.chol_avg is None and model.has_draws


def test_the_model_maps_over_the_shape_grid_when_many_shape_samples_are_lost() -> None:
    """Lost shape samples lengthen the recording's median stamp interval; the regression still maps over the
    identifier's uniform grid, and the learned cycle takes that grid's steps."""
    from suds_ros.core.physics.lab import LabConditions, simulate_lab

    system = make_system("purcell3")
    rec = simulate_lab(system, SimConfig(cycles=10, seed=5),
                       LabConditions(pose_hz=47.0, pose_phase=0.003, jitter=0.001, drop=0.45))
    assert np.median(np.diff(rec.t)) > 1.05 * 0.01  # 100 samples a cycle at 1 Hz, nearly half of them lost
    model = learn_model(rec)
    assert model.dt == pytest.approx(0.01, rel=0.01)
    assert LearnedCycle(model, 1.0, 2).steps == 100
