"""CDR (XCDR1) encoding and decoding of the bag types through ``rosbags``, plus two fast decoders.

Encoding and decoding go through the ``rosbags`` typestore, built from the
``ros2msg`` texts of ``msg_defs/`` (the schemas our bags carry), so the bytes
are rosbag2's: little-endian plain CDR with the 4-byte encapsulation header, no
trailing padding.  ``rosbags`` was measured faster than ``mcap-ros2-support`` on
every one of our types, both ways (``benchmarks/bench_codec.py``,
``docs/results/codec.md``).  Messages to encode may be ROS message objects,
``rosbags`` objects, any object with the same attribute names, or nested mappings;
missing fields take the ROS defaults (zero, empty, quaternion ``w = 1``).

:func:`parse_joint_state` and :func:`parse_pose_stamped` are hand-written decoders
of the two recorded streams, kept because they measured 1.6× (JointState) and
3.7× (PoseStamped) faster than ``rosbags`` (codec.md); anything they refuse goes
through :func:`decode`.  :func:`parse_joint_states` and :func:`parse_pose_stampeds` decode
a chunk's messages of one layout (same names, frame and counts, checked byte for byte) as
numpy arrays at once, for long recordings (``docs/results/long_identify.md``); others go one
at a time.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping, Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from suds_ros.core.errors import SudsBagError
from suds_ros.io import msgdefs
from suds_ros.io.stamps import split_ns

#: Encapsulation header of little-endian plain CDR.
CDR_LE_HEADER = b"\x00\x01\x00\x00"
#: fields whose ROS default is not zero
_DEFAULTS = {("geometry_msgs/msg/Quaternion", "w"): 1.0}


@lru_cache(maxsize=1)
def typestore() -> Any:
    """The ``rosbags`` typestore of every type in ``msg_defs/`` (built once)."""
    return _store_from({t: msgdefs.schema_text(t) for t in msgdefs.known_types()})


def _store_from(texts: Mapping[str, str]) -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    types: dict[str, Any] = {}
    for name, text in texts.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


@lru_cache(maxsize=64)
def _store_for(type_name: str, schema: bytes) -> Any:
    """Typestore for ``type_name`` as a bag's ``schema`` text defines it."""
    if not schema:
        msgdefs.schema_text(type_name)  # SudsBagError for an unknown type
        return typestore()
    if type_name in msgdefs.known_types() and schema == msgdefs.schema_text(type_name).encode():
        return typestore()
    try:
        return _store_from({type_name: schema.decode("utf-8")})
    except Exception as exc:  # rosbags raises its own parse errors
        msg = f"cannot parse the bag's ros2msg schema of {type_name!r}: {exc}"
        raise SudsBagError(msg) from None


def _get(msg: Any, name: str) -> Any:
    if isinstance(msg, Mapping):
        return msg.get(name)
    return getattr(msg, name, None)


@lru_cache(maxsize=None)
def _builder(type_name: str) -> Callable[[Any], Any]:
    """Message (object or mapping, any nesting) → ``rosbags`` object of ``type_name``."""
    from rosbags.interfaces import Nodetype

    store = typestore()
    cls = store.types[type_name]
    plan: list[tuple[str, Callable[[Any], Any]]] = []
    for name, (kind, spec) in store.get_msgdef(type_name).fields:
        if kind == Nodetype.NAME:
            plan.append((name, _nested(spec)))
        elif kind in (Nodetype.SEQUENCE, Nodetype.ARRAY):
            plan.append((name, _sequence(spec[0])))
        else:
            plan.append((name, _primitive(spec, _DEFAULTS.get((type_name, name)))))

    def build(msg: Any) -> Any:
        if isinstance(msg, cls):
            return msg
        return cls(**{name: conv(_get(msg, name)) for name, conv in plan})
    return build


def _nested(type_name: str) -> Callable[[Any], Any]:
    def conv(value: Any) -> Any:
        return _builder(type_name)({} if value is None else value)
    return conv


