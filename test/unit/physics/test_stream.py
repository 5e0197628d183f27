"""Streaming simulator: chunking does not change the physics; stamps continue."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.stream import StreamingSimulator
from suds_ros.core.physics.systems import make_system


def test_chunking_does_not_change_the_trajectory() -> None:
    cfg = SimConfig(seed=5, warmup=1.0)
    a = StreamingSimulator(make_system("purcell3"), cfg)
    b = StreamingSimulator(make_system("purcell3"), cfg)
    whole = a.step(300)
    parts = [b.step(n) for n in (100, 1, 199)]
    np.testing.assert_allclose(np.concatenate([p.r_true for p in parts]), whole.r_true, atol=1e-12)
    np.testing.assert_allclose(np.concatenate([p.pose_true for p in parts]), whole.pose_true, atol=1e-12)
    np.testing.assert_allclose(np.concatenate([p.t for p in parts]), whole.t)
    assert whole.t[0] == cfg.t0
    np.testing.assert_allclose(np.diff(whole.t), 0.01, atol=1e-6)


def test_stream_excites_the_passive_joint_and_moves() -> None:
    sim = StreamingSimulator(make_system("purcell3"), SimConfig(seed=1))
    c = sim.step(500)
    assert 0.2 < c.r_true[:, 1].std() < 0.5
    assert np.linalg.norm(c.pose_true[-1, :2] - c.pose_true[0, :2]) > 0.05
    assert np.abs(c.r - c.r_true).std() < 2e-3


def test_streamed_effort_does_the_physics_work_of_the_gait() -> None:
    """Without the excitation, on the steady cycle: Σ τ_a·Δr_a over one cycle of the streamed effort
    is the work the physics optimiser reads for the gait (its own integration), and chunking does
    not change the effort."""
    from suds_ros.core.optimize.physics import evaluate_gait
    from suds_ros.core.physics.gait import nominal_gait

    system = make_system("purcell3")
    cfg = SimConfig(seed=0, ou_std=0.0, noise_std=0.0, warmup=8.0)
    assert StreamingSimulator(system, cfg).step(3).effort is None  # only when asked for
    sim = StreamingSimulator(system, cfg, effort=True)
    c = sim.step(cfg.samples_per_cycle + 1)
    ra = c.r_true[:, list(system.actuated)]
    work = np.sum(c.effort[1:] * np.diff(ra, axis=0))
    ev = evaluate_gait(system, nominal_gait(system))
    assert work == pytest.approx(ev["distance"] / ev["efficiency"], rel=2e-3)
    other = StreamingSimulator(system, cfg, effort=True)
    parts = [other.step(n) for n in (40, 61)]
    np.testing.assert_allclose(np.concatenate([p.effort for p in parts]), c.effort, rtol=1e-12, atol=1e-12)
