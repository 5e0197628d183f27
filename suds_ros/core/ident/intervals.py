"""From samples to regression data: forward differences with midpoint states.

Velocities are estimated over the interval between consecutive shape samples
k → k + 1 (or k → k + w for a window of w samples): ṙ = (r_{k+w} − r_k)/Δt, and
the body velocity is the constant twist that carries pose k to pose k + w
(SE(2) logarithm).  They are attributed to the interval's midpoint, with the
midpoint state r̄ = (r_k + r_{k+w})/2 and midpoint stamp.  This matches how a
piecewise-linear servo stream moves (ṙ_a constant within an interval) and
keeps the regressors and the targets on the same time grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from suds_ros.core import se2
from suds_ros.core._typing import BoolArray, FloatArray, IntArray
from suds_ros.core.errors import SudsDataError
from suds_ros.core.ident.sysid import SudsConfig, regressor_input, segment_state
from suds_ros.core.recording import POSE_SPAN_TOL, Recording
from suds_ros.core.resample import window_any


@dataclass(frozen=True)
class Intervals:
    """Interval-midpoint data of one recording.

    Attributes
    ----------
    t : (m,) midpoint stamps, s.
    k : (m,) index of the interval's first shape sample.
    r : (m, nj) midpoint joint values.
    rdot : (m, nj) joint velocities over the interval.
    xi : (m, 3) body velocity over the interval (body frame: m/s, m/s, rad/s).
    effort : (m, na) or None, mean actuator effort over the interval (recorded effort is
        taken as the mean over the sample period ending at its stamp).
    dt : (m,) interval durations, s.
    """

    t: FloatArray
    k: FloatArray
    r: FloatArray
    rdot: FloatArray
    xi: FloatArray
    effort: FloatArray | None
    dt: FloatArray


def measured_intervals(rec: Recording, window: int = 1) -> BoolArray | None:
    """Intervals k → k + ``window`` whose shape samples were all measured (none ``rec.bridged``); None: every one.

    The one rule for what is fitted and scored: an interval over a shape sample bridged across
    a run of lost messages was never measured (:func:`~suds_ros.core.resample.bridged`).
    """
    if rec.bridged is None:
        return None
    bad = window_any(rec.bridged, window)
    return ~bad if bad.any() else None


def make_intervals(rec: Recording, window: int = 1, pose: FloatArray | None = None) -> Intervals:
    """Difference a recording over ``window`` samples.

    Parameters
    ----------
    rec : Recording
        Shape and pose series; pose is interpolated at the shape stamps.
    window : int
        Samples per difference (1 = consecutive samples).  Longer windows average
        measurement noise at the cost of time resolution.
    pose : (n, 3) float, optional
        Pose already sampled at the shape stamps (e.g. noise-free truth); default
        ``rec.pose_at(rec.t)`` at the shape stamps inside the pose stream's span.  A shape
        stamp outside that span has no pose (a separate pose stream may start later or end
        earlier): the intervals ending there get NaN body velocity, never a held or
        extrapolated pose.  Such recordings score the body over the pose intervals
        (:func:`pose_intervals`), not over these.
    """
    if window < 1:
        raise SudsDataError(f"`window`: expected ≥ 1, got {window}")
    n = rec.n_samples
    if n <= window + 1:
        raise SudsDataError(f"recording has {n} samples; need more than {window + 1}")
    P = _pose_in_span(rec) if pose is None else np.asarray(pose, dtype=float)
    dt = rec.t[window:] - rec.t[:-window]
    r0, r1 = rec.r[:-window], rec.r[window:]
    xi = se2.body_velocity(P, dt, stride=window)
    effort = None
    if rec.effort is not None:
        # effort_k covers the period (k − 1, k]: the interval (k, k + w] is covered by samples k+1 … k+w
        E = rec.effort[:, rec.actuated_index]
        c = np.concatenate([np.zeros((1, E.shape[1])), np.cumsum(E, axis=0)])
        effort = (c[1 + window :] - c[1:-window]) / window
    return Intervals(
        t=0.5 * (rec.t[:-window] + rec.t[window:]),
        k=np.arange(n - window, dtype=float),
        r=0.5 * (r0 + r1),
        rdot=(r1 - r0) / dt[:, None],
        xi=xi,
        effort=effort,
        dt=dt,
    )


def _pose_in_span(rec: Recording) -> FloatArray:
    """Pose (n, 3) at the shape stamps; NaN at the stamps outside the pose stream's span."""
    t = rec.t
    inside = (t >= rec.pose_t[0] - POSE_SPAN_TOL) & (t <= rec.pose_t[-1] + POSE_SPAN_TOL)
    if inside.all():
        return rec.pose_at(t)
    P = np.full((t.size, 3), np.nan)
    if inside.any():
        P[inside] = rec.pose_at(t[inside])
    return P


