"""suds_ros.io.mcap: the writer, the truncation-tolerant reader and the bag summary."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _bags import JS, META, PS, STAMPS, js, make_rec, raw_bag, shared
from mcap.writer import CompressionType

from suds_ros.core.errors import DAMAGED_BAG, SudsBagError
from suds_ros.io import cdr, msgdefs
from suds_ros.io.mcap import (
    BagInfo,
    BagWriter,
    bag_info,
    decode_message,
    iter_raw_messages,
    read_metadata,
)
from suds_ros.io.recording_bag import read_recording
from suds_ros.io.stamps import float_to_ns


def test_shared_bag_info_and_raw() -> None:
    path = shared("purcell3_nominal")
    info = bag_info(path)
    assert isinstance(info, BagInfo)
    assert info.topics["/suds/shape"].type_name == JS
    assert info.topics["/suds/shape"].count == 6000
    assert info.as_dict()["topics"]["/suds/shape"] == {"type": JS, "count": 6000,
                                                       "message_encoding": "cdr"}
    assert info.topics["/suds/body_pose"].count == 6000 and info.message_count == 12000
    assert info.compression == ("zstd",) and info.has_summary and not info.truncated
    assert info.duration_s == pytest.approx(59.99) and info.start_ns == 1_700_000_000 * 10**9
    assert list(info.as_dict()) == ["path", "profile", "library", "topics", "message_count",
                                    "start_ns", "end_ns", "duration_s", "metadata",
                                    "compression", "has_summary", "truncated", "problem",
                                    "damage", "messages_lost"]
    assert info.damage == () and info.messages_lost == 0
    assert read_metadata(path)["suds"]["system"] == "purcell3"
    msgs = list(iter_raw_messages(path, ["/suds/body_pose"]))
    assert len(msgs) == 6000 and {m.type_name for m in msgs} == {PS}
    assert all(a.log_time_ns <= b.log_time_ns for a, b in zip(msgs, msgs[1:]))
    m = decode_message(PS, msgs[0].data)
    assert m.header.frame_id == "world" and m.header.stamp.sec == 1_700_000_000


def test_truncated_copies_read_up_to_last_complete_record(tmp_path: Path) -> None:
    rec = make_rec(n=400)
    full = tmp_path / "full.mcap"
    with BagWriter(full, chunk_size=2048) as w:
        w.add_topic("/suds/shape", JS)
        w.add_topic("/suds/body_pose", PS)
        w.write_metadata("suds", {"system": "s", "actuated": "joint_1"})
        for k in range(rec.n_samples):
            ns = float_to_ns(rec.t[k])
            w.write_raw("/suds/shape", cdr.joint_state(ns, rec.joint_names, rec.r[k]), ns)
            w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (k, 0, 0), (0, 0, 0, 1)), ns)
    data = full.read_bytes()
    footer = len(data) - 8 - 29
    summary_start = int.from_bytes(data[footer + 9:footer + 17], "little")
    seen = []
    for frac in (0.3, 0.55, 0.8, 0.97):
        cut = tmp_path / f"cut{frac}.mcap"
        cut.write_bytes(data[: int(summary_start * frac)])
        info = bag_info(cut)
        assert info.truncated and "without a complete footer" in info.problem
        back = read_recording(cut)
        n = back.n_samples
        assert 0 < n < rec.n_samples
        np.testing.assert_array_equal(back.r, rec.r[:n])
        np.testing.assert_array_equal(back.t, rec.t[:n])
        assert back.passive == ("joint_2", "joint_3")  # complement of metadata 'actuated'
        seen.append(n)
    assert seen == sorted(seen)
    # a cut inside the summary section keeps every message
    cut = tmp_path / "cut_summary.mcap"
    cut.write_bytes(data[:-40])
    assert read_recording(cut).n_samples == rec.n_samples


def test_flush_makes_complete_records(tmp_path: Path) -> None:
    path = tmp_path / "live.mcap"
    w = BagWriter(path)
    w.add_topic("/suds/shape", JS)
    w.add_topic("/suds/body_pose", PS)
    for ns in STAMPS[:5]:
        w.write_raw("/suds/shape", js(ns), ns)
        w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (0, 0, 0), (0, 0, 0, 1)), ns)
    w.flush()
    assert len(list(iter_raw_messages(path))) == 10  # file still open, no summary
    w.close()
    w.close()
    with pytest.raises(SudsBagError, match="closed"):
        w.write_raw("/suds/shape", js(1), 1)
    assert bag_info(path).has_summary


@pytest.mark.parametrize("compression", [CompressionType.LZ4, CompressionType.NONE,
                                         CompressionType.ZSTD])
@pytest.mark.parametrize("summary", [True, False])
def test_foreign_layouts(tmp_path: Path, compression: CompressionType, summary: bool) -> None:
    path = tmp_path / "foreign.mcap"
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, compression=compression,
            summary=summary, meta=META)
    rec = read_recording(path)
    assert rec.n_samples == 20 and rec.system == "purcell3"
    np.testing.assert_allclose(rec.pose[:, 0], 0.1 * np.arange(20))
    assert bag_info(path).has_summary is summary


def test_unchunked_file(tmp_path: Path) -> None:
    path = tmp_path / "plain.mcap"
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, chunked=False, meta=META)
    assert read_recording(path).n_samples == 20
    assert bag_info(path).compression == ()


@pytest.mark.parametrize(("content", "match"), [
    (b"", r"empty \(0 bytes\)"),
    (b"\x89MCA", r"truncated MCAP file: only 4 bytes"),
    (b"hello, this is a text file\n" * 10, r"not an MCAP file"),
    (bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8)), r"not an MCAP file"),
    (b"\x89MCAP0\r\n\x01\xff\x00", r"header record is incomplete"),
])
def test_foreign_files(tmp_path: Path, content: bytes, match: str) -> None:
    path = tmp_path / "bad.mcap"
    path.write_bytes(content)
    with pytest.raises(SudsBagError, match=match) as info:
        read_recording(path)
    assert str(path) in str(info.value) and info.value.code == DAMAGED_BAG


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(SudsBagError, match=r"nope\.mcap: no such file"):
        read_recording(tmp_path / "nope.mcap")


def test_writer_argument_errors(tmp_path: Path) -> None:
    with pytest.raises(SudsBagError, match=r"compression: expected one of .*got 'gzip'"):
        BagWriter(tmp_path / "a.mcap", compression="gzip")
    with BagWriter(tmp_path / "b.mcap") as w:
        with pytest.raises(SudsBagError, match=r"'nav_msgs/msg/Odometry' has no schema"):
            w.add_topic("/odom", "nav_msgs/msg/Odometry")
        with pytest.raises(SudsBagError, match=r"topic '/x' was not added"):
            w.write_raw("/x", b"", 0)
        w.add_topic("/x", "std_msgs/msg/String", qos_yaml="- depth: 1")
        w.add_topic("/x", "std_msgs/msg/String")
        with pytest.raises(SudsBagError, match=r"cannot add it again as 'rosgraph_msgs/"):
            w.add_topic("/x", "rosgraph_msgs/msg/Clock")
        with pytest.raises(SudsBagError, match=r"keys and values must be str"):
            w.write_metadata("suds", {"gait_hz": 1.0})  # type: ignore[dict-item]
        w.write_raw("/x", cdr.encode("std_msgs/msg/String", {"data": "hi"}), 5)
    from mcap.reader import make_reader

    with open(tmp_path / "b.mcap", "rb") as f:
        ch = next(iter(make_reader(f).get_summary().channels.values()))
    assert ch.metadata == {"offered_qos_profiles": "- depth: 1",
                           "topic_type_hash": msgdefs.type_hash("std_msgs/msg/String")}
    [m] = iter_raw_messages(tmp_path / "b.mcap")
    assert decode_message(m.type_name, m.data).data == "hi"


def test_decode_message_errors() -> None:
    with pytest.raises(SudsBagError, match=r"cannot decode 'sensor_msgs/msg/JointState'"):
        decode_message(JS, b"\x00\x01\x00\x00\x01")


def test_cut_at_any_offset_reads_or_raises_bag_error(tmp_path: Path) -> None:
    path = tmp_path / "rec.mcap"
    rec = make_rec(n=200)
    with BagWriter(path, compression="lz4", chunk_size=1500) as w:
        w.write_metadata("suds", {"system": "s", "actuated": "joint_1"})
        w.add_topic("/suds/shape", JS)
        w.add_topic("/suds/body_pose", PS)
        for k in range(rec.n_samples):
            ns = float_to_ns(rec.t[k])
            w.write_raw("/suds/shape", cdr.joint_state(ns, rec.joint_names, rec.r[k]), ns)
            w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (k, 0, 0), (0, 0, 0, 1)), ns)
    data = path.read_bytes()
    counts = []
    for cut_at in np.linspace(0, len(data), 60).astype(int):
        cut = tmp_path / "cut.mcap"
        cut.write_bytes(data[:cut_at])
        try:
            counts.append(read_recording(cut).n_samples)
        except SudsBagError as exc:
            assert str(cut) in str(exc)
            assert any(w in str(exc) for w in ("empty", "truncated", "not in the bag",
                                               "no messages")), str(exc)
            counts.append(0)
    assert counts == sorted(counts) and counts[-1] == 200 and 0 < counts[30] < 200


def _top_records(data: bytes) -> list[tuple[int, int]]:
    """``(offset, opcode)`` of the top-level records after the magic."""
    pos, out = 8, []
    while pos + 9 <= len(data):
        out.append((pos, data[pos]))
        pos += 9 + int.from_bytes(data[pos + 1:pos + 9], "little")
    return out


def test_bad_length_without_summary_resyncs_to_the_next_chunk(tmp_path: Path) -> None:
    stamps = [STAMPS[0] + k * 10_000_000 for k in range(300)]
    path = tmp_path / "nosummary.mcap"
    raw_bag(path, [js(ns) for ns in stamps], stamps, summary=False, meta=META)
    data = bytearray(path.read_bytes())
    chunks = [pos for pos, op in _top_records(bytes(data)) if op == 0x06]
    assert len(chunks) >= 4
    victim = chunks[1]
    data[victim + 1:victim + 9] = (2**40).to_bytes(8, "little")  # an impossible length
    path.write_bytes(bytes(data))
    info = bag_info(path)
    [d] = info.damage
    assert d.record == "bytes" and d.offset == victim and d.messages is None
    assert f"skipped to the next record at byte {chunks[2]}" in d.reason
    rec = read_recording(path)  # chunks before and after the damaged one are read
    assert 0 < rec.n_samples < 300 and rec.t[-1] == pytest.approx(stamps[-1] * 1e-9)


def test_cut_chunk_is_reported_and_channels_lost_with_first_chunk(tmp_path: Path) -> None:
    path = tmp_path / "cut.mcap"
    rec = make_rec(n=400)
    with BagWriter(path, chunk_size=2048) as w:
        w.add_topic("/suds/shape", JS)
        w.write_metadata("suds", {"system": "s", "actuated": "joint_1"})
        for k in range(rec.n_samples):
            ns = float_to_ns(rec.t[k])
            w.write_raw("/suds/shape", cdr.joint_state(ns, rec.joint_names, rec.r[k]), ns)
    data = path.read_bytes()
    chunks = [pos for pos, op in _top_records(data) if op == 0x06]
    cut = tmp_path / "c.mcap"
    cut.write_bytes(data[:chunks[3] + 100])
    info = bag_info(cut)
    [d] = info.damage
    assert info.truncated and d.record == "chunk" and d.offset == chunks[3]
    assert "file ends inside this chunk" in d.reason and d.messages is None
    assert d.start_ns is not None and d.start_ns > info.end_ns  # the lost part comes after
    # the first chunk holds the channel record: without it (and no summary) its messages are lost
    broken = bytearray(data[:chunks[3]])
    broken[chunks[0] + 60] ^= 0x01
    cut.write_bytes(bytes(broken))
    info = bag_info(cut)
    assert [x.record for x in info.damage] == ["chunk", "channel"]
    assert info.topics == {} and info.damage[0].messages > 0  # from its message index records
    assert info.messages_lost == sum(x.messages for x in info.damage)
    with pytest.raises(SudsBagError, match=r"not in the bag.*\(the bag is damaged: .*chunk at byte"):
        read_recording(cut)


# ------------------------------------------------------------------ streaming and the mcap package
def _bag_of(path: Path, n: int) -> bytes:
    """A bag of ``n`` shape and pose samples written by our writer; its bytes."""
    rec = make_rec(n=n)
    with BagWriter(path, overwrite=True, chunk_size=64 * 1024, chunk_interval=None) as w:
        w.add_topic("/suds/shape", JS)
        w.add_topic("/suds/body_pose", PS)
        for k in range(n):
            ns = int(float_to_ns(rec.t[k]))
            w.write_raw("/suds/shape", cdr.joint_state(ns, rec.joint_names, rec.r[k]), ns)
            w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (k, 0, 0), (0, 0, 0, 1)), ns)
    return path.read_bytes()


def _peak_bytes(fn, *args) -> int:
    import tracemalloc

    tracemalloc.start()
    try:
        fn(*args)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_memory_does_not_grow_with_the_file(tmp_path: Path) -> None:
    """bag_info streams the file: the peak is about one chunk, for a 4× larger file as well."""
    sizes, peaks = [], []
    for n in (4000, 16000):
        data = _bag_of(tmp_path / f"b{n}.mcap", n)
        chunks = [pos for pos, op in _top_records(data) if op == 0x06]
        damaged = bytearray(data)
        damaged[chunks[len(chunks) // 2] + 80] ^= 0x10  # one chunk in the middle
        cut = data[:len(data) * 3 // 4]  # and a truncated copy
        (tmp_path / "d.mcap").write_bytes(bytes(damaged))
        (tmp_path / "c.mcap").write_bytes(cut)
        assert bag_info(tmp_path / "d.mcap").damage and bag_info(tmp_path / "c.mcap").truncated
        sizes.append(len(data))
        peaks.append([_peak_bytes(bag_info, tmp_path / name)
                      for name in (f"b{n}.mcap", "d.mcap", "c.mcap")])
    assert sizes[1] > 3.5 * sizes[0]
    for small, large in zip(*peaks):
        assert large < 1.5 * small + 256 * 1024, (sizes, peaks)
        assert large < sizes[1] / 4, (sizes, peaks)  # far below the file: never read whole


def test_messages_equal_the_mcap_stream_reader(tmp_path: Path) -> None:
    """The fast path over chunk records gives what the mcap package's own reader gives."""
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader

    path = tmp_path / "b.mcap"
    _bag_of(path, 700)
    with open(path, "rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)
    topic = {r.id: r.topic for r in records if isinstance(r, Channel)}
    theirs = sorted(((topic[m.channel_id], m.log_time, m.publish_time, m.data)
                     for m in records if isinstance(m, Message)), key=lambda m: m[1])
    ours = [(m.topic, m.log_time_ns, m.publish_time_ns, m.data) for m in iter_raw_messages(path)]
    assert len(ours) == 1400 and ours == theirs


def _walk(records: bytes) -> list[int]:
    """Record offsets of a chunk, one record at a time (the reference for the array paths)."""
    import struct

    out, p = [], 0
    while p < len(records):
        out.append(p)
        p += 9 + struct.unpack_from("<Q", records, p + 1)[0]
    return out


@pytest.mark.parametrize("case", ["alternating", "odd tail", "one longer", "channel record"])
def test_record_offsets_predicted_from_a_period_equal_the_walk(case: str) -> None:
    """Offsets predicted from the lengths' period are checked; where the period breaks the walk takes over."""
    import struct

    from suds_ros.io.mcap_records import MESSAGE_HEAD
    from suds_ros.io.mcap_scan import _message_offsets, _repeating_offsets

    def record(n: int, op: int = 0x05) -> bytes:
        return struct.pack("<BQ", op, MESSAGE_HEAD + n) + bytes(MESSAGE_HEAD + n)

    sizes = [70 if k % 2 else 41 for k in range(100 if case == "alternating" else 101)]
    if case == "one longer":
        sizes[57] += 8
    records = b"".join(record(n, 0x04 if case == "channel record" and k == 30 else 0x05)
                       for k, n in enumerate(sizes))
    got = _repeating_offsets(records)
    if case in ("alternating", "odd tail"):
        assert got is not None and got.tolist() == _walk(records)
    else:
        assert got is None
    walked = _message_offsets(records)
    if case == "channel record":
        assert walked is None  # not messages only: the record-by-record walk reads it
    else:
        assert walked is not None and walked.tolist() == _walk(records)
