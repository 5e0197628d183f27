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

The file is streamed, never read whole: records are read one at a time (a
chunk, then its decompressed records), the byte search reads blocks, and the
data-section CRC is accumulated as the walk goes, so memory does not grow with
the file (only with the messages kept).  Records are parsed by the ``mcap``
package; lengths are checked and sizes bounded before anything is read or
allocated (:mod:`suds_ros.io.mcap_records`).  Nothing here knows the recording
contract; the writer and bag summaries are in :mod:`suds_ros.io.mcap`.
"""

from __future__ import annotations

import struct
import zlib
from array import array
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap import records as rec
from mcap.opcode import Opcode

from suds_ros.core.errors import DAMAGED_BAG, SudsBagError
from suds_ros.io.mcap_records import (BLOCK, FOOTER_LEN, KNOWN_OPS, MAGIC, MESSAGE_HEAD, RECORD_HEAD,
                                      RESYNC, SUMMARY_OPS, ChannelInfo, Damage, RecordError,
                                      ScanResult, Source, Strict, Summary, body_stream,
                                      check_start, decompress, file_stream, open_file, parse,
                                      plausible)

#: the fast path over the records of a decompressed chunk (``chunk``), where almost every
#: record is a message: one unpack of the record head and one of the message head instead of
#: the seven stream reads of ``mcap.records.Message.read`` (the whole scan, damage checks
#: included, beats the mcap package's StreamReader: ``docs/results/codec.md``; test_mcap.py
#: checks the messages against it)
_HEAD = struct.Struct("<BQ")
_MESSAGE = struct.Struct("<HIQQ")  # channel_id, sequence, log_time, publish_time
if _HEAD.size != RECORD_HEAD or _MESSAGE.size != MESSAGE_HEAD:  # pragma: no cover
    raise ImportError("the mcap package's record layout is not the one this fast path reads")

_NAMES = {Opcode.MESSAGE: "message", Opcode.SCHEMA: "schema", Opcode.CHANNEL: "channel",
          Opcode.METADATA: "metadata", Opcode.MESSAGE_INDEX: "message index"}


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


#: takes one message: its channel, log time (ns) and CDR payload
MessageSink = Callable[[ChannelInfo, int, bytes], None]
#: takes a chunk's messages of one channel at once: the channel, log times (k,) int64 ns, the
#: chunk's decompressed records, and where each payload starts in them and how long it is ((k,) int64)
BatchSink = Callable[[ChannelInfo, np.ndarray, bytes, np.ndarray, np.ndarray], None]


def _gather(buf: np.ndarray, at: np.ndarray, dtype: str) -> np.ndarray:
    """The little-endian ``dtype`` values (k,) found at byte offsets ``at`` (k,) of ``buf`` (uint8)."""
    size = np.dtype(dtype).itemsize
    return buf[at[:, None] + np.arange(size)].view(dtype)[:, 0].astype(np.int64)


def _message_offsets(records: bytes) -> np.ndarray | None:
    """Offsets of the records of a decompressed chunk when every one is a whole message record.

    None when any record is something else or does not fit (the record-by-record walk then
    reads the chunk and names the problem).
    """
    n, p = len(records), 0
    offsets = array("q")
    unpack, add, message = _HEAD.unpack_from, offsets.append, Opcode.MESSAGE
    repeated = _repeating_offsets(records)
    if repeated is not None:
        return repeated
    while p + RECORD_HEAD <= n:
        op, length = unpack(records, p)
        if op != message or length < MESSAGE_HEAD:
            return None
        add(p)
        p += RECORD_HEAD + length
    return np.frombuffer(offsets, dtype=np.int64) if p == n else None


def _repeating_offsets(records: bytes, lead: int = 8) -> np.ndarray | None:
    """The record offsets of a chunk whose record lengths repeat with a short period, or None.

    The first ``lead`` records are walked one by one; if their lengths repeat with a period of
    q ≤ ``lead`` / 2 records (shape and pose messages alternating, say), every later offset is
    predicted from it and then checked all at once: each predicted record must be a message
    record of the predicted length, and they must end exactly at the chunk's end.  Then the
    offsets are those the record-by-record walk finds; otherwise None (walk it).
    """
    n, p = len(records), 0
    walked: list[tuple[int, int]] = []
    while p + RECORD_HEAD <= n and len(walked) < lead:
        op, length = _HEAD.unpack_from(records, p)
        if op != Opcode.MESSAGE or length < MESSAGE_HEAD:
            return None
        walked.append((p, length))
        p += RECORD_HEAD + length
    lengths = [ln for _, ln in walked]
    q = next((q for q in range(1, len(lengths) // 2 + 1) if lengths[q:] == lengths[:-q]), None)
    if q is None or len(walked) < lead:
        return None
    sizes = np.array(lengths[:q], dtype=np.int64) + RECORD_HEAD
    period = int(sizes.sum())
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    full, rest = divmod(n, period)
    ends = np.cumsum(sizes)
    if rest and rest not in set(ends.tolist()):
        return None
    tail = 0 if not rest else int(np.flatnonzero(ends == rest)[0]) + 1
    offsets = np.concatenate([(np.arange(full, dtype=np.int64)[:, None] * period + start[None, :]).ravel(),
                              full * period + start[:tail]])
    expected = np.concatenate([np.tile(sizes - RECORD_HEAD, full), sizes[:tail] - RECORD_HEAD])
    buf = np.frombuffer(records, dtype=np.uint8)
    if not (np.array_equal(buf[offsets], np.full(offsets.size, int(Opcode.MESSAGE), dtype=np.uint8))
            and np.array_equal(_gather(buf, offsets + 1, "<u8"), expected)):
        return None
    return offsets


def _same_entries(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two (k, 2) tables of (log time, offset) hold the same rows, in any order."""
    if a.shape != b.shape:
        return False
    return bool(np.array_equal(a[np.lexsort(a.T[::-1])], b[np.lexsort(b.T[::-1])]))


