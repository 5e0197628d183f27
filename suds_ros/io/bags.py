"""Read and write recordings as MCAP bags (ROS 2 profile, ``ros2msg`` schemas, CDR).

Implements the bag contract of ``spec/recording.md`` without rclpy: writing
uses the ``mcap`` writer with schema texts from ``msg_defs/``; reading walks
the records itself (:mod:`suds_ros.io._mcap_scan`), so it works whatever the
channel/schema ids, compression and presence of a summary, and reads a
truncated file up to its last complete record.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO, Callable

import numpy as np

from suds_ros.core.errors import SudsBagError, SudsDataError
from suds_ros.core.recording import Recording
from suds_ros.io import cdr, msgdefs
from suds_ros.io._mcap_scan import ScanResult, scan

SHAPE_TYPE = "sensor_msgs/msg/JointState"
POSE_TYPE = "geometry_msgs/msg/PoseStamped"
METADATA_NAME = "suds"
LIBRARY = "suds_ros.io.bags (mcap-python)"

#: rosbag2 (Jazzy, metadata version 9) style QoS YAML: reliable, volatile, keep last 10.
DEFAULT_QOS_YAML = """- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
  deadline:
    sec: 0
    nsec: 0
  lifespan:
    sec: 0
    nsec: 0
  liveliness: automatic
  liveliness_lease_duration:
    sec: 0
    nsec: 0
  avoid_ros_namespace_conventions: false"""


@dataclass(frozen=True)
class RawMessage:
    """One serialized message as stored in the bag.

    Attributes
    ----------
    topic, type_name : str
        Channel topic and schema name (``pkg/msg/Type``).
    data : bytes
        CDR payload with its 4-byte encapsulation header.
    log_time_ns, publish_time_ns : int
        MCAP log and publish times, ns.
    """

    topic: str
    type_name: str
    data: bytes
    log_time_ns: int
    publish_time_ns: int


# ====================================================================== writing
class BagWriter:
    """Context manager writing an MCAP bag the way rosbag2's MCAP storage does.

    Parameters
    ----------
    path : str or Path
        Output ``.mcap`` file; its directory must exist.
    overwrite : bool
        Replace an existing file (otherwise :class:`SudsBagError`).
    compression : {'zstd', 'lz4', 'none'}
        Chunk compression.
    chunk_size : int
        Uncompressed chunk size (bytes) after which a chunk is written.
    """

    def __init__(self, path: str | Path, *, overwrite: bool = False, compression: str = "zstd",
                 chunk_size: int = 256 * 1024) -> None:
        from mcap.writer import CompressionType, Writer

        kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                 "none": CompressionType.NONE, "": CompressionType.NONE}
        if compression not in kinds:
            msg = f"compression: expected one of 'zstd', 'lz4', 'none', got {compression!r}"
            raise SudsBagError(msg)
        if chunk_size <= 0:
            raise SudsBagError(f"chunk_size: expected a positive byte count, got {chunk_size!r}")
        self.path = Path(path)
        if self.path.exists() and not overwrite:
            msg = f"{self.path}: file exists; refusing to overwrite it (pass overwrite=True)"
            raise SudsBagError(msg)
        if self.path.is_dir():
            raise SudsBagError(f"{self.path}: is a directory, expected a .mcap file path")
        try:
            self._file: BinaryIO | None = open(self.path, "wb")  # noqa: SIM115
        except OSError as exc:
            raise SudsBagError(f"{self.path}: cannot create: {exc.strerror}") from None
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=kinds[compression])
        self._writer.start(profile="ros2", library=LIBRARY)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        self._sequence: dict[str, int] = {}

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._file is None:
            raise SudsBagError(f"{self.path}: bag writer is closed")

    def add_topic(self, topic: str, type_name: str, *, qos_yaml: str | None = None) -> None:
        """Register ``topic`` of ``type_name`` (e.g. ``'sensor_msgs/msg/JointState'``).

        Adding the same topic again with the same type does nothing.

        Raises
        ------
        SudsBagError
            Unknown type, or the topic already exists with another type.
        """
        self._check_open()
        if topic in self._channels:
            if self._channels[topic][1] != type_name:
                msg = (f"topic {topic!r} was added as {self._channels[topic][1]!r}, "
                       f"cannot add it again as {type_name!r}")
                raise SudsBagError(msg)
            return
        text = msgdefs.schema_text(type_name)
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding="ros2msg", data=text.encode("utf-8"))
        meta = {"offered_qos_profiles": DEFAULT_QOS_YAML if qos_yaml is None else qos_yaml,
                "topic_type_hash": msgdefs.type_hash(type_name)}
        cid = self._writer.register_channel(topic=topic, message_encoding="cdr",
                                            schema_id=self._schemas[type_name], metadata=meta)
        self._channels[topic] = (cid, type_name)
        self._sequence[topic] = 0

    def write_raw(self, topic: str, data: bytes, log_time_ns: int,
                  publish_time_ns: int | None = None) -> None:
        """Append one serialized (CDR) message of an added topic.

        Parameters
        ----------
        topic : str
        data : bytes
            CDR payload with encapsulation header (as from a ``raw=True`` subscription).
        log_time_ns, publish_time_ns : int
            Receive and publish times, ns; ``publish_time_ns`` defaults to ``log_time_ns``.
        """
        self._check_open()
        if topic not in self._channels:
            known = ", ".join(sorted(self._channels)) or "none"
            raise SudsBagError(f"topic {topic!r} was not added (call add_topic first); "
                               f"added topics: {known}")
        log = int(log_time_ns)
        pub = log if publish_time_ns is None else int(publish_time_ns)
        if log < 0 or pub < 0:
            raise SudsBagError(f"topic {topic!r}: negative time (log {log}, publish {pub} ns)")
        self._writer.add_message(channel_id=self._channels[topic][0], log_time=log,
                                 data=bytes(data), publish_time=pub,
                                 sequence=self._sequence[topic])
        self._sequence[topic] += 1

    def write_metadata(self, name: str, data: dict[str, str]) -> None:
        """Write an MCAP metadata record ``name`` with string keys and values."""
        self._check_open()
        bad = {k: v for k, v in data.items() if not isinstance(k, str) or not isinstance(v, str)}
        if bad:
            raise SudsBagError(f"metadata {name!r}: keys and values must be str, got {bad!r}")
        self._writer.add_metadata(name, dict(data))

    def flush(self) -> None:
        """End the current chunk and push everything written so far to the file."""
        self._check_open()
        self._writer.flush()

    def close(self) -> None:
        """Write the summary (schemas, channels, statistics, indexes) and close; idempotent."""
        if self._file is None:
            return
        try:
            self._writer.finish()
        finally:
            self._file.close()
            self._file = None


# ====================================================================== reading
def iter_raw_messages(path: str | Path, topics: Iterable[str] | None = None
                      ) -> Iterator[RawMessage]:
    """Messages of ``path`` in log-time order, optionally only of ``topics``.

    Truncated files are read up to their last complete record; the summary is
    not needed.

    Raises
    ------
    SudsBagError
        If the file is missing, empty or not MCAP.
    """
    res = scan(path, None if topics is None else frozenset(topics))
    for cid, log, pub, data in res.messages:
        ch = res.channels[cid]
        yield RawMessage(ch.topic, ch.schema_name, data, log, pub)


def read_metadata(path: str | Path) -> dict[str, dict[str, str]]:
    """All MCAP metadata records of ``path``, keyed by record name."""
    return scan(path, keep_messages=False, chunks=False).metadata


def bag_info(path: str | Path) -> dict[str, Any]:
    """Summary of a bag, computed from its records (works without a summary section).

    Returns
    -------
    dict
        ``path``, ``profile``, ``library``, ``topics`` (topic → ``{'type', 'count',
        'message_encoding'}``), ``message_count``, ``start_ns``/``end_ns`` (log time, or
        None), ``duration_s``, ``metadata``, ``compression`` (sorted list of chunk
        compressions, ``'none'`` for uncompressed chunks; empty if unchunked),
        ``has_summary``, ``truncated`` and ``problem`` (why it counts as truncated).
    """
    res = scan(path, keep_messages=False)
    topics: dict[str, dict[str, Any]] = {}
    for cid, ch in res.channels.items():
        entry = topics.setdefault(ch.topic, {"type": ch.schema_name, "count": 0,
                                             "message_encoding": ch.message_encoding})
        entry["count"] += res.counts.get(cid, 0)
    duration = None if res.start_ns is None else (res.end_ns - res.start_ns) * 1e-9
    return {"path": str(res.path), "profile": res.profile, "library": res.library,
            "topics": topics, "message_count": sum(res.counts.values()),
            "start_ns": res.start_ns, "end_ns": res.end_ns, "duration_s": duration,
            "metadata": res.metadata, "compression": sorted(res.compressions),
            "has_summary": res.has_summary, "truncated": res.truncated,
            "problem": res.problem}


@lru_cache(maxsize=64)
def _decoder(type_name: str, schema: bytes) -> Callable[[bytes], Any]:
    from mcap.records import Schema
    from mcap_ros2.decoder import DecoderFactory

    rec = Schema(id=1, name=type_name, encoding="ros2msg", data=schema)
    dec = DecoderFactory().decoder_for("cdr", rec)
    if dec is None:  # pragma: no cover - factory always handles cdr + ros2msg
        raise SudsBagError(f"no decoder for {type_name!r}")
    return dec


def decode_message(type_name: str, data: bytes) -> Any:
    """Decode CDR ``data`` of ``type_name`` (one of the types in ``msg_defs``).

    Returns
    -------
    object
        Message with attribute access by ROS field name (``msg.header.stamp.sec``).

    Raises
    ------
    SudsBagError
        Unknown type or malformed data.
    """
    dec = _decoder(type_name, msgdefs.schema_text(type_name).encode("utf-8"))
    try:
        return dec(data)
    except Exception as exc:  # mcap_ros2 raises assorted errors on bad input
        raise SudsBagError(f"cannot decode {type_name!r} message ({len(data)} bytes): {exc}"
                           ) from None


def _select(res: ScanResult, topic: str, type_name: str) -> list[tuple[int, bytes, bytes]]:
    """``(sample index, data, schema)`` list of ``topic``'s messages of ``type_name``."""
    present = sorted({ch.topic for ch in res.channels.values()})
    chans = {cid: ch for cid, ch in res.channels.items() if ch.topic == topic}
    if not chans:
        raise SudsBagError(f"{res.path}: topic {topic!r} is not in the bag; topics present: "
                           f"{', '.join(present) or 'none'}")
    good = {cid: ch for cid, ch in chans.items() if ch.schema_name == type_name}
    if not good:
        types = sorted({ch.schema_name for ch in chans.values()})
        raise SudsBagError(f"{res.path}: topic {topic!r} has type {', '.join(types)}, "
                           f"expected {type_name}")
    for ch in good.values():
        if ch.message_encoding != "cdr":
            raise SudsBagError(f"{res.path}: topic {topic!r} has message encoding "
                               f"{ch.message_encoding!r}, expected 'cdr'")
    out = [(k, data, good[cid].schema_data) for k, (cid, _, _, data)
           in enumerate(m for m in res.messages if m[0] in good)]
    if not out:
        raise SudsBagError(f"{res.path}: topic {topic!r} has no messages")
    return out