_NUMPY = {"float64": np.float64, "float32": np.float32, "int8": np.int8, "uint8": np.uint8,
          "byte": np.uint8, "char": np.uint8, "int16": np.int16, "uint16": np.uint16,
          "int32": np.int32, "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64,
          "bool": np.bool_}


def _sequence(item: tuple[Any, Any]) -> Callable[[Any], Any]:
    from rosbags.interfaces import Nodetype

    kind, spec = item
    if kind == Nodetype.NAME:
        return lambda v: [_builder(spec)(x) for x in (v if v is not None else ())]
    if spec[0] == "string":
        return lambda v: [str(x) for x in (v if v is not None else ())]
    dtype = _NUMPY[spec[0]]
    # rosbags serializes arrays from their buffer: they must be contiguous
    return lambda v: np.ascontiguousarray(np.asarray(v if v is not None else (), dtype=dtype).reshape(-1))


def _primitive(spec: tuple[str, int], default: Any) -> Callable[[Any], Any]:
    name = spec[0]
    if name == "string":
        return lambda v: "" if v is None else str(v)
    if name.startswith("float"):
        zero = 0.0 if default is None else default
        return lambda v: zero if v is None else float(v)
    if name == "bool":
        return lambda v: bool(v)

    def integer(v: Any) -> int:
        if isinstance(v, (bytes, bytearray)):  # a ``byte`` field from rclpy
            return v[0] if v else 0
        return 0 if v is None else int(v)
    return integer


def _f64(values: Any) -> np.ndarray:
    """``values`` (None: empty) as a contiguous float64 vector (rosbags serializes from the buffer)."""
    return np.ascontiguousarray(np.asarray(() if values is None else values, dtype=np.float64).reshape(-1))


def encode(type_name: str, msg: Any) -> bytes:
    """Encode ``msg`` of type ``type_name`` as CDR (with encapsulation header).

    Parameters
    ----------
    type_name : str
        ``pkg/msg/Type``, one of :func:`~suds_ros.io.msgdefs.known_types`.
    msg : object or mapping
        Message with ROS field names (attributes or keys), nested the same way.

    Returns
    -------
    bytes
        Serialized message, as rosbag2 stores it (no trailing padding).

    Raises
    ------
    SudsBagError
        If ``type_name`` has no schema in ``msg_defs/``, or a field cannot be encoded.
    """
    msgdefs.schema_text(type_name)  # SudsBagError for an unknown type
    try:
        obj = _builder(type_name)(msg)
        return bytes(typestore().serialize_cdr(obj, type_name))
    except (TypeError, ValueError, OverflowError, struct.error) as exc:
        raise SudsBagError(f"cannot encode a {type_name!r} message: {exc}") from None


def decode(type_name: str, data: bytes, schema: bytes = b"") -> Any:
    """Decode CDR ``data`` of ``type_name`` with the bag's ``schema`` text (default: ``msg_defs``).

    Returns
    -------
    object
        ``rosbags`` message with attribute access by ROS field name
        (``msg.header.stamp.sec``; float arrays as numpy arrays).

    Raises
    ------
    SudsBagError
        Unknown type, unparsable schema, or malformed data.
    """
    store = _store_for(type_name, bytes(schema))
    raw = bytes(data)
    if len(raw) < 4 or raw[0] != 0 or raw[1] not in (0, 1):
        raise SudsBagError(f"cannot decode {type_name!r} message ({len(raw)} bytes): not plain "
                           f"CDR (encapsulation header {raw[:4].hex()})")
    msgdef = store.get_msgdef(type_name)
    # rosbags' generated deserializer, without the size check of ``deserialize_cdr``: rclpy
    # (and so rosbag2) may leave more than 3 trailing padding bytes after the last field
    read = msgdef.deserialize_cdr_le if raw[1] else msgdef.deserialize_cdr_be
    try:
        return read(raw[4:], 0, msgdef.cls, store)[0]
    except Exception as exc:  # struct.error, UnicodeDecodeError, ValueError, IndexError, …
        raise SudsBagError(f"cannot decode {type_name!r} message ({len(raw)} bytes): "
                           f"{type(exc).__name__}: {exc}") from None


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
    store = typestore()
    t = store.types
    msg = t["sensor_msgs/msg/JointState"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                        frame_id=frame_id),
        name=[str(n) for n in names],
        position=_f64(position), velocity=_f64(velocity), effort=_f64(effort))
    return bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))


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
    store = typestore()
    t = store.types
    x, y, z = (float(v) for v in position)
    qx, qy, qz, qw = (float(v) for v in orientation)
    msg = t["geometry_msgs/msg/PoseStamped"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                        frame_id=frame_id),
        pose=t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=x, y=y, z=z),
                                         orientation=t["geometry_msgs/msg/Quaternion"](
                                             x=qx, y=qy, z=qz, w=qw)))
    return bytes(store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))


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
    return _parse_joint_state(data)[:6]


