"""suds_ros.io.recording_bag: the recording contract, read and written."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from _bags import BAGS, JS, META, PS, STAMPS, assert_rec_equal, js, make_rec, raw_bag, shared

from suds_ros.core.errors import (
    DUPLICATE_STAMP,
    EXISTS,
    MISSING_JOINT_ROLES,
    MISSING_SYSTEM,
    MISSING_TOPIC,
    OUT_OF_ORDER_STAMP,
    SudsBagError,
    SudsDataError,
)
from suds_ros.io import cdr
from suds_ros.io.mcap import bag_info, iter_raw_messages
from suds_ros.io.recording_bag import RecordingWriter, read_recording, write_recording
from suds_ros.io.stamps import ns_to_float


@pytest.mark.parametrize("name", BAGS)
def test_read_shared_bags(name: str) -> None:
    path = shared(name)
    t0 = time.perf_counter()
    rec = read_recording(path)
    elapsed = time.perf_counter() - t0
    assert elapsed < 2.0
    assert rec.n_samples == 6000 and rec.pose_t.size == 6000
    np.testing.assert_allclose(rec.t, 1.7e9 + 0.01 * np.arange(6000), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(rec.t, rec.pose_t)
    assert rec.gait_hz == 1.0 and rec.effort is None
    if name.startswith("purcell3"):
        assert rec.system == "purcell3"
        assert rec.joint_names == ("joint_1", "joint_2")
        assert rec.actuated == ("joint_1",) and rec.passive == ("joint_2",)
    else:
        assert rec.system == "swimmer9"
        assert rec.joint_names == tuple(f"joint_{i}" for i in range(1, 9))
        assert rec.actuated == ("joint_1", "joint_2", "joint_3", "joint_4")
        assert rec.passive == ("joint_5", "joint_6", "joint_7", "joint_8")
    if name == "purcell3_real_friction":
        assert rec.r[:, 1].std() == pytest.approx(0.269, abs=0.005)
    if name == "purcell3_nominal":
        assert rec.r[:, 1].std() == pytest.approx(0.36, abs=0.01)
    if name == "swimmer9_real_rest_offset":
        assert rec.r[:, 5].mean() == pytest.approx(0.16, abs=0.01)
        assert rec.r[:, 4].mean() == pytest.approx(-0.08, abs=0.01)


def test_shared_bag_rewrite_equal(tmp_path: Path) -> None:
    rec = read_recording(shared("swimmer9_nominal"))
    out = tmp_path / "copy.mcap"
    write_recording(out, rec)
    assert_rec_equal(read_recording(out), rec)


# --------------------------------------------------------------------------- roundtrip
@pytest.mark.parametrize("effort", [False, True])
@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_roundtrip(tmp_path: Path, effort: bool, compression: str) -> None:
    rec = make_rec(effort=effort)
    path = tmp_path / "rec.mcap"
    write_recording(path, rec, compression=compression)
    back = read_recording(path)
    np.testing.assert_array_equal(back.t, rec.t)
    np.testing.assert_array_equal(back.r, rec.r)
    np.testing.assert_allclose(back.pose, rec.pose, rtol=0, atol=1e-12)
    assert (back.joint_names, back.actuated, back.passive) == (
        rec.joint_names, rec.actuated, rec.passive)
    assert back.system == "swimmer4" and back.gait_hz == 1.5
    if effort:
        np.testing.assert_array_equal(back.effort, rec.effort)
    else:
        assert back.effort is None
    info = bag_info(path)
    assert info.compression == (compression,) and info.has_summary
    assert info.metadata["suds"] == {"system": "swimmer4", "actuated": "joint_1",
                                     "passive": "joint_2,joint_3", "gait_hz": "1.5"}


def test_roundtrip_unaligned_streams_and_truth_not_written(tmp_path: Path) -> None:
    rec = make_rec(n=30, pose_t=1.7e9 + 0.005 + 0.02 * np.arange(20),
                   pose=np.zeros((20, 3)), truth={"xi": np.zeros((30, 3))})
    path = tmp_path / "rec.mcap"
    write_recording(path, rec)
    back = read_recording(path)
    back_pose = back.pose
    np.testing.assert_allclose(back_pose, rec.pose, atol=1e-12)
    assert back.truth == {}
    np.testing.assert_array_equal(back.pose_t, rec.pose_t)
    np.testing.assert_array_equal(back.r, rec.r)
    logs = [m.log_time_ns for m in iter_raw_messages(path)]
    assert logs == sorted(logs)


# --------------------------------------------------------------------------- block by block
def _write_in_blocks(path: Path, rec, shape_cuts: list[int], pose_cuts: list[int]) -> RecordingWriter:
    w = RecordingWriter(path, system=rec.system, joint_names=rec.joint_names, actuated=rec.actuated,
                        passive=rec.passive, gait_hz=rec.gait_hz)
    with w:
        for (a, b), (c, d) in zip(zip(shape_cuts[:-1], shape_cuts[1:]), zip(pose_cuts[:-1], pose_cuts[1:])):
            w.write(rec.t[a:b], rec.r[a:b], rec.pose_t[c:d], rec.pose[c:d],
                    None if rec.effort is None else rec.effort[a:b])
    return w


@pytest.mark.parametrize("effort", [False, True])
def test_blocks_write_the_bytes_of_the_whole_recording(tmp_path: Path, effort: bool) -> None:
    # pose at its own stamps, some equal to shape stamps (shape first), blocks of uneven spans
    pose_t = 1.7e9 + np.concatenate([0.01 * np.arange(0, 20), 0.2 + 0.0073 * np.arange(1, 70)])
    rec = make_rec(n=80, effort=effort, pose_t=pose_t,
                   pose=np.column_stack([np.sin(pose_t - 1.7e9), np.zeros(pose_t.size), np.zeros(pose_t.size)]))
    whole, parts = tmp_path / "whole.mcap", tmp_path / "parts.mcap"
    write_recording(whole, rec)
    w = _write_in_blocks(parts, rec, [0, 1, 1, 30, 31, 80, 80], [0, 0, 40, 41, 41, 60, 89])
    assert w.counts == (80, 89)
    assert parts.read_bytes() == whole.read_bytes()


def test_blocks_are_checked(tmp_path: Path) -> None:
    rec = make_rec(n=20, effort=True)
    kw = dict(system=rec.system, joint_names=rec.joint_names, actuated=rec.actuated, passive=rec.passive)
    with RecordingWriter(tmp_path / "a.mcap", **kw) as w:
        w.write(rec.t[:10], rec.r[:10], rec.pose_t[:10], rec.pose[:10], rec.effort[:10])
        with pytest.raises(SudsDataError, match="/suds/shape: stamps are not sorted: sample 10 comes before "
                                                "sample 9"):
            w.write(rec.t[5:8], rec.r[5:8], rec.pose_t[:0], rec.pose[:0], rec.effort[5:8])
        with pytest.raises(SudsDataError, match="`effort`: expected it with every block or with none"):
            w.write(rec.t[10:], rec.r[10:], rec.pose_t[10:], rec.pose[10:])
        bad = rec.pose[10:].copy()
        bad[3, 1] = np.nan
        with pytest.raises(SudsDataError, match="/suds/body_pose: sample 13 .* contains NaN or Inf"):
            w.write(rec.t[10:], rec.r[10:], rec.pose_t[10:], bad, rec.effort[10:])
        with pytest.raises(SudsDataError, match=r"`r`: expected shape \(10, 3\), got \(10, 2\)"):
            w.write(rec.t[10:], rec.r[10:, :2], rec.pose_t[10:], rec.pose[10:], rec.effort[10:])
    with pytest.raises(SudsBagError, match="recording writer is closed"):
        w.write(rec.t[10:], rec.r[10:], rec.pose_t[10:], rec.pose[10:], rec.effort[10:])
    back = read_recording(tmp_path / "a.mcap")
    assert back.n_samples == 10 and back.pose_t.size == 10


def test_our_files_open_with_rosbags(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    rec = make_rec(effort=True)
    path = tmp_path / "rec.mcap"
    write_recording(path, rec)
    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([path], default_typestore=store) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == {
            "/suds/shape": JS, "/suds/body_pose": PS}
        shape = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(
            connections=[c for c in reader.connections if c.topic == "/suds/shape"])]
        pose_conn = [c for c in reader.connections if c.topic == "/suds/body_pose"]
        poses = [store.deserialize_cdr(raw, PS) for _, _, raw in reader.messages(pose_conn)]
    assert len(shape) == rec.n_samples
    np.testing.assert_array_equal(np.array([m.position for m in shape]), rec.r)
    np.testing.assert_array_equal(np.array([m.effort for m in shape]), rec.effort)
    assert shape[3].name == list(rec.joint_names) and len(shape[3].velocity) == 0
    yaw = [2 * np.arctan2(m.pose.orientation.z, m.pose.orientation.w) for m in poses]
    np.testing.assert_allclose(np.unwrap(yaw), rec.pose[:, 2], atol=1e-12)
    assert poses[0].header.frame_id == "world"


def test_missing_topic(tmp_path: Path) -> None:
    path = tmp_path / "rec.mcap"
    write_recording(path, make_rec())
    with pytest.raises(SudsBagError,
                       match=r"topic '/robot/joints' is not in the bag; topics present: "
                             r"/suds/body_pose, /suds/shape") as err:
        read_recording(path, shape_topic="/robot/joints")
    assert err.value.code == MISSING_TOPIC
    with pytest.raises(SudsBagError, match=r"topic '/suds/shape' has type sensor_msgs/msg/Joint"
                                           r"State, expected geometry_msgs/msg/PoseStamped"):
        read_recording(path, pose_topic="/suds/shape")


def test_refuses_to_overwrite(tmp_path: Path) -> None:
    path = tmp_path / "rec.mcap"
    path.write_bytes(b"precious")
    with pytest.raises(SudsBagError, match=r"rec\.mcap: file exists; refusing to overwrite") as err:
        write_recording(path, make_rec())
    assert err.value.code == EXISTS
    assert path.read_bytes() == b"precious"
    write_recording(path, make_rec(), overwrite=True)
    assert read_recording(path).n_samples == 50


def test_joint_count_change(tmp_path: Path) -> None:
    msgs = [js(ns) for ns in STAMPS]
    msgs[7] = js(STAMPS[7], names=("joint_1", "joint_2", "joint_3"), pos=(1, 2, 3))
    path = tmp_path / "bad.mcap"
    raw_bag(path, msgs, STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"/suds/shape: sample 7 "
                                            r"\(stamp 1700000000\.070000000 s\)"
                                            r".*'joint_3'\], but sample 0 has"):
        read_recording(path)


def test_joint_order_change_and_bad_lengths(tmp_path: Path) -> None:
    msgs = [js(ns) for ns in STAMPS]
    msgs[3] = js(STAMPS[3], names=("joint_2", "joint_1"))
    path = tmp_path / "bad.mcap"
    raw_bag(path, msgs, STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"sample 3 .*\['joint_2', 'joint_1'\]"):
        read_recording(path)
    msgs[3] = js(STAMPS[3], vel=(1.0,))
    raw_bag(path, msgs, STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"sample 3 .*velocity has 1 values for 2 joints"):
        read_recording(path)


def test_effort_only_if_in_all_samples(tmp_path: Path) -> None:
    msgs = [js(ns, eff=(1.0, 2.0)) for ns in STAMPS]
    path = tmp_path / "e.mcap"
    raw_bag(path, msgs, STAMPS, meta=META)
    assert read_recording(path).effort.shape == (20, 2)
    msgs[5] = js(STAMPS[5])
    raw_bag(path, msgs, STAMPS, meta=META)
    assert read_recording(path).effort is None


def test_nan_sample(tmp_path: Path) -> None:
    msgs = [js(ns) for ns in STAMPS]
    msgs[4] = js(STAMPS[4], pos=(0.1, float("nan")))
    path = tmp_path / "nan.mcap"
    raw_bag(path, msgs, STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"/suds/shape: sample 4 .*NaN"):
        read_recording(path)
    poses = [cdr.pose_stamped(ns, (0, 0, 0), (0, 0, 0, 1)) for ns in STAMPS]
    poses[2] = cdr.pose_stamped(STAMPS[2], (float("nan"), 0, 0), (0, 0, 0, 1))
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta=META, pose_msgs=poses)
    with pytest.raises(SudsDataError, match=r"/suds/body_pose: sample 2 .*NaN"):
        read_recording(path)


def test_duplicate_and_unsorted_stamps(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    stamps = list(STAMPS)
    msgs = [js(ns) for ns in stamps]
    msgs[6] = js(stamps[5])
    raw_bag(path, msgs, stamps, meta=META)
    with pytest.raises(SudsDataError, match=r"/suds/shape: duplicate stamp "
                                            r"1700000000\.050000000 s at "
                                            r"samples 5 and 6") as err:
        read_recording(path)
    assert err.value.code == DUPLICATE_STAMP
    msgs[6] = js(stamps[2])
    raw_bag(path, msgs, stamps, meta=META)
    with pytest.raises(SudsDataError, match=r"/suds/shape: stamps are not sorted: sample 6") as err:
        read_recording(path)
    assert err.value.code == OUT_OF_ORDER_STAMP


def test_stamps_are_header_stamps_not_log_time(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    header = [ns - 3_000_000_000 for ns in STAMPS]  # stamped 3 s before logging
    poses = [cdr.pose_stamped(ns, (0, 0, 0), (0, 0, 0, 1)) for ns in header]
    raw_bag(path, [js(ns) for ns in header], STAMPS, meta=META, pose_msgs=poses)
    rec = read_recording(path)
    assert rec.t[0] == pytest.approx(1_699_999_997.0, abs=1e-6)


def test_metadata_override(tmp_path: Path) -> None:
    path = tmp_path / "m.mcap"
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta=META)
    rec = read_recording(path, system="mine", actuated=["joint_2"])
    assert rec.system == "mine" and rec.actuated == ("joint_2",) and rec.passive == ("joint_1",)
    rec = read_recording(path, passive=[])
    assert rec.actuated == ("joint_1", "joint_2") and rec.passive == ()
    assert rec.gait_hz == 1.0


def test_missing_metadata(tmp_path: Path) -> None:
    path = tmp_path / "m.mcap"
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta=None)
    with pytest.raises(SudsBagError, match=r"no 'system': the bag has no 'suds' metadata "
                                           r"record$") as err:
        read_recording(path)
    assert err.value.code == MISSING_SYSTEM  # the CLI adds "pass --system" for this code
    with pytest.raises(SudsBagError, match=r"no 'actuated' joints: the bag has no 'suds' "
                                           r"metadata record \(joints in the bag: joint_1, "
                                           r"joint_2\)") as err:
        read_recording(path, system="purcell3")
    assert err.value.code == MISSING_JOINT_ROLES
    rec = read_recording(path, system="purcell3", passive=["joint_2"])
    assert rec.actuated == ("joint_1",) and rec.gait_hz is None
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta={"system": "x"})
    with pytest.raises(SudsBagError, match=r"record has neither 'actuated' nor 'passive'"):
        read_recording(path)
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta={**META, "gait_hz": "fast"})
    with pytest.raises(SudsBagError, match=r"gait_hz: expected a number, got 'fast'"):
        read_recording(path)
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"joints \['joint_9'\] are not among"):
        read_recording(path, actuated=["joint_9"])


def test_io_does_not_import_rclpy() -> None:
    code = ("import sys, suds_ros.io.recording_bag, suds_ros.io.mcap, suds_ros.io.stamps, "
            "suds_ros.io.cdr, suds_ros.io.msgdefs; sys.exit('rclpy' in sys.modules)")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    assert subprocess.run([sys.executable, "-c", code], env=env, check=False).returncode == 0


# ------------------------------------------------------------------ several robots in one bag
def write_fleet(path: Path, robots: dict[str, object], meta: dict[str, str] | None = None) -> None:
    """One bag with each robot's contract topics under its namespace, and its <ns>/suds/system."""
    import json

    from suds_ros.io.mcap import BagWriter
    from suds_ros.io.recording_bag import (
        POSE_TOPIC, POSE_TYPE, SHAPE_TOPIC, SHAPE_TYPE, STRING_TYPE, SYSTEM_TOPIC, namespaced,
    )
    from suds_ros.io.stamps import float_to_ns, yaw_quaternion

    with BagWriter(path) as w:
        if meta is not None:
            w.write_metadata("suds", meta)
        for ns, rec in robots.items():
            topics = {k: namespaced(ns, t) for k, t in (("s", SHAPE_TOPIC), ("p", POSE_TOPIC), ("y", SYSTEM_TOPIC))}
            w.add_topic(topics["s"], SHAPE_TYPE)
            w.add_topic(topics["p"], POSE_TYPE)
            w.add_topic(topics["y"], STRING_TYPE)
            info = {"system": rec.system, "joint_names": list(rec.joint_names), "actuated": list(rec.actuated),
                    "passive": list(rec.passive), "gait_hz": rec.gait_hz}
            t0 = int(float_to_ns(rec.t[0]))
            w.write_raw(topics["y"], cdr.encode(STRING_TYPE, {"data": json.dumps(info)}), t0, t0)
            for k, t in enumerate(rec.t):
                n = int(float_to_ns(t))
                w.write_raw(topics["s"], cdr.joint_state(n, rec.joint_names, rec.r[k], (), ()), n, n)
                x, y, yaw = rec.pose[k]
                w.write_raw(topics["p"], cdr.pose_stamped(n, (x, y, 0.0), yaw_quaternion(yaw), "world"), n, n)


