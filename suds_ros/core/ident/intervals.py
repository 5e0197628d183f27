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
from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsDataError
from suds_ros.core.recording import Recording


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
        ``rec.pose_at(rec.t)``.
    """
    if window < 1:
        raise SudsDataError(f"`window`: expected ≥ 1, got {window}")
    n = rec.n_samples
    if n <= window + 1:
        raise SudsDataError(f"recording has {n} samples; need more than {window + 1}")
    P = rec.pose_at(rec.t) if pose is None else np.asarray(pose, dtype=float)
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
