"""An N-link chain fitted to tracked midlines or keypoints, frame by frame (numerics only).

Trackers of filmed animals write, per video frame, a polyline along the body: a
dense midline (worm trackers) or a few keypoints (a fish's snout, gills, fins,
tail).  This module turns those points into what a recording holds
(``shared/spec/recording.md``, ``shared/spec/robot_model.md``):

* the polyline is cut at arc-length fractions into N straight links, head to
  tail; the **first point of each frame is the head**;
* link i (1-based) runs from cut point q_{i−1} (its head end) to q_i (its tail
  end); its angle θ_i is the direction of q_{i−1} − q_i (x axis tail → head);
* joint j joins link j and link j+1; r_j = θ_{j+1} − θ_j, wrapped to (−π, π];
* the body pose is the centre frame of the body link: its midpoint and θ.

With exactly N + 1 points per frame and no fractions given, the points are the
joints themselves (keypoints: no resampling).  Everything is vectorised across
frames; nothing here reads files.  Frames with any non-finite coordinate are
*lost*: they are reported (:func:`lost_runs`) and dropped by the caller, never
filled in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import BoolArray, FloatArray, IntArray
from suds_ros.core.errors import TOO_LITTLE_DATA, SudsConfigError, SudsDataError

#: code of a file whose points support fewer links than asked
TOO_FEW_POINTS = "too_few_points"
#: code of a file with no usable frame (every frame lost)
NO_MIDLINE = "no_midline"


def max_links(n_points: int) -> int:
    """Links a polyline of ``n_points`` points supports: ``n_points − 1`` (≥ 0)."""
    return max(int(n_points) - 1, 0)


def link_fractions(n_links: int, fractions: FloatArray | list[float] | tuple[float, ...] | None = None
                   ) -> FloatArray:
    """Cut points along the body as fractions of its arc length, head (0) to tail (1).

    Parameters
    ----------
    n_links : int
        Links N ≥ 2.
    fractions : (N,) float, optional
        Relative link lengths head to tail (any positive scale; normalised here).
        None: equal links.

    Returns
    -------
    (N + 1,) float
        Increasing cut points, 0 first and 1 last.

    Raises
    ------
    SudsConfigError
        ``n_links`` < 2, or ``fractions`` not N positive finite numbers.
    """
    if int(n_links) != n_links or n_links < 2:
        raise SudsConfigError(f"`n_links`: expected an integer ≥ 2, got {n_links!r}")
    if fractions is None:
        return np.linspace(0.0, 1.0, int(n_links) + 1)
    f = np.asarray(fractions, dtype=float).reshape(-1)
    if f.size != n_links or not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise SudsConfigError(f"`fractions`: expected {n_links} positive relative link lengths "
                              f"(head to tail), got {f.tolist()}")
    return np.concatenate([[0.0], np.cumsum(f) / f.sum()])


def resample(points: FloatArray, cuts: FloatArray) -> FloatArray:
    """Points at arc-length fractions ``cuts`` along each frame's polyline.

    Parameters
    ----------
    points : (n, P, 2) float
        Polyline per frame, head first, all finite.
    cuts : (K,) float
        Fractions in [0, 1] of each frame's own arc length.

    Returns
    -------
    (n, K, 2) float
        The interpolated points (the ends of the polyline at 0 and 1).
    """
    seg = np.linalg.norm(np.diff(points, axis=1), axis=2)  # (n, P-1)
    s = np.concatenate([np.zeros((points.shape[0], 1)), np.cumsum(seg, axis=1)], axis=1)  # (n, P)
    n, p = s.shape
    out = np.empty((n, cuts.size, 2))
    rows = np.arange(n)
    for k, c in enumerate(cuts):
        target = c * s[:, -1]
        # segment holding the target: last vertex with s ≤ target, kept inside [0, P-2]
        i = np.clip(np.sum(s <= target[:, None], axis=1) - 1, 0, p - 2)
        s0, s1 = s[rows, i], s[rows, i + 1]
        span = s1 - s0
        w = np.divide(target - s0, span, out=np.zeros(n), where=span > 0)
        w = np.clip(w, 0.0, 1.0)[:, None]
        out[:, k] = (1 - w) * points[rows, i] + w * points[rows, i + 1]
    return out


def wrap(angle: FloatArray) -> FloatArray:
    """Angles wrapped to (−π, π]."""
    return np.pi - np.mod(np.pi - angle, 2 * np.pi)


@dataclass(frozen=True)
class ChainFit:
    """An N-link chain fitted to each of n frames.

    Attributes
    ----------
    joints : (n, N + 1, 2) float
        Chain points head to tail (file units or m, as given).
    theta : (n, N) float
        Link angles, rad (x axis tail → head), each unwrapped over frames.
    r : (n, N − 1) float
        Joint angles r_j = θ_{j+1} − θ_j, rad, in (−π, π].
    lengths : (n, N) float
        Link lengths per frame.
    pose : (n, 3) float
        Body link centre frame: x, y, yaw (rad, unwrapped).
    body_link : int
        0-based index of the body link.
    """

    joints: FloatArray
    theta: FloatArray
    r: FloatArray
    lengths: FloatArray
    pose: FloatArray
    body_link: int

    @property
    def n_links(self) -> int:
        """Links N."""
        return int(self.theta.shape[1])

    @property
    def mean_lengths(self) -> FloatArray:
        """Mean length of each link over the frames, shape (N,)."""
        return np.asarray(self.lengths.mean(axis=0), dtype=float)


def fit_chain(points: FloatArray, n_links: int, body_link: int | None = None,
              fractions: FloatArray | list[float] | tuple[float, ...] | None = None) -> ChainFit:
    """Fit an ``n_links``-link chain to each frame's polyline.

    Parameters
    ----------
    points : (n, P, 2) float
        Tracked points per frame, head first, all finite (drop lost frames first).
    n_links : int
        Links N, 2 ≤ N ≤ P − 1.
    body_link : int, optional
        0-based body link; default the middle link ⌈N/2⌉ − 1 (as in ``suds-robot/1``).
    fractions : (N,) float, optional
        Relative link lengths head to tail.  None: equal arc length, except that with exactly
        P = N + 1 points the points themselves are the joints.

    Returns
    -------
    ChainFit

    Raises
    ------
    SudsDataError
        (code ``too_few_points``) P < N + 1; (code ``no_midline``) no frame, or a frame whose
        points all coincide; (code ``nan_or_inf``) non-finite points.
    SudsConfigError
        Bad ``n_links``, ``body_link`` or ``fractions``.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 3 or pts.shape[2] != 2:
        raise SudsDataError(f"`points`: expected shape (frames, points, 2), got {pts.shape}")
    n, p, _ = pts.shape
    cuts = link_fractions(n_links, fractions)
    if p < n_links + 1:
        raise SudsDataError(f"`points`: {n_links} links need at least {n_links + 1} points per frame, "
                            f"the file has {p} (they support at most {max_links(p)} links)",
                            code=TOO_FEW_POINTS)
    if n == 0:
        raise SudsDataError("`points`: no frame to fit (every frame was lost)", code=NO_MIDLINE)
    if not np.all(np.isfinite(pts)):
        raise SudsDataError("`points`: lost frames (NaN) must be dropped before the fit",
                            code="nan_or_inf")
    m = (n_links + 1) // 2 - 1 if body_link is None else int(body_link)
    if not 0 <= m < n_links:
        raise SudsConfigError(f"`body_link`: expected a link 1..{n_links}, got {m + 1}")
    q = pts if (fractions is None and p == n_links + 1) else resample(pts, cuts)
    d = q[:, :-1] - q[:, 1:]  # (n, N, 2), tail end → head end of each link
    lengths = np.hypot(d[..., 0], d[..., 1])
    if np.any(lengths <= 0):
        frame = int(np.flatnonzero(np.any(lengths <= 0, axis=1))[0])
        raise SudsDataError(f"`points`: frame {frame} has a link of zero length (its points coincide): "
                            "no midline to fit", code=NO_MIDLINE)
    theta = np.unwrap(np.arctan2(d[..., 1], d[..., 0]), axis=0)
    r = wrap(np.diff(theta, axis=1))
    centre = 0.5 * (q[:, m] + q[:, m + 1])
    pose = np.column_stack([centre, theta[:, m]])
    return ChainFit(joints=q, theta=theta, r=r, lengths=lengths, pose=pose, body_link=m)


