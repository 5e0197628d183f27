"""The offline run → fit → step loop: measurement, acceptance, budget, bounds, refusals."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from suds_ros.core import se2
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.optimize.loop import (
    POOR_RATIO,
    GaitSearch,
    LoopConfig,
    LoopResult,
    Measurement,
    RunRequest,
    is_better,
    measure_cycles,
    motion_doubt,
    optimize_loop,
    translation_p,
)
from suds_ros.core.optimize.physics import evaluate_gait
from suds_ros.core.physics.gait import constraint_violations, gait_limits, nominal_gait
from suds_ros.core.physics.systems import load_system, make_system

ROBOTS = Path(__file__).resolve().parents[2] / "data" / "robots"


def test_measure_cycles_reads_the_per_cycle_net_motion() -> None:
    spc, hz = 50, 2.0
    t = np.arange(4 * spc + 1) / (spc * hz)
    # body moving along its own x at 0.3 m/s while turning at 0.1 rad/s: a circular arc
    w, v = 0.1, 0.3
    yaw = w * t + 0.2 * np.sin(2 * np.pi * hz * t)  # a periodic wiggle does not change the net motion
    x, y = v / w * np.sin(w * t), v / w * (1 - np.cos(w * t))
    m = measure_cycles(np.stack([x, y, yaw], axis=1), spc, hz)
    assert m.cycles == 4 and m.rotation == pytest.approx(w / hz, rel=1e-9)
    assert m.turn == pytest.approx(w, rel=1e-9)
    chord = 2 * v / w * np.sin(w / hz / 2)  # the arc's chord per cycle
    assert m.speed == pytest.approx(chord * hz, rel=1e-6) and m.speed_se < 1e-9
    assert m.translation_p == 0.0  # every cycle the same, and not zero
    with pytest.raises(SudsConfigError, match="expected at least one cycle"):
        measure_cycles(np.zeros((spc, 3)), spc, hz)


def test_the_speed_counts_every_point_of_the_cycle_so_a_turn_does_not_move_the_tracked_points_chord() -> None:
    """The tracked point is a head 0.6 m ahead of a centre that moves straight at 0.5 m/s while the body
    swings (yaw 0.8 cos 2πft) and meanders by 0.2 sin(2πft/3).  Counted from the cycle starts, each
    cycle's chord takes in the meander's turn times the head's offset there (7 % short); counted from
    every point of the cycle, the head's mean position over a cycle is what moves (0.7 %, from the
    windows' headings), with one block per whole cycle of starts but the last."""
    spc, f, v, head = 100, 1.0, 0.5, 0.6
    t = np.arange(4 * spc + 1) / (spc * f)
    psi = 0.8 * np.cos(2 * np.pi * f * t) + 0.2 * np.sin(2 * np.pi * f * t / 3)
    pose = np.stack([v * t + head * np.cos(psi), head * np.sin(psi), psi], axis=1)
    m = measure_cycles(pose, spc, f)
    idx = np.arange(5) * spc
    starts = se2.relative(pose[idx[:-1]], pose[idx[1:]])[:, :2].mean(axis=0)  # the reading from the starts
    assert abs(np.hypot(*starts) * f / v - 1) > 0.05
    assert m.speed == pytest.approx(v, rel=0.01)
    assert m.speed_dof == 2.0 and 0 < m.speed_se < 0.05 * v
    assert measure_cycles([pose, pose[:3 * spc + 1]], spc, f).speed_dof == 4.0  # 3 + 2 blocks
    assert measure_cycles(pose[:2 * spc + 1], spc, f).speed_dof == 1.0  # one block: the 2 cycles from their starts


def test_the_change_tests_read_a_few_cycles_standard_errors_through_students_t() -> None:
    from scipy import stats

    from suds_ros.core.optimize.loop import _sigmas

    assert _sigmas(1.3, 1.0, 0.1, 0.05) == pytest.approx(0.3 / np.hypot(0.1, 0.05))  # known: the plain ratio
    se1, se2_, n1, n2 = 0.1, 0.05, 2.0, 3.0
    nu = (se1 ** 2 + se2_ ** 2) ** 2 / (se1 ** 4 / n1 + se2_ ** 4 / n2)  # Welch–Satterthwaite
    t = 0.3 / np.hypot(se1, se2_)
    z = _sigmas(1.3, 1.0, se1, se2_, n1, n2)
    assert z == pytest.approx(stats.norm.isf(stats.t.sf(t, nu)), rel=1e-9) and z < t
    assert _sigmas(1.0, 1.3, se1, se2_, n1, n2) == pytest.approx(z)  # |new − old|
    assert _sigmas(1.3, 1.0, se1, se2_, 1e9, 1e9) == pytest.approx(t, rel=1e-6)
    assert _sigmas(1.3, 1.0, float("nan"), 0.1, 2.0, 2.0) == 0.0


def test_translation_p_is_hotellings_test_against_no_motion() -> None:
    rng = np.random.default_rng(20261202)
    for m in (3, 4, 8):  # under the null: p uniform, so p < 0.05 in 5 % of draws (binomial sd 0.49 % at 2000)
        p = np.array([translation_p(rng.normal(size=(m, 2)) * [1.0, 4.0]) for _ in range(2000)])
        assert 0.035 < np.mean(p < 0.05) < 0.065 and 0.46 < np.mean(p < 0.5) < 0.54
    # a mean of 1.5 sd per cycle is found over 8 cycles, not over 3
    shifted = [translation_p(rng.normal(size=(m, 2)) + [1.5, 0.0]) for m in (3, 8) for _ in range(400)]
    assert np.mean(np.array(shifted[400:]) < 0.05) > 0.8 > np.mean(np.array(shifted[:400]) < 0.05)
    assert translation_p(np.zeros((4, 2))) == 1.0 and translation_p(np.ones((2, 2))) is None
    line = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])  # spread along x only: a t test along it
    assert translation_p(line) == pytest.approx(0.0742, abs=1e-3)
    assert translation_p(line + [0.0, 1.0]) == 0.0  # a mean off the only direction of spread


def test_motion_doubt_warns_when_the_motion_cannot_be_told_from_none() -> None:
    m = Measurement(speed=0.004, rotation=0.02, turn=0.01, speed_se=0.003, rotation_se=0.015, cycles=4,
                    translation_p=0.31)
    text = motion_doubt(m, "speed")
    assert text is not None and "p = 0.31" in text and "4 cycles" in text and "more cycles" in text
    assert motion_doubt(m, "efficiency") == text
    assert motion_doubt(dataclasses.replace(m, translation_p=0.01), "speed") is None
    assert motion_doubt(dataclasses.replace(m, translation_p=None), "speed") is None  # too few cycles to say
    turn = motion_doubt(m, "turn")  # |0.02| / 0.015 = 1.33 se over 3 degrees of freedom: p = 0.27
    assert turn is not None and "p = 0.27" in turn and "rotation per cycle" in turn
    assert motion_doubt(dataclasses.replace(m, rotation=0.2), "turn") is None


def _m(speed: float, rotation: float) -> Measurement:
    return Measurement(speed=speed, rotation=rotation, turn=rotation, speed_se=0.0, rotation_se=0.0, cycles=4)