def test_robots_in_namespaces(tmp_path: Path) -> None:
    from suds_ros.core.errors import SudsConfigError

    a = make_rec()
    b = make_rec(system="eel4", actuated=("joint_1", "joint_3"), passive=("joint_2",), gait_hz=0.5,
                 r=make_rec().r[::-1].copy())
    path = tmp_path / "fleet.mcap"
    # the bag's metadata record (e.g. the recorder's parameters) describes one robot only
    write_fleet(path, {"/robot1": a, "/fleet/eel_2": b}, meta={"system": "other", "actuated": "joint_3"})
    got_a = read_recording(path, namespace="/robot1")
    got_b = read_recording(path, namespace="/fleet/eel_2")
    assert_rec_equal(got_a, a)
    assert_rec_equal(got_b, b)
    with pytest.raises(SudsBagError, match=r"topic '/suds/shape' is not in the bag.*namespace "
                                           r"/fleet/eel_2, /robot1") as err:
        read_recording(path)
    assert err.value.code == MISSING_TOPIC
    with pytest.raises(SudsBagError, match="'/robot9/suds/shape' is not in the bag"):
        read_recording(path, namespace="/robot9")
    for bad in ("robot1", "/robot1/", "/1robot", "/ro-bot"):
        with pytest.raises(SudsConfigError, match="`namespace`: expected"):
            read_recording(path, namespace=bad)


