"""Streaming simulator: chunking does not change the physics; stamps continue."""

from __future__ import annotations

import numpy as np

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