def _message_index(body: bytes) -> tuple[int, np.ndarray] | None:
    """A message index record's channel id and (k, 2) entries (None: not well formed)."""
    if len(body) < 6:
        return None
    cid, size = struct.unpack_from("<HI", body, 0)
    if size % 16 or 6 + size != len(body):
        return None
    return cid, np.frombuffer(body, dtype="<u8", offset=6).reshape(-1, 2).astype(np.int64)


class _Walker:
    """One pass over a file; see the module docstring for the rules."""

    def __init__(self, src: Source, topics: frozenset[str] | None, keep: bool,
                 chunks: bool, sink: MessageSink | None = None, batch_sink: BatchSink | None = None) -> None:
        self.src, self.n = src, src.size
        self.r = ScanResult(path=src.path)
        self.topics, self.keep, self.chunks, self.sink = topics, keep, chunks, sink
        self.batch_sink = batch_sink
        self.skips: list[_Skip] = []
        self.times: dict[int, list[int]] = {}
        self.read_keys: dict[tuple[int, int, int, int], int] = {}
        self.visited: set[int] = set()
        self.after_chunk: _Skip | None = None
        #: offset and (log time, offset) pairs ((k, 2) int64) by channel of the chunk just read
        self.last_read: tuple[int, dict[int, np.ndarray]] | None = None
        #: (offset, chunk offset) of message indexes that do not match the chunk before them
        self.bad_indexes: list[tuple[int, int]] = []
        self.summary: Summary | None = None
        self.footer_ok = False
        #: data-section CRCs from byte 0 and from byte 8 up to ``crc_pos`` (None: not followed)
        self.crc_pos: int | None = None
        self.crc0 = self.crc8 = 0

    # ------------------------------------------------------------ records
    def record(self, op: int, s: Strict, pos: int) -> None:
        """Parse and apply one complete record; :class:`RecordError` and decoding errors propagate."""
        r = self.r
        if op == Opcode.CHUNK:
            if self.chunks:
                self.chunk(pos, s)
            return
        if op == Opcode.MESSAGE_INDEX:  # thousands in a long file: the entries as one array
            body = s.read(s.size)
            index = _message_index(body)
            if index is not None:
                self.message_index(*index, pos)
                return
            s = body_stream(body)  # not well formed: the mcap package's parser names the problem
        record = parse(op, s)
        if isinstance(record, rec.Message):
            self.message(record.channel_id, record.log_time, record.publish_time, record.data)
        elif isinstance(record, rec.Schema):
            r.schemas[record.id] = (record.name, record.encoding, bytes(record.data))
        elif isinstance(record, rec.Channel):
            name, _, data = r.schemas.get(record.schema_id, ("", "", b""))
            r.channels[record.id] = ChannelInfo(record.topic, name, data, record.message_encoding,
                                                record.metadata)
        elif isinstance(record, rec.MessageIndex):
            self.message_index(record.channel_id, np.array(record.records, dtype=np.int64).reshape(-1, 2), pos)
        elif isinstance(record, rec.Metadata):
            r.metadata[record.name] = record.metadata
        elif isinstance(record, rec.Header):
            r.profile, r.library = record.profile, record.library

    def message(self, cid: int, log_time: int, pub_time: int, data: bytes, counted: bool = False) -> None:
        """Count one message unless already counted, then hand it to the sink or keep it."""
        r = self.r
        if not counted:
            r.counts[cid] = r.counts.get(cid, 0) + 1
            span = self.times.setdefault(cid, [log_time, log_time])
            if log_time < span[0]:
                span[0] = log_time
            elif log_time > span[1]:
                span[1] = log_time
        if self.keep:
            ch = r.channels.get(cid)
            if ch is None or self.topics is None or ch.topic in self.topics:
                if self.sink is not None and ch is not None:
                    self.sink(ch, log_time, data)  # handed over as read: nothing kept here
                else:  # (a channel record may come after its messages in a damaged file)
                    r.messages.append((cid, log_time, pub_time, data))

    def message_index(self, cid: int, entries: np.ndarray, pos: int) -> None:
        """Check a message index against the chunk before it, or count what a damaged one held.

        ``entries`` (k, 2) int64: the index's (log time, offset) pairs.
        """
        skip = self.after_chunk
        if skip is None:
            if self.last_read is not None:
                chunk_pos, found = self.last_read
                if not _same_entries(entries, found.get(cid, np.zeros((0, 2), dtype=np.int64))):
                    self.bad_indexes.append((pos, chunk_pos))
            return
        lost = entries.shape[0] - skip.read.get(cid, 0)
        skip.counts = skip.counts or {}
        if lost > 0:
            skip.counts[cid] = skip.counts.get(cid, 0) + lost

    def chunk(self, pos: int, s: Strict) -> None:
        """Read one chunk, or record why not (never raises for a bad chunk)."""
        self.after_chunk, self.last_read = None, None
        self.visited.add(pos)
        indexed = self.summary.chunk_index.get(pos) if self.summary else None
        try:
            chunk = parse(Opcode.CHUNK, s)
            assert isinstance(chunk, rec.Chunk)
        except (RecordError, UnicodeDecodeError) as exc:
            times = indexed[:2] if indexed else (None, None)
            self.skip(pos, "chunk", f"malformed chunk header: {exc}", *times)
            return
        start, end = chunk.message_start_time, chunk.message_end_time
        size, crc = chunk.uncompressed_size, chunk.uncompressed_crc
        key = (start, end, size, crc)
        if indexed and indexed[2] == s.size + RECORD_HEAD:
            start, end = indexed[0], indexed[1]  # the CRC-checked index's times, for reports
        if key in self.read_keys:
            self.skips.append(_Skip(pos, "chunk", f"duplicate of the chunk at byte "
                                    f"{self.read_keys[key]}; read once", start, end, {}))
            return
        self.r.compressions.add(chunk.compression or "none")
        try:
            records = decompress(chunk.compression, chunk.data, size)
            got = zlib.crc32(records) if crc else 0
            if got != crc:
                raise RecordError(f"CRC of the uncompressed records is 0x{got:08x}, the chunk "
                                  f"header says 0x{crc:08x}")
        except (RecordError, MemoryError) as exc:
            self.after_chunk = self.skip(pos, "chunk", str(exc) or "out of memory", start, end)
            return
        del chunk
        self.read_keys[key] = pos
        offsets = _message_offsets(records)
        if offsets is not None:
            self.last_read = (pos, self.messages(records, offsets))
            return
        before = dict(self.r.counts)
        found: dict[int, list[tuple[int, int]]] = {}
        n = len(records)
        p = 0
        while p < n:
            try:
                if p + RECORD_HEAD > n:
                    raise RecordError(f"{n - p} stray bytes at the end of the chunk")
                op, length = _HEAD.unpack_from(records, p)
                body = p + RECORD_HEAD
                if body + length > n:
                    raise RecordError(f"record at chunk offset {p} overruns the chunk")
                if op == Opcode.MESSAGE:
                    if length < MESSAGE_HEAD:
                        raise RecordError(f"message record of {length} bytes is shorter than "
                                          "its header")
                    cid, _, log_time, pub_time = _MESSAGE.unpack_from(records, body)
                    self.message(cid, log_time, pub_time, records[body + MESSAGE_HEAD:body + length])
                    found.setdefault(cid, []).append((log_time, p))
                elif op in (Opcode.SCHEMA, Opcode.CHANNEL):
                    self.record(op, body_stream(records[body:body + length]), -1)
            except (RecordError, UnicodeDecodeError) as exc:
                skip = self.skip(pos, "chunk", f"{exc}; rest of the chunk skipped", start, end)
                skip.read = {c: k - before.get(c, 0) for c, k in self.r.counts.items()}
                self.after_chunk = skip
                return
            p = body + length
        self.last_read = (pos, {c: np.array(v, dtype=np.int64).reshape(-1, 2) for c, v in found.items()})

    def messages(self, records: bytes, offsets: np.ndarray) -> dict[int, np.ndarray]:
        """Take a chunk's message records (at ``offsets``) a channel at a time; their (log time, offset) by channel.

        The same bookkeeping as :meth:`message` for each, in numpy; a channel's messages go to
        the batch sink together (to the per-message sink, or are kept, without one).
        """
        buf = np.frombuffer(records, dtype=np.uint8)
        cids = _gather(buf, offsets + RECORD_HEAD, "<u2")
        logs = _gather(buf, offsets + RECORD_HEAD + 6, "<u8")
        lengths = _gather(buf, offsets + 1, "<u8") - MESSAGE_HEAD
        starts = offsets + RECORD_HEAD + MESSAGE_HEAD
        r, found = self.r, {}
        kept = []
        for cid in np.unique(cids).tolist():
            sel = np.flatnonzero(cids == cid)
            log = logs[sel]
            found[cid] = np.column_stack([log, offsets[sel]])
            r.counts[cid] = r.counts.get(cid, 0) + sel.size
            lo, hi = int(log.min()), int(log.max())
            span = self.times.setdefault(cid, [lo, hi])
            span[0], span[1] = min(span[0], lo), max(span[1], hi)
            ch = r.channels.get(cid)
            if not self.keep or ch is not None and self.topics is not None and ch.topic not in self.topics:
                continue
            if ch is not None and self.batch_sink is not None:
                self.batch_sink(ch, log, records, starts[sel], lengths[sel])
            else:
                kept.append(sel)
        if kept:  # one at a time, in file order, as the record-by-record walk hands them over
            sel = np.sort(np.concatenate(kept))
            pubs = _gather(buf, offsets[sel] + RECORD_HEAD + 14, "<u8").tolist()
            for cid, log, pub, a, n in zip(cids[sel].tolist(), logs[sel].tolist(), pubs, starts[sel].tolist(),
                                           lengths[sel].tolist()):
                self.message(cid, log, pub, records[a:a + n], counted=True)
        return found

    def skip(self, offset: int, record: str, reason: str, start: int | None = None,
             end: int | None = None) -> _Skip:
        s = _Skip(offset, record, reason, start, end)
        self.skips.append(s)
        return s

    # ------------------------------------------------------------ summary (via the footer)
    def read_summary(self) -> int:
        """Read the summary section if the footer and its CRC are intact; returns the data end."""
        n, src = self.n, self.src
        fpos = n - 8 - FOOTER_LEN
        if fpos < 8:
            return n
        tail = src.read(fpos, FOOTER_LEN + 8)
        head = src.head(fpos)
        if tail[FOOTER_LEN:] != MAGIC or head is None or head[0] != Opcode.FOOTER or \
                head[1] != FOOTER_LEN - RECORD_HEAD:
            return n
        self.footer_ok = True
        footer = parse(Opcode.FOOTER, body_stream(tail[RECORD_HEAD:FOOTER_LEN]))
        assert isinstance(footer, rec.Footer)
        start, crc = footer.summary_start, footer.summary_crc
        if start == 0:
            return fpos
        if not 8 < start <= fpos:
            self.skip(fpos, "summary", f"footer points to a summary at byte {start}, outside "
                      "the file; scanned the data section").counts = {}
            return fpos
        # the CRC covers the summary and the footer up to its summary_crc field
        if crc and self.crc_of(start, fpos + FOOTER_LEN - 4) != crc:
            self.skip(start, "summary", "summary section CRC mismatch; ignored it and scanned "
                      "the data section").counts = {}
            return fpos
        summary = Summary()
        saved = (dict(self.r.schemas), dict(self.r.channels))
        try:
            pos = start
            while pos < fpos:
                head = src.head(pos)
                assert head is not None  # pos < fpos leaves the footer's bytes after it
                op, length = head
                if pos + RECORD_HEAD + length > fpos:
                    raise RecordError("a record overruns the footer")
                s = file_stream(src, pos + RECORD_HEAD, length)
                if op in (Opcode.SCHEMA, Opcode.CHANNEL):
                    self.record(op, s, -1)
                elif op in (Opcode.CHUNK_INDEX, Opcode.STATISTICS):
                    summary.add(parse(op, s))
                pos += RECORD_HEAD + length
        except (RecordError, UnicodeDecodeError) as exc:
            self.r.schemas, self.r.channels = saved
            self.skip(start, "summary", f"malformed summary section ({exc}); ignored it and "
                      "scanned the data section").counts = {}
            return fpos
        self.summary = summary
        self.r.has_summary = True
        return start

    def crc_of(self, start: int, stop: int, crc: int = 0) -> int:
        """CRC-32 of the file's bytes ``[start, stop)``, read block by block."""
        for pos in range(start, stop, BLOCK):
            crc = zlib.crc32(self.src.read(pos, min(BLOCK, stop - pos)), crc)
        return crc

    # ------------------------------------------------------------ the data section
    def walk(self, end: int, header_length: int) -> int:
        """Walk records from after the header up to ``end``; returns where the walk stopped."""
        src = self.src
        pos = 8 + RECORD_HEAD + header_length
        self.crc_pos, self.crc8 = pos, self.crc_of(8, pos)
        self.crc0 = zlib.crc32(self.src.read(8, pos - 8), zlib.crc32(MAGIC))
        while pos < end:
            head = src.head(pos) if pos + RECORD_HEAD <= end else None
            op, length = head if head is not None else (src.read(pos, 1)[0], end)
            nxt = pos + RECORD_HEAD + length
            if nxt > end or op not in KNOWN_OPS and (op < 0x80 or not self.next_ok(nxt, end)):
                if nxt > end and not self.footer_ok and self.find_record(pos + 1, end) is None:
                    self.cut_short(pos, op)
                    return end
                pos = self.resync(pos, op, end)
                continue
            if op == Opcode.FOOTER:
                return pos
            body: bytes | None = None
            if op != Opcode.CHUNK or self.chunks:
                body = src.read(pos + RECORD_HEAD, length)
            if op != Opcode.DATA_END:  # its CRC covers everything before it
                self.follow_crc(pos, nxt, body)
            if op == Opcode.HEADER:
                self.skip(pos, "bytes", "a second header record in the data section"
                          ).counts = {}
            elif op in KNOWN_OPS and body is not None:
                try:
                    self.record(op, body_stream(body), pos)
                except (RecordError, UnicodeDecodeError) as exc:
                    self.bad_record(pos, op, body, str(exc))
            if op == Opcode.DATA_END:
                assert body is not None
                self.check_data_crc(pos, body)
                return nxt
            pos = nxt
        return pos

    def follow_crc(self, pos: int, nxt: int, body: bytes | None) -> None:
        """Add the record ``[pos, nxt)`` to the data-section CRCs if the walk has read every byte so far."""
        if self.crc_pos != pos or body is None:
            self.crc_pos = None
            return
        raw = self.src.read(pos, RECORD_HEAD)
        self.crc0 = zlib.crc32(body, zlib.crc32(raw, self.crc0))
        self.crc8 = zlib.crc32(body, zlib.crc32(raw, self.crc8))
        self.crc_pos = nxt

    def bad_record(self, pos: int, op: int, body: bytes, why: str) -> None:
        skip = self.skip(pos, _NAMES.get(op, f"record 0x{op:02x}"), f"malformed: {why}")
        if op == Opcode.MESSAGE and len(body) >= MESSAGE_HEAD:
            m = rec.Message.read(body_stream(body), len(body))
            skip.start_ns = skip.end_ns = m.log_time
            skip.counts = {m.channel_id: 1}
        elif op == Opcode.MESSAGE:
            skip.counts = None
        elif op != Opcode.MESSAGE_INDEX:
            skip.counts = {}

    def next_ok(self, pos: int, end: int) -> bool:
        """Whether a record could start at ``pos`` (or the data section ends there)."""
        if pos == end:
            return True
        if pos + RECORD_HEAD > end:
            return False
        head = self.src.head(pos)
        assert head is not None
        op, length = head
        return op in KNOWN_OPS and pos + RECORD_HEAD + length <= end and \
            plausible(op, file_stream(self.src, pos + RECORD_HEAD, length))

    def candidates(self, pos: int, end: int) -> Iterator[int]:
        """Offsets in ``[pos, end)`` where :data:`RESYNC` matches, searching block by block."""
        start = pos
        while start < end:
            stop = min(end, start + BLOCK)
            data = self.src.read(start, min(end, stop + RECORD_HEAD - 1) - start)
            for m in RESYNC.finditer(data):
                if start + m.start() >= stop:
                    break
                yield start + m.start()
            start = stop

    def find_record(self, pos: int, end: int) -> int | None:
        """The first offset ≥ ``pos`` where a plausible record followed by another one starts.

        With an intact summary, the chunk index gives chunk starts and ends (the
        end of a chunk whose own length field is damaged); the byte search never
        stops inside an indexed chunk, whose records the index reads later.
        """
        spans: list[tuple[int, int]] = []
        if self.summary is not None:
            spans = [(o, o + ln) for o, (_, _, ln) in self.summary.chunk_index.items()]
            marks = sorted({a for a, _ in spans} | {b for _, b in spans})
            for o in (o for o in marks if pos <= o < end):
                if self.next_ok(o, end):
                    return o
        for q in self.candidates(pos, end):
            if any(a < q < b for a, b in spans):
                continue
            if self.next_ok(q, end):
                head = self.src.head(q)
                assert head is not None
                nxt = q + RECORD_HEAD + head[1]
                if self.next_ok(nxt, end) or (nxt + RECORD_HEAD > end and not self.footer_ok):
                    return q
        return None

    def resync(self, pos: int, op: int, end: int) -> int:
        self.after_chunk, self.last_read = None, None  # indexes after here follow no read chunk
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
        if op == Opcode.CHUNK and pos + RECORD_HEAD + 16 <= self.n:
            s = file_stream(self.src, pos + RECORD_HEAD, 16)  # the chunk's two log times
            start, end = s.read8(), s.read8()
            self.skip(pos, "chunk", f"file ends inside this chunk (cut at byte {self.n})",
                      start, end).counts = None
        elif op == Opcode.MESSAGE:
            self.skip(pos, "message", f"file ends inside this message (cut at byte {self.n})")

    def check_data_crc(self, pos: int, body: bytes) -> None:
        crc = rec.DataEnd.read(body_stream(body)).data_section_crc if len(body) >= 4 else 0
        if crc and self.crc_pos is not None and not self.skips and crc not in (self.crc0, self.crc8):
            self.skip(pos, "data section", "data section CRC mismatch outside the chunks "
                      "(chunks passed their own CRC checks)").counts = None

    def tail(self, pos: int) -> None:
        """After the data section when the summary was not used: its schemas and channels, if any.

        They fill in only ids the data section did not define (its channel records may
        have been in a damaged chunk).  Without an intact footer the file is truncated.
        """
        src, n = self.src, self.n
        while pos + RECORD_HEAD <= n:
            head = src.head(pos)
            assert head is not None
            op, length = head
            if pos + RECORD_HEAD + length > n or op not in KNOWN_OPS:
                q = self.find_record(pos + 1, n) if self.footer_ok else None
                if q is None:
                    break
                pos = q
                continue
            if op in SUMMARY_OPS and not self.footer_ok:
                self.r.has_summary = True
            if op in (Opcode.SCHEMA, Opcode.CHANNEL):
                self.salvage(op, file_stream(src, pos + RECORD_HEAD, length))
            if op == Opcode.FOOTER:
                pos += RECORD_HEAD + length
                if src.read(pos, 8) == MAGIC:
                    return
                break
            pos += RECORD_HEAD + length
        if self.footer_ok:
            return
        self.r.truncated = True
        self.r.problem = (f"file ends at byte {n} without a complete footer; read up to "
                          f"byte {pos}")

    def salvage(self, op: int, s: Strict) -> None:
        """A schema or channel record outside the data section, for an id still unknown."""
        r = self.r
        saved = (dict(r.schemas), dict(r.channels))
        try:
            self.record(op, s, -1)
        except (RecordError, UnicodeDecodeError):
            return
        for old, new in zip(saved, (r.schemas, r.channels)):
            new.update(old)  # what the data section said wins

    def unread_indexed_chunks(self) -> None:
        """Read chunks the summary indexes but the walk never reached (stepped over)."""
        if self.summary is None:
            return
        read = {(k[0], k[1]) for k in self.read_keys}
        for offset, (start, end, length) in sorted(self.summary.chunk_index.items()):
            if offset in self.visited or (start, end) in read:
                continue
            head = self.src.head(offset) if offset + length <= self.n and length >= 9 else None
            if head is not None and head[0] == Opcode.CHUNK:
                body = self.src.read(offset + RECORD_HEAD, length - RECORD_HEAD)
                self.chunk(offset, body_stream(body))
            else:
                self.skip(offset, "chunk", "the summary's chunk index points here but no chunk "
                          "record is there", start, end).counts = None

    # ------------------------------------------------------------ the result
    def finish(self) -> ScanResult:
        r = self.r
        if self.bad_indexes:
            where = ", ".join(str(p) for p, _ in self.bad_indexes[:5])
            more = ", …" if len(self.bad_indexes) > 5 else ""
            self.skip(self.bad_indexes[0][0], "message index",
                      f"{len(self.bad_indexes)} message index record(s) (bytes {where}{more}) "
                      "do not match the chunk before them: indexes damaged or records moved; "
                      "the chunks themselves were read").counts = {}
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
        if self.sink is not None:  # the messages whose channel record came after them
            for cid, log_time, _, data in r.messages:
                self.sink(r.channels[cid], log_time, data)
            r.messages = []
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


