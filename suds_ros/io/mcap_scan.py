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

Lengths are checked and sizes bounded before anything is allocated
(:mod:`suds_ros.io.mcap_records`).  Nothing here knows the recording contract;
the writer and bag summaries are in :mod:`suds_ros.io.mcap`.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from suds_ros.core.errors import DAMAGED_BAG, SudsBagError
from suds_ros.io.mcap_records import (FOOTER, FOOTER_LEN, KNOWN_OPS, MAGIC, MSG_HEAD, OP_CHANNEL,
                                      OP_CHUNK, OP_DATA_END, OP_FOOTER, OP_HEADER, OP_MESSAGE,
                                      OP_MESSAGE_INDEX, OP_METADATA, OP_SCHEMA, RESYNC, SUMMARY_OPS,
                                      U16, U32, U64, ChannelInfo, Damage, RecordError, ScanResult,
                                      Summary, check_start, chunk_header, decompress, plausible,
                                      read_bytes, read_file, read_int, read_map, read_string, take)


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
        #: offset and (log time, offset) pairs by channel of the chunk just read
        self.last_read: tuple[int, dict[int, list[tuple[int, int]]]] | None = None
        #: (offset, chunk offset) of message indexes that do not match the chunk before them
        self.bad_indexes: list[tuple[int, int]] = []
        self.summary: Summary | None = None
        self.footer_ok = False

    # ------------------------------------------------------------ records
    def record(self, op: int, body: memoryview, pos: int) -> None:
        """Apply one complete record; :class:`RecordError` and decoding errors propagate."""
        r = self.r
        if op == OP_MESSAGE:
            self.message(body)
        elif op == OP_SCHEMA:
            sid, p = read_int(U16, body, 0)
            name, p = read_string(body, p)
            encoding, p = read_string(body, p)
            data, _ = read_bytes(body, p)
            r.schemas[sid] = (name, encoding, bytes(data))
        elif op == OP_CHANNEL:
            cid, p = read_int(U16, body, 0)
            sid, p = read_int(U16, body, p)
            topic, p = read_string(body, p)
            encoding, p = read_string(body, p)
            meta, _ = read_map(body, p)
            name, _, data = r.schemas.get(sid, ("", "", b""))
            r.channels[cid] = ChannelInfo(topic, name, data, encoding, meta)
        elif op == OP_CHUNK:
            if self.chunks:
                self.chunk(pos, body)
        elif op == OP_MESSAGE_INDEX:
            self.message_index(body, pos)
        elif op == OP_METADATA:
            name, p = read_string(body, 0)
            r.metadata[name], _ = read_map(body, p)
        elif op == OP_HEADER:
            r.profile, p = read_string(body, 0)
            r.library, _ = read_string(body, p)

    def message(self, body: memoryview) -> None:
        if len(body) < MSG_HEAD.size:
            raise RecordError(f"message record of {len(body)} bytes is shorter than its header")
        cid, _seq, log_time, pub_time = MSG_HEAD.unpack_from(body, 0)
        r = self.r
        r.counts[cid] = r.counts.get(cid, 0) + 1
        span = self.times.setdefault(cid, [log_time, log_time])
        span[0], span[1] = min(span[0], log_time), max(span[1], log_time)
        if self.keep:
            ch = r.channels.get(cid)
            if ch is None or self.topics is None or ch.topic in self.topics:
                r.messages.append((cid, log_time, pub_time, bytes(body[MSG_HEAD.size:])))

    def message_index(self, body: memoryview, pos: int) -> None:
        """Check a message index against the chunk before it, or count what a damaged one held."""
        cid, p = read_int(U16, body, 0)
        entries, _ = read_bytes(body, p)
        skip = self.after_chunk
        if skip is None:
            if self.last_read is not None:
                chunk_pos, found = self.last_read
                listed = sorted(struct.iter_unpack("<QQ", entries)) if len(entries) % 16 == 0 \
                    else None
                if listed != sorted(found.get(cid, [])):
                    self.bad_indexes.append((pos, chunk_pos))
            return
        lost = len(entries) // 16 - skip.read.get(cid, 0)
        skip.counts = skip.counts or {}
        if lost > 0:
            skip.counts[cid] = skip.counts.get(cid, 0) + lost

    def chunk(self, pos: int, body: memoryview) -> None:
        """Read one chunk, or record why not (never raises for a bad chunk)."""
        self.after_chunk, self.last_read = None, None
        self.visited.add(pos)
        indexed = self.summary.chunk_index.get(pos) if self.summary else None
        try:
            start, end, size, crc, compression, data = chunk_header(body)
        except (RecordError, UnicodeDecodeError) as exc:
            times = indexed[:2] if indexed else (None, None)
            self.skip(pos, "chunk", f"malformed chunk header: {exc}", *times)
            return
        key = (start, end, size, crc)
        if indexed and indexed[2] == len(body) + 9:
            start, end = indexed[0], indexed[1]  # the CRC-checked index's times, for reports
        if key in self.read_keys:
            self.skips.append(_Skip(pos, "chunk", f"duplicate of the chunk at byte "
                                    f"{self.read_keys[key]}; read once", start, end, {}))
            return
        self.r.compressions.add(compression or "none")
        try:
            records = decompress(compression, data, size)
            got = zlib.crc32(records) if crc else 0
            if got != crc:
                raise RecordError(f"CRC of the uncompressed records is 0x{got:08x}, the chunk "
                                  f"header says 0x{crc:08x}")
        except (RecordError, MemoryError) as exc:
            self.after_chunk = self.skip(pos, "chunk", str(exc) or "out of memory", start, end)
            return
        self.read_keys[key] = pos
        before = dict(self.r.counts)
        found: dict[int, list[tuple[int, int]]] = {}
        inner = memoryview(records)
        p = 0
        while p < len(inner):
            try:
                if p + 9 > len(inner):
                    raise RecordError(f"{len(inner) - p} stray bytes at the end of the chunk")
                op, length = inner[p], U64.unpack_from(inner, p + 1)[0]
                if p + 9 + length > len(inner):
                    raise RecordError(f"record at chunk offset {p} overruns the chunk")
                if op in (OP_MESSAGE, OP_SCHEMA, OP_CHANNEL):
                    self.record(op, inner[p + 9:p + 9 + length], -1)
                if op == OP_MESSAGE:
                    cid, _, log, _ = MSG_HEAD.unpack_from(inner, p + 9)
                    found.setdefault(cid, []).append((log, p))
            except (RecordError, UnicodeDecodeError) as exc:
                skip = self.skip(pos, "chunk", f"{exc}; rest of the chunk skipped", start, end)
                skip.read = {c: k - before.get(c, 0) for c, k in self.r.counts.items()}
                self.after_chunk = skip
                return
            p += 9 + length
        self.last_read = (pos, found)

    def skip(self, offset: int, record: str, reason: str, start: int | None = None,
             end: int | None = None) -> _Skip:
        s = _Skip(offset, record, reason, start, end)
        self.skips.append(s)
        return s

    # ------------------------------------------------------------ summary (via the footer)
    def read_summary(self) -> int:
        """Read the summary section if the footer and its CRC are intact; returns the data end."""
        n, buf = self.n, self.buf
        fpos = n - 8 - FOOTER_LEN
        if fpos < 8 or buf[n - 8:] != MAGIC or buf[fpos] != OP_FOOTER or \
                U64.unpack_from(buf, fpos + 1)[0] != FOOTER.size:
            return n
        self.footer_ok = True
        start, _, crc = FOOTER.unpack_from(buf, fpos + 9)
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
        summary = Summary()
        saved = (dict(self.r.schemas), dict(self.r.channels))
        try:
            pos = start
            while pos < fpos:
                op, length = buf[pos], U64.unpack_from(buf, pos + 1)[0]
                body, pos = take(self.view, pos + 9, length)
                if pos > fpos:
                    raise RecordError("a record overruns the footer")
                self.summary_record(op, body, summary)
        except (RecordError, UnicodeDecodeError, struct.error) as exc:
            self.r.schemas, self.r.channels = saved
            self.skip(start, "summary", f"malformed summary section ({exc}); ignored it and "
                      "scanned the data section").counts = {}
            return fpos
        self.summary = summary
        self.r.has_summary = True
        return start

    def summary_record(self, op: int, body: memoryview, summary: Summary) -> None:
        if op in (OP_SCHEMA, OP_CHANNEL):
            self.record(op, body, -1)
        else:
            summary.add(op, body)

    # ------------------------------------------------------------ the data section
    def walk(self, end: int) -> int:
        """Walk records from after the header up to ``end``; returns where the walk stopped."""
        buf, view = self.buf, self.view
        pos = 8 + 9 + U64.unpack_from(buf, 9)[0]
        while pos < end:
            op = buf[pos]
            length = U64.unpack_from(buf, pos + 1)[0] if pos + 9 <= end else end
            nxt = pos + 9 + length
            if nxt > end or op not in KNOWN_OPS and (op < 0x80 or not self.next_ok(nxt, end)):
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
            elif op in KNOWN_OPS:
                try:
                    self.record(op, view[pos + 9:nxt], pos)
                except (RecordError, UnicodeDecodeError) as exc:
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
        if op == OP_MESSAGE and len(body) >= MSG_HEAD.size:
            cid, _, log, _ = MSG_HEAD.unpack_from(body, 0)
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
        op, length = self.buf[pos], U64.unpack_from(self.buf, pos + 1)[0]
        return op in KNOWN_OPS and pos + 9 + length <= end and \
            plausible(op, self.view[pos + 9:pos + 9 + length])

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
        for m in RESYNC.finditer(self.buf, pos, end):
            q = m.start()
            if any(a < q < b for a, b in spans):
                continue
            if self.next_ok(q, end):
                nxt = q + 9 + U64.unpack_from(self.buf, q + 1)[0]
                if self.next_ok(nxt, end) or (nxt + 9 > end and not self.footer_ok):
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
        if op == OP_CHUNK and pos + 9 + 16 <= self.n:
            start, end = struct.unpack_from("<QQ", self.buf, pos + 9)
            self.skip(pos, "chunk", f"file ends inside this chunk (cut at byte {self.n})",
                      start, end).counts = None
        elif op == OP_MESSAGE:
            self.skip(pos, "message", f"file ends inside this message (cut at byte {self.n})")

    def check_data_crc(self, pos: int, body: memoryview) -> None:
        crc = U32.unpack_from(body, 0)[0] if len(body) >= 4 else 0
        if crc and crc not in (zlib.crc32(self.view[:pos]), zlib.crc32(self.view[8:pos])) \
                and not self.skips:
            self.skip(pos, "data section", "data section CRC mismatch outside the chunks "
                      "(chunks passed their own CRC checks)").counts = None

    def tail(self, pos: int) -> None:
        """After the data section when the summary was not used: its schemas and channels, if any.

        They fill in only ids the data section did not define (its channel records may
        have been in a damaged chunk).  Without an intact footer the file is truncated.
        """
        buf, n = self.buf, self.n
        while pos + 9 <= n:
            op, length = buf[pos], U64.unpack_from(buf, pos + 1)[0]
            if pos + 9 + length > n or op not in KNOWN_OPS:
                q = self.find_record(pos + 1, n) if self.footer_ok else None
                if q is None:
                    break
                pos = q
                continue
            if op in SUMMARY_OPS and not self.footer_ok:
                self.r.has_summary = True
            if op in (OP_SCHEMA, OP_CHANNEL):
                self.salvage(op, self.view[pos + 9:pos + 9 + length])
            if op == OP_FOOTER:
                pos += 9 + length
                if buf[pos:pos + 8] == MAGIC:
                    return
                break
            pos += 9 + length
        if self.footer_ok:
            return
        self.r.truncated = True
        self.r.problem = (f"file ends at byte {n} without a complete footer; read up to "
                          f"byte {pos}")

    def salvage(self, op: int, body: memoryview) -> None:
        """A schema or channel record outside the data section, for an id still unknown."""
        r = self.r
        saved = (dict(r.schemas), dict(r.channels))
        try:
            self.record(op, body, -1)
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
            if offset + length <= self.n and length >= 9 and self.buf[offset] == OP_CHUNK:
                self.chunk(offset, self.view[offset + 9:offset + length])
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
    p, buf = read_file(path)
    check_start(p, buf)
    walker = _Walker(p, buf, topics, keep_messages, chunks)
    try:
        walker.record(OP_HEADER, memoryview(buf)[17:17 + U64.unpack_from(buf, 9)[0]], 8)
    except (RecordError, UnicodeDecodeError) as exc:
        raise SudsBagError(f"{p}: malformed MCAP header record: {exc}", code=DAMAGED_BAG) from None
    data_end = walker.read_summary()
    stop = walker.walk(data_end)
    if walker.summary is None and not walker.r.truncated:
        walker.tail(stop)
    if chunks:
        walker.unread_indexed_chunks()
    return walker.finish()