def _parse_joint_state(
    data: bytes,
) -> tuple[int, int, tuple[str, ...], tuple[float, ...], tuple[float, ...], tuple[float, ...], int]:
    """:func:`parse_joint_state` and the offset where the names end (the position sequence starts)."""
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
    names_end = pos
    position, velocity, effort = _joint_values(data, pos, e)
    return sec, nanosec, tuple(names), position, velocity, effort, names_end


def _joint_values(data: bytes, pos: int, e: str
                  ) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    position, pos = _read_f64_seq(data, pos, e)
    velocity, pos = _read_f64_seq(data, pos, e)
    effort, pos = _read_f64_seq(data, pos, e)
    if pos + 3 < len(data):
        raise ValueError(f"{len(data) - pos} unread bytes after JointState")
    return position, velocity, effort


class JointStateParser:
    """:func:`parse_joint_state` for a stream of messages that mostly repeat their frame and names.

    The bytes from the frame id to the end of the names are compared with the previous
    message's; when they are the same, only the stamp and the three value sequences are
    decoded (the names are the same tuple).  Results are those of :func:`parse_joint_state`.
    """

    def __init__(self) -> None:
        self._key: bytes | None = None
        self._names: tuple[str, ...] = ()
        self._end = 0
        self._head = b""
        self._e = "<"

    def __call__(self, data: bytes) -> tuple[int, int, tuple[str, ...], tuple[float, ...],
                                             tuple[float, ...], tuple[float, ...]]:
        key, end = self._key, self._end
        if key is not None and len(data) > end and data[:2] == self._head and data[12:end] == key:
            e = self._e
            sec, nanosec = struct.unpack_from(e + "iI", data, 4)
            return (sec, nanosec, self._names, *_joint_values(data, end, e))
        sec, nanosec, names, position, velocity, effort, end = _parse_joint_state(data)
        self._key, self._names, self._end = bytes(data[12:end]), names, end
        self._head, self._e = bytes(data[:2]), _prefix(data)
        return sec, nanosec, names, position, velocity, effort


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


# ------------------------------------------------- many messages of one layout at once
def _rows(records: bytes, starts: np.ndarray, length: int) -> np.ndarray:
    """The ``length`` bytes at each of ``starts`` (k,) of ``records``, as a (k, length) uint8 table."""
    buf = np.frombuffer(records, dtype=np.uint8)
    return buf[starts[:, None] + np.arange(length)]


def _same_as_first(rows: np.ndarray, spans: Sequence[tuple[int, int]]) -> bool:
    """Whether every row's bytes in each [a, b) of ``spans`` equal the first row's."""
    return all(bool((rows[:, a:b] == rows[0, a:b]).all()) for a, b in spans if b > a)


