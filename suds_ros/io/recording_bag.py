"""The recording contract (`shared/spec/recording.md`): topics, message types, metadata, reader, writer.

Every module that reads, writes, publishes or subscribes a contract topic takes
its name from here.  :func:`read_recording` turns a contract bag into a
:class:`~suds_ros.core.recording.Recording` and :func:`write_recording` the
reverse, without rclpy (generic MCAP in :mod:`suds_ros.io.mcap`, CDR in
:mod:`suds_ros.io.cdr`: rosbags, plus fast decoders of the two recorded streams).
"""

from __future__ import annotations

import json
import math
import struct
from array import array
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from suds_ros.core.errors import (
    DUPLICATE_STAMP,
    MISSING_JOINT_ROLES,
    MISSING_SYSTEM,
    MISSING_TOPIC,
    NAN_OR_INF,
    OUT_OF_ORDER_STAMP,
    WRONG_JOINT_COUNT,
    WRONG_JOINT_NAMES,
    SudsBagError,
    SudsConfigError,
    SudsDataError,
    SudsError,
)
from suds_ros.core.recording import Recording
from suds_ros.io import cdr
from suds_ros.io.mcap import BagWriter, decode_message
from suds_ros.io.mcap_records import Damage, ScanResult
from suds_ros.io.mcap_scan import scan
from suds_ros.io.stamps import float_to_ns, format_ns, join_ns, ns_to_float, quaternion_yaw, yaw_quaternion

# topics of a recording, as stored in bags
SHAPE_TOPIC = "/suds/shape"
POSE_TOPIC = "/suds/body_pose"
# topics the suds_ros nodes add
SYSTEM_TOPIC = "/suds/system"
#: the gait in force (std_msgs/String, the suds-gait/1 text; latched), published by the simulator
GAIT_TOPIC = "/suds/gait"
MODEL_TOPIC = "/suds/model"
STATUS_TOPIC = "/suds/status"
PREDICTED_BODY_TOPIC = "/suds/predicted/body_velocity"
PREDICTED_PASSIVE_TOPIC = "/suds/predicted/passive_velocity"
#: shell-style pattern matching every predicted topic
PREDICTED_PATTERN = "/suds/predicted/*"

SHAPE_TYPE = "sensor_msgs/msg/JointState"
POSE_TYPE = "geometry_msgs/msg/PoseStamped"
TWIST_TYPE = "geometry_msgs/msg/TwistStamped"
STRING_TYPE = "std_msgs/msg/String"
DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"

# the MCAP metadata record and its keys
METADATA_NAME = "suds"
META_SYSTEM = "system"
META_ACTUATED = "actuated"
META_PASSIVE = "passive"
META_GAIT_HZ = "gait_hz"
#: optional: steady stretches of intermittent motion, ``t_first:t_last`` pairs (s), comma-joined
META_BOUTS = "bouts"
#: a second metadata record (not part of the ``suds`` record's contract): the gait that drove the run
GAIT_METADATA_NAME = "suds_gait"
#: its one key: the ``suds-gait/1`` file text
META_GAIT_YAML = "yaml"
#: frame of the recorded body pose
WORLD_FRAME = "world"


def parse_system_info(text: str) -> dict[str, Any]:
    """The robot description published on ``/suds/system`` (std_msgs/String, JSON).

    Keys: ``system``, ``joint_names``, ``actuated`` (required, among the joints), ``passive`` and
    ``gait_hz`` (None unless a positive number); other keys are kept as they are.

    Raises
    ------
    SudsDataError
        Not JSON, a required key missing, or actuated joints that are not among the joints.
    """
    try:
        info = json.loads(text)
        names = tuple(str(j) for j in info["joint_names"])
        actuated = tuple(str(j) for j in info["actuated"])
    except (ValueError, KeyError, TypeError) as exc:
        raise SudsDataError(f"expected JSON with joint_names and actuated: {type(exc).__name__}: {exc}") from None
    if not actuated or not set(actuated) <= set(names):
        raise SudsDataError(f"actuated {list(actuated)} not among joints {list(names)}")
    gait = info.get("gait_hz")
    return {**info, "joint_names": names, "actuated": actuated,
            "gait_hz": float(gait) if isinstance(gait, (int, float)) and gait > 0 else None}


def valid_namespace(ns: str) -> bool:
    """True for an absolute namespace of ROS name tokens (``/robot1``, ``/fleet/eel_2``)."""
    parts = ns.split("/")
    return (ns.startswith("/") and len(ns) > 1 and not ns.endswith("/")
            and all(t and (t[0].isalpha() or t[0] == "_") and all(c.isalnum() or c == "_" for c in t)
                    for t in parts[1:]))


