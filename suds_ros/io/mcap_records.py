"""MCAP records for the tolerant reader: the ``mcap`` package's parsers, bounded, on a streamed file.

The record layouts, opcodes and field readers are the ``mcap`` package's
(``mcap.records``, ``mcap.opcode``, ``mcap.data_stream``); this module bounds
them.  A :class:`Source` reads the file piece by piece (never whole), and every
record is parsed from a :class:`Strict` stream that refuses to read past the
record's declared length, raising :class:`RecordError` before anything is read
or allocated.  :func:`decompress` bounds the decompressed size (the ``mcap``
package's chunk reader does not), so a corrupted file cannot make the reader
allocate more than a small multiple of one record.  The walk that uses them is
:mod:`suds_ros.io.mcap_scan`.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from mcap import records as rec
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.opcode import Opcode
from mcap.writer import MCAP0_MAGIC as MAGIC

from suds_ros.core.errors import DAMAGED_BAG, SudsBagError
from suds_ros.io.stamps import format_ns

#: every opcode MCAP v0 defines (0x80–0xFF are for private records)
KNOWN_OPS = frozenset(int(op) for op in Opcode)
SUMMARY_OPS = frozenset({Opcode.SCHEMA, Opcode.CHANNEL, Opcode.CHUNK_INDEX, Opcode.ATTACHMENT_INDEX,
                         Opcode.STATISTICS, Opcode.METADATA_INDEX, Opcode.SUMMARY_OFFSET})
#: records that may appear in the data section (where a resync search may land)
DATA_OPS = (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE, Opcode.CHUNK, Opcode.MESSAGE_INDEX,
            Opcode.ATTACHMENT, Opcode.METADATA, Opcode.DATA_END)
COMPRESSIONS = ("", "zstd", "lz4")
#: a record start worth checking when searching for the next record after a bad one:
#: a data-section opcode and a length below 2**32
RESYNC = re.compile(b"[" + re.escape(bytes(sorted(DATA_OPS))) + rb"][\x00-\xff]{4}\x00\x00\x00\x00",
                    re.DOTALL)
#: decompressed chunks are at most this many times their compressed size (plus 1 MiB)…
MAX_RATIO = 1024
#: …and never larger than this (bytes)
MAX_CHUNK = 1 << 31
#: bytes read at a time where the file is walked or searched rather than parsed record by record
BLOCK = 1 << 20


def _encoded(record: rec.McapRecord) -> bytes:
    out = RecordBuilder()
    record.write(out)
    return out.end()


#: opcode (1) + length (8): the start of every record
RECORD_HEAD = 9
#: a whole footer record, and the fixed part of a message record (before its data)
FOOTER_LEN = len(_encoded(rec.Footer(0, 0, 0)))
MESSAGE_HEAD = len(_encoded(rec.Message(0, 0, b"", 0, 0))) - RECORD_HEAD


class RecordError(ValueError):
    """A record that cannot be right; the message says why."""


class Source:
    """An open MCAP file read piece by piece: its size, and bytes at an offset."""

    def __init__(self, path: Path, f: BinaryIO) -> None:
        self.path, self.f = path, f
        self.size = f.seek(0, io.SEEK_END)

    def read(self, pos: int, n: int) -> bytes:
        """Up to ``n`` bytes at ``pos`` (fewer only at the end of the file)."""
        n = max(0, min(n, self.size - pos))
        if n == 0:
            return b""
        self.f.seek(pos)
        return self.f.read(n)

    def head(self, pos: int) -> tuple[int, int] | None:
        """``(opcode, length)`` of the record at ``pos`` (None if the file ends first)."""
        raw = self.read(pos, RECORD_HEAD)
        if len(raw) < RECORD_HEAD:
            return None
        s = ReadDataStream(io.BytesIO(raw))
        return s.read1(), s.read8()

    def close(self) -> None:
        self.f.close()


class _Window:
    """A file-like view of ``[pos, …)`` of a :class:`Source` (what :class:`Strict` reads from)."""

    def __init__(self, src: Source, pos: int) -> None:
        self.src, self.pos = src, pos

    def read(self, n: int) -> bytes:
        data = self.src.read(self.pos, n)
        self.pos += len(data)
        return data


class Strict(ReadDataStream):
    """An ``mcap`` read stream over one record body that cannot be read past its ``size``."""

    def __init__(self, raw: Any, size: int) -> None:
        super().__init__(raw)
        self.size = size

    def read(self, length: int) -> bytes:
        """Exactly ``length`` bytes, or :class:`RecordError` (checked before reading)."""
        if length < 0 or self.count + length > self.size:
            raise RecordError(f"field of {length} bytes at {self.count} overruns its record "
                              f"({self.size} bytes)")
        data = super().read(length)
        if len(data) != length:
            raise RecordError(f"record of {self.size} bytes ends early (file changed?)")
        return data


def body_stream(body: bytes) -> Strict:
    """A :class:`Strict` stream over a record body held in memory."""
    return Strict(io.BytesIO(body), len(body))


def file_stream(src: Source, pos: int, length: int) -> Strict:
    """A :class:`Strict` stream over the ``length``-byte record body at ``pos`` of the file."""
    return Strict(_Window(src, pos), length)


def parse(op: int, s: Strict) -> rec.McapRecord | None:
    """The record of opcode ``op`` read from ``s`` by the ``mcap`` package (None: not parsed here).

    Raises :class:`RecordError` (or ``UnicodeDecodeError``) for a record that cannot be right.
    """
    if op == Opcode.MESSAGE:
        if s.size < MESSAGE_HEAD:
            raise RecordError(f"message record of {s.size} bytes is shorter than its header")
        return rec.Message.read(s, s.size)
    if op == Opcode.CHUNK:
        chunk = rec.Chunk.read(s)
        if s.count != s.size:
            raise RecordError(f"chunk length {s.size} does not match its fields ({s.count} bytes)")
        return chunk
    reader = _READERS.get(op)
    return reader(s) if reader is not None else None


_READERS = {Opcode.SCHEMA: rec.Schema.read, Opcode.CHANNEL: rec.Channel.read,
            Opcode.METADATA: rec.Metadata.read, Opcode.HEADER: rec.Header.read,
            Opcode.MESSAGE_INDEX: rec.MessageIndex.read, Opcode.CHUNK_INDEX: rec.ChunkIndex.read,
            Opcode.STATISTICS: rec.Statistics.read, Opcode.DATA_END: rec.DataEnd.read,
            Opcode.FOOTER: rec.Footer.read}


def plausible(op: int, s: Strict) -> bool:
    """Whether the body in ``s`` parses as a record of ``op`` (used to find records after a bad one)."""
    try:
        if op == Opcode.CHUNK:
            chunk = parse(op, s)
            assert isinstance(chunk, rec.Chunk)
            return chunk.message_start_time <= chunk.message_end_time and \
                chunk.compression in COMPRESSIONS
        if op == Opcode.MESSAGE:
            return s.size >= MESSAGE_HEAD
        if op == Opcode.MESSAGE_INDEX:
            return s.size >= 6 and (s.size - 6) % 16 == 0
        if op == Opcode.DATA_END:
            return s.size == 4
        if op in (Opcode.METADATA, Opcode.SCHEMA, Opcode.CHANNEL):
            parse(op, s)
            return op != Opcode.METADATA or s.count == s.size
        return op in KNOWN_OPS
    except (RecordError, UnicodeDecodeError):
        return False


@dataclass
class ChannelInfo:
    """One MCAP channel: topic, schema (type) name, message encoding, metadata."""

    topic: str
    schema_name: str
    schema_data: bytes
    message_encoding: str
    metadata: dict[str, str]


@dataclass(frozen=True)
class Damage:
    """One damaged part of a bag that the reader skipped.

    Attributes
    ----------
    offset : int
        Byte offset of the record (or region) in the file (-1: not tied to one place).
    record : str
        What was skipped: ``'chunk'``, ``'summary'``, ``'bytes'`` (an unreadable region),
        ``'channel'`` (messages whose channel record was lost), ``'data section'``, or the
        record kind (``'metadata'``, ``'message'``, ``'schema'``).
    reason : str
        Why, in words (decompression error, CRC mismatch, truncation, …).
    start_ns, end_ns : int or None
        Log-time range of the lost messages, ns (None: unknown).
    messages : int or None
        Messages lost (0: none; None: unknown).
    topics : tuple of (str, int)
        Messages lost per topic, where known.
    """

    offset: int
    record: str
    reason: str
    start_ns: int | None = None
    end_ns: int | None = None
    messages: int | None = None
    topics: tuple[tuple[str, int], ...] = ()

    def describe(self) -> str:
        """One line: offset, record, reason, time range, messages lost."""
        where = f"byte {self.offset}: " if self.offset >= 0 else ""
        text = f"{where}{self.record}: {self.reason}"
        if self.start_ns is not None and self.end_ns is not None:
            text += f"; log time {format_ns(self.start_ns)} – {format_ns(self.end_ns)}"
        lost = "unknown" if self.messages is None else str(self.messages)
        text += f"; messages lost: {lost}"
        if self.topics:
            text += " (" + ", ".join(f"{t} {n}" for t, n in self.topics) + ")"
        return text

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary of every attribute (topics as a topic → count map)."""
        return {"offset": self.offset, "record": self.record, "reason": self.reason,
                "start_ns": self.start_ns, "end_ns": self.end_ns, "messages": self.messages,
                "topics": dict(self.topics)}