def test_system_topic_when_the_bag_has_no_metadata(tmp_path: Path) -> None:
    a = make_rec()
    path = tmp_path / "root.mcap"
    write_fleet(path, {"": a})  # root topics, no metadata record, but /suds/system recorded
    assert_rec_equal(read_recording(path), a)
    # the metadata record wins at the root (the recording contract's own record)
    path = tmp_path / "root_meta.mcap"
    write_fleet(path, {"": a}, meta={"system": "other", "actuated": "joint_1,joint_2"})
    rec = read_recording(path)
    assert rec.system == "other" and rec.actuated == ("joint_1", "joint_2") and rec.gait_hz is None


def test_parse_system_info() -> None:
    from suds_ros.io.recording_bag import parse_system_info

    info = parse_system_info('{"system": "purcell3", "joint_names": ["joint_1", "joint_2"], '
                             '"actuated": ["joint_1"], "passive": ["joint_2"], "gait_hz": 0, "rate": 100}')
    assert info["actuated"] == ("joint_1",) and info["joint_names"] == ("joint_1", "joint_2")
    assert info["gait_hz"] is None and info["rate"] == 100
    with pytest.raises(SudsDataError, match="expected JSON with joint_names and actuated"):
        parse_system_info('{"system": "x", "actuated": ["joint_1"]}')
    with pytest.raises(SudsDataError, match=r"actuated \['joint_9'\] not among joints"):
        parse_system_info('{"joint_names": ["joint_1"], "actuated": ["joint_9"]}')


