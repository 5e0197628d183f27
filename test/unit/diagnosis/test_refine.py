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
