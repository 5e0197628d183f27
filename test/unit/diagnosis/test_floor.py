"""Noise floor from the white part of the replay residual (:mod:`suds_ros.core.diagnosis.floor`)."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.diagnosis.floor import noise_floor


def test_floor_recovers_white_noise_under_a_smooth_error() -> None:
    """A smooth (gait-correlated) error is removed by the fourth difference; the white part stays."""
    rng = np.random.default_rng(0)
    B, m, dt, w = 4, 2000, 0.01, 10
    t = np.arange(m) * dt
    smooth = 0.3 * np.sin(2 * np.pi * t)[None, :, None]
    sim_rp = np.zeros((B, m, 2))
    rec_rp = sim_rp + smooth + 2e-3 * rng.standard_normal((B, m, 2))
    sim_pose = np.zeros((B, m, 3))
    rec_pose = sim_pose + smooth + 1e-3 * rng.standard_normal((B, m, 3))
    pose_d4 = np.diff(rec_pose - sim_pose, n=4, axis=1).reshape(-1, 3)
    sig_rp, s_xy, s_th = noise_floor(rec_rp, sim_rp, pose_d4, w, dt)
    np.testing.assert_allclose(sig_rp, 2e-3, rtol=0.05)
    # ξ over w samples from two noisy poses: √2·σ/(w·dt)
    assert s_xy == pytest.approx(np.sqrt(2) * 1e-3 / (w * dt), rel=0.05)
    assert s_th == pytest.approx(np.sqrt(2) * 1e-3 / (w * dt), rel=0.05)


def test_floor_is_nan_without_enough_samples() -> None:
    z = np.zeros((1, 10, 1))
    sig_rp, _, _ = noise_floor(z, z, np.zeros((6, 3)), 5, 0.01)
    assert np.isnan(sig_rp).all()