def _generic(type_name: str, schema: bytes, data: bytes, where: str) -> Any:
    try:
        return _decoder(type_name, schema or msgdefs.schema_text(type_name).encode())(data)
    except Exception as exc:
        raise SudsBagError(f"{where}: cannot decode the message: {exc}") from None


def _read_shape(res: ScanResult, topic: str) -> tuple[
        np.ndarray, tuple[str, ...], np.ndarray, np.ndarray | None]:
    """Stamps (n,) int ns, joint names, positions (n, nj) and efforts (n, nj) or None."""
    sec, nsec, pos, eff = [], [], [], []
    first: tuple[str, ...] | None = None
    for k, data, schema in _select(res, topic, SHAPE_TYPE):
        try:
            s, ns, names, p, v, e = cdr.parse_joint_state(data)
        except (ValueError, struct.error, UnicodeDecodeError):
            m = _generic(SHAPE_TYPE, schema, data, f"{res.path}: {topic}: sample {k}")
            s, ns = m.header.stamp.sec, m.header.stamp.nanosec
            names, p, v, e = (tuple(m.name), tuple(m.position), tuple(m.velocity),
                              tuple(m.effort))
        stamp = _fmt(s * 1_000_000_000 + ns)
        if first is None:
            first = names
        elif names != first:
            raise SudsDataError(f"{res.path}: {topic}: sample {k} (stamp {stamp}) has "
                                f"joints {list(names)}, but sample 0 has {list(first)}")
        nj = len(first)
        for field, vals in (("position", p), ("velocity", v), ("effort", e)):
            if len(vals) != nj and (field == "position" or len(vals) != 0):
                raise SudsDataError(
                    f"{res.path}: {topic}: sample {k} (stamp {stamp}): {field} has "
                    f"{len(vals)} values for {nj} joints {list(first)}")
        sec.append(s)
        nsec.append(ns)
        pos.append(p)
        eff.append(e)
    assert first is not None
    r = np.asarray(pos, dtype=float).reshape(len(pos), len(first))
    effort = None
    if first and all(len(e) == len(first) for e in eff):
        effort = np.asarray(eff, dtype=float)
    return _stamps_ns(sec, nsec), first, r, effort