def namespaced(namespace: str, topic: str) -> str:
    """The contract ``topic`` (e.g. ``/suds/shape``) of the robot in ``namespace`` ('' for the root).

    Nodes started in a namespace (``pipeline --namespace /robot1``) publish ``/robot1/suds/shape``
    etc., and one recorder can hold several robots' topics in one bag.

    Raises
    ------
    SudsConfigError
        ``namespace`` is neither '' nor an absolute ROS namespace.
    """
    if namespace and not valid_namespace(namespace):
        raise SudsConfigError(f"`namespace`: expected '' or an absolute ROS namespace such as /robot1, "
                              f"got {namespace!r}")
    return namespace + topic


def _check_topic(res: ScanResult, topic: str, type_name: str, n_messages: int) -> None:
    """Raise unless ``topic`` is in the bag with ``type_name``, CDR, and ``n_messages`` > 0 were read."""
    present = sorted({ch.topic for ch in res.channels.values()})
    chans = {cid: ch for cid, ch in res.channels.items() if ch.topic == topic}
    if not chans:
        under = sorted({t[:-len(topic)] for t in present if t.endswith(topic) and len(t) > len(topic)})
        hint = f" (namespaced: read it with namespace {', '.join(under)})" if under else ""
        raise SudsBagError(f"{res.path}: topic {topic!r} is not in the bag; topics present: "
                           f"{', '.join(present) or 'none'}{hint}", code=MISSING_TOPIC)
    good = {cid: ch for cid, ch in chans.items() if ch.schema_name == type_name}
    if not good:
        types = sorted({ch.schema_name or "unknown (its schema record is lost)"
                        for ch in chans.values()})
        raise SudsBagError(f"{res.path}: topic {topic!r} has type {', '.join(types)}, "
                           f"expected {type_name}")
    for ch in good.values():
        if ch.message_encoding != "cdr":
            raise SudsBagError(f"{res.path}: topic {topic!r} has message encoding "
                               f"{ch.message_encoding!r}, expected 'cdr'")
    if not n_messages:
        raise SudsBagError(f"{res.path}: topic {topic!r} has no messages", code=MISSING_TOPIC)


def _decode(type_name: str, schema: bytes, data: bytes, where: str) -> Any:
    """Decode with the bag's schema text (the slow path); errors name ``where``."""
    try:
        return decode_message(type_name, data, schema)
    except SudsBagError as exc:
        raise SudsBagError(f"{where}: {exc}", code=exc.code) from None


class _Topic:
    """Decodes one topic's messages as the scan reads them (compact arrays, not payloads).

    Messages of another type or encoding are not taken (:func:`_check_topic` then names the
    problem).  The first message that cannot be decoded or breaks the contract is kept as
    ``error`` (raised after the scan, with the bag's damage report); later ones are counted only.
    """

    type_name = ""

    def __init__(self, path: Path, topic: str) -> None:
        self.path, self.topic = path, topic
        self.n = 0
        self.log = array("q")
        self.sec = array("q")
        self.nsec = array("q")
        self.error: SudsError | None = None

    def take(self, ch: Any, log_time: int, data: bytes) -> None:
        if ch.schema_name != self.type_name or ch.message_encoding != "cdr":
            return
        k, self.n = self.n, self.n + 1
        if self.error is not None:
            return
        try:
            self.add(k, ch.schema_data, data)
        except SudsError as exc:
            self.error = exc
            return
        self.log.append(log_time)

    def take_batch(self, ch: Any, log: np.ndarray, records: bytes, starts: np.ndarray,
                   lengths: np.ndarray) -> None:
        """:meth:`take` of a chunk's messages on this topic; decoded together when they share one layout."""
        if ch.schema_name != self.type_name or ch.message_encoding != "cdr":
            return
        if self.error is None and bool((lengths == lengths[0]).all()) and \
                self.add_batch(records, starts, int(lengths[0])):
            self.n += starts.size
            self.log.frombytes(log.astype(np.int64).tobytes())
            return
        for t, a, n in zip(log.tolist(), starts.tolist(), lengths.tolist()):
            self.take(ch, t, records[a:a + n])

    def add(self, k: int, schema: bytes, data: bytes) -> None:
        raise NotImplementedError

    def add_batch(self, records: bytes, starts: np.ndarray, length: int) -> bool:
        """Add messages of ``length`` bytes at ``starts`` at once; False (nothing added): one at a time."""
        return False

    def _stamps(self, sec: np.ndarray, nsec: np.ndarray) -> None:
        self.sec.frombytes(sec.tobytes())
        self.nsec.frombytes(nsec.tobytes())

    def order(self) -> np.ndarray | slice:
        """Indices that sort the messages by log time, stably (a slice when they already are)."""
        log = np.frombuffer(self.log, dtype=np.int64)
        if np.all(log[1:] >= log[:-1]):
            return slice(None)  # in order (as written): no reordered copy of the values
        return np.argsort(log, kind="stable")

    def stamps(self, order: np.ndarray | slice) -> np.ndarray:
        return join_ns(np.frombuffer(self.sec, dtype=np.int64)[order], np.frombuffer(self.nsec, dtype=np.int64)[order])


