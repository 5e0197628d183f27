"""Output-error refinement (:mod:`suds_ros.core.diagnosis.refine`): standard errors and segments."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.diagnosis.refine import _sandwich_stderr, _segments


# ------------------------------------------------------------------------------ standard errors
def test_stderr_is_consistent_with_the_seed_to_seed_spread(run_case) -> None:  # type: ignore[no-untyped-def]
    """Same injected effect, six seeds: the recovered values scatter as the reported stderr says."""
    true = -0.15
    vals, ses = [], []
    for seed in range(1, 7):
        rep = run_case("swimmer9", [dict(name="spring_rest_offset", joint="joint_8", offset=true)],
                       cycles=20, seed=seed)
        (e,) = [e for e in rep.effects if e.name == "spring_rest_offset" and e.target == "joint_8"]
        vals.append(e.parameters["offset"])
        ses.append(e.stderr["offset"])
    vals_a, ses_a = np.array(vals), np.array(ses)
    z = (vals_a - true) / ses_a
    assert np.sum(np.abs(z) < 4) >= 5, (vals, ses)
    assert ses_a.mean() >= np.std(vals_a, ddof=1) / 3, (vals, ses)
    assert ses_a.mean() <= 10 * max(np.std(vals_a, ddof=1), np.abs(vals_a - true).max()), (vals, ses)


def test_segments_are_whole_and_consecutive() -> None:
    assert _segments(0, 1000, 300) == [0, 300, 600]
    assert _segments(100, 350, 100) == [100, 200]
    assert _segments(0, 50, 100) == []


def test_sandwich_stderr_matches_ordinary_least_squares_for_iid_residuals() -> None:
    """Many clusters of i.i.d. residuals: the sandwich and the model-based error agree with σ/√(Σx²)."""
    rng = np.random.default_rng(2)
    B, k = 400, 20
    J = rng.standard_normal((B * k, 1))
    R = 0.5 * rng.standard_normal((B, k))
    se = _sandwich_stderr(J, R, 1)
    expect = 0.5 / np.sqrt(np.sum(J**2))
    assert se[0] == pytest.approx(expect, rel=0.1)
    assert np.isnan(_sandwich_stderr(np.zeros((B * k, 1)), R, 1)).all()


# ------------------------------------------------------------------------------ neutral members
@pytest.mark.parametrize("spread, dropped", [(1.4e-4, ("sensor_time_offset",)), (0.0, ())])
def test_a_member_is_dropped_when_its_reported_stderr_covers_its_neutral_value(monkeypatch, spread, dropped) -> None:
    """A time offset of -0.1 ms beside a damping, known to 0.02 ms by sampling but spread by 0.14 ms
    over the channels and gait quarters (a misfit): the report could only say "-0.1 ± 0.14 ms", so
    the member is dropped and the damping refined alone; with no spread it is 5 stderr from zero
    and kept."""
    from suds_ros.core.diagnosis import DiagnoseConfig, refine
    from suds_ros.core.diagnosis.naming import Candidate
    from suds_ros.core.physics.systems import purcell3_model

    calls = []

    def fake(cand, x0, *args):  # type: ignore[no-untyped-def]
        calls.append(cand)
        if len(cand.parts) == 2:
            return refine.Refined(cand, np.array([0.4, -1e-4]), np.array([0.01, 2e-5]),
                                  np.array([0.0, spread]), np.array([1.0, 1e-9]))
        return refine.Refined(cand, np.array([0.41]), np.array([0.01]), np.zeros(1), np.ones(1))

    monkeypatch.setattr(refine, "_refine", fake)
    cand = Candidate((("joint_viscous_damping", "joint_2"), ("sensor_time_offset", None)))
    got = refine.refine_choice(cand, np.array([0.5, 0.0]), purcell3_model(), None, DiagnoseConfig(), 1, 1, None)
    assert got.dropped == dropped
    assert len(calls) == 1 + len(dropped)
    assert len(got.cand.parts) == 2 - len(dropped)


# ------------------------------------------------------------------------------ score test
def _gains(effects, parts):  # type: ignore[no-untyped-def]
    """First-order output-error gains of ``parts`` on top of a damping on joint_2 refined alone."""
    from suds_ros.core.diagnosis import DiagnoseConfig
    from suds_ros.core.diagnosis.data import prepare
    from suds_ros.core.diagnosis.naming import Candidate
    from suds_ros.core.diagnosis.pipeline import replay_nominal
    from suds_ros.core.diagnosis.refine import extension_gains, refine_choice
    from suds_ros.core.physics.effects import apply_effects
    from suds_ros.core.physics.rft import RFTChain
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import purcell3_model

    base = purcell3_model()
    model, _ = apply_effects(base, effects)
    config = DiagnoseConfig(refine_cycles=10)
    nom = replay_nominal(prepare(simulate(RFTChain(model), SimConfig(cycles=20, seed=8)), base), base, config, None)
    damping = Candidate((("joint_viscous_damping", "joint_2"),))
    got = refine_choice(damping, np.array([0.5]), base, nom.data, config, nom.w, nom.substeps, nom.floors)
    return extension_gains(got.cand, got.x, parts, base, nom.data, config, nom.w, nom.substeps, nom.floors)


def test_the_score_test_sees_an_effect_that_a_damping_on_its_joint_stood_in_for() -> None:
    """A damping refined alone on a joint that also has a Coulomb friction: the friction's first-order
    gain on top of it is far above the evidence threshold and ten times any other effect's (which
    also explain a little of what the damping misses); with no friction in the robot, nothing
    passes the threshold."""
    from suds_ros.core.diagnosis import DiagnoseConfig

    parts = [("joint_coulomb_friction", "joint_2"), ("spring_rest_offset", "joint_2"), ("link_drag_error", "link_1")]
    threshold = DiagnoseConfig().evidence_threshold
    both = _gains([dict(name="joint_viscous_damping", joint="joint_2", d=0.45),
                   dict(name="joint_coulomb_friction", joint="joint_2", mu=0.4)], parts)
    assert both[0] > 10 * threshold and both[0] > 10 * max(both[1:]), both
    alone = _gains([dict(name="joint_viscous_damping", joint="joint_2", d=0.45)], parts)
    assert max(alone) < threshold, alone


# ------------------------------------------------------------------------------ misfit spread
def _parts_fit(bias_sd: float, seed: int):  # type: ignore[no-untyped-def]
    """A one-parameter least-squares fit over 20 segments × 8 parts whose parts are biased.

    Each part s carries a systematic offset b_s (the same in every segment, sd ``bias_sd``) along
    the parameter's column, as an error the model lacks would; returns (J, R, parts, true spread).
    """
    rng = np.random.default_rng(seed)
    B, S, m = 20, 8, 30
    parts = np.repeat(np.arange(S), m)
    j = rng.standard_normal((B, S * m))
    b = bias_sd * rng.standard_normal(S)
    y = j * b[parts][None, :] + rng.standard_normal((B, S * m))
    x = np.sum(j * y) / np.sum(j**2)  # the fit
    return j.reshape(-1, 1), y - x * j, parts, float(np.std(b, ddof=1))


def test_misfit_spread_is_zero_when_the_parts_agree() -> None:
    """No part biased: over 100 fits the test rejects about as often as its level (1 %), and a
    spread, when it is reported at all, is small next to the sampling error."""
    from suds_ros.core.diagnosis.refine import _sandwich_stderr, misfit_spread

    rejected, pvals = 0, []
    for seed in range(100):
        J, R, parts, _ = _parts_fit(0.0, seed)
        spread, p = misfit_spread(J, R, parts, 0.01)
        pvals.append(p[0])
        rejected += int(spread[0] > 0)
        assert spread[0] <= 3 * _sandwich_stderr(J, R, 1)[0] * np.sqrt(8)
    assert rejected <= 5
    assert 0.3 < np.median(pvals) < 0.7  # roughly uniform under agreement


def test_misfit_spread_measures_the_parts_disagreement() -> None:
    """Parts biased by sd 0.3 with a sampling error near 0.015 (0.04 per part): the test rejects,
    and the spread is the parts' own (within 40 %), more than ten times the sampling error."""
    from suds_ros.core.diagnosis.refine import _sandwich_stderr, misfit_spread

    for seed in range(5):
        J, R, parts, true = _parts_fit(0.3, seed)
        spread, p = misfit_spread(J, R, parts, 0.01)
        assert p[0] < 1e-6
        assert spread[0] == pytest.approx(true, rel=0.4), (spread, true)
        assert spread[0] > 10 * _sandwich_stderr(J, R, 1)[0]


