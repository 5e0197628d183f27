"""Planar rigid-body (SE(2)) helpers: exponential step, logarithm and body velocities from poses."""

from __future__ import annotations

import numpy as np

from suds_ros.core._typing import FloatArray


def _coeffs(w: FloatArray, series_below: float = 1e-6) -> tuple[FloatArray, FloatArray]:
    """sin(w)/w and (1 − cos w)/w, by their series where |w| < ``series_below``."""
    small = np.abs(w) < series_below
    ws = np.where(small, 1.0, w)
    a = np.where(small, 1.0 - w * w / 6.0, np.sin(ws) / ws)
    b = np.where(small, w / 2.0 - w**3 / 24.0, (1.0 - np.cos(ws)) / ws)
    return a, b


def exp_step(pose: FloatArray, twist: FloatArray) -> FloatArray:
    """The pose g · exp(twist) for world poses (…, 3) and body twists (…, 3) (velocity already times the step).

    The exact SE(2) exponential: a constant body twist carries the pose along a circular arc.
    Every integrator of the package takes its pose steps with this function.  It switches to the
    series at |w| < 1e-8 (the logarithm at 1e-6): the integrators' historical choice, kept so
    simulated and replayed trajectories stay bit-identical.
    """
    vx, vy, w = twist[..., 0], twist[..., 1], twist[..., 2]
    a, b = _coeffs(w, series_below=1e-8)
    dx = a * vx - b * vy
    dy = b * vx + a * vy
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    out = np.empty_like(pose)
    out[..., 0] = pose[..., 0] + c * dx - s * dy
    out[..., 1] = pose[..., 1] + s * dx + c * dy
    out[..., 2] = pose[..., 2] + w
    return out


def relative(p0: FloatArray, p1: FloatArray) -> FloatArray:
    """g0⁻¹ g1 for poses (…, 3) = (x, y, yaw): displacement of p1 expressed in the frame of p0."""
    dx = p1[..., 0] - p0[..., 0]
    dy = p1[..., 1] - p0[..., 1]
    c, s = np.cos(p0[..., 2]), np.sin(p0[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, p1[..., 2] - p0[..., 2]], axis=-1)


def log(rel: FloatArray) -> FloatArray:
    """Twist (…, 3) = (vx, vy, w) whose exponential is the relative pose ``rel`` (yaw unwrapped)."""
    w = rel[..., 2]
    a, b = _coeffs(w)
    det = a * a + b * b
    vx = (a * rel[..., 0] + b * rel[..., 1]) / det
    vy = (-b * rel[..., 0] + a * rel[..., 1]) / det
    return np.stack([vx, vy, w], axis=-1)


def body_velocity(pose: FloatArray, dt: float | FloatArray, stride: int = 1) -> FloatArray:
    """Constant body velocity that carries pose k to pose k + stride, shape (n − stride, 3).

    Parameters
    ----------
    pose : (n, 3) float
        World poses (x m, y m, yaw rad unwrapped).
    dt : float or (n − stride,) float
        Time between pose k and pose k + stride, s.
    stride : int
        Sample distance of the difference.
    """
    rel = relative(pose[:-stride], pose[stride:])
    return log(rel) / np.asarray(dt, dtype=float)[..., None] if np.ndim(dt) else log(rel) / dt
