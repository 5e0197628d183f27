"""Reading MCAP files that may be cut short or damaged: the record walk behind every reader.

:func:`scan` reads every intact record of a file and reports what it could not
read instead of failing on it:

* the summary section (found through the footer) is read first if its CRC
  holds; it supplies schemas, channels, the chunk index and the statistics.
  A damaged summary is ignored (one :class:`Damage` entry) and the data
  section is scanned on its own;
* the data section is walked record by record.  A chunk that does not
  decompress, whose size or ``uncompressed_crc`` is wrong, or whose header is
  malformed is skipped and reported with its log-time range and, when the
  message index records after it (or the statistics) tell, the messages lost;
  a malformed record inside a chunk ends that chunk only;
* a record whose opcode or length cannot be right (overrunning the file,
  unknown opcode) starts a search for the next plausible record (the chunk
  index gives the exact offsets when the summary is intact), so one bad
  length field does not lose the rest of the file; indexed chunks the walk
  stepped over are read through the index afterwards;
* a file without a complete footer is read up to its last complete record
  (a recording cut by a crash); the partial chunk at the end is reported;
* duplicated chunks are read once; records in any order are accepted
  (messages are sorted by log time at the end).

Every length field is checked against the bytes present before anything is
allocated, and decompressed sizes are bounded, so a corrupted file cannot make
the reader allocate more than a small multiple of its own size.  Nothing here
knows the recording contract; the writer and bag summaries are in
:mod:`suds_ros.io.mcap`.
"""

from __future__ import annotations

import re
import struct
import zlib
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
_KNOWN_OPS = frozenset(range(0x01, 0x10))
_SUMMARY_OPS = frozenset({0x03, 0x04, 0x08, 0x0A, 0x0B, 0x0D, 0x0E})
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_MSG_HEAD = struct.Struct("<HIQQ")
_CHUNK_HEAD = struct.Struct("<QQQI")
_FOOTER = struct.Struct("<QQI")
_FOOTER_LEN = 9 + _FOOTER.size
_COMPRESSIONS = ("", "zstd", "lz4")
#: a record start worth checking when searching for the next record after a bad one:
#: a data-section opcode and a length below 2**32
_RESYNC = re.compile(rb"[\x03-\x07\x09\x0c\x0f][\x00-\xff]{4}\x00\x00\x00\x00", re.DOTALL)
#: decompressed chunks are at most this many times their compressed size (plus 1 MiB)…
_MAX_RATIO = 1024
#: …and never larger than this (bytes)
_MAX_CHUNK = 1 << 31


class _Bad(ValueError):
    """A record that cannot be right; the message says why."""


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


# ---------------------------------------------------------------- field parsers
def _take(buf: memoryview, pos: int, n: int) -> tuple[memoryview, int]:
    if n < 0 or pos + n > len(buf):
        raise _Bad(f"field of {n} bytes at {pos} overruns its record ({len(buf)} bytes)")
    return buf[pos:pos + n], pos + n


def _int(fmt: struct.Struct, buf: memoryview, pos: int) -> tuple[int, int]:
    if pos + fmt.size > len(buf):
        raise _Bad(f"record of {len(buf)} bytes too short for its fields")
    return fmt.unpack_from(buf, pos)[0], pos + fmt.size


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    n, pos = _int(_U32, buf, pos)
    raw, pos = _take(buf, pos, n)
    return bytes(raw).decode("utf-8"), pos


def _bytes(buf: memoryview, pos: int, size: struct.Struct = _U32) -> tuple[memoryview, int]:
    n, pos = _int(size, buf, pos)
    return _take(buf, pos, n)


def _map(buf: memoryview, pos: int) -> tuple[dict[str, str], int]:
    raw, end = _bytes(buf, pos)
    out: dict[str, str] = {}
    p = 0
    while p < len(raw):
        key, p = _string(raw, p)
        out[key], p = _string(raw, p)
    return out, end


def _chunk_header(body: memoryview) -> tuple[int, int, int, int, str, memoryview]:
    """``(start_ns, end_ns, uncompressed_size, crc, compression, compressed records)``."""
    if len(body) < _CHUNK_HEAD.size:
        raise _Bad(f"chunk of {len(body)} bytes is shorter than its header")
    start, end, size, crc = _CHUNK_HEAD.unpack_from(body, 0)
    compression, pos = _string(body, _CHUNK_HEAD.size)
    data, pos = _bytes(body, pos, _U64)
    if pos != len(body):
        raise _Bad(f"chunk length {len(body)} does not match its fields ({pos} bytes)")
    return start, end, size, crc, compression, data