def test_misfit_spread_holds_the_other_parameters_at_their_fit() -> None:
    """Two parameters: a bias along the second's column shows in the second's spread; the first,
    whose column is orthogonal to it, is left alone."""
    from suds_ros.core.diagnosis.refine import misfit_spread

    rng = np.random.default_rng(5)
    B, S, m = 20, 8, 30
    parts = np.repeat(np.arange(S), m)
    j1, j2 = rng.standard_normal((2, B, S * m))
    b = 0.2 * rng.standard_normal(S)
    y = j2 * b[parts][None, :] + rng.standard_normal((B, S * m))
    J = np.stack([j1.ravel(), j2.ravel()], axis=1)
    x = np.linalg.lstsq(J, y.ravel(), rcond=None)[0]
    R = (y.ravel() - J @ x).reshape(B, -1)
    spread, p = misfit_spread(J, R, parts, 0.01)
    assert spread[0] == 0.0 and p[0] > 0.01
    assert spread[1] > 0.1 and p[1] < 1e-6


def test_is_neutral_needs_every_parameter_within_z_and_a_defined_stderr() -> None:
    """One rule for a refined member dropped as neutral and an alternative set aside as one."""
    from suds_ros.core.diagnosis.refine import is_neutral

    assert is_neutral([2.01, 0.0], [0.01, 0.5], [2.0, 0.0], 4.0)
    assert not is_neutral([2.01, 3.0], [0.01, 0.5], [2.0, 0.0], 4.0)  # one parameter 6 se off
    assert not is_neutral([2.0], [np.nan], [2.0], 4.0)  # a fit that cannot say: not neutral
    assert not is_neutral([2.0], [0.0], [2.0], 4.0)


