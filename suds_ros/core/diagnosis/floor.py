"""The noise floor of each channel, estimated from the white part of the replay residual."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.diagnosis.data import Data
from suds_ros.core.recording import stream_period

#: Per-segment recorded and simulated r_p, each (B, m, np), and the fourth differences (K, 3)
#: of the pose residual at the pose stream's own stamps, all segments together.
FloorArrays = tuple[FloatArray, FloatArray, FloatArray]
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


def _passive_sigma(rec_rp: FloatArray, sim_rp: FloatArray) -> FloatArray:
    """σ of each passive angle from the fourth differences of the replay residual (np,).

    A drive whose set-points kink at every sample (a servo stream, an OU perturbation) kinks the
    passive response at every sample too; where the model is wrong, the recorded and replayed
    responses to those kinks differ, and the residual's fourth differences hold that difference
    at every sample, not only the noise (measured on a tail robot with a friction, a cubic spring
    and a link-drag error: σ 5–14× the true 1e-3 rad).  The part of each joint's fourth difference
    that follows the replay's own fourth differences (every passive joint's, one least-squares
    gain each) is taken out first.  On a matching model that part holds no noise to speak of
    (σ unchanged to 2 % on nominal recordings); on a mismatched one it removes most of the excess.
    """
    e = rec_rp - sim_rp
    n_p = e.shape[-1]
    if n_p == 0:  # a fully actuated chain
        return np.zeros(0)
    d_e = _d4(e, axis=1).reshape(-1, n_p)
    d_s = _d4(sim_rp, axis=1).reshape(-1, n_p)
    ok = np.all(np.isfinite(d_e), axis=1) & np.all(np.isfinite(d_s), axis=1)
    if ok.sum() >= 20 * max(n_p, 1):
        beta = np.linalg.lstsq(d_s[ok], d_e[ok], rcond=None)[0]
        d_e = np.where(ok[:, None], d_e - d_s @ beta, np.nan)
    return np.array([_mad_sigma(d_e[:, j]) for j in range(n_p)]) / np.sqrt(70)


def noise_floor(
    rec_rp: FloatArray, sim_rp: FloatArray, pose_d4: FloatArray, w: int, dt: float,
    gain: float = float(np.sqrt(2.0)),
) -> Floors:
    """Noise floor from the white part of the replay residual.

    ``rec_rp``, ``sim_rp`` are per segment (B, m, np); ``pose_d4`` the fourth differences of
    the pose residual at the pose stamps (:func:`floor_arrays`).  Returns σ of each passive
    angle (np,), and the floor of the windowed ξ translation (m/s) and rotation (rad/s)
    components: gain·σ_pose/(w·dt), with ``gain`` √2 for white pose noise on the grid (two
    independent window ends) and :func:`~suds_ros.core.diagnosis.data.xi_noise_gain` for a pose
    stream fitted onto it.
    """
    sig_rp = _passive_sigma(rec_rp, sim_rp)
    sx, sy, sth = (_mad_sigma(pose_d4[:, c]) for c in range(3))
    s_xy = np.sqrt((sx**2 + sy**2) / 2 / 70)
    s_th = sth / np.sqrt(70)
    k = gain / (w * dt)
    return sig_rp, float(k * s_xy), float(k * s_th)


def floor_arrays(
    data: Data, segs: Sequence[tuple[int, int]], sim_rp: Sequence[FloatArray], sim_pose: Sequence[FloatArray]
) -> FloorArrays:
    """The arrays :func:`noise_floor` takes, from the replayed segments.

    ``segs`` holds (first sample, length) of each replayed segment; ``sim_rp[k]`` and
    ``sim_pose[k]`` are segment k's simulated passive angles and pose on the grid from its first
    sample on.  The passive angles are cut to a common length and stacked.  The pose residual is
    taken at the pose stream's own stamps (the simulated pose, smooth between the grid's
    set-points, interpolated there), where the measurement noise is white whatever the stream's
    rate: on the grid a pose stream slower than the grid is an interpolation whose fourth
    differences hold the kinks of the motion between samples.  On a recording whose pose shares
    the grid's stamps the two are the same.  Recorded passive angles at or next to a lost shape
    sample (:attr:`Data.shape_lost`) are NaN: they were bridged, not measured; so are the pose
    differences over a lost pose sample.
    """
    m = min(length for _, length in segs)
    rr, ss, d4 = [], [], []
    period = stream_period(data.pose_t) if data.pose_t.size > 1 else np.inf
    for k, (s0, length) in enumerate(segs):
        rec = data.r[s0:s0 + m][:, data.pas]
        if data.shape_lost is not None:  # a bridged sample is no measurement: its differences are left out
            rec = np.where(data.shape_lost[s0:s0 + m, None], np.nan, rec)
        rr.append(rec)
        ss.append(sim_rp[k][:m])
        T = data.t[s0:s0 + length]
        lo = int(np.searchsorted(data.pose_t, T[0], side="left"))
        hi = int(np.searchsorted(data.pose_t, T[-1], side="right"))
        ts = data.pose_t[lo:hi]
        if ts.size < 5:
            continue
        P = np.asarray(sim_pose[k][:length], dtype=float)
        sim = np.stack([np.interp(ts, T, P[:, c]) for c in range(3)], axis=1)
        d = _d4(data.pose_raw[lo:hi] - sim, axis=0)
        # only over five samples in a row: across a lost one the stamps are unevenly spaced and the
        # difference keeps part of the motion (measured: half the pose frames lost in 0.3 s bursts
        # raised swimmer9's ξ translation floor 70 %, so its F sank to 0.34 on a nominal recording)
        even = np.convolve((np.diff(ts) <= 1.5 * period).astype(float), np.ones(4), mode="valid") == 4
        d4.append(np.where(even[:, None], d, np.nan))
    pose_d4 = np.concatenate(d4, axis=0) if d4 else np.full((0, 3), np.nan)
    return np.stack(rr), np.stack(ss), pose_d4