@dataclass(frozen=True)
class PoseIntervals:
    """Body velocity as measured: the pose displacement over each pose interval.

    The pose stream has its own stamps τ; over the pose interval [τ_i, τ_{i+w}] the measured
    body velocity is the constant twist log(g_i⁻¹ g_{i+w}) / (τ_{i+w} − τ_i).  The shape
    intervals cut each pose interval into *segments* (its overlaps with the shape intervals,
    1–3 at comparable rates).  Within a shape interval the joints move on a straight line
    (ṙ constant), so the model's velocity on a segment is its prediction at the segment's
    midpoint state, and its prediction for the pose interval is the duration-weighted mean
    over the segments: ``weights @ segment_predictions``.  Only pose intervals lying wholly
    inside the shape intervals are kept.

    Attributes
    ----------
    t0, t1 : (q,) start and end stamps of the pose intervals, s.
    xi : (q, 3) measured body velocity over each (body frame: m/s, m/s, rad/s).
    seg_k : (s,) int, the shape interval each segment lies in.
    seg_t : (s,) midpoint stamp of each segment, s.
    weights : scipy.sparse.csr_matrix (q, s)
        Segment durations over the pose interval's duration; each row sums to 1.
    """

    t0: FloatArray
    t1: FloatArray
    xi: FloatArray
    seg_k: IntArray
    seg_t: FloatArray
    weights: object

    def is_identity(self, shape_t: FloatArray) -> bool:
        """True when every pose interval is exactly one shape interval, in order (aligned streams).

        ``shape_t`` are the shape intervals' midpoints.
        """
        W = self.weights
        q, m = W.shape  # type: ignore[attr-defined]
        return bool(q == m == shape_t.size and W.nnz == m  # type: ignore[attr-defined]
                    and np.array_equal(self.seg_k, np.arange(m)) and np.all(W.data == 1.0)  # type: ignore[attr-defined]
                    and np.array_equal(self.seg_t, shape_t))

    def over_shape(self, n_shape: int) -> object:
        """Weights (q, n_shape) onto the shape intervals.

        They give the time average over each pose interval of a signal constant on each shape
        interval.
        """
        import scipy.sparse

        S = scipy.sparse.csr_matrix((np.ones(self.seg_k.size), (np.arange(self.seg_k.size), self.seg_k)),
                                    shape=(self.seg_k.size, n_shape))
        return (self.weights @ S).tocsr()  # type: ignore[operator]


def overlap_segments(a0: FloatArray, a1: FloatArray, b0: FloatArray, b1: FloatArray
                     ) -> tuple[IntArray, IntArray, FloatArray, FloatArray]:
    """The overlaps of intervals [b0_i, b1_i] with sorted intervals [a0_k, a1_k].

    Returns
    -------
    rows, cols : (s,) int
        The b-interval i and a-interval k of each overlap segment, sorted by i then k.
    s0, s1 : (s,) float
        Start and end of each segment (s1 > s0: intervals touching in a point do not overlap).
    """
    a0, a1, b0, b1 = (np.asarray(v, dtype=float) for v in (a0, a1, b0, b1))
    lo = np.searchsorted(a1, b0, side="right")  # first a-interval ending after b0
    hi = np.searchsorted(a0, b1, side="left")  # one past the last a-interval starting before b1
    counts = np.maximum(hi - lo, 0)
    rows = np.repeat(np.arange(b0.size), counts)
    starts = np.repeat(lo - np.cumsum(counts) + counts, counts)
    cols = starts + np.arange(rows.size)
    s0 = np.maximum(a0[cols], b0[rows])
    s1 = np.minimum(a1[cols], b1[rows])
    keep = s1 > s0
    return rows[keep], cols[keep], s0[keep], s1[keep]


def covered_segments(a0: FloatArray, a1: FloatArray, b0: FloatArray, b1: FloatArray
                     ) -> tuple[BoolArray, IntArray, IntArray, FloatArray, FloatArray, FloatArray]:
    """:func:`overlap_segments` of the b-intervals that the a-intervals cover wholly.

    The a-intervals may leave holes (intervals left out, e.g. over lost samples); a b-interval
    that spans one is dropped.  Returns ``whole`` (b.size,), the b-intervals kept, and the
    segments of those: ``rows`` numbered 0 … whole.sum() − 1, ``cols``, ``s0``, ``s1`` and
    ``share``, each segment's part of its b-interval's covered length (a row's shares sum to 1:
    the time-overlap averaging weights).
    """
    rows, cols, s0, s1 = overlap_segments(a0, a1, b0, b1)
    total = np.bincount(rows, weights=s1 - s0, minlength=np.size(b0))
    whole = total >= (np.asarray(b1) - np.asarray(b0)) * (1 - 1e-9)
    covered = total[rows]  # each segment's b-interval's covered length
    if not whole.all():
        seg = whole[rows]
        rows, cols, s0, s1, covered = (np.cumsum(whole) - 1)[rows[seg]], cols[seg], s0[seg], s1[seg], covered[seg]
    return whole, rows, cols, s0, s1, (s1 - s0) / covered