def _plausible(op: int, body: memoryview) -> bool:
    """Whether ``body`` parses as a record of ``op`` (used to find records after a bad one)."""
    try:
        if op == OP_CHUNK:
            start, end, _, _, compression, _ = _chunk_header(body)
            return start <= end and compression in _COMPRESSIONS
        if op == OP_MESSAGE:
            return len(body) >= _MSG_HEAD.size
        if op == OP_MESSAGE_INDEX:
            return len(body) >= 6 and (len(body) - 6) % 16 == 0
        if op == OP_DATA_END:
            return len(body) == 4
        if op == OP_METADATA:
            _, pos = _string(body, 0)
            return _map(body, pos)[1] == len(body)
        if op in (OP_SCHEMA, OP_CHANNEL):
            pos = 2 if op == OP_SCHEMA else 4
            _, pos = _string(body, pos)
            return len(body) >= pos
        return op in _KNOWN_OPS
    except (_Bad, UnicodeDecodeError):
        return False


# ---------------------------------------------------------------- decompression
def _decompress(compression: str, data: memoryview, size: int) -> bytes | memoryview:
    """Records of a chunk, exactly ``size`` bytes (raises :class:`_Bad` otherwise)."""
    if size > min(_MAX_CHUNK, _MAX_RATIO * len(data) + (1 << 20)):
        raise _Bad(f"implausible uncompressed size {size} for {len(data)} compressed bytes")
    if compression == "":
        out: bytes | memoryview = data
    elif compression == "zstd":
        import zstandard

        try:
            declared = zstandard.frame_content_size(data)
            if declared not in (-1, size):
                raise _Bad(f"zstd frame holds {declared} bytes, the chunk header says {size}")
            out = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        except zstandard.ZstdError as exc:
            raise _Bad(f"zstd: {exc}") from None
    elif compression == "lz4":
        import lz4.frame

        try:
            out = lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
        except RuntimeError as exc:
            raise _Bad(f"lz4: {exc}") from None
    else:
        raise _Bad(f"unsupported chunk compression {compression!r}")
    if len(out) != size:
        raise _Bad(f"decompressed to {len(out)} bytes, the chunk header says {size}")
    return out


# ---------------------------------------------------------------- the walk
@dataclass
class _Skip:
    """A :class:`Damage` under construction (counts by channel id until the channels are known)."""

    offset: int
    record: str
    reason: str
    start_ns: int | None = None
    end_ns: int | None = None
    counts: dict[int, int] | None = None  # lost per channel; None: unknown
    read: dict[int, int] = field(default_factory=dict)  # read per channel (chunk cut short)


@dataclass
class _Summary:
    chunk_index: dict[int, tuple[int, int, int, int]] = field(default_factory=dict)
    stats_total: int | None = None
    stats_counts: dict[int, int] = field(default_factory=dict)


