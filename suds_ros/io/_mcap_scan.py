"""Tolerant sequential MCAP record scanner (pure python, no seeking, no summary needed).

The scanner walks the records of a file in order, unpacks chunks (zstd, lz4 or
uncompressed) and collects schemas, channels, metadata and messages.  It
stops quietly at the first incomplete record, so a file cut short by a crash
is read up to its last complete record; it never depends on the summary
section, on channel or schema ids being stable across files, or on indexes.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

from suds_ros.core.errors import SudsBagError

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 1, 2, 3, 4, 5, 6
OP_METADATA, OP_DATA_END = 0x0C, 0x0F
_SUMMARY_OPS = frozenset({0x03, 0x04, 0x08, 0x0A, 0x0B, 0x0D, 0x0E})
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_MSG_HEAD = struct.Struct("<HIQQ")


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
    p, buf = read_file(path)
    result = ScanResult(path=p)
    n = len(buf)
    if n == 0:
        raise SudsBagError(f"{p}: file is empty (0 bytes), not an MCAP recording")
    if buf[:8] != MAGIC:
        if n < 8 and MAGIC.startswith(buf):
            raise SudsBagError(f"{p}: truncated MCAP file: only {n} bytes of the 8-byte magic")
        raise SudsBagError(
            f"{p}: not an MCAP file (starts with {buf[:8]!r}, expected the magic {MAGIC!r})"
        )
    view = memoryview(buf)
    if n < 17 or buf[8] != OP_HEADER or 17 + _U64.unpack_from(buf, 9)[0] > n:
        msg = f"{p}: truncated MCAP file: the header record is incomplete ({n} bytes)"
        raise SudsBagError(msg)
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
            raise SudsBagError(msg) from None
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