def test_acceptance_is_by_measurement_feasible_first() -> None:
    cfg = LoopConfig(budget_cycles=20)
    assert is_better(_m(0.2, 0.01), _m(0.1, 0.0), cfg)
    assert not is_better(_m(0.1, 0.0), _m(0.1, 0.0), cfg)  # equal is not better
    assert not is_better(_m(0.9, 0.06), _m(0.1, 0.0), cfg)  # faster but off the straight course
    assert is_better(_m(0.1, 0.0), _m(0.9, -0.06), cfg)
    assert is_better(_m(0.1, 0.07), _m(0.9, 0.08), cfg)  # both off course: the smaller violation
    turn = LoopConfig(budget_cycles=20, objective="turn")
    assert is_better(_m(0.5, -0.3), _m(0.5, 0.2), turn, speed_floor=0.4)  # |turn| counts
    assert not is_better(_m(0.3, 0.9), _m(0.5, 0.2), turn, speed_floor=0.4)  # below the speed floor
    # the floor is a measured speed too: a shortfall within floor_sigmas se of the difference is no shortfall
    assert is_better(_m(0.39, 0.9), _m(0.5, 0.2), turn, speed_floor=0.4, floor_se=0.02)
    assert not is_better(_m(0.39, 0.9), _m(0.5, 0.2), turn, speed_floor=0.4, floor_se=0.005)
    eff = LoopConfig(budget_cycles=20, objective="efficiency")
    fast = dataclasses.replace(_m(0.5, 0.0), efficiency=0.02)
    frugal = dataclasses.replace(_m(0.45, 0.0), efficiency=0.03)
    assert is_better(frugal, fast, eff, speed_floor=0.44)
    assert not is_better(frugal, fast, eff, speed_floor=0.5)  # more efficient, but slower than the start
    assert not is_better(dataclasses.replace(frugal, rotation=0.06), fast, eff, speed_floor=0.44)  # off course
    # the rotation is a measured number too: over the bound by less than rotation_sigmas se is not off course
    lax = LoopConfig(budget_cycles=20, rotation_sigmas=1.0)
    noisy = dataclasses.replace(_m(0.9, 0.07), rotation_se=0.03)
    assert is_better(noisy, _m(0.1, 0.0), lax)
    assert not is_better(noisy, _m(0.1, 0.0), dataclasses.replace(lax, rotation_sigmas=0.0))
    assert not is_better(dataclasses.replace(noisy, rotation_se=0.01), _m(0.1, 0.0), lax)


@pytest.mark.parametrize("kwargs, message, code", [
    ({"budget_cycles": 4}, "`budget_cycles`: expected at least settle_cycles \\+ first_cycles = 5", "budget_too_small"),
    ({"budget_cycles": 20, "floor_sigmas": -1.0}, "`floor_sigmas`: expected ≥ 0, got -1.0", "bad_config"),
    ({"budget_cycles": 20, "step_cycles": 3}, "`step_cycles`: expected ≥ 4, got 3", "bad_config"),
    ({"budget_cycles": 20, "shrink": 1.0}, "`shrink`: expected in \\(0, 1\\), got 1.0", "bad_config"),
    ({"budget_cycles": 20, "confirm_sigmas": -1.0}, "`confirm_sigmas`: expected ≥ 0, got -1.0", "bad_config"),
    ({"budget_cycles": 20, "model_miss": 0.0}, "`model_miss`: expected > 0, got 0.0", "bad_config"),
    ({"budget_cycles": 20, "body_frame": "head"}, "`body_frame`: expected one of \\['shape', 'pose'\\], got 'head'",
     "bad_config"),
])
def test_config_refusals(kwargs: dict[str, object], message: str, code: str) -> None:
    with pytest.raises(SudsConfigError, match=message) as exc:
        LoopConfig(**kwargs)  # type: ignore[arg-type]
    assert exc.value.code == code


@pytest.fixture(scope="module")
def p3_half() -> tuple[object, object, LoopResult]:
    system = make_system("purcell3")
    nom = nominal_gait(system)
    half = nom.from_vector(0.5 * nom.to_vector(), nom.order)
    return system, half, optimize_loop(system, LoopConfig(budget_cycles=17, seed=0, first_cycles=5), start=half)


def test_loop_improves_a_poor_start_within_budget_and_bounds(p3_half: tuple[object, object, LoopResult]) -> None:
    system, half, res = p3_half
    limits = gait_limits(system)  # type: ignore[arg-type]
    its = res.iterations
    assert res.cycles_used <= 17 and res.cycles_used == sum(it.cycles for it in its) == its[-1].cycles_used
    assert its[0].cycles == 6 and all(it.cycles == 5 for it in its[1:]) and len(its) == 3
    assert "budget spent" in res.stopped
    assert all(constraint_violations(it.gait, limits) == [] for it in its)  # nothing run outside the bounds
    assert all(it.gait.is_half_wave() for it in its)  # the half-amplitude sine's steps keep its symmetry
    assert constraint_violations(res.gait, limits) == []
    assert its[0].predicted is not None and all(it.predicted is not None for it in its)
    # the returned gait is the best measured among the accepted ones, and carries its prediction
    accepted = [it for it in its if it.accepted]
    assert res.index == max(accepted, key=lambda it: it.index).index
    assert res.measured == its[res.index].measured and res.gait.predicted[0][1] == pytest.approx(res.predicted)
    assert all(is_better(b.measured, a.measured, LoopConfig(budget_cycles=17)) for a, b in zip(accepted, accepted[1:]))
    # judged on the physics: a real gain over the half-amplitude start
    true_start = evaluate_gait(system, half)["speed"]  # type: ignore[arg-type]
    true_end = evaluate_gait(system, res.gait)["speed"]  # type: ignore[arg-type]
    assert true_end > 1.3 * true_start


def test_a_start_outside_the_bounds_is_refused() -> None:
    system = make_system("purcell3")
    nom = nominal_gait(system)
    wide = nom.from_vector(1.5 * nom.to_vector(), nom.order)
    with pytest.raises(SudsConfigError, match="limit") as exc:
        optimize_loop(system, LoopConfig(budget_cycles=10), start=wide)
    assert exc.value.code == "gait_constraint"


def test_stretches_are_pooled_in_the_measurement() -> None:
    spc = 20
    t = np.arange(3 * spc + 1) / spc
    a = np.stack([0.1 * t, 0 * t, 0.02 * t], axis=1)
    b = np.stack([0.3 * t, 0 * t, 0.0 * t], axis=1)
    m = measure_cycles([a, b[: 2 * spc + 1]], spc, 1.0)
    # every one-cycle window counts: 2·spc + 1 windows turning 0.02 rad, spc + 1 turning none
    assert m.cycles == 5 and m.rotation == pytest.approx(0.02 * (2 * spc + 1) / (3 * spc + 2), rel=1e-9)
    # the speed: every point of each whole cycle but the last, 2 cycles of them at 0.1 m/s, 1 at 0.3
    # (a's heading turns under its straight track, so its windows point up to 0.04 rad off: cos ≈ 1 − 1e-3)
    assert m.speed == pytest.approx((2 * 0.1 + 0.3) / 3, rel=1e-3)


def test_a_collapsed_trust_region_re_runs_the_incumbent() -> None:
    system = make_system("purcell3")
    cfg = LoopConfig(budget_cycles=21, seed=0, trust=2.0, trust_min=2.0, first_cycles=5)  # one rejection collapses it
    res = optimize_loop(system, cfg)
    its = res.iterations
    assert not its[1].accepted and "trust → 1" in its[1].note
    assert its[2].note.startswith("incumbent re-run") and its[2].gait is its[0].gait and its[2].accepted
    assert its[2].measured.cycles == 5 + 4 and res.cycles_used == 21
    # the next step comes from the model of both stretches, with the radius afresh
    assert its[3].predicted is not None and its[3].trust == pytest.approx(2.0)
    assert res.index == (3 if its[3].accepted else 2)


