"""Minimal CDR (XCDR1, little endian) encoder and fast decoders for the bag types.

Encoded messages start with the 4-byte encapsulation header ``00 01 00 00``
(CDR_LE); alignment of every primitive is relative to the byte after that
header, exactly as rosbag2/rclpy (Fast-CDR) lay it out.  Unlike
``rclpy.serialization.serialize_message`` no padding is appended after the
last field, so strict readers (``rosbags``) accept the result.

Supported types: ``sensor_msgs/msg/JointState``, ``geometry_msgs/msg/PoseStamped``,
``geometry_msgs/msg/TwistStamped``, ``diagnostic_msgs/msg/DiagnosticArray``,
``rosgraph_msgs/msg/Clock`` and ``std_msgs/msg/String``.  Messages to encode
may be ROS message objects, any object with the same attribute names, or
nested mappings; missing fields take the ROS defaults (zero, empty, ``w = 1``).
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from suds_ros.core.errors import SudsBagError
from suds_ros.io.stamps import split_ns

#: Encapsulation header of little-endian plain CDR.
CDR_LE_HEADER = b"\x00\x01\x00\x00"


class _Out:
    """Growing CDR payload (without the encapsulation header)."""

    __slots__ = ("buf", "pads")

    def __init__(self) -> None:
        self.buf = bytearray(CDR_LE_HEADER)
        self.pads: list[tuple[int, int]] = []  # [start, stop) of alignment padding

    def align(self, n: int) -> None:
        pad = -(len(self.buf) - 4) % n
        if pad:
            self.pads.append((len(self.buf), len(self.buf) + pad))
            self.buf += b"\x00" * pad

    def pack(self, fmt: str, size: int, *values: Any) -> None:
        self.align(size)
        self.buf += struct.pack("<" + fmt, *values)

    def string(self, value: str) -> None:
        raw = value.encode("utf-8") + b"\x00"
        self.pack("I", 4, len(raw))
        self.buf += raw

    def f64_seq(self, values: Any) -> None:
        arr = np.asarray(values if values is not None else (), dtype="<f8").reshape(-1)
        self.pack("I", 4, arr.size)
        if arr.size:
            self.align(8)
            self.buf += arr.tobytes()

    def str_seq(self, values: Sequence[str]) -> None:
        self.pack("I", 4, len(values))
        for value in values:
            self.string(value)


def _get(msg: Any, name: str, default: Any = None) -> Any:
    if isinstance(msg, Mapping):
        return msg.get(name, default)
    return getattr(msg, name, default)


def _time(out: _Out, t: Any) -> None:
    out.pack("iI", 4, int(_get(t, "sec", 0)), int(_get(t, "nanosec", 0)))


def _header(out: _Out, h: Any) -> None:
    _time(out, _get(h, "stamp"))
    out.string(str(_get(h, "frame_id", "")))


def _vec3(out: _Out, v: Any, w: float | None = None) -> None:
    vals = [float(_get(v, k, 0.0)) for k in "xyz"]
    if w is not None:
        vals.append(float(_get(v, "w", w)))
    out.pack(f"{len(vals)}d", 8, *vals)


def _joint_state(out: _Out, m: Any) -> None:
    _header(out, _get(m, "header"))
    out.str_seq([str(n) for n in (_get(m, "name") or ())])
    for field in ("position", "velocity", "effort"):
        out.f64_seq(_get(m, field))


def _pose_stamped(out: _Out, m: Any) -> None:
    _header(out, _get(m, "header"))
    pose = _get(m, "pose")
    _vec3(out, _get(pose, "position"))
    _vec3(out, _get(pose, "orientation"), w=1.0)


def _twist_stamped(out: _Out, m: Any) -> None:
    _header(out, _get(m, "header"))
    twist = _get(m, "twist")
    _vec3(out, _get(twist, "linear"))
    _vec3(out, _get(twist, "angular"))


def _diagnostic_array(out: _Out, m: Any) -> None:
    _header(out, _get(m, "header"))
    status = list(_get(m, "status") or ())
    out.pack("I", 4, len(status))
    for s in status:
        level = _get(s, "level", 0)
        out.buf += level if isinstance(level, bytes) else bytes([int(level) & 0xFF])
        for field in ("name", "message", "hardware_id"):
            out.string(str(_get(s, field, "")))
        values = list(_get(s, "values") or ())
        out.pack("I", 4, len(values))
        for kv in values:
            out.string(str(_get(kv, "key", "")))
            out.string(str(_get(kv, "value", "")))


def _clock(out: _Out, m: Any) -> None:
    _time(out, _get(m, "clock"))


def _string(out: _Out, m: Any) -> None:
    out.string(str(_get(m, "data", "")))


_ENCODERS: dict[str, Callable[[_Out, Any], None]] = {
    "sensor_msgs/msg/JointState": _joint_state,
    "geometry_msgs/msg/PoseStamped": _pose_stamped,
    "geometry_msgs/msg/TwistStamped": _twist_stamped,
    "diagnostic_msgs/msg/DiagnosticArray": _diagnostic_array,
    "rosgraph_msgs/msg/Clock": _clock,
    "std_msgs/msg/String": _string,
}


def serialize(type_name: str, msg: Any) -> bytes:
    """Encode ``msg`` of type ``type_name`` as CDR (with encapsulation header).

    Parameters
    ----------
    type_name : str
        ``pkg/msg/Type``, one of the supported types.
    msg : object or mapping
        Message with ROS field names (attributes or keys), nested the same way.

    Returns
    -------
    bytes
        Serialized message, no trailing padding.

    Raises
    ------
    SudsBagError
        If ``type_name`` is not supported.
    """
    if type_name not in _ENCODERS:
        msg_ = f"no CDR encoder for {type_name!r}; supported: {', '.join(sorted(_ENCODERS))}"
        raise SudsBagError(msg_)
    return bytes(_encode(type_name, msg).buf)


def _encode(type_name: str, msg: Any) -> _Out:
    out = _Out()
    _ENCODERS[type_name](out, msg)
    return out


def joint_state(
    stamp_ns: int,
    names: Sequence[str],
    position: Any,
    velocity: Any = (),
    effort: Any = (),
    frame_id: str = "",
) -> bytes:
    """Encode a ``sensor_msgs/msg/JointState``.

    Parameters
    ----------
    stamp_ns : int
        ``header.stamp`` in integer nanoseconds.
    names : sequence of str, length nj
    position, velocity, effort : array_like, shape (nj,) or (0,)
        rad (m), rad/s (m/s), N·m (N).
    frame_id : str
    """
    sec, nanosec = split_ns(stamp_ns)
    header = {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": frame_id}
    msg = {"header": header, "name": list(names), "position": position,
           "velocity": velocity, "effort": effort}
    return serialize("sensor_msgs/msg/JointState", msg)


def pose_stamped(
    stamp_ns: int,
    position: Sequence[float],
    orientation: Sequence[float],
    frame_id: str = "world",
) -> bytes:
    """Encode a ``geometry_msgs/msg/PoseStamped``.

    Parameters
    ----------
    stamp_ns : int
        ``header.stamp`` in integer nanoseconds.
    position : (3,) float
        x, y, z in m.
    orientation : (4,) float
        Quaternion x, y, z, w.
    frame_id : str
    """
    sec, nanosec = split_ns(stamp_ns)
    out = _Out()
    _header(out, {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": frame_id})
    out.pack("7d", 8, *(float(v) for v in (*position, *orientation)))
    return bytes(out.buf)


# ----------------------------------------------------------------- fast decoders
def _prefix(data: bytes) -> str:
    if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError(f"not a plain CDR message (header {bytes(data[:4]).hex()})")
    return "<" if data[1] == 1 else ">"


def _read_string(data: bytes, pos: int, e: str) -> tuple[str, int]:
    pos += -(pos - 4) % 4
    (n,) = struct.unpack_from(e + "I", data, pos)
    pos += 4
    if n == 0 or pos + n > len(data):
        raise ValueError("bad string length")
    return data[pos:pos + n - 1].decode("utf-8"), pos + n


def _read_f64_seq(data: bytes, pos: int, e: str) -> tuple[tuple[float, ...], int]:
    pos += -(pos - 4) % 4
    (n,) = struct.unpack_from(e + "I", data, pos)
    pos += 4
    if n == 0:
        return (), pos
    pos += -(pos - 4) % 8
    values = struct.unpack_from(f"{e}{n}d", data, pos)
    return values, pos + 8 * n


def parse_joint_state(
    data: bytes,
) -> tuple[int, int, tuple[str, ...], tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """Decode a CDR ``sensor_msgs/msg/JointState`` without a schema.

    Returns
    -------
    sec, nanosec : int
        ``header.stamp``.
    names : tuple of str
    position, velocity, effort : tuple of float

    Raises
    ------
    ValueError, struct.error, UnicodeDecodeError
        If ``data`` is not a well-formed message.
    """
    e = _prefix(data)
    sec, nanosec = struct.unpack_from(e + "iI", data, 4)
    _, pos = _read_string(data, 12, e)
    pos += -(pos - 4) % 4
    (count,) = struct.unpack_from(e + "I", data, pos)
    pos += 4
    if count > len(data):
        raise ValueError("bad name count")
    names = []
    for _ in range(count):
        name, pos = _read_string(data, pos, e)
        names.append(name)
    position, pos = _read_f64_seq(data, pos, e)
    velocity, pos = _read_f64_seq(data, pos, e)
    effort, pos = _read_f64_seq(data, pos, e)
    if pos + 3 < len(data):
        raise ValueError(f"{len(data) - pos} unread bytes after JointState")
    return sec, nanosec, tuple(names), position, velocity, effort


def parse_pose_stamped(data: bytes) -> tuple[int, int, str, tuple[float, ...]]:
    """Decode a CDR ``geometry_msgs/msg/PoseStamped`` without a schema.

    Returns
    -------
    sec, nanosec : int
        ``header.stamp``.
    frame_id : str
    values : (7,) tuple of float
        position x, y, z (m) and orientation x, y, z, w.
    """
    e = _prefix(data)
    sec, nanosec = struct.unpack_from(e + "iI", data, 4)
    frame_id, pos = _read_string(data, 12, e)
    pos += -(pos - 4) % 8
    values = struct.unpack_from(e + "7d", data, pos)
    if pos + 56 + 3 < len(data):
        raise ValueError(f"{len(data) - pos - 56} unread bytes after PoseStamped")
    return sec, nanosec, frame_id, values