class _ShapeTopic(_Topic):
    """JointState: stamps, joint names (one set), positions and efforts."""

    type_name = SHAPE_TYPE

    def __init__(self, path: Path, topic: str) -> None:
        super().__init__(path, topic)
        self.names: tuple[str, ...] | None = None
        self.pos = array("d")
        self.eff = array("d")
        self.all_effort = True
        self._parse = cdr.JointStateParser()

    def add(self, k: int, schema: bytes, data: bytes) -> None:
        try:
            s, ns, names, p, v, e = self._parse(data)
        except (ValueError, struct.error, UnicodeDecodeError):
            m = _decode(SHAPE_TYPE, schema, data, f"{self.path}: {self.topic}: sample {k}")
            s, ns = m.header.stamp.sec, m.header.stamp.nanosec
            names, p, v, e = (tuple(m.name), tuple(m.position), tuple(m.velocity), tuple(m.effort))
        if self.names is None:
            self.names = names
        elif names != self.names:
            raise SudsDataError(f"{self.path}: {self.topic}: sample {k} (stamp {format_ns(join_ns(s, ns))}) has "
                                f"joints {list(names)}, but sample 0 has {list(self.names)}",
                                code=WRONG_JOINT_NAMES)
        nj = len(self.names)
        for field, vals in (("position", p), ("velocity", v), ("effort", e)):
            if len(vals) != nj and (field == "position" or len(vals) != 0):
                raise SudsDataError(
                    f"{self.path}: {self.topic}: sample {k} (stamp {format_ns(join_ns(s, ns))}): {field} has "
                    f"{len(vals)} values for {nj} joints {list(self.names)}", code=WRONG_JOINT_COUNT)
        self.sec.append(s)
        self.nsec.append(ns)
        self.pos.extend(p)
        if self.all_effort and nj and len(e) == nj:
            self.eff.extend(e)
        else:
            self.all_effort = False

    def add_batch(self, records: bytes, starts: np.ndarray, length: int) -> bool:
        got = cdr.parse_joint_states(records, starts, length)
        if got is None:
            return False
        s, ns, names, p, v, e = got
        nj = len(names)
        if self.names is not None and names != self.names or p.shape[1] != nj or \
                v.shape[1] not in (0, nj) or e.shape[1] not in (0, nj):
            return False  # one at a time: the first message that breaks the contract is named
        self.names = names
        self._stamps(s, ns)
        self.pos.frombytes(p.tobytes())
        if self.all_effort and nj and e.shape[1] == nj:
            self.eff.frombytes(e.tobytes())
        else:
            self.all_effort = False
        return True

    def result(self) -> tuple[np.ndarray, tuple[str, ...], np.ndarray, np.ndarray | None]:
        """Stamps (n,) int ns, joint names, positions (n, nj) and efforts (n, nj) or None, by log time."""
        assert self.names is not None
        nj, o = len(self.names), self.order()
        r = np.frombuffer(self.pos, dtype=float).reshape(-1, nj)[o] if nj else np.zeros((len(self.log), 0))
        effort = np.frombuffer(self.eff, dtype=float).reshape(-1, nj)[o] if self.all_effort and nj else None
        return self.stamps(o), self.names, r, effort