class _Walker:
    """One pass over a file; see the module docstring for the rules."""

    def __init__(self, path: Path, buf: bytes, topics: frozenset[str] | None, keep: bool,
                 chunks: bool) -> None:
        self.buf, self.view, self.n = buf, memoryview(buf), len(buf)
        self.r = ScanResult(path=path)
        self.topics, self.keep, self.chunks = topics, keep, chunks
        self.skips: list[_Skip] = []
        self.times: dict[int, list[int]] = {}
        self.read_keys: dict[tuple[int, int, int, int], int] = {}
        self.visited: set[int] = set()
        self.after_chunk: _Skip | None = None
        self.summary: _Summary | None = None
        self.footer_ok = False

    # ------------------------------------------------------------ records
    def record(self, op: int, body: memoryview, pos: int) -> None:
        """Apply one complete record; :class:`_Bad` and decoding errors propagate."""
        r = self.r
        if op == OP_MESSAGE:
            self.message(body)
        elif op == OP_SCHEMA:
            sid, p = _int(_U16, body, 0)
            name, p = _string(body, p)
            encoding, p = _string(body, p)
            data, _ = _bytes(body, p)
            r.schemas[sid] = (name, encoding, bytes(data))
        elif op == OP_CHANNEL:
            cid, p = _int(_U16, body, 0)
            sid, p = _int(_U16, body, p)
            topic, p = _string(body, p)
            encoding, p = _string(body, p)
            meta, _ = _map(body, p)
            name, _, data = r.schemas.get(sid, ("", "", b""))
            r.channels[cid] = ChannelInfo(topic, name, data, encoding, meta)
        elif op == OP_CHUNK:
            if self.chunks:
                self.chunk(pos, body)
        elif op == OP_MESSAGE_INDEX:
            self.message_index(body)
        elif op == OP_METADATA:
            name, p = _string(body, 0)
            r.metadata[name], _ = _map(body, p)
        elif op == OP_HEADER:
            r.profile, p = _string(body, 0)
            r.library, _ = _string(body, p)

    def message(self, body: memoryview) -> None:
        if len(body) < _MSG_HEAD.size:
            raise _Bad(f"message record of {len(body)} bytes is shorter than its header")
        cid, _seq, log_time, pub_time = _MSG_HEAD.unpack_from(body, 0)
        r = self.r
        r.counts[cid] = r.counts.get(cid, 0) + 1
        span = self.times.setdefault(cid, [log_time, log_time])
        span[0], span[1] = min(span[0], log_time), max(span[1], log_time)
        if self.keep:
            ch = r.channels.get(cid)
            if ch is None or self.topics is None or ch.topic in self.topics:
                r.messages.append((cid, log_time, pub_time, bytes(body[_MSG_HEAD.size:])))

    def message_index(self, body: memoryview) -> None:
        """The message index after a damaged chunk says how many messages it held."""
        skip = self.after_chunk
        if skip is None:
            return
        cid, p = _int(_U16, body, 0)
        entries, _ = _bytes(body, p)
        lost = len(entries) // 16 - skip.read.get(cid, 0)
        skip.counts = skip.counts or {}
        if lost > 0:
            skip.counts[cid] = skip.counts.get(cid, 0) + lost

    def chunk(self, pos: int, body: memoryview) -> None:
        """Read one chunk, or record why not (never raises for a bad chunk)."""
        self.after_chunk = None
        self.visited.add(pos)
        indexed = self.summary.chunk_index.get(pos) if self.summary else None
        try:
            start, end, size, crc, compression, data = _chunk_header(body)
        except (_Bad, UnicodeDecodeError) as exc:
            times = indexed[:2] if indexed else (None, None)
            self.skip(pos, "chunk", f"malformed chunk header: {exc}", *times)
            return
        if indexed:
            start, end = indexed[0], indexed[1]
        key = (start, end, size, crc)
        if key in self.read_keys:
            self.skips.append(_Skip(pos, "chunk", f"duplicate of the chunk at byte "
                                    f"{self.read_keys[key]}; read once", start, end, {}))
            return
        self.r.compressions.add(compression or "none")
        try:
            records = _decompress(compression, data, size)
            if crc and zlib.crc32(records) != crc:
                raise _Bad(f"CRC of the uncompressed records is 0x{zlib.crc32(records):08x}, "
                           f"the chunk header says 0x{crc:08x}")
        except (_Bad, MemoryError) as exc:
            self.after_chunk = self.skip(pos, "chunk", str(exc) or "out of memory", start, end)
            return
        self.read_keys[key] = pos
        before = dict(self.r.counts)
        inner = memoryview(records)
        p = 0
        while p < len(inner):
            try:
                if p + 9 > len(inner):
                    raise _Bad(f"{len(inner) - p} stray bytes at the end of the chunk")
                op, length = inner[p], _U64.unpack_from(inner, p + 1)[0]
                if p + 9 + length > len(inner):
                    raise _Bad(f"record at chunk offset {p} overruns the chunk")
                if op in (OP_MESSAGE, OP_SCHEMA, OP_CHANNEL):
                    self.record(op, inner[p + 9:p + 9 + length], -1)
            except (_Bad, UnicodeDecodeError) as exc:
                skip = self.skip(pos, "chunk", f"{exc}; rest of the chunk skipped", start, end)
                skip.read = {c: k - before.get(c, 0) for c, k in self.r.counts.items()}
                self.after_chunk = skip
                return
            p += 9 + length

    def skip(self, offset: int, record: str, reason: str, start: int | None = None,
             end: int | None = None) -> _Skip:
        s = _Skip(offset, record, reason, start, end)
        self.skips.append(s)
        return s

    # ------------------------------------------------------------ summary (via the footer)
    def read_summary(self) -> int:
        """Read the summary section if the footer and its CRC are intact; returns the data end."""
        n, buf = self.n, self.buf
        fpos = n - 8 - _FOOTER_LEN
        if fpos < 8 or buf[n - 8:] != MAGIC or buf[fpos] != OP_FOOTER or \
                _U64.unpack_from(buf, fpos + 1)[0] != _FOOTER.size:
            return n
        self.footer_ok = True
        start, _, crc = _FOOTER.unpack_from(buf, fpos + 9)
        if start == 0:
            return fpos
        if not 8 < start <= fpos:
            self.skip(fpos, "summary", f"footer points to a summary at byte {start}, outside "
                      "the file; scanned the data section").counts = {}
            return fpos
        if crc and zlib.crc32(self.view[start:fpos + 9 + 16]) != crc:
            self.skip(start, "summary", "summary section CRC mismatch; ignored it and scanned "
                      "the data section").counts = {}
            return fpos
        summary = _Summary()
        saved = (dict(self.r.schemas), dict(self.r.channels))
        try:
            pos = start
            while pos < fpos:
                op, length = buf[pos], _U64.unpack_from(buf, pos + 1)[0]
                body, pos = _take(self.view, pos + 9, length)
                if pos > fpos:
                    raise _Bad("a record overruns the footer")
                self.summary_record(op, body, summary)
        except (_Bad, UnicodeDecodeError, struct.error) as exc:
            self.r.schemas, self.r.channels = saved
            self.skip(start, "summary", f"malformed summary section ({exc}); ignored it and "
                      "scanned the data section").counts = {}
            return fpos
        self.summary = summary
        self.r.has_summary = True
        return start

    def summary_record(self, op: int, body: memoryview, summary: _Summary) -> None:
        if op in (OP_SCHEMA, OP_CHANNEL):
            self.record(op, body, -1)
        elif op == OP_CHUNK_INDEX:
            if len(body) < 32:
                raise _Bad("chunk index record too short")
            start, end, offset, length = struct.unpack_from("<QQQQ", body, 0)
            summary.chunk_index[offset] = (start, end, length, offset)
        elif op == OP_STATISTICS:
            total, p = _int(_U64, body, 0)
            counts, _ = _bytes(body, p + 2 + 4 * 4 + 16)
            if len(counts) % 10:
                raise _Bad("statistics channel counts have a bad length")
            summary.stats_total = total
            summary.stats_counts = {c: k for c, k in struct.iter_unpack("<HQ", counts)}

    # ------------------------------------------------------------ the data section
    def walk(self, end: int) -> int:
        """Walk records from after the header up to ``end``; returns where the walk stopped."""
        buf, view = self.buf, self.view
        pos = 8 + 9 + _U64.unpack_from(buf, 9)[0]
        while pos < end:
            op = buf[pos]
            length = _U64.unpack_from(buf, pos + 1)[0] if pos + 9 <= end else end
            nxt = pos + 9 + length
            if nxt > end or op not in _KNOWN_OPS and (op < 0x80 or not self.next_ok(nxt, end)):
                if nxt > end and not self.footer_ok and self.find_record(pos + 1, end) is None:
                    self.cut_short(pos, op)
                    return end
                pos = self.resync(pos, op, end)
                continue
            if op == OP_FOOTER:
                return pos
            if op == OP_HEADER:
                self.skip(pos, "bytes", "a second header record in the data section"
                          ).counts = {}
            elif op in _KNOWN_OPS:
                try:
                    self.record(op, view[pos + 9:nxt], pos)
                except (_Bad, UnicodeDecodeError) as exc:
                    self.bad_record(pos, op, view[pos + 9:nxt], str(exc))
            if op == OP_DATA_END:
                self.check_data_crc(pos, view[pos + 9:nxt])
                return nxt
            pos = nxt
        return pos

    def bad_record(self, pos: int, op: int, body: memoryview, why: str) -> None:
        names = {OP_MESSAGE: "message", OP_SCHEMA: "schema", OP_CHANNEL: "channel",
                 OP_METADATA: "metadata", OP_MESSAGE_INDEX: "message index"}
        skip = self.skip(pos, names.get(op, f"record 0x{op:02x}"), f"malformed: {why}")
        if op == OP_MESSAGE and len(body) >= _MSG_HEAD.size:
            cid, _, log, _ = _MSG_HEAD.unpack_from(body, 0)
            skip.start_ns = skip.end_ns = log
            skip.counts = {cid: 1}
        elif op == OP_MESSAGE:
            skip.counts = None
        elif op != OP_MESSAGE_INDEX:
            skip.counts = {}

    def next_ok(self, pos: int, end: int) -> bool:
        """Whether a record could start at ``pos`` (or the data section ends there)."""
        if pos == end:
            return True
        if pos + 9 > end:
            return False
        op, length = self.buf[pos], _U64.unpack_from(self.buf, pos + 1)[0]
        return op in _KNOWN_OPS and pos + 9 + length <= end and \
            _plausible(op, self.view[pos + 9:pos + 9 + length])

    def find_record(self, pos: int, end: int) -> int | None:
        """The first offset ≥ ``pos`` where a plausible record followed by another one starts."""
        if self.summary is not None:
            later = sorted(o for o in self.summary.chunk_index if pos <= o < end)
            for o in later:
                if self.next_ok(o, end):
                    return o
        for m in _RESYNC.finditer(self.buf, pos, end):
            q = m.start()
            if self.next_ok(q, end):
                nxt = q + 9 + _U64.unpack_from(self.buf, q + 1)[0]
                if self.next_ok(nxt, end) or (nxt + 9 > end and not self.footer_ok):
                    return q
        return None

    def resync(self, pos: int, op: int, end: int) -> int:
        q = self.find_record(pos + 1, end)
        stop = end if q is None else q
        where = "the end of the data section" if q is None else f"the next record at byte {q}"
        skip = self.skip(pos, "bytes", f"unreadable bytes {pos}–{stop} (opcode 0x{op:02x} "
                         f"with an impossible length or opcode); skipped to {where}")
        if self.summary is not None:
            skip.counts = {}  # chunks in the region are read through the chunk index
            skip.reason += "; chunks inside are read through the summary's chunk index"
        else:
            skip.counts = None
        return stop

    def cut_short(self, pos: int, op: int) -> None:
        """The file ends inside the record at ``pos``: a truncated recording."""
        self.r.truncated = True
        self.r.problem = (f"file ends at byte {self.n} without a complete footer; read up to "
                          f"byte {pos}")
        if op == OP_CHUNK and pos + 9 + 16 <= self.n:
            start, end = struct.unpack_from("<QQ", self.buf, pos + 9)
            self.skip(pos, "chunk", f"file ends inside this chunk (cut at byte {self.n})",
                      start, end).counts = None
        elif op == OP_MESSAGE:
            self.skip(pos, "message", f"file ends inside this message (cut at byte {self.n})")

    def check_data_crc(self, pos: int, body: memoryview) -> None:
        crc = _U32.unpack_from(body, 0)[0] if len(body) >= 4 else 0
        if crc and zlib.crc32(self.view[:pos]) != crc and not self.skips:
            self.skip(pos, "data section", "data section CRC mismatch outside the chunks "
                      "(chunks passed their own CRC checks)").counts = None

    def tail(self, pos: int) -> None:
        """After the data section of a file without an intact footer: summary records, if any."""
        buf, n = self.buf, self.n
        while pos + 9 <= n:
            op, length = buf[pos], _U64.unpack_from(buf, pos + 1)[0]
            if pos + 9 + length > n:
                break
            if op in _SUMMARY_OPS:
                self.r.has_summary = True
            if op == OP_FOOTER:
                pos += 9 + length
                if buf[pos:pos + 8] == MAGIC:
                    return
                break
            pos += 9 + length
        self.r.truncated = True
        self.r.problem = (f"file ends at byte {n} without a complete footer; read up to "
                          f"byte {pos}")

    def unread_indexed_chunks(self) -> None:
        """Read chunks the summary indexes but the walk never reached (stepped over)."""
        if self.summary is None:
            return
        read = {(k[0], k[1]) for k in self.read_keys}
        for offset, (start, end, length, _) in sorted(self.summary.chunk_index.items()):
            if offset in self.visited or (start, end) in read:
                continue
            if offset + length <= self.n and length >= 9 and self.buf[offset] == OP_CHUNK:
                self.chunk(offset, self.view[offset + 9:offset + length])
            else:
                self.skip(offset, "chunk", "the summary's chunk index points here but no chunk "
                          "record is there", start, end).counts = None

    # ------------------------------------------------------------ the result
    def finish(self) -> ScanResult:
        r = self.r
        for cid in [c for c in r.counts if c not in r.channels]:
            n = r.counts.pop(cid)
            lo, hi = self.times[cid]
            self.skips.append(_Skip(-1, "channel", f"channel id {cid}: its channel record is "
                                    "lost, so its messages cannot be read", lo, hi, {cid: n}))
        known = set(r.channels)
        spans = [self.times[c] for c in r.counts if c in known]
        r.start_ns = min((s[0] for s in spans), default=None)
        r.end_ns = max((s[1] for s in spans), default=None)
        r.messages = [m for m in r.messages if m[0] in known and
                      (self.topics is None or r.channels[m[0]].topic in self.topics)]
        r.messages.sort(key=lambda m: m[1])
        self.fill_from_statistics()
        topic = {c: ch.topic for c, ch in r.channels.items()}
        for s in self.skips:
            lost, by_topic = None, ()
            if s.counts is not None:
                lost = sum(s.counts.values())
                merged: dict[str, int] = {}
                for c, k in s.counts.items():
                    merged[topic.get(c, f"channel {c}")] = merged.get(
                        topic.get(c, f"channel {c}"), 0) + k
                by_topic = tuple(sorted(merged.items()))
            r.damage.append(Damage(s.offset, s.record, s.reason, s.start_ns, s.end_ns, lost,
                                   by_topic))
        unknown = any(d.messages is None for d in r.damage)
        r.messages_lost = None if unknown else sum(d.messages or 0 for d in r.damage)
        return r

    def fill_from_statistics(self) -> None:
        """Where exactly one loss is unknown, the summary statistics give it."""
        s = self.summary
        if s is None or s.stats_total is None or not self.skips:
            return
        unknown = [k for k in self.skips if k.counts is None]
        if len(unknown) != 1:
            return
        missing: dict[int, int] = {}
        for cid, total in s.stats_counts.items():
            lost = total - self.r.counts.get(cid, 0) - sum(
                (k.counts or {}).get(cid, 0) for k in self.skips)
            if lost > 0:
                missing[cid] = lost
        unknown[0].counts = missing


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