def chain_points(r: FloatArray, pose: FloatArray, lengths: FloatArray | list[float] | tuple[float, ...],
                 body_link: int) -> FloatArray:
    """Forward kinematics: the chain's N + 1 joint points from joint angles and the body pose.

    The inverse of :func:`fit_chain` on N + 1 points.

    Parameters
    ----------
    r : (n, N − 1) float
        Joint angles, rad.
    pose : (n, 3) float
        Body link centre frame x, y, yaw.
    lengths : (N,) float
        Link lengths.
    body_link : int
        0-based body link.

    Returns
    -------
    (n, N + 1, 2) float
        Points head to tail.
    """
    r = np.asarray(r, dtype=float)
    pose = np.asarray(pose, dtype=float)
    L = np.asarray(lengths, dtype=float)
    n, nl = r.shape[0], r.shape[1] + 1
    cum = np.concatenate([np.zeros((n, 1)), np.cumsum(r, axis=1)], axis=1)  # θ_i − θ_1
    theta = pose[:, 2:3] + cum - cum[:, body_link:body_link + 1]
    u = np.stack([np.cos(theta), np.sin(theta)], axis=2) * L[None, :, None]  # tail → head per link
    q = np.empty((n, nl + 1, 2))
    centre = pose[:, :2]
    q[:, body_link] = centre + 0.5 * u[:, body_link]
    q[:, body_link + 1] = centre - 0.5 * u[:, body_link]
    for i in range(body_link - 1, -1, -1):  # towards the head
        q[:, i] = q[:, i + 1] + u[:, i]
    for i in range(body_link + 1, nl):  # towards the tail
        q[:, i + 1] = q[:, i] - u[:, i]
    return q


