"""Lab-style recordings: own rates and start times, jitter, drops — and the aligned twin inside."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.systems import make_system


@pytest.fixture(scope="module")
def purcell3():  # type: ignore[no-untyped-def]
    return make_system("purcell3")


def test_without_lab_effects_it_is_the_aligned_twin(purcell3) -> None:  # type: ignore[no-untyped-def]
    cfg = SimConfig(cycles=3, seed=4)
    twin = simulate(purcell3, cfg)
    lab = simulate_lab(purcell3, cfg, LabConditions(pose_hz=None, pose_phase=0.0, jitter=0.0, drop=0.0))
    np.testing.assert_allclose(lab.t, twin.t, rtol=0, atol=1e-6)
    np.testing.assert_allclose(lab.pose_t, twin.pose_t, rtol=0, atol=1e-6)
    # same drive and physics: the noise-free states agree to the integrator's accuracy
    np.testing.assert_allclose(lab.truth["r"], twin.truth["r"], atol=2e-5)
    np.testing.assert_allclose(lab.truth["pose"], twin.truth["pose"], atol=2e-5)


def test_lab_streams_have_their_own_rates_jitter_and_drops(purcell3) -> None:  # type: ignore[no-untyped-def]
    cfg = SimConfig(cycles=10, seed=5)
    lab = simulate_lab(purcell3, cfg, LabConditions(pose_hz=120.0, pose_phase=0.0037, jitter=4e-4, drop=0.02))
    ts, tp = lab.t - cfg.t0, lab.pose_t - cfg.t0
    assert np.all(np.diff(ts) > 0) and np.all(np.diff(tp) > 0)
    assert 0.95 * 1000 < ts.size < 1000 and 0.95 * 1200 < tp.size < 1200
    assert np.median(np.diff(tp)) == pytest.approx(1 / 120, rel=0.02)
    dev = ts - np.rint(ts / cfg.dt) * cfg.dt
    assert 2e-4 < dev.std() < 6e-4 and np.abs(dev).max() <= 0.4 * cfg.dt + 1e-9
    assert tp[0] == pytest.approx(0.0037, abs=0.4 / 120 + 1e-9)
    assert np.any(np.diff(ts) > 1.5 * cfg.dt)  # some shape messages are missing


def test_pose_delay_not_a_multiple_of_the_period(purcell3) -> None:  # type: ignore[no-untyped-def]
    # a smooth drive (no OU), so that interpolating either stream between its samples is accurate
    cfg = SimConfig(cycles=3, seed=6, noise_std=0.0, ou_std=0.0)
    base = simulate_lab(purcell3, cfg, LabConditions(jitter=0.0, drop=0.0))
    late = simulate_lab(purcell3, SimConfig(cycles=3, seed=6, noise_std=0.0, ou_std=0.0, pose_delay=0.017),
                        LabConditions(jitter=0.0, drop=0.0))
    # the pose stamped s is the true pose at s − 17 ms
    s = late.pose_t[10:-10]
    np.testing.assert_allclose(late.pose_at(s), base.pose_at(s - 0.017), atol=2e-4)
    assert np.abs(late.pose_at(s) - base.pose_at(s)).max() > 100 * 2e-4


def test_jittered_stamps_read_the_run_without_an_interpolation_error() -> None:
    """swimmer9's stiff passive joints curve within one 2.5 ms integration step; the reading follows them.

    A straight line between the integration points erred by 3e-3 rad here (three noise stds),
    the same at every cycle; the cubic reading with the physics' own rates agrees with a run
    integrated 4× finer to 1e-4.
    """
    system = make_system("swimmer9")
    cfg = SimConfig(cycles=2, seed=1, noise_std=0.0)
    lab = LabConditions(pose_hz=None, pose_phase=0.0, jitter=4e-4, drop=0.0)
    coarse = simulate_lab(system, cfg, lab)
    fine = simulate_lab(system, cfg, LabConditions(pose_hz=None, pose_phase=0.0, jitter=4e-4, drop=0.0, oversample=16))
    np.testing.assert_array_equal(coarse.t, fine.t)
    assert np.abs(coarse.r - fine.r).max() < 1e-4 and np.abs(coarse.pose - fine.pose).max() < 1e-4


def test_stamped_on_arrival_values_are_ticks_stamps_carry_jitter(purcell3) -> None:  # type: ignore[no-untyped-def]
    """A device sampling on its own clock, stamped by the host as messages arrive: each value is the one the
    jitter-free recording holds at its tick (the same draws), each stamp that tick + latency + jitter, and
    the grid stage reads it as stamped late; read at the same stamps instead, it does not."""
    from suds_ros.core.resample import Grid

    cfg = SimConfig(cycles=12, seed=3)
    ticks = simulate_lab(purcell3, cfg, LabConditions(jitter=0.0))
    late = simulate_lab(purcell3, cfg, LabConditions(jitter=0.002, stamping="arrival", latency=0.003))
    read = simulate_lab(purcell3, cfg, LabConditions(jitter=0.002))
    np.testing.assert_array_equal(late.r, ticks.r)
    np.testing.assert_array_equal(late.truth["r"], ticks.truth["r"])
    np.testing.assert_array_equal(late.pose_t, read.pose_t)  # the pose stream read at its (jittered) stamps
    np.testing.assert_array_equal(late.pose, read.pose)
    dev = late.t - ticks.t - 0.003
    assert 1.5e-3 < dev.std() < 2.5e-3 and np.abs(dev).max() <= 0.4 * cfg.dt + 1e-6 and abs(dev.mean()) < 3e-4
    np.testing.assert_allclose(read.t - cfg.t0, late.t - cfg.t0 - 0.003, atol=1e-6)  # the same jitter draws
    assert Grid.of(late).snapped and not Grid.of(read).snapped


def test_bad_conditions_are_refused() -> None:
    with pytest.raises(SudsConfigError, match="`stamping`"):
        LabConditions(stamping="late")
    with pytest.raises(SudsConfigError, match="`latency`"):
        LabConditions(latency=-0.001)
    with pytest.raises(SudsConfigError, match="`drop`"):
        LabConditions(drop=0.7)
    with pytest.raises(SudsConfigError, match="`pose_hz`"):
        LabConditions(pose_hz=0.0)
