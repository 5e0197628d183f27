"""Grid helpers (:mod:`suds_ros.core.resample`): the window rule for lost samples, the grid's count."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.resample import fit_grid, window_any


def test_window_any_matches_a_direct_scan_over_each_window() -> None:
    """Random masks (1-D and stacked 2-D), spans 0 … 9: out[k] is any(mask[k … k + span])."""
    rng = np.random.default_rng(4)
    for _ in range(200):
        n = int(rng.integers(2, 50))
        span = int(rng.integers(0, min(n, 10)))
        mask = rng.random((3, n)) < rng.choice([0.0, 0.05, 0.3, 1.0])
        want = np.array([[row[k:k + span + 1].any() for k in range(n - span)] for row in mask])
        got = window_any(mask, span)
        assert got.shape == (3, n - span)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(window_any(mask[0], span), want[0])


def test_a_single_lost_sample_spoils_every_window_that_spans_it() -> None:
    mask = np.zeros(10, dtype=bool)
    mask[5] = True
    np.testing.assert_array_equal(np.flatnonzero(window_any(mask, 3)), [2, 3, 4, 5])


def test_the_grid_recounts_its_indices_in_its_own_fitted_step() -> None:
    """Counted in a period 16 % long, runs of four and five lost messages come out a period short; counted again
    in the fitted step they come out right, and the step is the stream's."""
    period = 0.01
    k_true = np.concatenate([np.arange(0, 50), 54 + np.arange(0, 50), 109 + np.arange(0, 50)])  # 4, then 5 lost
    t = period * k_true + np.random.default_rng(1).normal(0.0, 0.0005, k_true.size)
    k, a, b = fit_grid(t, 1.16 * period)
    np.testing.assert_array_equal(k, k_true)
    assert b == pytest.approx(period, rel=1e-3)
    once = np.concatenate([[0.0], np.cumsum(np.maximum(np.round(np.diff(t) / (1.16 * period)), 1.0))])
    assert once[-1] < k_true[-1]  # what counting once in that period gives


def test_the_grid_locks_to_the_stamps_phase_under_heavy_jitter() -> None:
    """With 2 ms of jitter on a 10 ms period (clipped at 4 ms, as the lab simulator does) and 45 % of the
    messages lost, counting interval by interval miscounts and the errors add up; rounding every stamp against
    the grid fitted to all of them gets every index and the step right."""
    period = 0.01
    rng = np.random.default_rng(4)
    keep = rng.random(6000) >= 0.45
    keep[[0, -1]] = True
    k_true = np.flatnonzero(keep).astype(float)
    t = period * k_true + np.clip(0.002 * rng.standard_normal(k_true.size), -0.004, 0.004)
    counted = np.concatenate([[0.0], np.cumsum(np.maximum(np.round(np.diff(t) / period), 1.0))])
    assert not np.array_equal(counted, k_true)  # what counting interval by interval gives
    k, a, b = fit_grid(t, 1.02 * period)
    np.testing.assert_array_equal(k, k_true)
    assert b == pytest.approx(period, rel=1e-5)


def test_the_phase_lock_leaves_a_lightly_jittered_grid_alone() -> None:
    """0.4 ms of jitter: no stamp is a quarter step off the counted line, so the count stands as it was."""
    period = 0.01
    rng = np.random.default_rng(5)
    keep = rng.random(3000) >= 0.3
    keep[[0, -1]] = True
    k_true = np.flatnonzero(keep).astype(float)
    t = period * k_true + 0.0004 * rng.standard_normal(k_true.size)
    k, a, b = fit_grid(t, period)
    np.testing.assert_array_equal(k, k_true)
    assert np.max(np.abs(t - a - b * k)) < 0.25 * b
