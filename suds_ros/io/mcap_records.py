"""MCAP records for the tolerant reader: opcodes, bounded parsers, decompression, result types.

Every parser checks a length field against the bytes present before it slices
or allocates, raising :class:`RecordError` (never ``struct.error`` or an
over-long read), and :func:`decompress` bounds the decompressed size, so a
corrupted file cannot make the reader allocate more than a small multiple of
its own size.  The walk that uses them is :mod:`suds_ros.io.mcap_scan`.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from suds_ros.core.errors import DAMAGED_BAG, SudsBagError
from suds_ros.io.stamps import format_ns

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 1, 2, 3, 4, 5, 6
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_STATISTICS = 0x07, 0x08, 0x0B
OP_METADATA, OP_DATA_END = 0x0C, 0x0F
#: every opcode MCAP v0 defines (0x80–0xFF are for private records)
KNOWN_OPS = frozenset(range(0x01, 0x10))
SUMMARY_OPS = frozenset({0x03, 0x04, 0x08, 0x0A, 0x0B, 0x0D, 0x0E})
U16, U32, U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
MSG_HEAD = struct.Struct("<HIQQ")
CHUNK_HEAD = struct.Struct("<QQQI")
FOOTER = struct.Struct("<QQI")
FOOTER_LEN = 9 + FOOTER.size
COMPRESSIONS = ("", "zstd", "lz4")
#: a record start worth checking when searching for the next record after a bad one:
#: a data-section opcode and a length below 2**32
RESYNC = re.compile(rb"[\x03-\x07\x09\x0c\x0f][\x00-\xff]{4}\x00\x00\x00\x00", re.DOTALL)
#: decompressed chunks are at most this many times their compressed size (plus 1 MiB)…
MAX_RATIO = 1024
#: …and never larger than this (bytes)
MAX_CHUNK = 1 << 31


class RecordError(ValueError):
    """A record that cannot be right; the message says why."""


def take(buf: memoryview, pos: int, n: int) -> tuple[memoryview, int]:
    if n < 0 or pos + n > len(buf):
        raise RecordError(f"field of {n} bytes at {pos} overruns its record ({len(buf)} bytes)")
    return buf[pos:pos + n], pos + n


def read_int(fmt: struct.Struct, buf: memoryview, pos: int) -> tuple[int, int]:
    if pos + fmt.size > len(buf):
        raise RecordError(f"record of {len(buf)} bytes too short for its fields")
    return fmt.unpack_from(buf, pos)[0], pos + fmt.size


def read_string(buf: memoryview, pos: int) -> tuple[str, int]:
    n, pos = read_int(U32, buf, pos)
    raw, pos = take(buf, pos, n)
    return bytes(raw).decode("utf-8"), pos


def read_bytes(buf: memoryview, pos: int, size: struct.Struct = U32) -> tuple[memoryview, int]:
    n, pos = read_int(size, buf, pos)
    return take(buf, pos, n)


def read_map(buf: memoryview, pos: int) -> tuple[dict[str, str], int]:
    raw, end = read_bytes(buf, pos)
    out: dict[str, str] = {}
    p = 0
    while p < len(raw):
        key, p = read_string(raw, p)
        out[key], p = read_string(raw, p)
    return out, end


def chunk_header(body: memoryview) -> tuple[int, int, int, int, str, memoryview]:
    """``(start_ns, end_ns, uncompressed_size, crc, compression, compressed records)``."""
    if len(body) < CHUNK_HEAD.size:
        raise RecordError(f"chunk of {len(body)} bytes is shorter than its header")
    start, end, size, crc = CHUNK_HEAD.unpack_from(body, 0)
    compression, pos = read_string(body, CHUNK_HEAD.size)
    data, pos = read_bytes(body, pos, U64)
    if pos != len(body):
        raise RecordError(f"chunk length {len(body)} does not match its fields ({pos} bytes)")
    return start, end, size, crc, compression, data


def plausible(op: int, body: memoryview) -> bool:
    """Whether ``body`` parses as a record of ``op`` (used to find records after a bad one)."""
    try:
        if op == OP_CHUNK:
            start, end, _, _, compression, _ = chunk_header(body)
            return start <= end and compression in COMPRESSIONS
        if op == OP_MESSAGE:
            return len(body) >= MSG_HEAD.size
        if op == OP_MESSAGE_INDEX:
            return len(body) >= 6 and (len(body) - 6) % 16 == 0
        if op == OP_DATA_END:
            return len(body) == 4
        if op == OP_METADATA:
            _, pos = read_string(body, 0)
            return read_map(body, pos)[1] == len(body)
        if op in (OP_SCHEMA, OP_CHANNEL):
            pos = 2 if op == OP_SCHEMA else 4
            _, pos = read_string(body, pos)
            return len(body) >= pos
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


def decompress(compression: str, data: memoryview, size: int) -> bytes | memoryview:
    """Records of a chunk, exactly ``size`` bytes (raises :class:`RecordError` otherwise)."""
    if size > min(MAX_CHUNK, MAX_RATIO * len(data) + (1 << 20)):
        raise RecordError(f"implausible uncompressed size {size} for {len(data)} compressed bytes")
    if compression == "":
        out: bytes | memoryview = data
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
            out = lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
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

    def add(self, op: int, body: memoryview) -> None:
        """Take in a chunk index or statistics record (other records are ignored)."""
        if op == OP_CHUNK_INDEX:
            if len(body) < 32:
                raise RecordError("chunk index record too short")
            start, end, offset, length = struct.unpack_from("<QQQQ", body, 0)
            self.chunk_index[offset] = (start, end, length)
        elif op == OP_STATISTICS:
            total, p = read_int(U64, body, 0)
            counts, _ = read_bytes(body, p + 2 + 4 * 4 + 16)
            if len(counts) % 10:
                raise RecordError("statistics channel counts have a bad length")
            self.stats_total = total
            self.stats_counts = {c: k for c, k in struct.iter_unpack("<HQ", counts)}


def read_file(path: str | Path) -> tuple[Path, bytes]:
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


def check_start(p: Path, buf: bytes) -> None:
    """Raise :class:`SudsBagError` unless ``buf`` starts with the magic and a complete header."""
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
    if n < 17 or buf[8] != OP_HEADER or 17 + U64.unpack_from(buf, 9)[0] > n:
        msg = f"{p}: truncated MCAP file: the header record is incomplete ({n} bytes)"
        raise SudsBagError(msg, code=DAMAGED_BAG)
