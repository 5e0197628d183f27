"""Replaying the simulator on the recorded actuation, and the windowed body-velocity estimator."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray, IntArray
from suds_ros.core.errors import SudsDataError
from suds_ros.core.diagnosis.data import Data, prepare
from suds_ros.core.diagnosis.floor import FloorArrays, floor_arrays
from suds_ros.core.diagnosis.resimulate import DiscoveredTorqueChain
from suds_ros.core.physics.integrate import integrate_batch
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.recording import Recording
from suds_ros.core.resample import StreamSampling


def window_xi(pose: FloatArray, w: int, dt: float) -> FloatArray:
    """Body velocity over windows of w samples, (…, m − w, 3), NaN where the pose is NaN."""
    rel = se2.relative(pose[..., :-w, :], pose[..., w:, :])
    return se2.log(rel) / (w * dt)


def midpoint_xi(pose: FloatArray, data: Data, w: int) -> FloatArray:
    """Windowed body velocity of each half of ``pose`` (n_used, 3) at the window midpoints.

    Each half is estimated on its own (no window spans the two halves); NaN at the edges.
    """
    n = data.n_used
    xi = np.full((n, 3), np.nan)
    for lo, hi in ((0, data.n_train), (data.n_train, n)):
        xi[lo + w // 2: hi - w + w // 2] = window_xi(pose[lo:hi], w, data.dt)
    return xi


def measure(
    pose: FloatArray, t_seg: FloatArray, flow: tuple[float, float], delay: float, w: int, dt: float,
    sampling: StreamSampling | None = None, starts: Sequence[int] = (),
) -> FloatArray:
    """Simulated pose stream → windowed body velocity, with flow drift and pose-stamp delay.

    pose (B, m, 3) still-fluid poses at times t_seg (B, m) (segment-relative times start at 0).
    ``sampling``: the recording's pose stream (:class:`~suds_ros.core.resample.StreamSampling`),
    through which the simulated pose is seen as the recorded one was, for segments at grid
    indices ``starts``; None when the pose was recorded on the grid.
    """
    P = pose.copy()
    tt = t_seg - t_seg[:, :1]
    if flow != (0.0, 0.0):
        P[..., 0] += flow[0] * tt
        P[..., 1] += flow[1] * tt
    if delay != 0.0:
        Q = np.full_like(P, np.nan)
        for b in range(P.shape[0]):
            ts = tt[b] - delay
            ok = (ts >= tt[b, 0] - 1e-12) & (ts <= tt[b, -1] + 1e-12)
            for c in range(3):
                Q[b, ok, c] = np.interp(ts[ok], tt[b], P[b, :, c])
        P = Q
    if sampling is not None:
        P = sampling.apply(P, starts)
    return window_xi(P, w, dt)


@dataclass(frozen=True)
class Replay:
    """Simulated segments: passive angles, windowed ξ (with flow and delay) and pose (with flow)."""

    rp: FloatArray  # (B, m, np)
    xi: FloatArray  # (B, m − w, 3)
    pose: FloatArray  # (B, m, 3) (with flow drift, no delay)


def replay(
    model: ChainModel,
    delay: float,
    data: Data,
    starts: Sequence[int],
    length: int,
    w: int,
    substeps: int,
    torques: Mapping[str, Mapping[str, float]] | None = None,
) -> Replay:
    """Replay equal-length segments [s, s + length) of the recording through ``model``.

    Each segment starts from the recorded passive angles and pose at its first sample and is
    driven by the recorded actuated angles (:func:`~suds_ros.core.physics.integrate.integrate_batch`,
    all segments in one batch).  After a run of lost shape samples, whose drive is not known, its
    passive angles restart from the recorded ones (:attr:`Data.anchors`).  ``delay`` (s) is the
    pose-stamp delay of ``sensor_time_offset``.  ``torques``: discovered torques added to passive joints
    (:class:`~suds_ros.core.diagnosis.resimulate.DiscoveredTorqueChain`).
    """
    idx = np.asarray(starts)[:, None] + np.arange(length)[None, :]
    still = model.with_(flow=(0.0, 0.0))
    chain = DiscoveredTorqueChain(still, torques) if torques else RFTChain(still)
    ra = data.r[idx][:, :, data.act]
    rp0 = data.r[idx[:, 0]][:, data.pas]
    pose0 = data.pose[idx[:, 0]]
    RP, P = integrate_batch(chain.velocities, data.act, data.pas, ra, rp0, pose0, data.dt, substeps,
                            reset=_anchored(data, idx))
    xi = measure(P, data.t[idx], model.flow, delay, w, data.dt, data.pose_sampling, list(starts))
    tt = data.t[idx] - data.t[idx[:, :1]]
    Pf = P.copy()
    Pf[..., 0] += model.flow[0] * tt
    Pf[..., 1] += model.flow[1] * tt
    return Replay(RP, xi, Pf)


def _anchored(data: Data, idx: IntArray) -> FloatArray | None:
    """Recorded passive angles at the anchors inside the segments ``idx`` (B, m), NaN elsewhere; None if none."""
    if data.anchors is None or not data.anchors.size or not data.pas.size:
        return None
    at = np.isin(idx, data.anchors)
    at[:, 0] = False  # a segment starts from the recorded state anyway
    if not at.any():
        return None
    out = np.full(idx.shape + (data.pas.size,), np.nan)
    out[at] = data.r[idx[at]][:, data.pas]
    return out


@dataclass(frozen=True)
class RecordingReplay:
    """A whole-recording replay, each half from its recorded initial state.

    ``rp`` (n_used, np) simulated passive angles, ``xi`` (n_used, 3) windowed body velocity at the
    window midpoints (NaN at the edges of each half), ``pose`` (n_used, 3) simulated pose and
    ``floor_arrays`` the per-segment arrays for :func:`~suds_ros.core.diagnosis.floor.noise_floor`.
    """

    rp: FloatArray
    xi: FloatArray
    pose: FloatArray
    floor_arrays: FloorArrays


def replay_recording(
    data: Data, model: ChainModel, delay: float, w: int, substeps: int,
    reference: Recording | None = None, chunk: int = 0, warm: int = 0,
    torques: Mapping[str, Mapping[str, float]] | None = None,
) -> RecordingReplay:
    """Whole-recording replay (train half and held-out half from their recorded initial states).

    With ``reference`` the simulated recording replaces the replay (it must be driven by the same
    actuated trajectory).  With ``chunk`` > 0 each half is replayed as independent pieces run in
    one batch: the piece that outputs samples [c, c + chunk) starts ``warm`` samples earlier from
    the recorded state (the first piece of a half starts at the half's recorded initial state, as
    the whole-half replay).  The passive joints are strongly damped, so after the warm-up the
    piece has forgotten its initial state and its output equals the whole-half replay's (checked
    to ~1e-6 rad in the tests); the body velocity depends only on the pose *increments* over a
    window, so restarting the pose from the recorded one changes nothing but the (unused)
    absolute pose, except that heading-dependent terms (flow) use a heading that has not drifted
    over a whole half.  ``torques``: discovered torques on passive joints (as :func:`replay`).
    """
    if reference is not None:
        return _reference_replay(data, model, reference, w)
    n = data.n_used
    rp = np.full((n, data.pas.size), np.nan)
    xi = np.full((n, 3), np.nan)
    pose = np.full((n, 3), np.nan)
    segs: list[tuple[int, int]] = []
    seg_rp: list[FloatArray] = []
    seg_pose: list[FloatArray] = []
    for length, group in _pieces(data, w, chunk, warm).items():
        starts = [g[0] for g in group]
        rep = replay(model, delay, data, starts, length, w, substeps, torques)
        for b, (s0, c, e) in enumerate(group):
            rp[c:e] = rep.rp[b, c - s0: e - s0]
            pose[c:e] = rep.pose[b, c - s0: e - s0]
            # ξ at midpoint i comes from the window starting at i − w//2 within this piece
            half_lo = data.n_train if c >= data.n_train else 0
            half_hi = n if c >= data.n_train else data.n_train
            mids = np.arange(max(c, half_lo + w // 2), min(e, half_hi - w + w // 2))
            j = mids - w // 2 - s0
            okj = (j >= 0) & (j < rep.xi.shape[1])
            xi[mids[okj]] = rep.xi[b, j[okj]]
            segs.append((s0, length))
            seg_rp.append(rep.rp[b])
            seg_pose.append(rep.pose[b])
    return RecordingReplay(rp, xi, pose, floor_arrays(data, segs, seg_rp, seg_pose))


def piece_starts(data: Data, w: int, chunk: int, warm: int) -> IntArray:
    """Sorted output starts of the pieces :func:`replay_recording` replays.

    0 and the held-out start are among them: where the replayed pose restarts from the recorded one.
    """
    return np.array(sorted(c for group in _pieces(data, w, chunk, warm).values() for _, c, _ in group),
                    dtype=np.intp)


def _pieces(data: Data, w: int, chunk: int, warm: int) -> dict[int, list[tuple[int, int, int]]]:
    """Replay pieces (segment start, output start, output end) grouped by segment length.

    A piece covers its output plus the ξ window after it (within its half); pieces of equal
    length run in one batch.
    """
    n = data.n_used
    halves = ((0, data.n_train), (data.n_train, n))
    pieces: list[tuple[int, int, int]] = []
    if chunk <= 0:
        pieces = [(lo, lo, hi) for lo, hi in halves]
    else:
        for lo, hi in halves:
            c = lo
            while c < hi:
                e = min(c + chunk, hi)
                pieces.append((max(lo, c - warm), c, e))
                c = e
    groups: dict[int, list[tuple[int, int, int]]] = {}
    for s0, c, e in pieces:
        half_hi = n if c >= data.n_train else data.n_train
        length = min(e + w, half_hi) - s0
        groups.setdefault(length, []).append((s0, c, e))
    return groups


def _reference_replay(data: Data, model: ChainModel, reference: Recording, w: int) -> RecordingReplay:
    """A simulated recording of the same actuated trajectory in place of the replay."""
    n = data.n_used
    ref = prepare(reference, model)
    if ref.n_used < n or not np.allclose(ref.t[:n], data.t[:n], atol=0.5 * data.dt):
        raise SudsDataError("`reference`: must cover the same stamps as the recording `rec`")
    dev = np.sqrt(np.mean((ref.r[:n][:, data.act] - data.r[:n][:, data.act]) ** 2))
    if dev > 0.05:
        raise SudsDataError(
            f"`reference`: its actuated trajectory differs from the recording's (RMS {dev:.3g} rad); "
            "it must be driven by the same recorded r_a"
        )
    halves = ((0, data.n_train), (data.n_train, n))
    rp = ref.r[:n][:, data.pas]
    pose = ref.pose[:n].copy()
    xi = midpoint_xi(ref.pose, data, w)
    segs = [(lo, hi - lo) for lo, hi in halves]
    fa = floor_arrays(data, segs, [rp[lo:hi] for lo, hi in halves], [pose[lo:hi] for lo, hi in halves])
    return RecordingReplay(rp, xi, pose, fa)