def _stamps_ns(sec: list[int], nsec: list[int]) -> np.ndarray:
    """Integer nanosecond stamps (n,) from ROS ``sec``/``nanosec`` lists."""
    return np.asarray(sec, dtype=np.int64) * 1_000_000_000 + np.asarray(nsec, dtype=np.int64)


def _fmt(ns: int) -> str:
    """Stamp in ns as exact decimal seconds."""
    sec, rem = divmod(int(ns), 1_000_000_000)
    return f"{sec}.{rem:09d} s"


def quaternion_yaw(q: np.ndarray) -> np.ndarray:
    """Yaw (rotation about z, rad) of quaternions ``q`` (..., 4) ordered x, y, z, w.

    Uses ``atan2(2(wz + xy), w² + x² − y² − z²)``, which does not need unit
    quaternions; a zero quaternion gives NaN.
    """
    x, y, z, w = (q[..., i] for i in range(4))
    num = 2.0 * (w * z + x * y)
    den = w * w + x * x - y * y - z * z
    yaw = np.arctan2(num, den)
    return np.where(np.sum(q * q, axis=-1) > 0, yaw, np.nan)


def _read_pose(res: ScanResult, topic: str) -> tuple[np.ndarray, np.ndarray]:
    """Pose stamps (m,) int ns and pose (m, 3): x (m), y (m), yaw (rad)."""
    sec, nsec, vals = [], [], []
    for k, data, schema in _select(res, topic, POSE_TYPE):
        try:
            s, ns, _, v = cdr.parse_pose_stamped(data)
        except (ValueError, struct.error, UnicodeDecodeError):
            m = _generic(POSE_TYPE, schema, data, f"{res.path}: {topic}: sample {k}")
            s, ns = m.header.stamp.sec, m.header.stamp.nanosec
            p, o = m.pose.position, m.pose.orientation
            v = (p.x, p.y, p.z, o.x, o.y, o.z, o.w)
        sec.append(s)
        nsec.append(ns)
        vals.append(v)
    arr = np.asarray(vals, dtype=float).reshape(len(vals), 7)
    pose = np.column_stack([arr[:, 0], arr[:, 1], quaternion_yaw(arr[:, 3:7])])
    return _stamps_ns(sec, nsec), pose


