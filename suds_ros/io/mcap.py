"""Generic MCAP (ROS 2 profile): a writer like rosbag2's, a truncation-tolerant reader, bag summaries.

Writing uses the ``mcap`` writer with the ``ros2msg`` schema texts of
``msg_defs/``.  Reading walks the records in order itself (:func:`scan`): it
unpacks chunks (zstd, lz4 or uncompressed) and stops quietly at the first
incomplete record, so a file cut short by a crash is read up to its last
complete record; it never depends on the summary section, on channel or
schema ids being stable across files, or on indexes.  Nothing here knows the
recording contract (:mod:`suds_ros.io.recording_bag`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO, Callable

from suds_ros.core.errors import DAMAGED_BAG, EXISTS, SudsBagError
from suds_ros.io import msgdefs
from suds_ros.io.stamps import ns_to_float

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 1, 2, 3, 4, 5, 6
OP_METADATA, OP_DATA_END = 0x0C, 0x0F
_SUMMARY_OPS = frozenset({0x03, 0x04, 0x08, 0x0A, 0x0B, 0x0D, 0x0E})
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_MSG_HEAD = struct.Struct("<HIQQ")
LIBRARY = "suds_ros.io.mcap (mcap-python)"

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


@dataclass
class ChannelInfo:
    """One MCAP channel: topic, schema (type) name, message encoding, metadata."""

    topic: str
    schema_name: str
    schema_data: bytes
    message_encoding: str
    metadata: dict[str, str]


@dataclass
class ScanResult:
    """Everything :func:`scan` found in one file.

    ``messages`` holds ``(channel_id, log_time_ns, publish_time_ns, data)`` tuples
    in log-time order (stable for equal times), only for the selected topics.
    """

    path: Path
    profile: str = ""
    library: str = ""
    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)
    channels: dict[int, ChannelInfo] = field(default_factory=dict)
    messages: list[tuple[int, int, int, bytes]] = field(default_factory=list)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int | None = None
    end_ns: int | None = None
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    compressions: set[str] = field(default_factory=set)
    has_summary: bool = False
    truncated: bool = False
    problem: str | None = None


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(buf, pos)
    pos += 4
    return bytes(buf[pos:pos + n]).decode("utf-8"), pos + n


def _map(buf: memoryview, pos: int) -> tuple[dict[str, str], int]:
    (n,) = _U32.unpack_from(buf, pos)
    pos += 4
    end = pos + n
    out: dict[str, str] = {}
    while pos < end:
        key, pos = _string(buf, pos)
        out[key], pos = _string(buf, pos)
    return out, end


def _decompress(compression: str, data: memoryview, size: int) -> memoryview:
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard

        return memoryview(zstandard.ZstdDecompressor().decompress(data, max_output_size=size))
    if compression == "lz4":
        import lz4.frame

        return memoryview(lz4.frame.decompress(bytes(data)))
    raise ValueError(f"unsupported chunk compression {compression!r}")


class _Scanner:
    def __init__(self, result: ScanResult, topics: frozenset[str] | None, keep: bool,
                 chunks: bool) -> None:
        self.r = result
        self.topics = topics
        self.keep = keep
        self.chunks = chunks
        self.wanted: dict[int, bool] = {}

    def record(self, op: int, body: memoryview, in_summary: bool) -> None:
        r = self.r
        if op == OP_MESSAGE:
            self.message(body)
        elif op == OP_SCHEMA:
            (sid,) = _U16.unpack_from(body, 0)
            name, pos = _string(body, 2)
            encoding, pos = _string(body, pos)
            (n,) = _U32.unpack_from(body, pos)
            r.schemas[sid] = (name, encoding, bytes(body[pos + 4:pos + 4 + n]))
        elif op == OP_CHANNEL:
            cid, sid = struct.unpack_from("<HH", body, 0)
            topic, pos = _string(body, 4)
            encoding, pos = _string(body, pos)
            meta, _ = _map(body, pos)
            name, _, data = r.schemas.get(sid, ("", "", b""))
            r.channels[cid] = ChannelInfo(topic, name, data, encoding, meta)
            self.wanted[cid] = self.topics is None or topic in self.topics
        elif op == OP_CHUNK and not in_summary:
            if self.chunks:
                self.chunk(body)
        elif op == OP_METADATA and not in_summary:
            name, pos = _string(body, 0)
            r.metadata[name], _ = _map(body, pos)
        elif op == OP_HEADER:
            r.profile, pos = _string(body, 0)
            r.library, _ = _string(body, pos)

    def message(self, body: memoryview) -> None:
        cid, _seq, log_time, pub_time = _MSG_HEAD.unpack_from(body, 0)
        r = self.r
        r.counts[cid] = r.counts.get(cid, 0) + 1
        if r.start_ns is None or log_time < r.start_ns:
            r.start_ns = log_time
        if r.end_ns is None or log_time > r.end_ns:
            r.end_ns = log_time
        if self.keep and self.wanted.get(cid, False):
            r.messages.append((cid, log_time, pub_time, bytes(body[22:])))

    def chunk(self, body: memoryview) -> None:
        (size,) = _U64.unpack_from(body, 16)
        compression, pos = _string(body, 28)
        self.r.compressions.add(compression or "none")
        (n,) = _U64.unpack_from(body, pos)
        data = _decompress(compression, body[pos + 8:pos + 8 + n], size)
        pos, end = 0, len(data)
        while pos + 9 <= end:
            op = data[pos]
            (length,) = _U64.unpack_from(data, pos + 1)
            start = pos + 9
            if start + length > end:
                raise ValueError("record overruns its chunk")
            self.record(op, data[start:start + length], False)
            pos = start + length


def _read_file(path: str | Path) -> tuple[Path, bytes]:
    """Resolve ``path`` (a file, or a rosbag2 directory with one ``.mcap``) and read it.

    Raises
    ------
    SudsBagError
        Missing path, unreadable file, or a directory without exactly one ``.mcap``.
    """
    p = Path(path)
    if p.is_dir():
        found = sorted(p.glob("*.mcap"))
        if len(found) != 1:
            msg = f"{p}: is a directory with {len(found)} .mcap files; expected exactly one"
            raise SudsBagError(msg)
        p = found[0]
    try:
        return p, p.read_bytes()
    except FileNotFoundError:
        raise SudsBagError(f"{p}: no such file") from None
    except OSError as exc:
        raise SudsBagError(f"{p}: cannot read: {exc.strerror}") from None


def scan(path: str | Path, topics: frozenset[str] | None = None, *, keep_messages: bool = True,
         chunks: bool = True) -> ScanResult:
    """Read every complete record of an MCAP file.

    Parameters
    ----------
    path : str or Path
        MCAP file (or rosbag2 directory holding one).
    topics : frozenset of str, optional
        Keep only messages of these topics (all if None).
    keep_messages : bool
        Keep message payloads (False: only count them).
    chunks : bool
        Unpack chunks (False: skip them; channels and messages inside are not seen).

    Raises
    ------
    SudsBagError
        Not an MCAP file, empty file, truncated magic or header, corrupt chunk.
    """
    p, buf = _read_file(path)
    result = ScanResult(path=p)
    n = len(buf)
    if n == 0:
        raise SudsBagError(f"{p}: file is empty (0 bytes), not an MCAP recording",
                           code=DAMAGED_BAG)
    if buf[:8] != MAGIC:
        if n < 8 and MAGIC.startswith(buf):
            raise SudsBagError(f"{p}: truncated MCAP file: only {n} bytes of the 8-byte magic",
                               code=DAMAGED_BAG)
        raise SudsBagError(
            f"{p}: not an MCAP file (starts with {buf[:8]!r}, expected the magic {MAGIC!r})",
            code=DAMAGED_BAG)
    view = memoryview(buf)
    if n < 17 or buf[8] != OP_HEADER or 17 + _U64.unpack_from(buf, 9)[0] > n:
        msg = f"{p}: truncated MCAP file: the header record is incomplete ({n} bytes)"
        raise SudsBagError(msg, code=DAMAGED_BAG)
    scanner = _Scanner(result, topics, keep_messages, chunks)
    pos, in_summary, footer = 8, False, False
    while pos + 9 <= n:
        op = buf[pos]
        (length,) = _U64.unpack_from(buf, pos + 1)
        start = pos + 9
        if start + length > n:
            break
        if in_summary and op in _SUMMARY_OPS:
            result.has_summary = True
        try:
            scanner.record(op, view[start:start + length], in_summary)
        except (ValueError, struct.error, UnicodeDecodeError, MemoryError) as exc:
            msg = f"{p}: corrupt record (opcode 0x{op:02x}) at byte {pos}: {exc}"
            raise SudsBagError(msg, code=DAMAGED_BAG) from None
        pos = start + length
        if op == OP_DATA_END:
            in_summary = True
        elif op == OP_FOOTER:
            footer = True
            break
    if not footer or buf[pos:pos + 8] != MAGIC:
        result.truncated = True
        result.problem = f"file ends at byte {n} without a complete footer; read up to byte {pos}"
    result.messages.sort(key=lambda m: m[1])
    return result


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
            raise SudsBagError(msg, code=EXISTS)
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


# ====================================================================== summary
@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag: its type (``pkg/msg/Type``), message count and message encoding."""

    type_name: str
    count: int
    message_encoding: str