class _PoseTopic(_Topic):
    """PoseStamped: stamps, x, y and the quaternion (yaw taken at the end)."""

    type_name = POSE_TYPE

    def __init__(self, path: Path, topic: str) -> None:
        super().__init__(path, topic)
        self.vals = array("d")

    def add(self, k: int, schema: bytes, data: bytes) -> None:
        try:
            s, ns, _, v = cdr.parse_pose_stamped(data)
        except (ValueError, struct.error, UnicodeDecodeError):
            m = _decode(POSE_TYPE, schema, data, f"{self.path}: {self.topic}: sample {k}")
            s, ns = m.header.stamp.sec, m.header.stamp.nanosec
            p, o = m.pose.position, m.pose.orientation
            v = (p.x, p.y, p.z, o.x, o.y, o.z, o.w)
        self.sec.append(s)
        self.nsec.append(ns)
        self.vals.extend(v)

    def add_batch(self, records: bytes, starts: np.ndarray, length: int) -> bool:
        got = cdr.parse_pose_stampeds(records, starts, length)
        if got is None:
            return False
        self._stamps(got[0], got[1])
        self.vals.frombytes(got[2].tobytes())
        return True

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """Pose stamps (m,) int ns and pose (m, 3): x (m), y (m), yaw (rad), by log time."""
        o = self.order()
        arr = np.frombuffer(self.vals, dtype=float).reshape(-1, 7)[o]
        return self.stamps(o), np.column_stack([arr[:, 0], arr[:, 1], quaternion_yaw(arr[:, 3:7])])


class _RawTopic(_Topic):
    """A few messages kept whole (the system description)."""

    type_name = STRING_TYPE

    def __init__(self, path: Path, topic: str) -> None:
        super().__init__(path, topic)
        self.raw: list[tuple[int, bytes, bytes]] = []

    def add(self, k: int, schema: bytes, data: bytes) -> None:
        self.raw.append((k, data, schema))

    def last(self) -> tuple[int, bytes, bytes]:
        """The last message by log time."""
        o = self.order()
        return self.raw[-1 if isinstance(o, slice) else int(o[-1])]


def _check_series(path: Path, topic: str, t_ns: np.ndarray, values: np.ndarray) -> None:
    """Raise :class:`SudsDataError` naming ``topic`` for NaN, duplicate or unsorted data.

    ``t_ns`` (n,) int ns stamps, ``values`` (n, ...) float.
    """
    rows = ~np.all(np.isfinite(values.reshape(len(t_ns), -1)), axis=1)
    if np.any(rows):
        k = int(np.flatnonzero(rows)[0])
        raise SudsDataError(f"{path}: {topic}: sample {k} (stamp {format_ns(t_ns[k])}) contains "
                            "NaN or Inf (a zero quaternion counts as NaN yaw)", code=NAN_OR_INF)
    d = np.diff(t_ns)
    if np.any(d == 0):
        k = int(np.flatnonzero(d == 0)[0])
        raise SudsDataError(f"{path}: {topic}: duplicate stamp {format_ns(t_ns[k])} at samples "
                            f"{k} and {k + 1}", code=DUPLICATE_STAMP)
    if np.any(d < 0):
        k = int(np.flatnonzero(d < 0)[0])
        raise SudsDataError(f"{path}: {topic}: stamps are not sorted: sample {k + 1} "
                            f"({format_ns(t_ns[k + 1])}) comes before sample {k} "
                            f"({format_ns(t_ns[k])})", code=OUT_OF_ORDER_STAMP)


def _split(value: str) -> tuple[str, ...]:
    return tuple(x.strip() for x in value.split(",") if x.strip())


