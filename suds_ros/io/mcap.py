"""Generic MCAP (ROS 2 profile): a writer like rosbag2's, the readers, bag summaries.

Writing uses the ``mcap`` writer with the ``ros2msg`` schema texts of
``msg_defs/``, closing a chunk (and flushing the file) every ``chunk_interval``
s of log time so a crash loses little.  Reading goes through
:func:`~suds_ros.io.mcap_scan.scan`, which reads every intact record of a
truncated or damaged file and reports the rest as :class:`Damage`; it never
depends on the summary section, on channel or schema ids being stable across
files, or on indexes.  Nothing here knows the recording contract
(:mod:`suds_ros.io.recording_bag`).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

from suds_ros.core.errors import EXISTS, SudsBagError
from suds_ros.io import cdr, msgdefs
from suds_ros.io.mcap_records import Damage
from suds_ros.io.mcap_scan import scan
from suds_ros.io.stamps import ns_to_float

LIBRARY = "suds_ros.io.mcap (mcap-python)"
#: bytes of a message record besides its data (opcode, length, channel, sequence, two times)
_MESSAGE_RECORD = 1 + 8 + 2 + 4 + 8 + 8
#: chunk size given to the mcap writer so that it never closes a chunk on its own
_NEVER = 1 << 62

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
    chunk_interval : float or None
        Log time (s) after which the open chunk is written, even if smaller than
        ``chunk_size`` (None: only the size closes chunks).
    fsync : bool
        ``os.fsync`` the file after each chunk, so the data are on the disk, not only
        handed to the operating system.

    Notes
    -----
    Messages wait in the open chunk (in memory) until it is written; every
    written chunk is flushed to the operating system (and synced with
    ``fsync``).  A crash of the process therefore loses at most the open chunk:
    the last ``chunk_interval`` s of log time or ``chunk_size`` bytes, whichever
    is less; a power loss loses the same with ``fsync``, and otherwise whatever
    the operating system had not yet written back (see ``docs/recording_safety.md``).
    """

    def __init__(self, path: str | Path, *, overwrite: bool = False, compression: str = "zstd",
                 chunk_size: int = 256 * 1024, chunk_interval: float | None = 0.5,
                 fsync: bool = False) -> None:
        from mcap.writer import CompressionType, Writer

        kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                 "none": CompressionType.NONE, "": CompressionType.NONE}
        if compression not in kinds:
            msg = f"compression: expected one of 'zstd', 'lz4', 'none', got {compression!r}"
            raise SudsBagError(msg)
        if chunk_size <= 0:
            raise SudsBagError(f"chunk_size: expected a positive byte count, got {chunk_size!r}")
        if chunk_interval is not None and not chunk_interval > 0:
            msg = (f"chunk_interval: expected a positive number of seconds or None, got "
                   f"{chunk_interval!r}")
            raise SudsBagError(msg)
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
        # chunks are closed here (size or log-time span), never by the mcap writer itself
        self._writer = Writer(self._file, chunk_size=_NEVER, compression=kinds[compression],
                              enable_data_crcs=True)
        self._writer.start(profile="ros2", library=LIBRARY)
        self._chunk_size = chunk_size
        self._interval_ns = None if chunk_interval is None else round(chunk_interval * 1e9)
        self._fsync = fsync
        self._open_bytes, self._open_start = 0, 0
        self._synced = -1
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
        if self._open_bytes == 0:
            self._open_start = log
        self._writer.add_message(channel_id=self._channels[topic][0], log_time=log,
                                 data=bytes(data), publish_time=pub,
                                 sequence=self._sequence[topic])
        self._sequence[topic] += 1
        self._open_bytes += _MESSAGE_RECORD + len(data)
        if self._open_bytes >= self._chunk_size or (
                self._interval_ns is not None and log - self._open_start >= self._interval_ns):
            self.flush()

    def write_metadata(self, name: str, data: dict[str, str]) -> None:
        """Write an MCAP metadata record ``name`` with string keys and values."""
        self._check_open()
        bad = {k: v for k, v in data.items() if not isinstance(k, str) or not isinstance(v, str)}
        if bad:
            raise SudsBagError(f"metadata {name!r}: keys and values must be str, got {bad!r}")
        self._writer.add_metadata(name, dict(data))
        self._sync()

    def flush(self) -> None:
        """End the open chunk; push everything written to the file (and the disk with ``fsync``)."""
        self._check_open()
        self._writer.flush()
        self._open_bytes = 0
        self._sync()

    def _sync(self) -> None:
        assert self._file is not None
        self._file.flush()
        if self._fsync and self._file.tell() != self._synced:
            os.fsync(self._file.fileno())
            self._synced = self._file.tell()

    def close(self) -> None:
        """Write the summary (schemas, channels, statistics, indexes) and close; idempotent."""
        if self._file is None:
            return
        try:
            self._writer.finish()
            self._sync()
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
    damage : tuple of Damage
        Every damaged part that was skipped (empty for an intact bag), each with its
        offset, reason, log-time range and messages lost.
    messages_lost : int or None
        Messages lost to the damage in total (None: some loss is of unknown size).
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
    damage: tuple[Damage, ...] = ()
    messages_lost: int | None = 0

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
                "problem": self.problem, "damage": [d.as_dict() for d in self.damage],
                "messages_lost": self.messages_lost}


def bag_info(path: str | Path) -> BagInfo:
    """Summary of the bag ``path`` (works on truncated or damaged files, without a summary section).

    Raises
    ------
    SudsBagError
        Missing, empty or foreign file (damage inside the file is reported in ``damage``).
    """
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
        has_summary=res.has_summary, truncated=res.truncated, problem=res.problem,
        damage=tuple(res.damage), messages_lost=res.messages_lost)


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

    Truncated files are read up to their last complete record, damaged chunks
    are skipped (see :func:`~suds_ros.io.mcap_scan.scan`); the summary is not needed.

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


def decode_message(type_name: str, data: bytes, schema: bytes = b"") -> Any:
    """Decode CDR ``data`` of ``type_name`` with the bag's ``schema`` text (default: ``msg_defs``).

    Returns
    -------
    object
        Message with attribute access by ROS field name (``msg.header.stamp.sec``); see
        :func:`suds_ros.io.cdr.decode`.

    Raises
    ------
    SudsBagError
        Unknown type or malformed data.
    """
    return cdr.decode(type_name, data, schema)