def decompress(compression: str, data: bytes, size: int) -> bytes:
    """Records of a chunk, exactly ``size`` bytes (raises :class:`RecordError` otherwise)."""
    if size > min(MAX_CHUNK, MAX_RATIO * len(data) + (1 << 20)):
        raise RecordError(f"implausible uncompressed size {size} for {len(data)} compressed bytes")
    if compression == "":
        out = data
    elif compression == "zstd":
        import zstandard

        try:
            declared = zstandard.frame_content_size(data)
            if declared not in (-1, size):
                raise RecordError(f"zstd frame holds {declared} bytes, the chunk header says "
                                  f"{size}")
            out = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        except zstandard.ZstdError as exc:
            raise RecordError(f"zstd: {exc}") from None
    elif compression == "lz4":
        import lz4.frame

        try:
            out = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=size + 1)
        except RuntimeError as exc:
            raise RecordError(f"lz4: {exc}") from None
    else:
        raise RecordError(f"unsupported chunk compression {compression!r}")
    if len(out) != size:
        raise RecordError(f"decompressed to {len(out)} bytes, the chunk header says {size}")
    return out


@dataclass
class ScanResult:
    """Everything :func:`scan` found in one file.

    ``messages`` holds ``(channel_id, log_time_ns, publish_time_ns, data)`` tuples
    in log-time order (stable for equal times), only for the selected topics.
    ``damage`` lists what was skipped; ``messages_lost`` is their total (None if
    unknown).  A file cut short is ``truncated`` (``problem`` says where).
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
    damage: list[Damage] = field(default_factory=list)
    messages_lost: int | None = 0


@dataclass
class Summary:
    """What the summary section tells beyond schemas and channels: chunk index and statistics."""

    #: chunk offset → (message_start_time, message_end_time, chunk record length)
    chunk_index: dict[int, tuple[int, int, int]] = field(default_factory=dict)
    stats_total: int | None = None
    stats_counts: dict[int, int] = field(default_factory=dict)

    def add(self, record: rec.McapRecord | None) -> None:
        """Take in a chunk index or statistics record (other records are ignored)."""
        if isinstance(record, rec.ChunkIndex):
            self.chunk_index[record.chunk_start_offset] = (
                record.message_start_time, record.message_end_time, record.chunk_length)
        elif isinstance(record, rec.Statistics):
            self.stats_total = record.message_count
            self.stats_counts = dict(record.channel_message_counts)


def open_file(path: str | Path) -> Source:
    """Resolve ``path`` (a file, or a rosbag2 directory with one ``.mcap``) and open it.

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
        return Source(p, open(p, "rb"))  # noqa: SIM115 - closed by the caller
    except FileNotFoundError:
        raise SudsBagError(f"{p}: no such file") from None
    except OSError as exc:
        raise SudsBagError(f"{p}: cannot read: {exc.strerror}") from None


def check_start(src: Source) -> int:
    """Length of the header record; :class:`SudsBagError` unless the file starts with the magic and it.

    Raises
    ------
    SudsBagError
        Empty or foreign file, or one cut before the end of its header record.
    """
    p, n = src.path, src.size
    start = src.read(0, 8)
    if n == 0:
        raise SudsBagError(f"{p}: file is empty (0 bytes), not an MCAP recording",
                           code=DAMAGED_BAG)
    if start != MAGIC:
        if n < 8 and MAGIC.startswith(start):
            raise SudsBagError(f"{p}: truncated MCAP file: only {n} bytes of the 8-byte magic",
                               code=DAMAGED_BAG)
        raise SudsBagError(
            f"{p}: not an MCAP file (starts with {start!r}, expected the magic {MAGIC!r})",
            code=DAMAGED_BAG)
    head = src.head(8)
    if head is None or head[0] != Opcode.HEADER or 8 + RECORD_HEAD + head[1] > n:
        msg = f"{p}: truncated MCAP file: the header record is incomplete ({n} bytes)"
        raise SudsBagError(msg, code=DAMAGED_BAG)
    return head[1]