def _roles(path: Path, meta: dict[str, str] | None, names: tuple[str, ...],
           actuated: Sequence[str] | None, passive: Sequence[str] | None
           ) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Actuated and passive joints: keyword arguments first, else the metadata."""
    if actuated is None and passive is None and meta is not None:
        if META_ACTUATED in meta:
            actuated = _split(meta[META_ACTUATED])
        if META_PASSIVE in meta:
            passive = _split(meta[META_PASSIVE])
    if actuated is None and passive is None:
        why = ("the bag has no 'suds' metadata record" if meta is None else
               "the 'suds' metadata record has neither 'actuated' nor 'passive'")
        raise SudsBagError(f"{path}: no 'actuated' joints: {why} "
                           f"(joints in the bag: {', '.join(names)})", code=MISSING_JOINT_ROLES)
    if actuated is None:
        actuated = tuple(j for j in names if j not in set(passive or ()))
    if passive is None:
        passive = tuple(j for j in names if j not in set(actuated))
    return tuple(actuated), tuple(passive)


@dataclass(frozen=True)
class RecordingRead:
    """A recording read from a bag, with what the bag lost.

    Attributes
    ----------
    recording : Recording
        What was intact.
    damage : tuple of Damage
        Every damaged part of the bag that was skipped (empty for an intact bag).
    truncated : bool
        The file ends without its footer (e.g. the recorder was killed).
    path : str
        The file read.
    """

    recording: Recording
    damage: tuple[Damage, ...] = ()
    truncated: bool = False
    path: str = ""

    def warning(self) -> str | None:
        """One line naming the loss (None if nothing was lost)."""
        return damage_warning(self.path, self.damage)


def damage_warning(path: str | Path, damage: Sequence[Damage]) -> str | None:
    """One line for a person: how many parts of ``path`` were skipped and what they held."""
    if not damage:
        return None
    lost = [d.messages for d in damage]
    total = "an unknown number of" if None in lost else str(sum(x or 0 for x in lost))
    spans = [(d.start_ns, d.end_ns) for d in damage
             if d.start_ns is not None and d.end_ns is not None and d.messages != 0]
    when = ""
    if spans:
        lo, hi = min(s for s, _ in spans), max(e for _, e in spans)
        when = f" between log times {format_ns(lo)} and {format_ns(hi)}"
    d = damage[0]
    first = f"{d.record}{f' at byte {d.offset}' if d.offset >= 0 else ''}: {d.reason}"
    more = f"; {len(damage) - 1} more (see `suds info`)" if len(damage) > 1 else ""
    return (f"{path}: damaged bag: {total} messages lost{when}; read the intact rest "
            f"({first}{more})")


def read_recording(path: str | Path, *, system: str | None = None,
                   actuated: Sequence[str] | None = None, passive: Sequence[str] | None = None,
                   shape_topic: str = SHAPE_TOPIC, pose_topic: str = POSE_TOPIC, namespace: str = ""
                   ) -> Recording:
    """Read a bag that follows the recording contract into a :class:`Recording`.

    Damaged parts of the bag are skipped silently here; :func:`read_recording_report`
    takes the same arguments and also returns what was lost.

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
    namespace : str
        The robot's ROS namespace in a bag of namespaced topics (``/robot1``: the topics
        ``/robot1/suds/shape`` …).  Its system and joint roles then come from its
        ``<namespace>/suds/system`` messages when the bag has them (the bag's ``suds`` metadata
        may describe another robot); without a namespace they come from the metadata, else from
        ``/suds/system``.

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
    return read_recording_report(path, system=system, actuated=actuated, passive=passive,
                                 shape_topic=shape_topic, pose_topic=pose_topic,
                                 namespace=namespace).recording


def read_recording_report(path: str | Path, *, system: str | None = None,
                          actuated: Sequence[str] | None = None,
                          passive: Sequence[str] | None = None, shape_topic: str = SHAPE_TOPIC,
                          pose_topic: str = POSE_TOPIC, namespace: str = "") -> RecordingRead:
    """:func:`read_recording`, returning the recording with the bag's damage report.

    Raises
    ------
    SudsBagError, SudsDataError
        As :func:`read_recording`; when the bag is damaged, the message says so.
    SudsConfigError
        ``namespace`` is not a ROS namespace.
    """
    shape_topic, pose_topic, system_topic = (namespaced(namespace, t) for t in (shape_topic, pose_topic, SYSTEM_TOPIC))
    path = Path(path)
    topics = {shape_topic: _ShapeTopic(path, shape_topic), pose_topic: _PoseTopic(path, pose_topic),
              system_topic: _RawTopic(path, system_topic)}
    res = scan(path, frozenset(topics), sink=lambda ch, log_time, data: topics[ch.topic].take(ch, log_time, data),
               batch_sink=lambda ch, *batch: topics[ch.topic].take_batch(ch, *batch))
    try:
        meta = _description(res, topics[system_topic], prefer_topic=bool(namespace))  # type: ignore[arg-type]
        rec = _to_recording(res, meta, system, actuated, passive, topics[shape_topic],  # type: ignore[arg-type]
                            topics[pose_topic])  # type: ignore[arg-type]
    except (SudsBagError, SudsDataError) as exc:
        if not res.damage:
            raise
        note = damage_warning(res.path, res.damage)
        raise type(exc)(f"{exc} (the bag is damaged: {note})", code=exc.code) from None
    return RecordingRead(rec, tuple(res.damage), res.truncated, str(res.path))