class _Told(GaitSearch):
    """The search, with each run's measurement given instead of measured."""

    def __init__(self, *args: Any, told: list[Measurement], **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.told = told

    def _measure(self, data: Any, gait: Any) -> Measurement:
        return self.told.pop(0)


def test_the_radius_follows_how_far_the_measured_gain_bears_out_the_predicted_one() -> None:
    system = make_system("purcell3")
    nom = nominal_gait(system)
    told = [_m(0.10, 0.0), _m(0.11, 0.0), _m(0.12, 0.0), _m(0.20, 0.0), _m(0.21, 0.0)]
    search = _Told(nom, gait_limits(system), LoopConfig(budget_cycles=40), told=told)
    search.observe(None)  # type: ignore[arg-type]  # the start gait

    def candidate(predicted_gain: float, radius: float) -> Any:
        step = SimpleNamespace(value=1.0 + predicted_gain, recorded_value=1.0, value_std=None, trust_radius=radius,
                               trust_used=radius)
        search._pending = RunRequest(nom, 5, "candidate", step=step)
        return search.observe(None)  # type: ignore[arg-type]

    search._kappa = 8.0  # grown by earlier steps
    it = candidate(0.4, 8.0)  # measured +0.01: kept, but the model was far off that far out
    assert it.accepted and search._kappa == 4.0 and f"under {POOR_RATIO:g} of the prediction, trust → 4" in it.note
    it = candidate(0.03, 4.0)  # measured +0.01, a third: the radius stays
    assert it.accepted and search._kappa == 4.0 and "trust" not in it.note
    it = candidate(0.01, 4.0)  # measured +0.08, at the region's edge: it grows
    assert it.accepted and search._kappa == 8.0 and "trust grows to 8" in it.note
    search._kappa = 2.0  # never below the initial radius
    it = candidate(1.0, 2.0)
    assert it.accepted and search._kappa == 2.0 and "trust" not in it.note


def test_a_rotation_within_a_standard_error_of_the_bound_passes_only_on_a_symmetric_looking_robot() -> None:
    system = make_system("purcell3")
    nom = nominal_gait(system)  # half-wave: a sine
    skew = nom.from_vector(np.r_[0.1, nom.to_vector()[1:]], 1)  # an offset: not half-wave
    step = SimpleNamespace(value=1.2, recorded_value=1.0, value_std=None, trust_radius=2.0, trust_used=2.0)
    over = dataclasses.replace(_m(0.2, 0.07), rotation_se=0.03)  # 0.02 over the bound, within 1 se

    def judged(start_rotation: float, candidate: Any, se: float = 0.03) -> bool:
        start = dataclasses.replace(_m(0.1, start_rotation), rotation_se=se)
        search = _Told(nom, gait_limits(system), LoopConfig(budget_cycles=40), told=[start, over])
        search.observe(None)  # type: ignore[arg-type]
        search._pending = RunRequest(candidate, 5, "candidate", step=step)
        return search.observe(None).accepted  # type: ignore[arg-type]

    assert judged(0.01, nom)  # the start ran straight: a half-wave gait's excess is noise
    assert not judged(0.045, nom, se=0.01)  # the start turned, if within the bound: the bound is the measured number
    assert not judged(0.01, skew)  # a gait that is not half-wave can truly turn


def test_a_marginal_gain_is_run_again_before_it_is_kept() -> None:
    """From purcell3's nominal gait (98.8 % of the limit) the candidates' measured gains are within
    the measurement's noise: such a candidate is run again and judged on both stretches pooled,
    and none is kept on a first measurement within ``confirm_sigmas``."""
    system = make_system("purcell3")
    cfg = LoopConfig(budget_cycles=26, seed=3, confirm_sigmas=1.0, half_wave=False)  # (seed 3: two of them)
    its = optimize_loop(system, cfg).iterations
    confirming = [i for i, it in enumerate(its) if it.note.startswith("to be confirmed")]
    assert confirming, [it.note for it in its]
    for i in confirming:
        first, again = its[i], its[i + 1]
        assert not first.accepted and again.gait is first.gait
        assert again.measured.cycles == first.measured.cycles + cfg.step_cycles  # both stretches pooled
        incumbent = max((it for it in its[:i] if it.accepted), key=lambda it: it.index)
        assert again.accepted == is_better(again.measured, incumbent.measured, cfg)
    off = optimize_loop(system, dataclasses.replace(cfg, confirm_sigmas=0.0)).iterations
    assert not any(it.note.startswith("to be confirmed") for it in off)


def test_a_step_predicted_to_gain_beyond_the_noise_is_kept_on_its_first_measurement() -> None:
    """Only a gain that neither the measurement nor the model puts beyond ``confirm_sigmas`` standard
    errors is run again: from purcell3 at half amplitude the first step predicts a gain of several
    standard errors and is kept at once although its measured gain is within 3 of them."""
    system = make_system("purcell3")
    nom = nominal_gait(system)
    cfg = LoopConfig(budget_cycles=30, seed=1, confirm_sigmas=3.0, scale_step=math.inf)  # (trust-region steps)
    its = optimize_loop(system, cfg, start=nom.from_vector(0.5 * nom.to_vector(), nom.order)).iterations
    at_once = confirmed = 0
    incumbent = its[0]
    for before, it in zip(its, its[1:]):
        se = math.hypot(it.measured.speed_se, incumbent.measured.speed_se)
        z, z_pred = (it.measured.speed - incumbent.measured.speed) / se, (it.predicted - it.predicted_incumbent) / se
        if it.note.startswith("to be confirmed"):
            assert z < 3.0 and z_pred < 3.0, it.note
            confirmed += 1
        elif it.accepted and it.note.startswith("accepted") and not before.note.startswith("to be confirmed"):
            assert z >= 3.0 or z_pred >= 3.0, it.note
            at_once += 0 < z < 3.0
        if it.accepted:
            incumbent = it
    assert at_once >= 1 and confirmed >= 1, [it.note for it in its]


def test_measure_cycles_reads_the_gaits_work_from_phase_averages() -> None:
    """The work is that of the cycles' phase-averaged effort and angles: an excitation's effort that
    averages out over the cycles does not count (here it alternates sign from cycle to cycle)."""
    spc, hz, m = 40, 2.0, 4
    i = np.arange(m * spc + 1)
    t, s = i / (spc * hz), i / spc
    pose = np.stack([0.3 * t + 0.01 * np.sin(2 * np.pi * s), 0 * t, 0 * t], axis=1)
    ra = 0.5 * np.sin(2 * np.pi * s)[:, None]
    rate = np.concatenate([[0.0], np.diff(ra[:, 0])]) * spc * hz
    sign = np.where((np.maximum(i - 1, 0) // spc) % 2 == 0, 1.0, -1.0)  # the cycle a period ends in
    tau = (3.0 * rate + sign * 2.0 * np.cos(2 * np.pi * s))[:, None]  # a damper, plus the excitation's part
    meas = measure_cycles(pose, spc, hz, [(ra, tau)])
    work = 3.0 * spc * hz * np.sum(np.diff(ra[:spc + 1, 0]) ** 2)  # the damper's alone, by its definition
    first = np.sum(tau[1:spc + 1, 0] * np.diff(ra[:spc + 1, 0]))  # the first cycle's raw Σ τ·Δr
    assert meas.work == pytest.approx(work, rel=1e-12) and abs(first - work) > 0.1 * work
    assert meas.efficiency == pytest.approx(0.3 / hz / work, rel=1e-9)
    assert 0 < meas.efficiency_se < 0.1 * meas.efficiency  # the jackknife sees the cycles differ
    assert meas.value("efficiency") == meas.efficiency and meas.value_se("efficiency") == meas.efficiency_se
    assert measure_cycles(pose, spc, hz).efficiency is None
    with pytest.raises(SudsConfigError, match="`drive`: expected one row per pose sample"):
        measure_cycles(pose, spc, hz, [(ra[:-1], tau[:-1])])


def test_the_drive_is_read_from_the_recorded_effort() -> None:
    from suds_ros.core.optimize.loop import actuator_drive
    from suds_ros.core.recording import Recording

    t = np.arange(5) * 0.1
    r = np.stack([np.array([0.0, 0.1, 0.3, 0.2, 0.2]), np.zeros(5)], axis=1)
    effort = np.stack([np.array([9.0, 2.0, 1.0, 4.0, 3.0]), np.full(5, 7.0)], axis=1)  # the passive column unused
    rec = Recording(t=t, r=r, joint_names=("a", "p"), actuated=("a",), passive=("p",), pose_t=t,
                    pose=np.zeros((5, 3)), system="x", gait_hz=1.0, effort=effort)
    ra, tau = actuator_drive(rec)
    np.testing.assert_array_equal(ra, r[:, :1])
    np.testing.assert_array_equal(tau, effort[:, :1])
    with pytest.raises(SudsConfigError, match="no actuator effort") as exc:
        actuator_drive(dataclasses.replace(rec, effort=None))
    assert exc.value.code == "unsupported_objective"


def test_the_loop_optimises_efficiency_from_the_measured_work() -> None:
    """The loop measures each gait's work from the recorded effort and steps on the learned
    torques; every gait it keeps measured better than the one it replaced, within the side bounds
    (how far it gets is measured in ``benchmarks/optimize_efficiency.py``)."""
    system = load_system(str(ROBOTS / "eel4.yaml"))
    cfg = LoopConfig(budget_cycles=26, seed=0, objective="efficiency")
    res = optimize_loop(system, cfg)
    its = res.iterations
    assert all(np.isfinite(it.measured.value("efficiency")) and (it.measured.work or 0) > 0 for it in its)
    assert all(it.predicted is not None and np.isfinite(it.predicted) for it in its)
    start = its[0].measured
    accepted = [it for it in its if it.accepted]
    assert all(is_better(b.measured, a.measured, cfg, start.speed, start.speed_se)
               for a, b in zip(accepted, accepted[1:]) if not b.note.startswith("incumbent re-run"))
    assert constraint_violations(res.gait, gait_limits(system)) == []
    assert res.gait.objective == "efficiency" and res.measured.efficiency == its[res.index].measured.efficiency


def test_a_turning_gait_is_returned_counted_from_the_point_it_measured_furthest_from() -> None:
    """The same motion, counted from another point of its cycle: the chord of a turning gait is longer there.

    snake5 with joint_1 bent by 0.2 rad turns −0.039 rad/cycle; without excitation or noise the loop's
    start alone (5 cycles) already tells from where its cycle goes furthest, within a sample of the
    physics' own answer, and the returned gait is 6 % faster on the physics than the one it ran.
    Its measured speed, counted from every point of the cycle, is the same before and after.
    """
    from suds_ros.core.optimize.loop import measured_origin
    from suds_ros.core.optimize.physics import CycleEvaluator, origin_distances

    system, bent = _bent_snake5()
    x = bent.to_vector()
    quiet = LoopConfig(budget_cycles=5, ou_std=0.0, noise_std=0.0)
    res = optimize_loop(system, quiet, start=bent, limits=gait_limits(system))
    ev = CycleEvaluator(system, bent.gait_hz, bent.order, quiet.samples_per_cycle)
    steady, _, _ = ev.steady(x[None], np.zeros((1, ev.np)))
    best = int(np.argmax(origin_distances(ev, x, steady)))
    recorded = res.iterations[0]
    assert recorded.measured.rotation == pytest.approx(-0.039, abs=2e-3)
    j = measured_origin(_start_data(system, bent, quiet), quiet.samples_per_cycle, bent.gait_hz)
    assert abs(j - best) <= 1
    ran, returned = evaluate_gait(system, bent)["speed"], evaluate_gait(system, res.gait)["speed"]
    assert returned > 1.05 * ran
    # the measured speed counts every point of the cycle alike: the chord averaged over them, as run
    dist = origin_distances(ev, x, steady)
    assert res.measured == recorded.measured
    assert res.measured.speed == pytest.approx(dist.mean() * bent.gait_hz, rel=0.01)
    assert ran < res.measured.speed < returned
    assert constraint_violations(res.gait, gait_limits(system)) == []
    # a gait that runs straight, or an origin_sigmas no measurement reaches, is returned as it ran
    nom = nominal_gait(system)
    straight = nom.from_vector(0.8 * nom.to_vector(), nom.order)
    assert optimize_loop(system, quiet, start=straight, limits=gait_limits(system)).gait.to_vector() \
        == pytest.approx(straight.to_vector())
    strict = dataclasses.replace(quiet, origin_sigmas=math.inf)
    assert optimize_loop(system, strict, start=bent, limits=gait_limits(system)).gait.to_vector() \
        == pytest.approx(x)


def test_the_prediction_of_a_gait_counts_from_its_own_time_zero() -> None:
    """The model's speed of a turning gait is its chord from the gait's time zero, not from the model's phase zero.

    Checked against two predicted cycles integrated on from the model's periodic steady state: the
    chord g(s)⁻¹ g(s + T) from several points s of the motion, each the time zero of the gait
    time-shifted there.  The returned gait of a loop that shifts its origin carries the prediction
    counted from its new zero.
    """
    from suds_ros.core import se2
    from suds_ros.core.optimize.data import LearnedCycle, align_shift, learn_model
    from suds_ros.core.optimize.loop import origin_ratio, predict_value
    from suds_ros.core.physics.gait import time_shifted

    system, bent = _bent_snake5()
    quiet = LoopConfig(budget_cycles=5, ou_std=0.0, noise_std=0.0)
    model = learn_model(_start_data(system, bent, quiet))
    s0 = align_shift(model, bent)
    g = time_shifted(bent, s0)
    ev = LearnedCycle(model, g.gait_hz, g.order)
    x = g.to_vector()
    steady = ev.steady_of(x)
    first: list[Any] = []
    second: list[Any] = []
    rp, g_c, _ = ev.cycle(x[None], steady.r_p, poses=first)
    assert np.asarray(first[-1]) == pytest.approx(g_c)
    ev.cycle(x[None], rp, poses=second)
    n = ev.steps
    speeds = []
    for k in (0, n // 4, n // 2, 3 * n // 4):
        a = np.zeros((1, 3)) if k == 0 else first[k - 1]
        q = np.zeros((1, 3)) if k == 0 else second[k - 1]  # g(T + s) = g_c · g(s) in the first cycle's frame
        c, sn = math.cos(g_c[0, 2]), math.sin(g_c[0, 2])
        b = np.array([[g_c[0, 0] + c * q[0, 0] - sn * q[0, 1], g_c[0, 1] + sn * q[0, 0] + c * q[0, 1],
                       g_c[0, 2] + q[0, 2]]])
        want = float(np.hypot(*se2.relative(a, b)[0, :2])) * g.gait_hz
        shifted = time_shifted(bent, s0 + k / n)
        assert predict_value(model, shifted, "speed") == pytest.approx(want, rel=3e-3)
        from_zero = predict_value(model, bent, "speed") * origin_ratio(model, bent, s0 + k / n)
        assert from_zero == pytest.approx(want, rel=3e-3)
        speeds.append(want)
    assert max(speeds) > 1.02 * min(speeds)  # it turns: the origin matters
    res = optimize_loop(system, quiet, start=bent, limits=gait_limits(system))
    assert res.gait.to_vector() != pytest.approx(bent.to_vector())  # shifted (the test above)
    assert res.predicted == pytest.approx(predict_value(model, res.gait, "speed"), rel=3e-3)
    assert res.predicted > 1.02 * predict_value(model, bent, "speed")


def _bent_snake5() -> tuple[Any, Any]:
    """snake5 (shared/robots) and its nominal gait at 0.8 of its amplitude with joint_1 bent by 0.2 rad."""
    spec = Path(__file__).resolve().parents[3].parent / "shared" / "robots" / "snake5.yaml"
    if not spec.exists():
        pytest.skip(f"{spec} not found")
    system = load_system(str(spec))
    nom = nominal_gait(system)
    x = 0.8 * nom.to_vector()
    x[0] += 0.2
    return system, nom.from_vector(x, nom.order)


def _start_data(system: Any, gait: Any, cfg: LoopConfig) -> Any:
    """The start gait's measured cycles as the loop records them (its settling cycle cut)."""
    from suds_ros.core.optimize.loop import _Robot, _trim

    rec, _ = _Robot(system, gait, cfg).run(gait, cfg.settle_cycles + cfg.first_cycles)
    return _trim(rec, cfg.settle_cycles, cfg.samples_per_cycle)


def test_headroom_scales_the_oscillation_to_the_tightest_bound_and_keeps_the_offsets() -> None:
    from suds_ros.core.optimize.loop import _scaled, headroom

    system = make_system("purcell3")
    nom, limits = nominal_gait(system), gait_limits(system)
    half = nom.from_vector(0.5 * nom.to_vector(), nom.order)
    assert headroom(half, limits) == pytest.approx(2.0, rel=1e-5)
    assert headroom(nom, limits) == pytest.approx(1.0, rel=1e-5)
    x = 0.5 * nom.to_vector()
    x[0] = 0.1  # an offset: the range bound on that side is reached first
    bent = nom.from_vector(x, nom.order)
    s = headroom(bent, limits)
    grown = _scaled(bent, s)
    assert grown.offset == bent.offset and constraint_violations(grown, limits) == []
    assert 1.5 < s < 2.0 and constraint_violations(_scaled(bent, s * 1.001), limits)


def test_a_timid_start_is_first_scaled_to_its_bounds() -> None:
    """purcell3 at half its nominal amplitude: the first step is the same gait at full range (3× faster here)."""
    system = make_system("purcell3")
    nom, limits = nominal_gait(system), gait_limits(system)
    half = nom.from_vector(0.5 * nom.to_vector(), nom.order)
    res = optimize_loop(system, LoopConfig(budget_cycles=10, seed=0), start=half, limits=limits)
    first = res.iterations[1]
    assert first.accepted and first.note.startswith("accepted")
    assert first.gait.to_vector() == pytest.approx(nom.to_vector(), rel=1e-4)
    assert first.predicted == pytest.approx(4 * res.iterations[0].measured.speed, rel=1e-3)  # s² with s = 2
    assert evaluate_gait(system, res.gait)["speed"] > 3 * evaluate_gait(system, half)["speed"]
    # off: the first step is the trust region's, which stays near the data
    off = optimize_loop(system, LoopConfig(budget_cycles=10, seed=0, scale_step=math.inf), start=half, limits=limits)
    assert evaluate_gait(system, off.iterations[1].gait)["speed"] < 0.9 * evaluate_gait(system, first.gait)["speed"]
    # a start at its bounds is not scaled, nor one that cannot grow by scale_step
    for start, cfg in ((nom, LoopConfig(budget_cycles=10)), (half, LoopConfig(budget_cycles=10, scale_step=2.1)),
                       (half, LoopConfig(budget_cycles=10, scale_step=math.inf))):
        search = GaitSearch(start, limits, cfg)
        search.observe(_start_data(system, start, cfg))
        assert search.request().kind == "candidate"


def test_a_rejected_scaled_start_leaves_the_search_as_it_was() -> None:
    """Told that the scaled gait measured no better (its run fed the start's own cycles), the search goes on
    from the start: the radius is unchanged, nothing is pooled, and the next request is a trust-region step."""
    from suds_ros.core.optimize.loop import _Robot, _trim

    system = make_system("purcell3")
    nom, limits = nominal_gait(system), gait_limits(system)
    half = nom.from_vector(0.5 * nom.to_vector(), nom.order)
    cfg = LoopConfig(budget_cycles=30, seed=0)
    search = GaitSearch(half, limits, cfg)
    robot = _Robot(system, half, cfg)
    req = search.request()
    rec, _ = robot.run(req.gait, req.cycles)
    data = _trim(rec, cfg.settle_cycles, cfg.samples_per_cycle)
    search.observe(data)
    req = search.request()
    assert req.kind == "scale" and req.step.factor == pytest.approx(2.0, rel=1e-5)
    it = search.observe(data)  # the same cycles: not higher
    assert not it.accepted and "scaled start rejected" in it.note and search.best is half
    assert search._kappa == cfg.trust and search._near == [] and search._rejected == []
    assert search.request().kind == "candidate"


def test_a_reverse_trial_turns_a_wave_that_runs_the_slow_way_round() -> None:
    """neck4's nominal wave swims at a quarter of what the same wave run backwards does; the trust-region
    steps stay near it, the reverse trial (on by default) runs r(−t) once after the start and keeps it."""
    from suds_ros.core.physics.gait import time_reversed

    system = load_system(str(ROBOTS / "neck4.yaml"))
    nom, limits = nominal_gait(system), gait_limits(system)
    on = optimize_loop(system, LoopConfig(budget_cycles=10, seed=0), start=nom, limits=limits)
    trial = on.iterations[1]
    assert trial.accepted and trial.gait.to_vector() == pytest.approx(time_reversed(nom).to_vector())
    assert evaluate_gait(system, on.gait)["speed"] > 3 * evaluate_gait(system, nom)["speed"]
    assert constraint_violations(trial.gait, limits) == []
    off = optimize_loop(system, LoopConfig(budget_cycles=10, seed=0, reverse_trial=False), start=nom, limits=limits)
    assert off.iterations[1].gait.to_vector() != pytest.approx(trial.gait.to_vector(), abs=0.1)
    assert evaluate_gait(system, off.gait)["speed"] < 2 * evaluate_gait(system, nom)["speed"]


def _to_reverse_trial() -> Any:
    """neck4 at half amplitude: the start and the scaled start run; the next request is the reverse trial."""
    from suds_ros.core.optimize.loop import _Robot, _trim

    system = load_system(str(ROBOTS / "neck4.yaml"))
    nom, limits = nominal_gait(system), gait_limits(system)
    half = nom.from_vector(0.5 * nom.to_vector(), nom.order)
    cfg = LoopConfig(budget_cycles=30, seed=0)
    search = GaitSearch(half, limits, cfg)
    robot = _Robot(system, half, cfg)
    for kind in ("start", "scale"):
        req = search.request()
        assert req.kind == kind
        rec, _ = robot.run(req.gait, req.cycles)
        search.observe(_trim(rec, cfg.settle_cycles, cfg.samples_per_cycle))
    return search


def test_a_reverse_trial_follows_the_scaled_start_and_a_rejected_one_leaves_the_search_as_it_was() -> None:
    """From a timid start the scaled start runs first, then the (scaled) incumbent backwards; told that the
    reversed gait measured no better, the search goes on from the incumbent with its radius and data kept.
    Not tried where backwards is the same drive started elsewhere (purcell3: one joint, one harmonic), nor
    where the incumbent's model predicts the reversed drive no better (eel4's nominal wave)."""
    from suds_ros.core.physics.gait import time_reversed

    for robot in (make_system("purcell3"), load_system(str(ROBOTS / "eel4.yaml"))):
        # purcell3: backwards is the same drive; eel4's model predicts its reversed wave slower (it is)
        search = GaitSearch(nominal_gait(robot), gait_limits(robot), LoopConfig(budget_cycles=30))
        search.observe(_start_data(robot, nominal_gait(robot), LoopConfig(budget_cycles=30)))
        assert search.request().kind == "candidate"
    search = _to_reverse_trial()
    best, kappa = search.best, search._kappa  # (the start, or the scaled start if it measured better)
    req = search.request()
    assert req.kind == "reverse" and req.gait.to_vector() == pytest.approx(time_reversed(best).to_vector())
    it = search.observe(search._best_data[-1])  # the incumbent's own cycles: not higher
    assert not it.accepted and "reversed gait rejected" in it.note and search.best is best
    assert search._kappa == kappa and search._near == [] and search._rejected == []
    assert search.request().kind == "candidate"


@pytest.mark.parametrize("holds", [False, True])
def test_a_reversed_gait_measured_better_by_under_a_standard_error_is_run_again_before_it_is_kept(
        monkeypatch: pytest.MonkeyPatch, holds: bool) -> None:
    """A barely moving random robot's reversed wave read 0.046 ± 0.033 m/s against its start's 0.018 ± 0.004
    (truly 0.006 against 0.014): a reversed gait, like a trust-region step, whose measured gain is under
    ``confirm_sigmas`` se is run again, judged on both runs pooled, and as a reversed gait: rejected, the
    search goes on from the incumbent as if it had not been tried; confirmed, it is kept."""
    search = _to_reverse_trial()
    best, kappa, old = search.best, search._kappa, search._best_meas
    req = search.request()
    assert req.kind == "reverse"
    se = old.value_se("speed")
    readings = iter([dataclasses.replace(old, speed=old.speed + 0.5 * se)])
    monkeypatch.setattr(search, "_measure", lambda data, gait: next(readings))
    it = search.observe(search._best_data[-1])
    assert not it.accepted and "to be confirmed" in it.note and search.best is best
    again = search.request()
    assert again.kind == "confirm" and again.origin == "reverse" and again.gait is req.gait
    pooled = old.speed + (0.5 if holds else -0.5) * se
    # the new stretch, the first one again (the change test compares them), then both pooled
    readings = iter([dataclasses.replace(old, speed=old.speed + 0.5 * se), dataclasses.replace(old, speed=pooled),
                     dataclasses.replace(old, speed=pooled, speed_se=0.1 * se)])
    it = search.observe(search._best_data[-1])
    if holds:
        assert it.accepted and "the incumbent backwards in time, run again" in it.note and search.best is req.gait
    else:
        assert not it.accepted and "reversed gait rejected" in it.note and search.best is best
        assert search._kappa == kappa and search._near == [] and search._rejected == []
        assert search.request().kind == "candidate"


def test_a_stretch_of_one_cycle_is_no_obstacle_to_the_returned_gaits_origin() -> None:
    """A one-cycle stretch among the data (what a change can leave) still tells where the cycle goes
    furthest from: the measured speed counts every point of the cycle, so nothing is re-measured, and
    result() returns the gait shifted as with the whole stretch, its measurement as it was."""
    system, bent = _bent_snake5()
    x = bent.to_vector()
    quiet = LoopConfig(budget_cycles=5, ou_std=0.0, noise_std=0.0)
    search = GaitSearch(bent, gait_limits(system), quiet)
    data = _start_data(system, bent, quiet)
    search.observe(data)
    whole = search.result()
    assert whole.gait.to_vector() != pytest.approx(x)  # shifted, as in the test above
    search._best_data = [data.slice(0, quiet.samples_per_cycle + 1), data]
    res = search.result()
    assert res.gait.to_vector() == pytest.approx(whole.gait.to_vector(), abs=0.02)
    assert res.measured == whole.measured


def test_a_robot_said_changed_during_a_rejected_scaled_start_is_measured_afresh_next() -> None:
    """robot_changed() while the scaled start runs: when that run is rejected, the incumbent is re-run next."""
    from suds_ros.core.optimize.loop import _Robot, _trim

    system = make_system("purcell3")
    nom, limits = nominal_gait(system), gait_limits(system)
    half = nom.from_vector(0.5 * nom.to_vector(), nom.order)
    cfg = LoopConfig(budget_cycles=30, seed=0)
    search = GaitSearch(half, limits, cfg)
    req = search.request()
    rec, _ = _Robot(system, half, cfg).run(req.gait, req.cycles)
    data = _trim(rec, cfg.settle_cycles, cfg.samples_per_cycle)
    search.observe(data)
    assert search.request().kind == "scale"
    search.robot_changed("the monitor's alarm")
    assert not search.observe(data).accepted  # the same cycles: not higher
    nxt = search.request()
    assert nxt.kind == "rerun" and "the monitor's alarm" in nxt.note


def test_a_reverse_hint_without_a_steady_state_keeps_the_fitted_model(monkeypatch: pytest.MonkeyPatch) -> None:
    """swimmer9's model of its nominal wave has no steady state for the reversed drive: no trial, and the
    trust-region step uses the model the hint fitted (one fit, not two)."""
    from suds_ros.core.optimize import loop

    fits = []
    real = loop.learn_model
    monkeypatch.setattr(loop, "learn_model", lambda *a, **k: fits.append(1) or real(*a, **k))
    predicted = []
    real_predict = loop.predict_value
    monkeypatch.setattr(loop, "predict_value", lambda *a, **k: predicted.append(1) or real_predict(*a, **k))
    system = make_system("swimmer9")
    cfg = LoopConfig(budget_cycles=30, seed=0)
    search = GaitSearch(nominal_gait(system), gait_limits(system), cfg)
    search.observe(_start_data(system, nominal_gait(system), cfg))
    assert search.request().kind == "candidate"
    assert predicted and len(fits) == 1  # the hint was asked (and said nothing); the step fitted nothing again


def test_reverse_odds_count_paired_draws_that_predict_the_reversed_drive_better() -> None:
    """``reverse_odds``: each seeded draw predicts both drives with the same coefficients.  eel4's model of
    its wave run the wrong way says the other way is faster in most draws (it is, 1.7×); the model of its
    nominal wave says so in few (it is not).  Seeded; no covariance: (0, 0)."""
    from suds_ros.core.optimize.data import learn_model
    from suds_ros.core.optimize.loop import reverse_odds
    from suds_ros.core.physics.gait import time_reversed

    system = load_system(str(ROBOTS / "eel4.yaml"))
    nom = nominal_gait(system)
    cfg = LoopConfig(budget_cycles=5, seed=0)
    counts = {}
    for name, gait in (("nominal", nom), ("reversed", time_reversed(nom))):
        model = learn_model(_start_data(system, gait, cfg))
        wins, told = reverse_odds(model, gait, "speed", draws=16, seed=0)
        assert 0 <= wins <= told <= 16
        assert reverse_odds(model, gait, "speed", draws=16, seed=0) == (wins, told)
        assert reverse_odds(dataclasses.replace(model, chol=None), gait, "speed") == (0, 0)
        counts[name] = (wins, told)
    assert counts["reversed"][1] >= 12 and 2 * counts["reversed"][0] > counts["reversed"][1]
    assert 2 * counts["nominal"][0] < counts["nominal"][1]


@pytest.mark.parametrize(("odds", "tried"), [((12, 16), True), ((8, 16), False), ((7, 7), False)])
def test_a_reverse_trial_the_point_prediction_refuses_runs_when_most_draws_predict_it_faster(
        monkeypatch: pytest.MonkeyPatch, odds: tuple[int, int], tried: bool) -> None:
    """Far outside its data the model's point prediction of the reversed drive is skewed (a random 7-link
    robot's read 0.08× the incumbent from one start and 5.8× from another, truly 3.8×): where it says
    slower, the trial still runs when more than half of the draws that predict both drives say faster,
    and at least half of the draws predict.  eel4's nominal wave: the point prediction says slower."""
    from suds_ros.core.optimize import loop

    monkeypatch.setattr(loop, "reverse_odds", lambda *a, **k: odds)
    system = load_system(str(ROBOTS / "eel4.yaml"))
    cfg = LoopConfig(budget_cycles=30, seed=0)
    search = GaitSearch(nominal_gait(system), gait_limits(system), cfg)
    search.observe(_start_data(system, nominal_gait(system), cfg))
    req = search.request()
    assert (req.kind == "reverse") == tried
    if tried:
        assert f"{odds[0]} of {odds[1]} coefficient draws predict it faster" in req.note


def test_the_returned_prediction_carries_its_spread_over_coefficient_draws() -> None:
    """``predicted_std``: the robust spread of the prediction over seeded coefficient draws of the model that
    made it (the model's own coefficients give its prediction back; no covariance or one draw: None)."""
    from suds_ros.core.optimize.data import learn_model
    from suds_ros.core.optimize.loop import predict_value, predicted_std

    system = make_system("purcell3")
    gait = nominal_gait(system)
    cfg = LoopConfig(budget_cycles=5, seed=0)
    model = learn_model(_start_data(system, gait, cfg))
    assert predict_value(model, gait, "speed", coef=model.coef) == predict_value(model, gait, "speed")
    sd = predicted_std(model, gait, "speed", seed=3)
    assert sd is not None and 0 < sd < predict_value(model, gait, "speed")
    assert predicted_std(model, gait, "speed", seed=3) == sd and predicted_std(model, gait, "speed", seed=4) != sd
    assert predicted_std(model, gait, "speed", draws=1) is None
    assert predicted_std(dataclasses.replace(model, chol=None), gait, "speed") is None
    res = optimize_loop(system, cfg, start=gait)  # the start only: its model's prediction, with its spread
    assert res.predicted is not None and res.predicted_std is not None and res.predicted_std > 0


def test_a_model_with_more_coefficients_than_rows_has_a_spread_of_the_size_of_its_error() -> None:
    """A model of swimmer9's first 4 cycles (random shape features: more coefficients than rows) gets
    draws that keep a steady state and a spread of the size of its miss: its residual variance counts
    the ridge fit's effective parameters, not all of them (which made every sd √n too large)."""
    from suds_ros.core.optimize.data import learn_model
    from suds_ros.core.optimize.loop import predict_value, predicted_std

    system = load_system("swimmer9")
    gait = nominal_gait(system)
    model = learn_model(_start_data(system, gait, LoopConfig(budget_cycles=5, seed=0)))
    assert model.coef.shape[0] > model.identifier.regressor_.normal_.n  # (p > n: the case in question)
    assert np.all(model.resid_std < 1.0), model.resid_std  # m/s and rad/s; counting all p gave 4-9
    sd = predicted_std(model, gait, "speed", draws=8, seed=0)
    miss = abs(predict_value(model, gait, "speed") - evaluate_gait(system, gait)["speed"])
    assert sd is not None and miss / 4 < sd < 4 * miss + 0.05, (sd, miss)


def test_the_loop_fits_its_models_in_the_body_frame_it_is_given() -> None:
    """``body_frame``: the search's models carry the shape frame's weights by default, none in the pose frame;
    the rotation read off the model is the same either way (the frame turns with the periodic shape only)."""
    from suds_ros.core.optimize.loop import model_rotation

    system = make_system("purcell3")
    gait = nominal_gait(system)
    data = _start_data(system, gait, LoopConfig(budget_cycles=5, seed=0))
    models = {}
    for frame in ("shape", "pose"):
        search = GaitSearch(gait, gait_limits(system), LoopConfig(budget_cycles=20, seed=0, body_frame=frame))
        models[frame] = search._learn(data, torque=False)
    assert models["shape"].frame_weights is not None and models["pose"].frame_weights is None
    rot = {k: model_rotation(m, gait, draws=0)[0] for k, m in models.items()}
    assert abs(rot["shape"] - rot["pose"]) < 0.01, rot  # two fits of the same cycles: close, not equal


def test_random_features_decides_whether_the_loops_models_may_be_random_feature_models() -> None:
    """``random_features``: from purcell3's 5 cycles the default selection picks a random-feature model
    (``docs/results/optimize_loop.md``, ablation no-kernel); switched off, the model is the Fourier regression."""
    system = make_system("purcell3")
    gait = nominal_gait(system)
    data = _start_data(system, gait, LoopConfig(budget_cycles=5, seed=0))
    kernels = {}
    for on in (True, False):
        search = GaitSearch(gait, gait_limits(system), LoopConfig(budget_cycles=20, seed=0, random_features=on))
        kernels[on] = search._learn(data, torque=False).suds.kernel_features
    assert kernels[True] > 0 and kernels[False] == 0, kernels


def test_the_spread_of_draws_is_robust_to_the_few_that_predict_far_off() -> None:
    """``draw_spread``: the normal-scaled median absolute deviation of the finite draws.

    For normal draws it estimates their sd (2000 seeded draws of sd 0.3: within 5 %); two draws of 16
    far off (a coefficient draw near a gait with no steady state) leave it near the sd of the rest,
    where the sample sd grows a hundredfold; non-finite draws are left out; fewer than two: None.
    """
    from suds_ros.core.optimize.loop import draw_spread

    rng = np.random.default_rng(7)
    assert draw_spread(list(rng.normal(1.0, 0.3, 2000))) == pytest.approx(0.3, rel=0.05)
    good = list(rng.normal(0.3, 0.02, 14))
    wild = [*good, 40.0, -35.0]
    assert float(np.std(wild, ddof=1)) > 100 * float(np.std(good, ddof=1))
    assert draw_spread(wild) < 2 * float(np.std(good, ddof=1))
    assert draw_spread([*good, math.nan, math.inf]) == draw_spread(good)
    assert draw_spread([0.3]) is None and draw_spread([0.3, math.nan]) is None and draw_spread([]) is None


def test_the_bound_is_judged_on_the_models_rotation_where_one_was_fitted() -> None:
    """``rotation_reading``: the model's rotation at δ = 0 with the smaller of its spread and the cycles' se."""
    cfg = LoopConfig(budget_cycles=20, rotation_sigmas=0.0)
    raw_over = dataclasses.replace(_m(0.9, 0.09), rotation_se=0.1)
    straight = dataclasses.replace(raw_over, model_rotation=0.02, model_rotation_se=0.01)
    assert straight.rotation_reading() == (0.02, 0.01)
    assert is_better(straight, _m(0.1, 0.0), cfg)  # the mean of the cycles is over the bound; the model is not
    assert not is_better(raw_over, _m(0.1, 0.0), cfg)
    turning = dataclasses.replace(_m(0.9, 0.01), rotation_se=0.1, model_rotation=-0.09, model_rotation_se=0.01)
    assert not is_better(turning, _m(0.1, 0.0), cfg)  # the model says it turns: refused, whatever the mean says
    # the spread: never wider than the cycles' own se; no spread from the draws: the cycles' se
    assert dataclasses.replace(straight, model_rotation_se=0.5).rotation_reading() == (0.02, 0.1)
    assert dataclasses.replace(straight, model_rotation_se=None).rotation_reading() == (0.02, 0.1)
    one = dataclasses.replace(straight, rotation_se=float("nan"), model_rotation_se=None)
    assert one.rotation_reading()[0] == 0.02 and math.isnan(one.rotation_reading()[1])
    # a lax bound (a symmetric-looking robot) is lax by the reading's se, not by the cycles'
    lax = LoopConfig(budget_cycles=20, rotation_sigmas=1.0)
    assert is_better(dataclasses.replace(_m(0.9, 0.0), rotation_se=0.1), _m(0.1, 0.0), lax)
    assert not is_better(dataclasses.replace(raw_over, rotation=0.07, model_rotation=0.07, model_rotation_se=0.01),
                         _m(0.1, 0.0), lax)
    assert is_better(dataclasses.replace(raw_over, rotation=0.07), _m(0.1, 0.0), lax)  # the mean alone: within 1 se


def test_the_models_rotation_reads_a_turning_gait_closer_than_the_mean_of_its_cycles() -> None:
    """snake5 bent by 0.5 rad truly turns by −0.093 rad/cycle, about twice the bound.

    Over 3 seeds the model of each seed's 4 cycles reads it closer than their mean, and over the bound
    each time: a turning gait is still refused.  Its spread over draws is robust (a median absolute
    deviation) and is positive.
    """
    from suds_ros.core.optimize.data import learn_model
    from suds_ros.core.optimize.loop import measure_recording, model_rotation

    system, _ = _bent_snake5()
    nom = nominal_gait(system)
    x = 0.8 * nom.to_vector()
    x[0] += 0.5
    bent = nom.from_vector(x, nom.order)
    true = evaluate_gait(system, bent)["rotation"]
    assert true == pytest.approx(-0.093, abs=0.005)
    raw_err, model_err = [], []
    for seed in range(3):
        cfg = LoopConfig(budget_cycles=40, seed=seed)
        data = _start_data(system, bent, cfg)
        raw = measure_recording(data, cfg.samples_per_cycle, bent.gait_hz).rotation
        value, spread = model_rotation(learn_model(data), bent, seed=seed)
        assert value < -cfg.max_rotation
        assert spread is not None and spread > 0
        raw_err.append(raw - true)
        model_err.append(value - true)
    assert np.sqrt(np.mean(np.square(model_err))) < np.sqrt(np.mean(np.square(raw_err)))


def test_a_measurement_carries_the_models_rotation_and_falls_back_to_the_mean(monkeypatch: pytest.MonkeyPatch) -> None:
    """The search measures with the model of the run's cycles; a model that cannot be fitted leaves the mean."""
    from suds_ros.core.errors import SudsDataError
    from suds_ros.core.optimize import loop

    system = make_system("purcell3")
    gait = nominal_gait(system)
    cfg = LoopConfig(budget_cycles=20, seed=0)
    data = _start_data(system, gait, cfg)
    search = GaitSearch(gait, gait_limits(system), cfg)
    fitted = search._measure(data, gait)
    assert fitted.model_rotation is not None and abs(fitted.model_rotation) < cfg.max_rotation
    assert fitted.rotation_reading()[0] == fitted.model_rotation

    def refuse(*args: Any, **kwargs: Any) -> Any:
        raise SudsDataError("`rec`: expected at least 3 gait cycles to learn from, got 1.00", code="too_little_data")

    monkeypatch.setattr(loop, "learn_model", refuse)
    plain = GaitSearch(gait, gait_limits(system), cfg)._measure(data, gait)
    assert plain.model_rotation is None and plain.rotation_reading() == (plain.rotation, plain.rotation_se)
    assert plain.speed == fitted.speed and plain.rotation == fitted.rotation
    turn = GaitSearch(gait, gait_limits(system), dataclasses.replace(cfg, objective="turn"))._measure(data, gait)
    assert turn.model_rotation is None  # (the turn is the objective: read from the cycles)


def test_the_earlier_incumbents_stretches_join_the_steps_model_on_request() -> None:
    """``pool_incumbents``: the newest N stretches of earlier incumbents are fitted with the incumbent's.

    From purcell3 at half amplitude the scaled start is kept at once, so the step after it is planned on
    a model of the scaled gait's cycles and, with ``pool_incumbents`` = 1, the start's; by default
    (0) on the scaled gait's alone.  A change said while a candidate ran drops them.
    """
    system = make_system("purcell3")
    nom = nominal_gait(system)
    half = nom.from_vector(0.5 * nom.to_vector(), nom.order)
    fits: dict[int, list[tuple[Any, ...]]] = {}

    class Watched(GaitSearch):
        def _learn(self, data: Any, torque: bool) -> Any:
            recs = (data,) if not isinstance(data, (list, tuple)) else tuple(data)
            fits.setdefault(self.config.pool_incumbents, []).append(recs)
            return super()._learn(data, torque)

    for n in (0, 1):
        res = optimize_loop(system, LoopConfig(budget_cycles=15, seed=0, pool_incumbents=n), start=half,
                            search=Watched)
        assert [it.accepted for it in res.iterations][:2] == [True, True]  # the start, then its scaled run
    assert max(len(r) for r in fits[1]) > max(len(r) for r in fits[0])  # one more stretch: the start's
    # the bookkeeping itself: newest N, none across a change said while the new incumbent ran
    search = GaitSearch(nom, gait_limits(system), LoopConfig(budget_cycles=20, pool_incumbents=2))
    a, b, c = (SimpleNamespace(name=x) for x in "abc")
    search._best_meas, search._best_data = _m(0.1, 0.0), [a]
    for new in (b, c):
        search._take(nom, _m(0.1, 0.0), [new], None)
    assert search._past == [a, b] and search._best_data == [c]
    search._fresh = True
    search._take(nom, _m(0.1, 0.0), [a], None)
    assert search._past == []
    with pytest.raises(SudsConfigError, match="pool_incumbents"):
        LoopConfig(budget_cycles=20, pool_incumbents=-1)


def test_a_candidate_run_again_to_confirm_it_is_a_change_test_too() -> None:
    """A confirmation runs the same gait again, as a re-run of the incumbent does: when the robot changes
    between its two runs (purcell3's spring 3× stiffer against the drag), the candidate is not judged on the
    two robots pooled; the incumbent is measured afresh next and its old data dropped."""
    system = make_system("purcell3")
    cfg = LoopConfig(budget_cycles=26, seed=3, confirm_sigmas=1.0, half_wave=False)  # (seed 3: confirmations)
    its = optimize_loop(system, cfg).iterations
    i = next(k for k, it in enumerate(its) if it.note.startswith("to be confirmed"))
    assert not its[i + 1].note.startswith("not judged")  # unchanged: judged on both runs pooled
    stiffer = [{"name": "stiffness_to_drag_error", "scale": 3.0}]
    changed = optimize_loop(system, cfg, changes=[(its[i].cycles_used, stiffer)]).iterations
    assert [it.note for it in changed[:i + 1]] == [it.note for it in its[:i + 1]]  # the same run until then
    again, rerun = changed[i + 1], changed[i + 2]
    assert not again.accepted and again.note.startswith("not judged: the robot changed while it was confirmed")
    incumbent = max((it for it in changed[:i] if it.accepted), key=lambda it: it.index)
    assert rerun.accepted and rerun.gait is incumbent.gait
    assert "the robot changed (said changed: the candidate, run again" in rerun.note
    assert rerun.measured.cycles == cfg.step_cycles  # measured afresh: the standing data dropped


def test_a_half_wave_gait_turning_far_past_the_bound_on_a_symmetric_robot_has_the_incumbent_run_again() -> None:
    """On a mirror-symmetric robot a half-wave gait runs straight: snake5's nominal wave measures so.  Its
    spring rest bent after the start, the first candidate (a half-wave step) measures turning far past the
    bound; the incumbent is run again at once, which shows the change."""
    system, _ = _bent_snake5()
    cfg = LoopConfig(budget_cycles=15, seed=0)
    res = optimize_loop(system, cfg, changes=[(5, [{"name": "spring_rest_offset", "joint": "joint_3",
                                                    "offset": 0.7}])])
    its = res.iterations
    assert its[1].gait.is_half_wave() and not its[1].accepted, [it.note for it in its]
    assert its[2].note.startswith("incumbent re-run (a half-wave gait measured turning"), [it.note for it in its]
    assert "looked mirror-symmetric" in its[2].note and "the robot changed" in its[2].note
    unchanged = optimize_loop(system, cfg).iterations
    assert not any("looked mirror-symmetric" in it.note for it in unchanged)
