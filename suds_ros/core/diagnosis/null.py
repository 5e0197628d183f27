"""Null recordings for calibrating the evidence on the recording at hand (parametric bootstrap).

A null recording is what this recording would have been if the simulator with a given set of effects
were the truth: the recorded drive r_a (its noise included: the equation error meets it as it does
on the recording), the recording's grid, gaps and length, the passive angles and pose replayed from
that drive through the model, and white noise at the floors measured on the recording. The equation-
error evidence a candidate effect gains on such a null is what it gains here without being there:
the bias of the equation error for this robot, drive and sampling (finite differences, windowed body
velocity, the interpolated streams), plus chance. :mod:`.selection` subtracts it from the
candidate's evidence on the data.

Approximations, stated: the null's pose is on the grid (the raw stream's own stamps, jitter and
drops are not re-created; its gaps are kept as gaps), and its noise is white at the floors. The
replay responds to the drive's noise and gets the floor noise on top, so the null is a little
noisier than the recording and its bias estimates err on the large side (measured on nominal
recordings of a 6-link robot: spurious gains 1.2–1.6× those on the recording), which keeps false
discoveries down at some cost in sensitivity.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray, IntArray
from suds_ros.core.diagnosis.data import Data
from suds_ros.core.diagnosis.floor import Floors
from suds_ros.core.diagnosis.replay import RecordingReplay


def stitched_pose(data: Data, pose: FloatArray, starts: IntArray) -> FloatArray:
    """One continuous pose (n_used, 3) from a piecewise replay's pose.

    Each replay piece starts again from the recorded pose, so the replayed pose jumps where a
    piece begins (``starts``, output starts).  The steps inside a piece are the simulator's; the
    step into a piece's first sample is taken from the recording; the steps are composed from the
    first replayed pose on.
    """
    n = data.n_used
    inc = se2.relative(pose[:n - 1], pose[1:n])  # body-frame step i → i+1
    jumps = np.asarray(starts, dtype=np.intp)
    jumps = jumps[(jumps > 0) & (jumps < n)]
    inc[jumps - 1] = se2.relative(data.pose[jumps - 1], data.pose[jumps])
    yaw = pose[0, 2] + np.concatenate([[0.0], np.cumsum(inc[:, 2])])
    c, s = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    dx = c * inc[:, 0] - s * inc[:, 1]
    dy = s * inc[:, 0] + c * inc[:, 1]
    out = np.empty((n, 3))
    out[:, 0] = pose[0, 0] + np.concatenate([[0.0], np.cumsum(dx)])
    out[:, 1] = pose[0, 1] + np.concatenate([[0.0], np.cumsum(dy)])
    out[:, 2] = yaw
    return out


def pose_sigma(floors: Floors, w: int, dt: float, gain: float) -> tuple[float, float]:
    """White pose noise (σ_xy m, σ_yaw rad) whose windowed body velocity has the floors ``floors``.

    Inverts :func:`~suds_ros.core.diagnosis.floor.noise_floor`'s ξ floor = gain·σ/(w·dt).
    """
    _, s_xy, s_th = floors
    k = gain / (w * dt)
    return float(s_xy / k), float(s_th / k)


def null_recording(
    data: Data, rep: RecordingReplay, starts: IntArray, floors: Floors, w: int, rng: np.random.Generator,
) -> Data:
    """The recording ``data`` with its passive angles and pose replaced by ``rep`` plus floor noise.

    ``starts``: the output starts of ``rep``'s pieces (:func:`~.replay.piece_starts`); ``floors``
    the recording's noise floors; ``w`` the body-velocity window.  The null's pose lies on the
    grid with white noise, so its ξ floor is √2·σ/(w·dt): σ is chosen so that the null's body
    velocity is as noisy as the recording's, whatever the recording's pose rate.  Samples past
    ``n_used`` keep their recorded values (no stage reads them).
    """
    n = data.n_used
    sig_rp = np.nan_to_num(np.asarray(floors[0], dtype=float), nan=0.0)
    r = data.r.copy()
    if data.pas.size:
        r[:n, data.pas] = rep.rp + rng.standard_normal(rep.rp.shape) * sig_rp
    sxy, sth = pose_sigma(floors, w, data.dt, float(np.sqrt(2.0)))
    pose = data.pose.copy()
    pose[:n] = stitched_pose(data, rep.pose, starts) + rng.standard_normal((n, 3)) * np.array([sxy, sxy, sth])
    return dataclasses.replace(data, r=r, pose=pose, pose_t=data.t.copy(), pose_raw=pose, resampled=False)