def _long_stamps(n: int) -> list[int]:
    return [1_700_000_000_000_000_000 + k * 10_000_000 for k in range(n)]


def _batches(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the messages the chunk-at-a-time decoders took (the rest went one at a time)."""
    taken: list[int] = []
    for name in ("parse_joint_states", "parse_pose_stampeds"):
        real = getattr(cdr, name)

        def counted(records, starts, length, real=real):  # type: ignore[no-untyped-def]
            got = real(records, starts, length)
            taken.append(0 if got is None else starts.size)
            return got
        monkeypatch.setattr(cdr, name, counted)
    return taken


def test_chunks_decoded_at_once_equal_one_at_a_time(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunks of one layout are decoded as arrays; mixed chunks one message at a time; the same recording."""
    stamps = _long_stamps(600)
    rng = np.random.default_rng(1)
    msgs = [js(ns, pos=tuple(rng.normal(size=2)), eff=(1.0, 2.0)) for ns in stamps]
    msgs[450] = js(stamps[450], pos=(0.5, 0.6))  # one message without effort: no effort at all
    # the same length as the others, another frame id: the chunk's layout check refuses it
    msgs[300] = cdr.joint_state(stamps[300], ("joint_1", "joint_2"), (0.7, 0.8), (), (1.0, 2.0), frame_id="a")
    assert len(msgs[300]) == len(msgs[299])
    path = tmp_path / "long.mcap"
    raw_bag(path, msgs, stamps, meta=META)
    taken = _batches(monkeypatch)
    rec = read_recording(path)
    assert sum(taken) > 600  # most of both streams went through the array decoders
    assert taken.count(0) >= 1  # the chunk with the odd messages did not
    assert rec.effort is None
    want = np.array([cdr.parse_joint_state(m)[3] for m in msgs])
    np.testing.assert_array_equal(rec.r, want)
    np.testing.assert_array_equal(rec.t, ns_to_float(np.array(stamps)))
    np.testing.assert_allclose(rec.pose[:, 0], 0.1 * np.arange(600), rtol=0, atol=1e-12)


def test_names_change_in_a_later_chunk_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A chunk whose names differ from the stream's is read one message at a time, so its sample is named."""
    stamps = _long_stamps(600)
    msgs = [js(ns) for ns in stamps]
    for k in range(500, 600):
        msgs[k] = js(stamps[k], names=("joint_1", "joint_9"))
    path = tmp_path / "names.mcap"
    raw_bag(path, msgs, stamps, meta=META)
    taken = _batches(monkeypatch)
    with pytest.raises(SudsDataError, match=r"/suds/shape: sample 500 .*'joint_9'\], but sample 0 has") as err:
        read_recording(path)
    assert err.value.code == "wrong_joint_names"
    assert sum(taken) > 0