def lost_frames(points: FloatArray) -> BoolArray:
    """Frames with any non-finite coordinate, shape (n,): the tracker lost them."""
    pts = np.asarray(points, dtype=float)
    return np.asarray(~np.all(np.isfinite(pts.reshape(pts.shape[0], -1)), axis=1))


def lost_runs(mask: BoolArray) -> list[tuple[int, int]]:
    """Runs of True in ``mask`` as (first, last) row indices, inclusive, in order."""
    m = np.asarray(mask, dtype=bool).astype(np.int8)
    edges = np.diff(np.concatenate([[0], m, [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(int(a), int(b)) for a, b in zip(starts, stops)]


def frame_gaps(frame: IntArray) -> list[tuple[int, int]]:
    """Frame numbers missing from an increasing frame index, as (first, last) inclusive runs."""
    f = np.asarray(frame, dtype=np.int64)
    d = np.diff(f)
    at = np.flatnonzero(d > 1)
    return [(int(f[k] + 1), int(f[k + 1] - 1)) for k in at]


def dominant_frequency(t: FloatArray, r: FloatArray) -> float | None:
    """The frequency (Hz) with the most power in the joint angles, summed over joints.

    The samples are linearly interpolated onto a uniform grid at the median interval
    (across dropped frames too: for this estimate only), each joint's mean removed, and the
    summed power spectrum's highest bin above 0 Hz refined by a parabola through its
    neighbours (zero padding ×8).

    Parameters
    ----------
    t : (n,) float
        Stamps, s, increasing.
    r : (n, nj) float
        Joint angles, rad.

    Returns
    -------
    float or None
        Hz; None when the angles do not vary (no gait to see).

    Raises
    ------
    SudsDataError
        (code ``too_little_data``) fewer than 8 frames.
    """
    t = np.asarray(t, dtype=float)
    r = np.asarray(r, dtype=float).reshape(t.size, -1)
    if t.size < 8:
        raise SudsDataError(f"`t`: expected at least 8 frames to estimate the gait frequency, got {t.size}",
                            code=TOO_LITTLE_DATA)
    dt = float(np.median(np.diff(t)))
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt)) + 1)
    x = np.column_stack([np.interp(grid, t, r[:, j]) for j in range(r.shape[1])])
    x -= x.mean(axis=0)
    if not np.any(np.abs(x) > 1e-12):
        return None
    nfft = 8 * grid.size
    power = np.sum(np.abs(np.fft.rfft(x, n=nfft, axis=0)) ** 2, axis=1)
    freqs = np.fft.rfftfreq(nfft, dt)
    first = 8  # one cycle per record (bins are 1/8 of 1/record length): slower is no gait
    k = first + int(np.argmax(power[first:]))
    shift = 0.0
    if first < k < power.size - 1:
        a, b, c = np.log(power[k - 1:k + 2] + 1e-300)
        den = a - 2 * b + c
        shift = 0.5 * (a - c) / den if den < 0 else 0.0
    return float((k + shift) * (freqs[1] - freqs[0]))