def _check_series(path: Path, topic: str, t_ns: np.ndarray, values: np.ndarray) -> None:
    """Raise :class:`SudsDataError` naming ``topic`` for NaN, duplicate or unsorted data.

    ``t_ns`` (n,) int ns stamps, ``values`` (n, ...) float.
    """
    rows = ~np.all(np.isfinite(values.reshape(len(t_ns), -1)), axis=1)
    if np.any(rows):
        k = int(np.flatnonzero(rows)[0])
        raise SudsDataError(f"{path}: {topic}: sample {k} (stamp {_fmt(t_ns[k])}) contains NaN "
                            "or Inf (a zero quaternion counts as NaN yaw)")
    d = np.diff(t_ns)
    if np.any(d == 0):
        k = int(np.flatnonzero(d == 0)[0])
        raise SudsDataError(f"{path}: {topic}: duplicate stamp {_fmt(t_ns[k])} at samples "
                            f"{k} and {k + 1}")
    if np.any(d < 0):
        k = int(np.flatnonzero(d < 0)[0])
        raise SudsDataError(f"{path}: {topic}: stamps are not sorted: sample {k + 1} "
                            f"({_fmt(t_ns[k + 1])}) comes before sample {k} ({_fmt(t_ns[k])})")


def _split(value: str) -> tuple[str, ...]:
    return tuple(x.strip() for x in value.split(",") if x.strip())