def overlap_weights(a0: FloatArray, a1: FloatArray, b0: FloatArray, b1: FloatArray) -> object:
    """Time-overlap averaging weights (q, m) of intervals [b0_i, b1_i] onto intervals [a0_k, a1_k].

    Row i holds |[a0_k, a1_k] ∩ [b0_i, b1_i]| for every k, divided by the row's sum, so a
    piecewise-constant signal taking value v_k on interval k has time average ``W @ v`` over
    interval i (exactly, when the a-intervals tile time).  Rows with no overlap are empty.
    """
    import scipy.sparse

    rows, cols, s0, s1 = overlap_segments(a0, a1, b0, b1)
    ov = s1 - s0
    total = np.bincount(rows, weights=ov, minlength=np.size(b0))
    return scipy.sparse.csr_matrix((ov / total[rows], (rows, cols)), shape=(np.size(b0), np.size(a0)))


def pose_intervals(rec: Recording, shape_t0: FloatArray, shape_t1: FloatArray, window: int = 1) -> PoseIntervals:
    """The pose intervals of ``rec`` lying inside the shape intervals [shape_t0_k, shape_t1_k].

    Parameters
    ----------
    rec : Recording
        Its pose stream, differenced over ``window`` pose samples.
    shape_t0, shape_t1 : (m,) float
        Start and end stamps of the shape intervals (sorted).  They may leave holes (intervals
        left out): a pose interval is kept only if the given intervals cover it wholly.
    """
    import scipy.sparse

    if rec.pose_t.size <= window:
        raise SudsDataError(f"recording has {rec.pose_t.size} pose samples; need more than {window}")
    tau = rec.pose_t
    b0, b1 = tau[:-window], tau[window:]
    xi = se2.body_velocity(rec.pose, b1 - b0, stride=window)
    inside = (b0 >= shape_t0[0]) & (b1 <= shape_t1[-1])
    b0, b1, xi = b0[inside], b1[inside], xi[inside]
    whole, rows, cols, s0, s1, share = covered_segments(shape_t0, shape_t1, b0, b1)
    b0, b1, xi = b0[whole], b1[whole], xi[whole]
    W = scipy.sparse.csr_matrix((share, (rows, np.arange(rows.size))), shape=(b0.size, rows.size))
    return PoseIntervals(t0=b0, t1=b1, xi=xi, seg_k=cols, seg_t=0.5 * (s0 + s1), weights=W)


def segment_states(rec: Recording, pv: PoseIntervals, phase: FloatArray, window: int = 1
                   ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Phase (s,) and joint values (s, nj) at the segments' midpoints, and joint velocities (s, nj).

    The midpoint values lie on the straight line of the segment's shape interval; the joint
    velocities are those of the segments' shape intervals.

    ``phase`` (n,) is the phase at the shape stamps.
    """
    k = pv.seg_k
    t0, t1 = rec.t[k], rec.t[k + window]
    frac = (pv.seg_t - t0) / (t1 - t0)
    r0, r1 = rec.r[k], rec.r[k + window]
    ph = phase[k] + (phase[k + window] - phase[k]) * frac
    return ph, r0 + (r1 - r0) * frac[:, None], (r1 - r0) / (t1 - t0)[:, None]


def segment_features(suds: SudsConfig, template: object, omega: float, act: IntArray, t: FloatArray,
                     r: FloatArray, phase: FloatArray, k: IntArray, seg_t: FloatArray, window: int = 1
                     ) -> FloatArray:
    """Regressor rows of segments lying in the shape intervals k → k + ``window``.

    ``t`` (n,), ``r`` (n, nj) and ``phase`` (n,) are the shape samples; ``k`` (s,) the interval
    of each segment and ``seg_t`` (s,) its midpoint stamp.  The row's phase and state are the
    ones :func:`~suds_ros.core.ident.sysid.segment_state` names; ṙ is the interval's own.
    """
    k = np.asarray(k, dtype=int)
    t0, t1 = t[k], t[k + window]
    r0, r1 = r[k], r[k + window]
    frac = (np.asarray(seg_t, dtype=float) - t0) / (t1 - t0)
    ph, rs = segment_state(suds, phase[k], phase[k + window], r0, r1, frac)
    return interval_features(template, omega, act, ph, rs, (r1 - r0) / (t1 - t0)[:, None])


def interval_features(template: object, omega: float, act: FloatArray, phase: FloatArray, r: FloatArray,
                      rdot: FloatArray) -> FloatArray:
    """Regressor rows X = [φ, δ, δ̇_a, r, ṙ_a] for phases (k,), joint values and rates (k, nj)."""
    theta = template.predict(phase)  # type: ignore[attr-defined]
    dtheta = template.derivative(phase)  # type: ignore[attr-defined]
    return regressor_input(phase, r - theta, (rdot - dtheta * omega)[:, act], r, rdot[:, act])
