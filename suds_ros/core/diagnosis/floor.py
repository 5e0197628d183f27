"""The noise floor of each channel, estimated from the white part of the replay residual."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.diagnosis.data import Data

#: Per-segment (recorded r_p, simulated r_p, recorded pose, simulated pose), each (B, m, ·).
FloorArrays = tuple[FloatArray, FloatArray, FloatArray, FloatArray]
#: σ of each passive angle (np,) and the floors of the ξ translation (m/s) and rotation (rad/s).
Floors = tuple[FloatArray, float, float]


def _mad_sigma(x: FloatArray) -> float:
    """Median-absolute-deviation estimate of the spread of the finite values (NaN with fewer than 8)."""
    x = x[np.isfinite(x)]
    if x.size < 8:
        return float("nan")
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def _d4(x: FloatArray, axis: int = -1) -> FloatArray:
    """Fourth difference: removes everything smooth, keeps the white part (variance ×70)."""
    return np.diff(x, n=4, axis=axis)


def noise_floor(
    rec_rp: FloatArray, sim_rp: FloatArray, rec_pose: FloatArray, sim_pose: FloatArray, w: int, dt: float,
    gain: float = float(np.sqrt(2.0)),
) -> Floors:
    """Noise floor from the white part of the replay residual.

    Arrays are per segment (B, m, ·).  Returns σ of each passive angle (np,), and the floor of
    the windowed ξ translation (m/s) and rotation (rad/s) components: gain·σ_pose/(w·dt), with
    ``gain`` √2 for white pose noise on the grid (two independent window ends) and
    :func:`~suds_ros.core.diagnosis.data.xi_noise_gain` for a pose stream interpolated onto it.
    """
    e = rec_rp - sim_rp
    sig_rp = np.array([_mad_sigma(_d4(e[..., j], axis=1).ravel()) for j in range(e.shape[-1])]) / np.sqrt(70)
    ep = rec_pose - sim_pose
    sx = _mad_sigma(_d4(ep[..., 0], axis=1).ravel())
    sy = _mad_sigma(_d4(ep[..., 1], axis=1).ravel())
    sth = _mad_sigma(_d4(ep[..., 2], axis=1).ravel())
    s_xy = np.sqrt((sx**2 + sy**2) / 2 / 70)
    s_th = sth / np.sqrt(70)
    k = gain / (w * dt)
    return sig_rp, float(k * s_xy), float(k * s_th)


def floor_arrays(
    data: Data, segs: Sequence[tuple[int, int]], sim_rp: Sequence[FloatArray], sim_pose: Sequence[FloatArray]
) -> FloorArrays:
    """(recorded r_p, simulated r_p, recorded pose, simulated pose) per segment, cut to a common length.

    ``segs`` holds (first sample, length) of each replayed segment; ``sim_rp[k]`` and
    ``sim_pose[k]`` are segment k's simulated passive angles and pose from its first sample on.
    """
    m = min(length for _, length in segs)
    rr, ss, pr, ps = [], [], [], []
    for k, (s0, _) in enumerate(segs):
        rr.append(data.r[s0:s0 + m][:, data.pas])
        pr.append(data.pose[s0:s0 + m])
        ss.append(sim_rp[k][:m])
        ps.append(sim_pose[k][:m])
    return np.stack(rr), np.stack(ss), np.stack(pr), np.stack(ps)