def _roles(path: Path, meta: dict[str, str] | None, names: tuple[str, ...],
           actuated: Sequence[str] | None, passive: Sequence[str] | None
           ) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Actuated and passive joints: keyword arguments first, else the metadata."""
    if actuated is None and passive is None and meta is not None:
        if "actuated" in meta:
            actuated = _split(meta["actuated"])
        if "passive" in meta:
            passive = _split(meta["passive"])
    if actuated is None and passive is None:
        why = ("the bag has no 'suds' metadata record" if meta is None else
               "the 'suds' metadata record has neither 'actuated' nor 'passive'")
        raise SudsBagError(f"{path}: no 'actuated' joints: {why}; pass --actuated "
                           f"(joints in the bag: {', '.join(names)})")
    if actuated is None:
        actuated = tuple(j for j in names if j not in set(passive or ()))
    if passive is None:
        passive = tuple(j for j in names if j not in set(actuated))
    return tuple(actuated), tuple(passive)


def read_recording(path: str | Path, *, system: str | None = None,
                   actuated: Sequence[str] | None = None, passive: Sequence[str] | None = None,
                   shape_topic: str = "/suds/shape", pose_topic: str = "/suds/body_pose"
                   ) -> Recording:
    """Read a bag that follows the recording contract into a :class:`Recording`.

    Parameters
    ----------
    path : str or Path
        MCAP file (or rosbag2 directory with one ``.mcap``).
    system : str, optional
        System id; overrides the ``suds`` metadata.
    actuated, passive : sequence of str, optional
        Joint roles; if either is given, both come from the arguments (the missing one
        is the complement), otherwise from the ``suds`` metadata.
    shape_topic, pose_topic : str
        Topics of the JointState and PoseStamped streams.

    Returns
    -------
    Recording
        ``t`` (n,) and ``pose_t`` (m,) are the absolute ``header.stamp`` values in s;
        ``r`` (n, nj) the positions; ``pose`` (m, 3) x, y (m) and yaw (rad);
        ``effort`` (n, nj) only if every JointState carries one.

    Raises
    ------
    SudsBagError
        Unreadable/foreign file, missing topic, missing system or joint roles.
    SudsDataError
        Joint names changing mid-stream, NaN values, duplicate or unsorted stamps.
    """
    res = scan(path, frozenset({shape_topic, pose_topic}))
    t_ns, names, r, effort = _read_shape(res, shape_topic)
    pose_ns, pose = _read_pose(res, pose_topic)
    _check_series(res.path, shape_topic, t_ns, r)
    _check_series(res.path, pose_topic, pose_ns, pose)
    t = (t_ns // 1_000_000_000).astype(float) + (t_ns % 1_000_000_000).astype(float) * 1e-9
    pose_t = ((pose_ns // 1_000_000_000).astype(float)
              + (pose_ns % 1_000_000_000).astype(float) * 1e-9)
    meta = res.metadata.get(METADATA_NAME)
    if system is None:
        system = (meta or {}).get("system")
    if not system:
        why = ("the bag has no 'suds' metadata record" if meta is None
               else "the 'suds' metadata record has no 'system' key")
        raise SudsBagError(f"{res.path}: no 'system': {why}; pass --system")
    act, pas = _roles(res.path, meta, names, actuated, passive)
    gait_hz = None
    if meta is not None and meta.get("gait_hz", "").strip():
        try:
            gait_hz = float(meta["gait_hz"])
        except ValueError:
            raise SudsBagError(f"{res.path}: 'suds' metadata gait_hz: expected a number, got "
                               f"{meta['gait_hz']!r}") from None
        if not math.isfinite(gait_hz) or gait_hz <= 0:
            raise SudsBagError(f"{res.path}: 'suds' metadata gait_hz: expected a positive "
                               f"frequency, got {meta['gait_hz']!r}")
    try:
        return Recording(t=t, r=r, joint_names=names, actuated=act, passive=pas,
                         pose_t=pose_t, pose=pose, system=system, gait_hz=gait_hz,
                         effort=effort)
    except SudsDataError as exc:
        raise SudsDataError(f"{res.path}: {exc}") from None


def write_recording(path: str | Path, rec: Recording, *, overwrite: bool = False,
                    compression: str = "zstd", shape_topic: str = "/suds/shape",
                    pose_topic: str = "/suds/body_pose") -> None:
    """Write ``rec`` as a contract bag (``Recording.truth`` is never written).

    Shape samples become JointState messages (names, positions, empty velocity,
    effort if ``rec.effort``), pose samples PoseStamped messages in frame
    ``world`` with a yaw-only quaternion; header stamps are the sample stamps and
    the log times equal them.  The ``suds`` metadata record holds system,
    actuated, passive (comma-joined) and gait_hz (if known).
    """
    stamps = [cdr.ns_from_seconds(x) for x in rec.t]
    pose_stamps = [cdr.ns_from_seconds(x) for x in rec.pose_t]
    meta = {"system": rec.system, "actuated": ",".join(rec.actuated),
            "passive": ",".join(rec.passive)}
    if rec.gait_hz is not None:
        meta["gait_hz"] = repr(float(rec.gait_hz))
    events: list[tuple[int, int, int]] = [(ns, 0, k) for k, ns in enumerate(stamps)]
    events += [(ns, 1, k) for k, ns in enumerate(pose_stamps)]
    events.sort()
    half = 0.5 * rec.pose[:, 2]
    quat = np.column_stack([np.zeros_like(half), np.zeros_like(half), np.sin(half), np.cos(half)])
    with BagWriter(path, overwrite=overwrite, compression=compression) as w:
        w.add_topic(shape_topic, SHAPE_TYPE)
        w.add_topic(pose_topic, POSE_TYPE)
        w.write_metadata(METADATA_NAME, meta)
        for ns, kind, k in events:
            if kind == 0:
                eff = () if rec.effort is None else rec.effort[k]
                data = cdr.joint_state(ns, rec.joint_names, rec.r[k], (), eff)
                w.write_raw(shape_topic, data, ns, ns)
            else:
                x, y = rec.pose[k, 0], rec.pose[k, 1]
                data = cdr.pose_stamped(ns, (x, y, 0.0), quat[k], "world")
                w.write_raw(pose_topic, data, ns, ns)
