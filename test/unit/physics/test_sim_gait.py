"""The simulator driven by a gait.

The nominal gait as a gait reproduces the nominal run; the stream switches gait without a jump.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.gait import nominal_gait
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.physics.stream import StreamingSimulator
from suds_ros.core.physics.systems import make_system

CFG = SimConfig(cycles=3, samples_per_cycle=50, warmup=1.0, seed=3)


@pytest.mark.parametrize("name", ["purcell3", "swimmer9"])
def test_nominal_gait_reproduces_the_nominal_run(name: str) -> None:
    system = make_system(name)
    a = simulate(system, CFG)
    b = simulate(system, replace(CFG, gait=nominal_gait(system)))
    # same seed → same OU and noise draws; the reference differs only by rounding (sin of a sum vs its expansion)
    np.testing.assert_allclose(b.r, a.r, atol=1e-12)
    np.testing.assert_allclose(b.pose, a.pose, atol=1e-12)
    lab = LabConditions(pose_hz=40.0)
    np.testing.assert_allclose(simulate_lab(system, replace(CFG, gait=nominal_gait(system)), lab).pose,
                               simulate_lab(system, CFG, lab).pose, atol=1e-12)


def test_a_gait_drives_the_actuated_joints_and_ou_zero_switches_the_perturbation_off() -> None:
    system = make_system("purcell3")
    g = nominal_gait(system)
    g2 = g.from_vector(np.array([0.1, 0.3, -0.2, 0.9, 0.05, 0.0, 0.0]), 3)
    cfg = replace(CFG, gait=g2, ou_std=0.0, noise_std=0.0)
    rec = simulate(system, cfg)
    t = np.arange(rec.t.size) / cfg.samples_per_cycle  # (stamps near 1.7e9 s carry 2e-7 s rounding)
    np.testing.assert_allclose(rec.r[:, 0], g2.r(t)[:, 0], atol=1e-12)


def test_gait_of_another_system_or_frequency_is_refused() -> None:
    g = nominal_gait(make_system("swimmer9"))
    with pytest.raises(SudsConfigError, match="`system`: the gait is for 'swimmer9'"):
        simulate(make_system("purcell3"), replace(CFG, gait=g))
    with pytest.raises(SudsConfigError, match="`gait`: expected a Gait at `gait_hz` = 2 Hz, got 1.0"):
        replace(CFG, gait_hz=2.0, gait=g)


def test_stream_switches_gait_at_a_cycle_boundary_without_a_jump() -> None:
    system = make_system("purcell3")
    spc = 50
    cfg = SimConfig(samples_per_cycle=spc, warmup=0.0, ou_std=0.0, noise_std=0.0)
    sim = StreamingSimulator(system, cfg)
    first = sim.step(spc)
    new = nominal_gait(system).from_vector(np.array([0.3, 0.8, 0.0, 0.0, 0.6, 0.0, 0.0]), 3)
    s0 = sim.set_gait(new)
    assert s0 == pytest.approx(1.0)
    second, third = sim.step(spc), sim.step(spc)
    r = np.concatenate([first.r_true[:, 0], second.r_true[:, 0], third.r_true[:, 0]])
    steps = np.abs(np.diff(r))
    nominal_step = 2 * np.pi * 1.4 / spc  # the largest step the nominal gait takes per sample
    assert steps.max() <= 1.05 * max(nominal_step, 2 * np.pi * 0.8 * 3 / spc)  # no jump at the switch
    assert second.r_true[0, 0] == pytest.approx(system.reference(np.array([1.0]))[0, 0], abs=1e-12)
    # one cycle after the switch the new gait holds exactly
    t = np.arange(spc) / spc
    np.testing.assert_allclose(third.r_true[:, 0], new.r(t)[:, 0], atol=1e-12)
    assert sim.gait == new
    with pytest.raises(SudsConfigError, match="`gait_hz`: the gait runs at 2 Hz"):
        sim.set_gait(replace(new, gait_hz=2.0))