def _description(res: ScanResult, system: _RawTopic, prefer_topic: bool) -> dict[str, str] | None:
    """The robot's description as ``suds`` metadata keys: the metadata record or ``system_topic``.

    ``system_topic`` (:func:`parse_system_info`, as the simulator node publishes it) is used when
    ``prefer_topic`` and the bag has it, or when the bag has no metadata record; its last message
    counts.
    """
    meta = res.metadata.get(METADATA_NAME)
    system_topic = system.topic
    if not (prefer_topic or meta is None) or not any(ch.topic == system_topic for ch in res.channels.values()):
        return meta
    _check_topic(res, system_topic, STRING_TYPE, len(system.raw))
    k, data, schema = system.last()
    where = f"{res.path}: {system_topic}: message {k}"
    try:
        info = parse_system_info(_decode(STRING_TYPE, schema, data, where).data)
    except SudsDataError as exc:
        raise SudsBagError(f"{where}: {exc}", code=MISSING_SYSTEM) from None
    out = {META_ACTUATED: ",".join(info["actuated"])}
    if info.get("system"):
        out[META_SYSTEM] = str(info["system"])
    if "passive" in info:
        out[META_PASSIVE] = ",".join(str(j) for j in info["passive"])
    if info["gait_hz"] is not None:
        out[META_GAIT_HZ] = repr(info["gait_hz"])
    return out


def _to_recording(res: ScanResult, meta: dict[str, str] | None, system: str | None,
                  actuated: Sequence[str] | None, passive: Sequence[str] | None, shape: _ShapeTopic,
                  pose_reader: _PoseTopic) -> Recording:
    """The body of :func:`read_recording` on a scanned file (``meta``: :func:`_description`)."""
    shape_topic, pose_topic = shape.topic, pose_reader.topic
    for reader in (shape, pose_reader):
        _check_topic(res, reader.topic, reader.type_name, reader.n)
        if reader.error is not None:
            raise reader.error
    t_ns, names, r, effort = shape.result()
    pose_ns, pose = pose_reader.result()
    _check_series(res.path, shape_topic, t_ns, r)
    _check_series(res.path, pose_topic, pose_ns, pose)
    t, pose_t = ns_to_float(t_ns), ns_to_float(pose_ns)
    if system is None:
        system = (meta or {}).get(META_SYSTEM)
    if not system:
        why = ("the bag has no 'suds' metadata record" if meta is None
               else "the 'suds' metadata record has no 'system' key")
        raise SudsBagError(f"{res.path}: no 'system': {why}", code=MISSING_SYSTEM)
    act, pas = _roles(res.path, meta, names, actuated, passive)
    gait_hz = None
    if meta is not None and meta.get(META_GAIT_HZ, "").strip():
        try:
            gait_hz = float(meta[META_GAIT_HZ])
        except ValueError:
            raise SudsBagError(f"{res.path}: 'suds' metadata gait_hz: expected a number, got "
                               f"{meta[META_GAIT_HZ]!r}") from None
        if not math.isfinite(gait_hz) or gait_hz <= 0:
            raise SudsBagError(f"{res.path}: 'suds' metadata gait_hz: expected a positive "
                               f"frequency, got {meta[META_GAIT_HZ]!r}")
    bouts: tuple[tuple[float, float], ...] = ()
    if meta is not None and meta.get(META_BOUTS, "").strip():
        from suds_ros.core.bouts import parse_bouts

        try:
            bouts = parse_bouts(meta[META_BOUTS])
        except SudsDataError as exc:
            raise SudsBagError(f"{res.path}: 'suds' metadata {exc}") from None
    try:
        return Recording(t=t, r=r, joint_names=names, actuated=act, passive=pas,
                         pose_t=pose_t, pose=pose, system=system, gait_hz=gait_hz,
                         effort=effort, bouts=bouts)
    except SudsDataError as exc:
        raise SudsDataError(f"{res.path}: {exc}", code=exc.code) from None


def write_recording(path: str | Path, rec: Recording, *, overwrite: bool = False,
                    compression: str = "zstd", shape_topic: str = SHAPE_TOPIC,
                    pose_topic: str = POSE_TOPIC) -> None:
    """Write ``rec`` as a contract bag (``Recording.truth`` is never written).

    Shape samples become JointState messages (names, positions, empty velocity,
    effort if ``rec.effort``), pose samples PoseStamped messages in frame
    ``world`` with a yaw-only quaternion; header stamps are the sample stamps and
    the log times equal them.  The ``suds`` metadata record holds system,
    actuated, passive (comma-joined), gait_hz (if known) and bouts (if any).  The same file as
    :class:`RecordingWriter` given the recording in blocks.
    """
    with RecordingWriter(path, system=rec.system, joint_names=rec.joint_names, actuated=rec.actuated,
                         passive=rec.passive, gait_hz=rec.gait_hz, bouts=rec.bouts, overwrite=overwrite,
                         compression=compression, shape_topic=shape_topic, pose_topic=pose_topic) as w:
        w.write(rec.t, rec.r, rec.pose_t, rec.pose, rec.effort)