def fit_gait(t: FloatArray, r: FloatArray, gait_hz: float) -> FloatArray:
    """Each joint's drive offset + amplitude·sin(2π·gait_hz·(t − t₀) − phase), least squares.

    Parameters
    ----------
    t : (n,) float
        Stamps, s (t₀ = t[0]).
    r : (n, nj) float
        Joint angles, rad.
    gait_hz : float
        Gait frequency, Hz.

    Returns
    -------
    (nj, 3) float
        amplitude (rad, ≥ 0), phase (rad, in (−π, π]), offset (rad) per joint.
    """
    t = np.asarray(t, dtype=float)
    w = 2 * np.pi * gait_hz * (t - t[0])
    X = np.column_stack([np.ones_like(w), np.sin(w), np.cos(w)])
    coef, *_ = np.linalg.lstsq(X, np.asarray(r, dtype=float), rcond=None)
    c, a, b = coef
    # A sin(w − φ) = A cos φ sin w − A sin φ cos w
    return np.column_stack([np.hypot(a, b), wrap(np.arctan2(-b, a)), c])


def time_gaps(t: FloatArray, factor: float = 1.5) -> list[tuple[int, float, float]]:
    """Intervals longer than ``factor`` × the median interval: frames the file does not hold.

    Parameters
    ----------
    t : (n,) float
        Frame times, s, increasing.

    Returns
    -------
    list of (row, t_before, t_after)
        ``row`` is the row before the gap.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        return []
    d = np.diff(t)
    at = np.flatnonzero(d > factor * float(np.median(d)))
    return [(int(k), float(t[k]), float(t[k + 1])) for k in at]


#: a frame is linked to the one before it when its midline lies this many times nearer that one's
#: as given than reversed (or reversed than as given); between, the two readings are too alike
#: (a curled, nearly symmetric body) and the frames are not linked
SWAP_MARGIN = 2.0
#: frames further apart than this many median frame intervals are not linked
SWAP_GAP = 10.0


@dataclass(frozen=True)
class HeadTail:
    """Head–tail swaps of a tracker, found by continuity (:func:`head_tail_swaps`).

    Attributes
    ----------
    swapped : (n,) bool
        Frames whose points the tracker gave tail first, against the frames linked to them.
    runs : (n,) int
        The linked run of each frame (0, 1, …): frames of one run are oriented alike.
    unlinked : int
        Boundaries between consecutive frames that could not be linked because the midline read
        as given and reversed were too alike (not counting gaps in time).
    """

    swapped: BoolArray
    runs: IntArray
    unlinked: int


def head_tail_swaps(points: FloatArray, t: FloatArray, margin: float = SWAP_MARGIN,
                    gap: float = SWAP_GAP) -> HeadTail:
    """Frames whose head and tail a tracker swapped, from the continuity of the midline.

    A midline tracker decides the head of each frame afresh, and now and then picks the tail.
    Consecutive frames (``gap`` median intervals apart or less) are compared at equal arc-length
    fractions: the mean distance of a frame's points from the previous frame's, as given (d) and
    reversed (d_rev).  They are linked as given when d_rev ≥ ``margin`` · d, as swapped when
    d ≥ ``margin`` · d_rev, and not linked otherwise.  Each run of linked frames is put in the
    orientation the tracker gave most of its frames (a tie: its first frame's), so the frames
    against that are the swapped ones.  A run that could not be linked to its neighbours keeps
    the tracker's orientation: the data cannot say more there.

    Parameters
    ----------
    points : (n, P, 2) float
        Kept frames, finite, head first as the tracker gave them.
    t : (n,) float
        Their times, increasing.
    """
    pts = np.asarray(points, dtype=float)
    n = pts.shape[0]
    if n < 2:
        return HeadTail(np.zeros(n, dtype=bool), np.zeros(n, dtype=np.int64), 0)
    q = resample(pts, np.linspace(0.0, 1.0, min(pts.shape[1], 25)))
    d = np.mean(np.linalg.norm(q[1:] - q[:-1], axis=2), axis=1)
    d_rev = np.mean(np.linalg.norm(q[1:, ::-1] - q[:-1], axis=2), axis=1)
    dt = np.diff(np.asarray(t, dtype=float))
    near = dt <= gap * float(np.median(dt))
    as_given, swap = d_rev >= margin * d, d >= margin * d_rev
    linked = near & (as_given | swap)
    runs = np.concatenate([[0], np.cumsum(~linked)])
    flips = np.concatenate([[0], np.cumsum(linked & swap)])
    start = np.concatenate([[0], np.flatnonzero(~linked) + 1])  # each run's first frame
    parity = (flips - flips[start[runs]]) % 2 == 1  # orientation against the run's first frame
    against = np.bincount(runs, weights=parity.astype(float))
    size = np.bincount(runs)
    flip_run = against > size - against  # most of the run's frames disagree with its first
    return HeadTail(parity != flip_run[runs], runs.astype(np.int64), int(np.count_nonzero(near & ~linked)))
