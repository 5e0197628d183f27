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
        if not (math.isfinite(t) and math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw)):
            raise SudsDataError(f"pose sample at {t!r} s contains NaN or Inf", code=NAN_OR_INF)
        check_stamp("pose", t, self.last_pose_stamp)
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
