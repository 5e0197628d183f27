"""Pairing shape samples with the body pose by stamps: the one place it is done.

Shape and pose arrive on two streams at their own rates, each in stamp order, in any
interleaving of arrival.  A shape sample at stamp t is *released* with the pose linearly
interpolated at t once a pose with stamp ≥ t has been given; until then it waits.  A waiting
sample is dropped (counted in ``dropped_no_pose``) when

* it lies before the first pose (it can never be covered), or
* the shape stream has run more than ``max_wait`` stamp seconds past it with no covering pose
  (the pose stream stalled, or stopped for good).

Arrival order never matters, only stamps: the same samples in any interleaving give the same
released pairs, as long as neither stream runs more than ``max_wait`` ahead of the other.

Work per sample is O(1) amortised: the poses are kept in a deque from the last one at or before
the oldest waiting (or next) shape stamp, and each released sample pops what it passed.
Yaw is unwrapped here, pose by pose, so the released poses are continuous.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import NAN_OR_INF, SudsDataError
from suds_ros.core.ident.model import check_stamp

_TWO_PI = 2.0 * math.pi


def check_pose_sample(t: float, x: float, y: float, yaw: float, last: float) -> None:
    """Refuse a pose sample with NaN or Inf (``nan_or_inf``) or a stamp not after ``last`` (s).

    Raises
    ------
    SudsDataError
        ``nan_or_inf``, ``duplicate_stamp`` or ``out_of_order_stamp``.
    """
    if not (math.isfinite(t) and math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw)):
        raise SudsDataError(f"pose sample at {t!r} s contains NaN or Inf", code=NAN_OR_INF)
    check_stamp("pose", t, last)


def unwrap_next(prev: float, yaw: float) -> float:
    """``yaw`` shifted by whole turns to lie within half a turn of ``prev`` (rad)."""
    return prev + ((yaw - prev + math.pi) % _TWO_PI - math.pi)


class StampPairer:
    """Shape samples waiting for a covering pose; poses kept for interpolation.

    Parameters
    ----------
    max_wait : float
        Stamp seconds a shape sample may wait for a covering pose while later shape samples
        arrive, before it is dropped.

    Attributes
    ----------
    last_shape_stamp, last_pose_stamp : float
        Newest accepted stamps (s), −inf before the first.
    dropped_no_pose : int
        Shape samples that could not be paired.
    """

    def __init__(self, max_wait: float) -> None:
        self.max_wait = float(max_wait)
        self.last_shape_stamp = -math.inf
        self.last_pose_stamp = -math.inf
        self.dropped_no_pose = 0
        self._yaw = math.nan  # last unwrapped yaw
        self._pose_t: deque[float] = deque()
        self._pose: deque[tuple[float, float, float]] = deque()
        self._wait_t: deque[float] = deque()
        self._wait_r: deque[FloatArray] = deque()

    @property
    def waiting(self) -> int:
        """Shape samples waiting for a covering pose."""
        return len(self._wait_t)

    @property
    def last_pose(self) -> tuple[float, float, float]:
        """The newest pose (x, y, unwrapped yaw)."""
        return self._pose[-1]

    def add_pose(self, t: float, x: float, y: float, yaw: float) -> None:
        """Accept a pose sample (stamp s, x and y m, yaw rad).

        Raises
        ------
        SudsDataError
            NaN or Inf (``nan_or_inf``), a stamp not after the previous pose's
            (``duplicate_stamp``, ``out_of_order_stamp``).
        """
        check_pose_sample(t, x, y, yaw, self.last_pose_stamp)
        self._yaw = yaw if math.isnan(self._yaw) else unwrap_next(self._yaw, yaw)
        self.last_pose_stamp = t
        self._pose_t.append(t)
        self._pose.append((x, y, self._yaw))

    def add_shape(self, t: float, r: FloatArray) -> None:
        """Queue a checked shape sample (stamp order is checked here).

        Raises
        ------
        SudsDataError
            A stamp not after the previous shape's (``duplicate_stamp``, ``out_of_order_stamp``).
        """
        check_stamp("shape", t, self.last_shape_stamp)
        self.last_shape_stamp = t
        self._wait_t.append(t)
        self._wait_r.append(r)

    def release(self) -> tuple[list[float], list[FloatArray], list[FloatArray]]:
        """The shape samples now paired, in stamp order: stamps, joint values, poses (x, y, yaw)."""
        ts: list[float] = []
        rs: list[FloatArray] = []
        ps: list[FloatArray] = []
        wt, wr, pt, pv = self._wait_t, self._wait_r, self._pose_t, self._pose
        while wt:
            t = wt[0]
            if not pt or pt[-1] < t:  # no covering pose yet
                if self.last_shape_stamp - t > self.max_wait:
                    wt.popleft()
                    wr.popleft()
                    self.dropped_no_pose += 1
                    continue
                break
            if pt[0] > t:  # before the first pose: never pairable
                wt.popleft()
                wr.popleft()
                self.dropped_no_pose += 1
                continue
            while len(pt) > 2 and pt[1] <= t:  # keep the last pose at or before t
                pt.popleft()
                pv.popleft()
            t0, t1 = pt[0], pt[1] if len(pt) > 1 else pt[0]
            (x0, y0, a0), (x1, y1, a1) = pv[0], pv[1] if len(pv) > 1 else pv[0]
            if t >= t1:  # exactly on the newest pose (or the only one)
                pose = (x1, y1, a1)
            else:
                f = (t - t0) / (t1 - t0)
                pose = (x0 + f * (x1 - x0), y0 + f * (y1 - y0), a0 + f * (a1 - a0))
            ts.append(wt.popleft())
            rs.append(wr.popleft())
            ps.append(np.array(pose))
        return ts, rs, ps


#: the first stamps of each stream the estimator compares to tell one frame's samples (shared stamps)
FRAME_PROBE = 4
#: samples of one stream held while the other has given fewer than FRAME_PROBE (it may never come)
FRAME_PROBE_MAX = 64


class FrameJoiner:
    """Shape and pose samples stamped alike (one video frame, one message) joined into frames.

    A tracker that reads a frame's midline and its pose, or a rig that derives joint angles from
    the same camera frame as the body pose, stamps the two alike; whatever a later stage does to
    that time (a grid stage taking it to the camera's tick) must then be done to both.  Samples
    are given as they arrive (each stream in stamp order, any interleaving); :meth:`frames`
    returns the frames complete now, in stamp order: (stamp, joint values, pose (x, y, unwrapped
    yaw)).  A shape sample whose pose was lost gets the pose interpolated between the poses
    either side, once the later one is in (as :class:`StampPairer` would give it).  A shape sample
    before the first pose, or one the shape stream has run more than ``max_wait`` stamp seconds
    past with no pose at or after it (the pose stream stalled or stopped), is dropped and counted
    (``dropped_shapes``), as the pairer drops it; a pose whose shape sample was lost is dropped too
    (``dropped_poses``).
    """

    def __init__(self, max_wait: float) -> None:
        self.max_wait = float(max_wait)
        self._shapes: deque[tuple[float, FloatArray]] = deque()
        self._poses: deque[tuple[float, FloatArray]] = deque()
        self._prev: tuple[float, FloatArray] | None = None  # the newest pose taken off the queue
        self._yaw = math.nan
        self.dropped_shapes = 0
        self.dropped_poses = 0

    @property
    def waiting(self) -> int:
        """Shape samples waiting for a pose at or after their stamp."""
        return len(self._shapes)

    def add_shape(self, t: float, r: FloatArray) -> None:
        """A checked shape sample (its stamp after the previous one's)."""
        self._shapes.append((t, r))

    def add_pose(self, t: float, x: float, y: float, yaw: float) -> None:
        """A checked pose sample (finite, its stamp after the previous one's); yaw unwrapped here."""
        self._yaw = yaw if math.isnan(self._yaw) else unwrap_next(self._yaw, yaw)
        self._poses.append((t, np.array([x, y, self._yaw])))

    def frames(self) -> list[tuple[float, FloatArray, FloatArray]]:
        """The frames complete now, in stamp order."""
        out: list[tuple[float, FloatArray, FloatArray]] = []
        shapes, poses = self._shapes, self._poses
        while shapes and poses:
            ts, r = shapes[0]
            tp, p = poses[0]
            if tp <= ts:
                poses.popleft()
                self._prev = (tp, p)
                if tp == ts:
                    shapes.popleft()
                    out.append((ts, r, p))
                else:
                    self.dropped_poses += 1  # its shape sample was lost
                continue
            shapes.popleft()  # this sample's pose was lost: between the poses either side
            if self._prev is None:
                self.dropped_shapes += 1
                continue
            t0, p0 = self._prev
            out.append((ts, r, p0 + (ts - t0) / (tp - t0) * (p - p0)))
        while shapes and shapes[-1][0] - shapes[0][0] > self.max_wait:  # no pose came for it in time
            shapes.popleft()
            self.dropped_shapes += 1
        return out