def scan(path: str | Path, topics: frozenset[str] | None = None, *, keep_messages: bool = True,
         chunks: bool = True, sink: MessageSink | None = None, batch_sink: BatchSink | None = None) -> ScanResult:
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
    sink : callable (channel, log time ns, data), optional
        Takes each kept message as it is read (in file order; a message read before its
        channel record comes at the end), instead of ``ScanResult.messages``: memory then does
        not grow with the file.  The damage report is the same.
    batch_sink : callable (channel, log times, records, starts, lengths), optional
        Takes the kept messages of one channel in one chunk together, when the chunk holds
        message records only (the usual case; other chunks go through ``sink``): log times (k,)
        int64 ns, the chunk's decompressed records, and each payload's start and length in them.

    Returns
    -------
    ScanResult
        With ``damage`` listing every skipped part (empty for an intact file).

    Raises
    ------
    SudsBagError
        Missing, empty or foreign file, or one cut before the end of its header.
    """
    src = open_file(path)
    try:
        header_length = check_start(src)
        walker = _Walker(src, topics, keep_messages, chunks, sink, batch_sink)
        try:
            walker.record(Opcode.HEADER, file_stream(src, 8 + RECORD_HEAD, header_length), 8)
        except (RecordError, UnicodeDecodeError) as exc:
            raise SudsBagError(f"{src.path}: malformed MCAP header record: {exc}",
                               code=DAMAGED_BAG) from None
        data_end = walker.read_summary()
        stop = walker.walk(data_end, header_length)
        if walker.summary is None and not walker.r.truncated:
            walker.tail(stop)
        if chunks:
            walker.unread_indexed_chunks()
        return walker.finish()
    finally:
        src.close()
