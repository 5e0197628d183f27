"""Time stamps and planar orientation: the one place that converts between representations.

Stamps travel in three forms: float seconds (the core's arrays), integer
nanoseconds (MCAP log times, exact arithmetic) and ROS ``(sec, nanosec)`` pairs
(``builtin_interfaces/msg/Time``, ``sec`` floored so ``0 ≤ nanosec < 1e9``).

Rounding rule (one rule for the whole package): float seconds ``t`` become
``floor(t)·1e9 + rint((t − floor(t))·1e9)`` ns.  ``t − floor(t)`` is exact in
floating point, so the only rounding is that of the sub-second part to the
nearest nanosecond (half to even).  Nanoseconds become float seconds by one
correctly rounded division.
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import BAD_QUATERNION, BAD_STAMP, NAN_OR_INF, SudsDataError

NS_PER_S = 1_000_000_000


@overload
def float_to_ns(t: float) -> int: ...
@overload
def float_to_ns(t: FloatArray) -> np.ndarray: ...


def float_to_ns(t):  # type: ignore[no-untyped-def]
    """Float seconds (scalar or array) → integer nanoseconds (``int`` or int64 array).

    Raises
    ------
    SudsDataError
        (code ``nan_or_inf``) for a non-finite stamp.
    """
    if isinstance(t, (float, int)):  # one stamp per message on the live path: no array round trip
        if not math.isfinite(t):
            raise SudsDataError(f"`stamp`: expected finite seconds, got {t!r}", code=NAN_OR_INF)
        sec = math.floor(t)
        return sec * NS_PER_S + round((t - sec) * 1e9)  # round() is half-to-even, as np.rint
    a = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(a)):
        raise SudsDataError(f"`stamp`: expected finite seconds, got {t!r}", code=NAN_OR_INF)
    sec = np.floor(a)
    ns = sec.astype(np.int64) * NS_PER_S + np.rint((a - sec) * 1e9).astype(np.int64)
    return int(ns) if ns.ndim == 0 else ns


@overload
def ns_to_float(ns: int) -> float: ...
@overload
def ns_to_float(ns: np.ndarray) -> FloatArray: ...


def ns_to_float(ns):  # type: ignore[no-untyped-def]
    """Integer nanoseconds (scalar or array) → float seconds."""
    if isinstance(ns, int) or np.ndim(ns) == 0:
        return int(ns) / NS_PER_S
    a = np.asarray(ns, dtype=np.int64)
    sec, rem = np.divmod(a, NS_PER_S)
    return sec.astype(float) + rem.astype(float) * 1e-9


def split_ns(ns: int) -> tuple[int, int]:
    """Integer nanoseconds → ROS ``(sec, nanosec)`` with ``sec`` floored."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return sec, nanosec


def join_ns(sec, nanosec):  # type: ignore[no-untyped-def]
    """ROS ``(sec, nanosec)`` (scalars or sequences) → integer nanoseconds (``int`` or int64 array).

    Raises
    ------
    SudsDataError
        (code ``bad_stamp``) when a ``nanosec`` lies outside [0, 1e9).
    """
    if isinstance(sec, int) or np.ndim(sec) == 0:
        s, n = int(sec), int(nanosec)
        if not 0 <= n < NS_PER_S:
            raise SudsDataError(f"`stamp.nanosec`: expected 0 ≤ nanosec < 1e9, got {n}", code=BAD_STAMP)
        return s * NS_PER_S + n
    s_a = np.asarray(sec, dtype=np.int64)
    n_a = np.asarray(nanosec, dtype=np.int64)
    bad = (n_a < 0) | (n_a >= NS_PER_S)
    if np.any(bad):
        raise SudsDataError(
            f"`stamp.nanosec`: expected 0 ≤ nanosec < 1e9, got {int(n_a[bad][0])}", code=BAD_STAMP)
    return s_a * NS_PER_S + n_a


def format_ns(ns: int) -> str:
    """A stamp in ns as exact decimal seconds, e.g. ``12.000500000 s``."""
    sign = "-" if int(ns) < 0 else ""
    sec, rem = divmod(abs(int(ns)), NS_PER_S)
    return f"{sign}{sec}.{rem:09d} s"


def quaternion_yaw(q):  # type: ignore[no-untyped-def]
    """Yaw (rotation about z, rad) of quaternions ``q`` (..., 4) ordered x, y, z, w.

    ``atan2(2(wz + xy), w² + x² − y² − z²)`` does not need unit quaternions; a
    zero quaternion gives NaN (arrays) or raises (a single quaternion, code
    ``bad_quaternion``).
    """
    if isinstance(q, tuple) and len(q) == 4:  # one quaternion (a message's): plain floats are faster
        x, y, z, w = (float(v) for v in q)
        norm2 = x * x + y * y + z * z + w * w
        if not (norm2 > 0 and math.isfinite(norm2)):
            raise SudsDataError(f"`orientation`: expected a non-zero finite quaternion, got {(x, y, z, w)}",
                                code=BAD_QUATERNION)
        return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)
    a = np.asarray(q, dtype=float)
    x, y, z, w = (a[..., i] for i in range(4))
    yaw = np.arctan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)
    norm2 = np.sum(a * a, axis=-1)
    if a.ndim == 1:
        if not norm2 > 0 or not np.isfinite(norm2):
            got = tuple(float(v) for v in a)
            raise SudsDataError(f"`orientation`: expected a non-zero finite quaternion, got {got}",
                                code=BAD_QUATERNION)
        return float(yaw)
    return np.where(norm2 > 0, yaw, np.nan)


@overload
def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]: ...
@overload
def yaw_quaternion(yaw: FloatArray) -> FloatArray: ...


def yaw_quaternion(yaw):  # type: ignore[no-untyped-def]
    """The unit quaternion (x, y, z, w) of a rotation by ``yaw`` rad about z.

    A scalar gives a 4-tuple of floats, an array of n yaws an (n, 4) array.
    """
    if np.ndim(yaw) == 0:
        return 0.0, 0.0, float(np.sin(yaw / 2.0)), float(np.cos(yaw / 2.0))
    half = np.asarray(yaw, dtype=float) / 2.0
    zero = np.zeros_like(half)
    return np.stack([zero, zero, np.sin(half), np.cos(half)], axis=-1)