def _floats(rows: np.ndarray, start: int, count: int, e: str) -> np.ndarray:
    """(k, count) float64 read at byte ``start`` of every row (byte order ``e``)."""
    return np.ascontiguousarray(rows[:, start:start + 8 * count]).view(e + "f8").astype(np.float64)


def _header_stamps(rows: np.ndarray, e: str) -> tuple[np.ndarray, np.ndarray]:
    """``header.stamp`` (sec, nanosec) of every row, int64 (k,) each (byte order ``e``)."""
    sec = np.ascontiguousarray(rows[:, 4:8]).view(e + "i4")[:, 0].astype(np.int64)
    nanosec = np.ascontiguousarray(rows[:, 8:12]).view(e + "u4")[:, 0].astype(np.int64)
    return sec, nanosec


def joint_state_layout(data: bytes) -> tuple[tuple[str, ...], int, list[tuple[int, int, int]], int]:
    """Where the parts of one CDR ``sensor_msgs/msg/JointState`` lie (the walk of :func:`parse_joint_state`).

    Returns the names, the offset where they end, (count offset, first value offset, count) of
    the position, velocity and effort sequences, and the offset where the effort ends.

    Raises
    ------
    ValueError, struct.error, UnicodeDecodeError
        If ``data`` is not a well-formed message.
    """
    e = _prefix(data)
    parsed = _parse_joint_state(data)  # checks the whole message
    names, pos = parsed[2], parsed[6]
    names_end, seqs = pos, []
    for _ in range(3):
        pos += -(pos - 4) % 4
        (n,) = struct.unpack_from(e + "I", data, pos)
        count_at, pos = pos, pos + 4
        if n:
            pos += -(pos - 4) % 8
        seqs.append((count_at, pos, n))
        pos += 8 * n
    return names, names_end, seqs, pos


def parse_joint_states(records: bytes, starts: np.ndarray, length: int
                       ) -> tuple[np.ndarray, np.ndarray, tuple[str, ...], np.ndarray, np.ndarray, np.ndarray] | None:
    """Decode k CDR JointState messages of ``length`` bytes each at ``starts`` (k,) of ``records`` at once.

    Only when they share one layout: the same encapsulation, frame id, joint names and value
    counts as the first (checked byte for byte); otherwise None (decode them one at a time).
    Returns ``sec``, ``nanosec`` (k,) int64, the names, and position, velocity, effort
    (k, count) float64: what :func:`parse_joint_state` gives for each, as arrays.
    """
    first = bytes(records[int(starts[0]):int(starts[0]) + length])
    try:
        names, names_end, seqs, end = joint_state_layout(first)
    except (ValueError, struct.error, UnicodeDecodeError):
        return None
    rows = _rows(records, starts, length)
    if not _same_as_first(rows, [(0, 4), (12, names_end)] + [(c, c + 4) for c, _, _ in seqs]):
        return None
    e = "<" if first[1] == 1 else ">"
    sec, nanosec = _header_stamps(rows, e)
    return (sec, nanosec, names, *(_floats(rows, at, n, e) for _, at, n in seqs))  # type: ignore[return-value]


def parse_pose_stampeds(records: bytes, starts: np.ndarray, length: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Decode k CDR PoseStamped messages of ``length`` bytes each at once (one frame id; else None).

    Returns ``sec``, ``nanosec`` (k,) int64 and the values (k, 7): position x, y, z and
    orientation x, y, z, w, as :func:`parse_pose_stamped` gives them.
    """
    first = bytes(records[int(starts[0]):int(starts[0]) + length])
    try:
        parse_pose_stamped(first)
    except (ValueError, struct.error, UnicodeDecodeError):
        return None
    e = _prefix(first)
    _, pos = _read_string(first, 12, e)
    pos += -(pos - 4) % 8
    rows = _rows(records, starts, length)
    if not _same_as_first(rows, [(0, 4), (12, pos)]):
        return None
    sec, nanosec = _header_stamps(rows, e)
    return sec, nanosec, _floats(rows, pos, 7, e)