def _check_start(p: Path, buf: bytes) -> None:
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
    if n < 17 or buf[8] != OP_HEADER or 17 + _U64.unpack_from(buf, 9)[0] > n:
        msg = f"{p}: truncated MCAP file: the header record is incomplete ({n} bytes)"
        raise SudsBagError(msg, code=DAMAGED_BAG)


def scan(path: str | Path, topics: frozenset[str] | None = None, *, keep_messages: bool = True,
         chunks: bool = True) -> ScanResult:
    """Read every intact record of an MCAP file; report what was damaged.

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

    Returns
    -------
    ScanResult
        With ``damage`` listing every skipped part (empty for an intact file).

    Raises
    ------
    SudsBagError
        Missing, empty or foreign file, or one cut before the end of its header.
    """
    p, buf = _read_file(path)
    _check_start(p, buf)
    walker = _Walker(p, buf, topics, keep_messages, chunks)
    try:
        walker.record(OP_HEADER, memoryview(buf)[17:17 + _U64.unpack_from(buf, 9)[0]], 8)
    except (_Bad, UnicodeDecodeError) as exc:
        raise SudsBagError(f"{p}: malformed MCAP header record: {exc}", code=DAMAGED_BAG) from None
    data_end = walker.read_summary()
    stop = walker.walk(data_end)
    if not walker.footer_ok and not walker.r.truncated:
        walker.tail(stop)
    if chunks:
        walker.unread_indexed_chunks()
    return walker.finish()