@dataclass(frozen=True)
class BagInfo:
    """Summary of a bag, computed from its records (the summary section is not needed).

    Attributes
    ----------
    path, profile, library : str
        Resolved file path and the MCAP header's profile and library.
    topics : dict
        Topic → :class:`TopicInfo`, in channel order.
    message_count : int
        Messages of every channel.
    start_ns, end_ns : int or None
        First and last log time, ns (None for a bag without messages).
    metadata : dict
        Metadata record name → its string map.
    compression : tuple of str
        Sorted chunk compressions (``'none'`` for uncompressed chunks; empty if unchunked).
    has_summary, truncated : bool
        Whether a summary section was found; whether the file ends without a complete footer.
    problem : str or None
        Why it counts as truncated.
    """

    path: str
    profile: str
    library: str
    topics: dict[str, TopicInfo]
    message_count: int
    start_ns: int | None
    end_ns: int | None
    metadata: dict[str, dict[str, str]]
    compression: tuple[str, ...]
    has_summary: bool
    truncated: bool
    problem: str | None

    @property
    def duration_s(self) -> float | None:
        """Log-time span ``end_ns − start_ns`` in s (None without messages)."""
        if self.start_ns is None or self.end_ns is None:
            return None
        return ns_to_float(self.end_ns - self.start_ns)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary; topics as ``{'type', 'count', 'message_encoding'}``."""
        topics = {t: {"type": i.type_name, "count": i.count, "message_encoding": i.message_encoding}
                  for t, i in self.topics.items()}
        return {"path": self.path, "profile": self.profile, "library": self.library,
                "topics": topics, "message_count": self.message_count,
                "start_ns": self.start_ns, "end_ns": self.end_ns, "duration_s": self.duration_s,
                "metadata": self.metadata, "compression": list(self.compression),
                "has_summary": self.has_summary, "truncated": self.truncated,
                "problem": self.problem}


def bag_info(path: str | Path) -> BagInfo:
    """Summary of the bag ``path`` (works on truncated files and without a summary section)."""
    res = scan(path, keep_messages=False)
    counts: dict[str, list[Any]] = {}
    for cid, ch in res.channels.items():
        entry = counts.setdefault(ch.topic, [ch.schema_name, 0, ch.message_encoding])
        entry[1] += res.counts.get(cid, 0)
    return BagInfo(
        path=str(res.path), profile=res.profile, library=res.library,
        topics={t: TopicInfo(*e) for t, e in counts.items()},
        message_count=sum(res.counts.values()), start_ns=res.start_ns, end_ns=res.end_ns,
        metadata=res.metadata, compression=tuple(sorted(res.compressions)),
        has_summary=res.has_summary, truncated=res.truncated, problem=res.problem)


# ====================================================================== raw messages
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


@lru_cache(maxsize=64)
def _decoder(type_name: str, schema: bytes) -> Callable[[bytes], Any]:
    from mcap.records import Schema
    from mcap_ros2.decoder import DecoderFactory

    rec = Schema(id=1, name=type_name, encoding="ros2msg", data=schema)
    dec = DecoderFactory().decoder_for("cdr", rec)
    if dec is None:  # pragma: no cover - factory always handles cdr + ros2msg
        raise SudsBagError(f"no decoder for {type_name!r}")
    return dec


def decode_message(type_name: str, data: bytes, schema: bytes = b"") -> Any:
    """Decode CDR ``data`` of ``type_name`` with the bag's ``schema`` text (default: ``msg_defs``).

    Returns
    -------
    object
        Message with attribute access by ROS field name (``msg.header.stamp.sec``).

    Raises
    ------
    SudsBagError
        Unknown type or malformed data.
    """
    dec = _decoder(type_name, schema or msgdefs.schema_text(type_name).encode("utf-8"))
    try:
        return dec(data)
    except Exception as exc:  # mcap_ros2 raises assorted errors on bad input
        raise SudsBagError(f"cannot decode {type_name!r} message ({len(data)} bytes): {exc}"
                           ) from None
