"""Locating a mismatch (:mod:`suds_ros.core.diagnosis.locate`): F statistics, improvement, phase ranges."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.diagnosis import excess_improvement
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.locate import ChannelTable, phase_ranges
from suds_ros.core.physics.systems import purcell3_model


def test_excess_improvement_counts_only_the_excess_over_the_floor() -> None:
    before = {"a": 5.0, "b": 1.0}
    assert excess_improvement(before, {"a": 1.0, "b": 1.0}, ["a", "b"]) == pytest.approx(1.0)
    assert excess_improvement(before, {"a": 2.0, "b": 0.5}, ["a"]) == pytest.approx(0.5)
    assert excess_improvement(before, {"a": 5.0, "b": 9.0}, ["a"]) == pytest.approx(0.0)
    assert excess_improvement({"a": 0.9}, {"a": 3.0}, ["a"]) == 0.0  # nothing to improve


def residual_on_a_quarter(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.random.Generator]:
    """12 cycles of 100 samples: phase, cycle number and a residual of noise 0.1 plus 1 on phase (π/2, π)."""
    rng = np.random.default_rng(seed)
    phase = 2 * np.pi * np.arange(12 * 100) / 100
    ph = np.mod(phase, 2 * np.pi)
    e = 0.1 * rng.standard_normal(phase.size) + np.where((ph > np.pi / 2) & (ph < np.pi), 1.0, 0.0)
    return phase, np.floor(phase / (2 * np.pi)), e, rng


def test_phase_ranges_find_the_affected_bins() -> None:
    phase, cycle, e, rng = residual_on_a_quarter(1)
    (rng_,) = phase_ranges(phase, e, cycle, 20, 0.01)
    assert rng_[0] == pytest.approx(np.pi / 2, abs=2 * np.pi / 20 + 1e-9)
    assert rng_[1] == pytest.approx(np.pi, abs=2 * np.pi / 20 + 1e-9)
    assert phase_ranges(phase, 0.1 * rng.standard_normal(phase.size), cycle, 20, 0.01) == ()
    # a residual spread over the whole cycle covers it
    assert phase_ranges(phase, 1.0 + 0.01 * rng.standard_normal(phase.size), cycle, 20, 0.01) == ((0.0, 2 * np.pi),)


def test_phase_ranges_skip_bins_seen_in_fewer_than_two_cycles_without_a_warning() -> None:
    """Frames lost by a tracker leave phase bins with data from one cycle or none: those bins are
    not tested (no spread to test against), no numpy warning reaches the user, the rest still is."""
    import warnings

    phase, cycle, e, _ = residual_on_a_quarter(3)
    ph = np.mod(phase, 2 * np.pi)
    lost = (ph > 4.0) & (ph < 5.0) & (cycle > 0)  # one bin range seen in cycle 0 only, one never
    e[lost | ((ph > 5.5) & (ph < 5.8))] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ranges = phase_ranges(phase, e, cycle, 20, 0.01)
    assert ranges[0][0] == pytest.approx(np.pi / 2, abs=2 * np.pi / 20 + 1e-9)
    assert ranges[0][1] == pytest.approx(np.pi, abs=2 * np.pi / 20 + 1e-9)
    assert not any(a < 5.7 and b > 5.6 for a, b in ranges)  # a bin no cycle saw is never called affected


def test_channel_table_statistics(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    data = prepare(purcell3_run, purcell3_model())
    table = ChannelTable.of(data, 10)
    assert table.channels == ("joint_2", "xi_x", "xi_y", "xi_theta")
    n = data.n_used
    E = table.residuals(data.r[:n][:, data.pas], table.xi_rec)
    assert np.nanmax(np.abs(E)) == 0.0  # the recording against itself
    floor = table.floor((np.array([0.5]), 0.25, 2.0))
    assert floor == {"joint_2": 0.5, "xi_x": 0.25, "xi_y": 0.25, "xi_theta": 2.0}
    E = np.ones((n, 4))
    assert table.rms(E) == {c: 1.0 for c in table.channels}
    assert table.fstats(E, floor)["joint_2"] == pytest.approx(4.0)


def test_replay_evidence_is_the_held_out_likelihood_gain(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    """Halving every held-out residual gains Σ (n_c/2)·log 4 nats, with n_c the held-out samples of a
    passive angle and held-out samples / w of a body velocity; parameters pay (p/2)·log median n_c;
    a NaN (a gap) counts in neither set of residuals."""
    data = prepare(purcell3_run, purcell3_model())
    w = 10
    table = ChannelTable.of(data, w)
    rng = np.random.default_rng(3)
    E0 = rng.normal(size=(data.n_used, 4))
    E0[data.n_used - 1, 0] = np.nan
    n_held = int(table.held.sum())
    n = np.array([n_held - 1, n_held / w, n_held / w, n_held / w])
    half = table.evidence(E0, E0 / 2, n_params=0)
    assert half == pytest.approx(0.5 * np.log(4.0) * n.sum(), rel=1e-12)
    assert table.evidence(E0, E0, n_params=2) == pytest.approx(-np.log(np.median(n)), rel=1e-12)
    E1 = E0.copy()
    E1[~table.held] = 0.0  # the training half does not count
    assert table.evidence(E0, E1, n_params=0) == pytest.approx(0.0, abs=1e-9)