def test_residual_parts_follow_the_residual_layout() -> None:
    """One passive joint, a 100-sample cycle, windows of 10: r_p's samples fall in its four
    quarters, 25 each; ξ's windows (centred at 5, 15, … 85) in channel 1–3's quarters by centre."""
    from types import SimpleNamespace

    from suds_ros.core.diagnosis.refine import _residual_parts

    data = SimpleNamespace(pas=np.array([1]), spc=100)
    parts = _residual_parts(data, 100, 10, 100 + 9 * 3)  # type: ignore[arg-type]
    assert np.array_equal(np.bincount(parts[:100]), [25, 25, 25, 25])
    xi = parts[100:].reshape(9, 3)  # window-major, (x, y, θ) per window
    assert np.array_equal(xi[:, 0] // 4, np.ones(9)) and np.array_equal(xi[:, 2] // 4, np.full(9, 3))
    assert list(xi[:, 0] % 4) == [0, 0, 1, 1, 1, 2, 2, 3, 3]  # centres 5, 15 | 25, 35, 45 | 55, 65 | 75, 85


def test_a_start_whose_replay_diverges_is_moved_towards_the_neutral_parameters() -> None:
    """The equation-error start of a softening spring can make the replay diverge: the refinement starts from
    the first point towards the neutral value that replays (and the neutral value's own failure is raised)."""
    from suds_ros.core.diagnosis.refine import _replayable_start
    from suds_ros.core.errors import SudsSimulationError

    tried = []

    def sim(x: np.ndarray) -> np.ndarray:
        tried.append(float(x[0]))
        if abs(x[0]) > 2.0:
            raise SudsSimulationError("diverged")
        return np.array([[x[0]]])

    x, r = _replayable_start(sim, np.array([-12.0]), np.array([0.0]))
    assert tried == [-12.0, -6.0, -3.0, -1.5] and x[0] == -1.5 and r[0, 0] == -1.5
    with pytest.raises(SudsSimulationError):  # not even the neutral parameters replay
        _replayable_start(sim, np.array([12.0]), np.array([3.0]))