class RecordingWriter:
    """Write a contract bag block by block, as :func:`write_recording` writes a whole recording.

    Each :meth:`write` takes the next samples of both streams; messages go to the bag in stamp
    order (shape before pose at equal stamps) as soon as no later block can precede them, so
    only the samples not yet past the other stream's newest stamp are held.  Blocks that
    together make a :class:`Recording` give the file :func:`write_recording` writes for it,
    byte for byte.

    Parameters
    ----------
    path : str or Path
        Output ``.mcap``; never overwritten unless ``overwrite``.
    system : str
        System id (metadata).
    joint_names, actuated, passive : sequence of str
        Joint names, in the column order of the shape samples, and the joint roles.
    gait_hz : float or None
        Nominal gait frequency, Hz (metadata, if known).
    bouts : sequence of (t_first, t_last)
        Steady stretches of intermittent motion, stamps in s (metadata key ``bouts``, only when
        there are any).
    overwrite, compression, shape_topic, pose_topic
        As :func:`write_recording`.
    gait_yaml : str or None
        The ``suds-gait/1`` text of the gait that drove the run: written as its own metadata
        record ``suds_gait`` (key ``yaml``), beside the contract's ``suds`` record.

    Raises
    ------
    SudsBagError
        The file exists (without ``overwrite``) or cannot be created.
    """

    def __init__(self, path: str | Path, *, system: str, joint_names: Sequence[str],
                 actuated: Sequence[str], passive: Sequence[str], gait_hz: float | None = None,
                 bouts: Sequence[tuple[float, float]] = (), overwrite: bool = False,
                 compression: str = "zstd", shape_topic: str = SHAPE_TOPIC,
                 pose_topic: str = POSE_TOPIC, gait_yaml: str | None = None) -> None:
        self.joint_names = tuple(joint_names)
        self._topics = (shape_topic, pose_topic)
        meta = {META_SYSTEM: system, META_ACTUATED: ",".join(actuated), META_PASSIVE: ",".join(passive)}
        if gait_hz is not None:
            meta[META_GAIT_HZ] = repr(float(gait_hz))
        if bouts:
            from suds_ros.core.bouts import bouts_text, parse_bouts

            meta[META_BOUTS] = bouts_text(tuple((float(a), float(b)) for a, b in bouts))
            parse_bouts(meta[META_BOUTS])  # in order and disjoint, as readers check
        self._writer = BagWriter(path, overwrite=overwrite, compression=compression)
        self.path = self._writer.path
        self._writer.add_topic(shape_topic, SHAPE_TYPE)
        self._writer.add_topic(pose_topic, POSE_TYPE)
        self._writer.write_metadata(METADATA_NAME, meta)
        if gait_yaml is not None:  # its own record: readers of the contract never see it
            self._writer.write_metadata(GAIT_METADATA_NAME, {META_GAIT_YAML: gait_yaml})
        nj = len(self.joint_names)
        # samples not yet written: stamps (ns) and values, per stream
        self._shape_ns, self._r = np.empty(0, dtype=np.int64), np.empty((0, nj))
        self._effort: np.ndarray | None = None
        self._pose_ns, self._pose = np.empty(0, dtype=np.int64), np.empty((0, 3))
        self._last = [None, None]  # newest stamp (ns) given per stream
        self._counts = [0, 0]  # samples given per stream
        self._closed = False

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def counts(self) -> tuple[int, int]:
        """Shape and pose samples given so far."""
        return self._counts[0], self._counts[1]

    def write(self, t: np.ndarray, r: np.ndarray, pose_t: np.ndarray, pose: np.ndarray,
              effort: np.ndarray | None = None) -> None:
        """Add the next samples of each stream (either may be empty).

        Parameters
        ----------
        t : (m,) float
            Shape stamps, s, increasing and after the previous block's.
        r : (m, nj) float
            Joint values.
        pose_t : (q,) float
            Pose stamps, s, increasing and after the previous block's.
        pose : (q, 3) float
            x, y (m), yaw (rad).
        effort : (m, nj) float or None
            Joint efforts; given with every block or with none.

        Raises
        ------
        SudsDataError
            Wrong shapes, NaN or Inf, stamps out of order, effort given for some blocks only.
        """
        if self._closed:
            raise SudsBagError(f"{self.path}: recording writer is closed")
        t, pose_t = np.asarray(t, dtype=float).reshape(-1), np.asarray(pose_t, dtype=float).reshape(-1)
        r, pose = np.asarray(r, dtype=float), np.asarray(pose, dtype=float)
        nj = len(self.joint_names)
        if r.shape != (t.size, nj):
            raise SudsDataError(f"`r`: expected shape ({t.size}, {nj}), got {r.shape}")
        if pose.shape != (pose_t.size, 3):
            raise SudsDataError(f"`pose`: expected shape ({pose_t.size}, 3), got {pose.shape}")
        if (effort is None) != (self._effort is None) and sum(self._counts):
            raise SudsDataError("`effort`: expected it with every block or with none")
        if effort is not None:
            effort = np.asarray(effort, dtype=float)
            if effort.shape != r.shape:
                raise SudsDataError(f"`effort`: expected shape {r.shape}, got {effort.shape}")
        shape_ns = self._checked(0, t, r if effort is None else np.concatenate([r, effort], axis=1))
        pose_ns = self._checked(1, pose_t, pose)
        for stream, ns in enumerate((shape_ns, pose_ns)):  # both checked: take them
            if ns.size:
                self._last[stream] = int(ns[-1])
            self._counts[stream] += ns.size
        self._shape_ns = np.concatenate([self._shape_ns, shape_ns])
        self._r = np.concatenate([self._r, r])
        if effort is not None:
            self._effort = effort if self._effort is None else np.concatenate([self._effort, effort])
        self._pose_ns = np.concatenate([self._pose_ns, pose_ns])
        self._pose = np.concatenate([self._pose, pose])
        if None not in self._last:
            # every later stamp of a stream is ≥ its newest: what lies before both newest is final
            self._emit(min(self._last))  # type: ignore[type-var]

    def _checked(self, stream: int, t: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Stamps in ns of the next samples of ``stream`` (0 shape, 1 pose), checked (nothing is kept)."""
        topic = self._topics[stream]
        first = self._counts[stream]
        rows = ~np.all(np.isfinite(values), axis=1) | ~np.isfinite(t)
        if np.any(rows):
            k = int(np.flatnonzero(rows)[0])
            raise SudsDataError(f"{self.path}: {topic}: sample {first + k} (stamp {t[k]!r} s) "
                                "contains NaN or Inf", code=NAN_OR_INF)
        ns = float_to_ns(t) if t.size else np.empty(0, dtype=np.int64)
        before = np.concatenate([[self._last[stream]], ns]) if self._last[stream] is not None else ns
        if np.any(np.diff(before) < 0):
            k = int(np.flatnonzero(np.diff(before) < 0)[0]) + (0 if self._last[stream] is None else -1)
            raise SudsDataError(f"{self.path}: {topic}: stamps are not sorted: sample {first + k + 1} "
                                f"comes before sample {first + k}", code=OUT_OF_ORDER_STAMP)
        return ns

    def _emit(self, upto: int | None) -> None:
        """Write the held samples stamped before ``upto`` ns (None: all) in stamp order."""
        a = self._shape_ns.size if upto is None else int(np.searchsorted(self._shape_ns, upto, side="left"))
        b = self._pose_ns.size if upto is None else int(np.searchsorted(self._pose_ns, upto, side="left"))
        shape_topic, pose_topic = self._topics
        quat = yaw_quaternion(self._pose[:b, 2])
        w = self._writer
        i = j = 0
        while i < a or j < b:
            if j >= b or (i < a and self._shape_ns[i] <= self._pose_ns[j]):
                ns = int(self._shape_ns[i])
                eff = () if self._effort is None else self._effort[i]
                w.write_raw(shape_topic, cdr.joint_state(ns, self.joint_names, self._r[i], (), eff), ns, ns)
                i += 1
            else:
                ns = int(self._pose_ns[j])
                x, y = self._pose[j, 0], self._pose[j, 1]
                w.write_raw(pose_topic, cdr.pose_stamped(ns, (x, y, 0.0), quat[j], WORLD_FRAME), ns, ns)
                j += 1
        self._shape_ns, self._r = self._shape_ns[a:], self._r[a:]
        if self._effort is not None:
            self._effort = self._effort[a:]
        self._pose_ns, self._pose = self._pose_ns[b:], self._pose[b:]

    def close(self) -> None:
        """Write what is held, then the bag's summary; idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            self._emit(None)
        finally:
            self._writer.close()
