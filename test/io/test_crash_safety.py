"""What a crash or power loss costs a bag being written: at most one flush period (0.5 s), or two
when the power fails while a chunk is being written (docs/recording_safety.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _bags import JS, PS

from suds_ros.core.errors import SudsBagError
from suds_ros.io import cdr
from suds_ros.io.mcap import BagWriter, bag_info, iter_raw_messages

T0 = 1_700_000_000 * 10**9
RATE_NS = 1_000_000  # 1 kHz
LIMIT_NS = 500_000_000  # BagWriter's default chunk_interval


def _logs(data: bytes, tmp: Path) -> list[int]:
    """Log times of the shape messages in a copy of a bag being written."""
    tmp.write_bytes(data)
    return [m.log_time_ns for m in iter_raw_messages(tmp, ["/suds/shape"])]


def test_copy_of_an_open_bag_holds_all_but_the_last_half_second(tmp_path: Path) -> None:
    path, copy = tmp_path / "live.mcap", tmp_path / "copy.mcap"
    rng = np.random.default_rng(3)
    w = BagWriter(path, compression="zstd")  # defaults: chunk_interval 0.5 s, chunk_size 256 KiB
    w.add_topic("/suds/shape", JS)
    w.add_topic("/suds/body_pose", PS)
    w.write_metadata("suds", {"system": "purcell3", "actuated": "joint_1"})
    copy_at = set(rng.integers(700, 4000, size=12).tolist())
    checked = 0
    for k in range(4000):  # 4 s of a 1 kHz stream of two topics
        ns = T0 + k * RATE_NS
        w.write_raw("/suds/shape", cdr.joint_state(ns, ("joint_1", "joint_2"),
                                                   (np.sin(k / 100), 0.1)), ns)
        w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (k * 1e-3, 0, 0), (0, 0, 0, 1)), ns)
        if k not in copy_at:
            continue
        data = path.read_bytes()  # what is on disk now, writer still open (no summary)
        logs = _logs(data, copy)
        assert logs == [T0 + j * RATE_NS for j in range(len(logs))]  # a prefix, nothing invented
        assert logs[-1] >= ns - LIMIT_NS, (k, len(logs))
        # a power loss while the last chunk was being written: any cut inside it
        info = bag_info(copy)
        last_chunk = max(d for d in _chunk_offsets(data))
        for cut in rng.integers(last_chunk + 1, len(data), size=4):
            try:
                cut_logs = _logs(data[:cut], copy)
            except SudsBagError as exc:  # only if nothing had been flushed yet
                pytest.fail(f"cut at {cut} of {len(data)}: {exc}")
            assert cut_logs == logs[:len(cut_logs)]
            must_have = [j for j in logs if j < ns - 2 * LIMIT_NS]
            assert cut_logs[:len(must_have)] == must_have, (k, cut)
        assert not info.damage and info.truncated
        checked += 1
    w.close()
    assert checked == len(copy_at)
    info = bag_info(path)
    assert info.message_count == 8000 and not info.truncated and info.damage == ()
    # one chunk per half second of log time (4 s → 8 chunks, the last one at close)
    assert len(_chunk_offsets(path.read_bytes())) == 8


def _chunk_offsets(data: bytes) -> list[int]:
    """Offsets of the chunk records of an MCAP file (walks the top-level records)."""
    pos, out = 8, []
    while pos + 9 <= len(data):
        op, length = data[pos], int.from_bytes(data[pos + 1:pos + 9], "little")
        if op == 0x06:
            out.append(pos)
        if op == 0x0F:
            break
        pos += 9 + length
    return out


def test_size_still_closes_chunks_and_interval_can_be_off(tmp_path: Path) -> None:
    path = tmp_path / "big.mcap"
    with BagWriter(path, chunk_size=4096, chunk_interval=None, compression="none") as w:
        w.add_topic("/suds/shape", JS)
        for k in range(400):
            ns = T0 + k * 10 * RATE_NS
            w.write_raw("/suds/shape", cdr.joint_state(ns, ("joint_1",), (0.0,)), ns)
    offsets = _chunk_offsets(path.read_bytes())
    assert 5 <= len(offsets) <= 40  # ~100-byte messages in ~4 KiB chunks
    with pytest.raises(SudsBagError, match=r"chunk_interval: expected a positive number.*got 0"):
        BagWriter(tmp_path / "x.mcap", chunk_interval=0)


def test_fsync_writer_syncs_each_chunk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import os

    synced: list[int] = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real(fd))[1])
    with BagWriter(tmp_path / "s.mcap", fsync=True) as w:
        w.add_topic("/suds/shape", JS)
        for k in range(1500):  # 1.5 s at 1 kHz: chunks at 0.5 s and 1.0 s, the rest at close
            ns = T0 + k * RATE_NS
            w.write_raw("/suds/shape", cdr.joint_state(ns, ("joint_1",), (0.0,)), ns)
        n_before_close = len(synced)
        w.flush()
        w.flush()  # nothing new: no second sync
    assert n_before_close == 2 and len(synced) == 4  # + the explicit flush + close
