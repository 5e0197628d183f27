"""Tests of suds_ros.io: CDR encoder, MCAP bag writer/reader, recording contract."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import CompressionType, IndexType, Writer

from suds_ros.core.errors import SudsBagError, SudsDataError
from suds_ros.core.recording import Recording
from suds_ros.io import bags, cdr, msgdefs

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "bags"
BAGS = ("purcell3_nominal", "swimmer9_nominal", "purcell3_real_friction",
        "swimmer9_real_rest_offset")
JS, PS = "sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseStamped"


def shared(name: str) -> Path:
    path = SHARED / f"{name}.mcap"
    if not path.is_file():
        pytest.skip(f"shared recording {path} is absent (the public test bags are not mounted)")
    return path


def make_rec(n: int = 50, t0: float = 1.7e9, effort: bool = False, **kw: object) -> Recording:
    rng = np.random.default_rng(0)
    t = t0 + 0.01 * np.arange(n)
    r = rng.normal(size=(n, 3))
    pose = np.column_stack([rng.normal(size=n), rng.normal(size=n),
                            np.linspace(-3.0, 3.0, n)])
    args = dict(t=t, r=r, joint_names=("joint_1", "joint_2", "joint_3"), actuated=("joint_1",),
                passive=("joint_2", "joint_3"), pose_t=t, pose=pose, system="swimmer4",
                gait_hz=1.5, effort=rng.normal(size=(n, 3)) if effort else None)
    args.update(kw)
    return Recording(**args)  # type: ignore[arg-type]


def assert_rec_equal(a: Recording, b: Recording) -> None:
    for name in ("t", "r", "pose_t"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    np.testing.assert_allclose(a.pose, b.pose, rtol=0, atol=1e-12)  # yaw via quaternion
    for name in ("joint_names", "actuated", "passive", "system", "gait_hz"):
        assert getattr(a, name) == getattr(b, name), name
    if a.effort is None or b.effort is None:
        assert a.effort is None and b.effort is None
    else:
        np.testing.assert_array_equal(a.effort, b.effort)


def raw_bag(path: Path, shape_msgs: list[bytes], stamps_ns: list[int], *,
            compression: CompressionType = CompressionType.ZSTD, summary: bool = True,
            meta: dict[str, str] | None = None, chunked: bool = True,
            pose_msgs: list[bytes] | None = None) -> None:
    """Write a bag with the mcap Writer directly (ids and layout unlike ours)."""
    with open(path, "wb") as f:
        w = Writer(f, compression=compression, use_chunking=chunked, chunk_size=4096,
                   repeat_channels=summary, repeat_schemas=summary, use_statistics=summary,
                   use_summary_offsets=summary,
                   index_types=IndexType.ALL if summary else IndexType(0))
        w.start(profile="ros2", library="test")
        w.register_schema("std_msgs/msg/String", "ros2msg", b"string data\n")  # id 1, unused
        sid_p = w.register_schema(PS, "ros2msg", msgdefs.schema_text(PS).encode())
        sid_j = w.register_schema(JS, "ros2msg", msgdefs.schema_text(JS).encode())
        w.register_channel("/other", "cdr", 1)
        cp = w.register_channel("/suds/body_pose", "cdr", sid_p)
        cj = w.register_channel("/suds/shape", "cdr", sid_j)
        if meta is not None:
            w.add_metadata("suds", meta)
        if pose_msgs is None:
            pose_msgs = [cdr.pose_stamped(ns, (0.1 * k, 0.0, 0.0), (0, 0, 0, 1))
                         for k, ns in enumerate(stamps_ns)]
        for k, (ns, data) in enumerate(zip(stamps_ns, shape_msgs)):
            w.add_message(cj, ns, data, ns, k)
            w.add_message(cp, ns, pose_msgs[k], ns, k)
        if summary:
            w.finish()
        else:
            w.flush()


def js(ns: int, names=("joint_1", "joint_2"), pos=(0.1, 0.2), vel=(), eff=()) -> bytes:
    return cdr.joint_state(ns, names, pos, vel, eff)


STAMPS = [1_700_000_000_000_000_000 + k * 10_000_000 for k in range(20)]
META = {"system": "purcell3", "actuated": "joint_1", "passive": "joint_2", "gait_hz": "1"}


# --------------------------------------------------------------------------- msg_defs
def test_msg_defs_match_shared_bags_schemas() -> None:
    from mcap.reader import make_reader

    with open(shared("swimmer9_nominal"), "rb") as f:
        schemas = make_reader(f).get_summary().schemas.values()
    for s in schemas:
        assert msgdefs.schema_text(s.name).encode() == s.data
    assert msgdefs.type_hash(JS).startswith("RIHS01_")
    assert len(msgdefs.known_types()) == 6


def test_msg_defs_unknown_type() -> None:
    with pytest.raises(SudsBagError, match=r"'nav_msgs/msg/Odometry' has no schema"):
        msgdefs.schema_text("nav_msgs/msg/Odometry")


# --------------------------------------------------------------------------- CDR
def _ros_messages() -> list[tuple[str, object]]:
    rclpy_ser = pytest.importorskip("rclpy.serialization", reason="rclpy not installed")
    del rclpy_ser
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    full = JointState(name=["joint_1", "j2"], position=[1.0, -2.5], velocity=[0.5, 0.25],
                      effort=[3.0, 4.0])
    full.header.stamp.sec, full.header.stamp.nanosec = 1_700_000_000, 990_000_000
    full.header.frame_id = "base"
    pose = PoseStamped()
    pose.header.frame_id = "world"
    pose.pose.position.x, pose.pose.orientation.z, pose.pose.orientation.w = 1.5, 0.6, 0.8
    tw = TwistStamped()
    tw.twist.linear.x, tw.twist.angular.z = 0.3, -0.2
    diag = DiagnosticArray(status=[
        DiagnosticStatus(level=b"\x02", name="sysid", message="drift", hardware_id="hw",
                         values=[KeyValue(key="k", value="v"), KeyValue(key="a", value="")]),
        DiagnosticStatus(name="x")])
    clock = Clock()
    clock.clock.sec = 12
    return [
        (JS, JointState()), (JS, JointState(name=["a"], position=[1.0])), (JS, full),
        (PS, PoseStamped()), (PS, pose),
        ("geometry_msgs/msg/TwistStamped", tw), ("geometry_msgs/msg/TwistStamped", TwistStamped()),
        ("diagnostic_msgs/msg/DiagnosticArray", DiagnosticArray()),
        ("diagnostic_msgs/msg/DiagnosticArray", diag),
        ("rosgraph_msgs/msg/Clock", clock), ("std_msgs/msg/String", String(data="héllo")),
        ("std_msgs/msg/String", String()),
    ]


def test_cdr_matches_rclpy_and_rosbags() -> None:
    from rclpy.serialization import deserialize_message, serialize_message
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    for type_name, msg in _ros_messages():
        ours = cdr._encode(type_name, msg)
        mine = bytes(ours.buf)
        theirs = serialize_message(msg)
        # rclpy leaves alignment padding uninitialised and may append trailing bytes:
        # compare everything else byte for byte
        assert len(theirs) >= len(mine), type_name
        pad = np.zeros(len(mine), bool)
        for a, b in ours.pads:
            pad[a:b] = True
        diff = np.frombuffer(mine, np.uint8) != np.frombuffer(theirs[:len(mine)], np.uint8)
        assert not np.any(diff & ~pad), (type_name, mine.hex(), theirs.hex())
        assert all(mine[a:b] == b"\x00" * (b - a) for a, b in ours.pads)
        # strict rosbags deserializer accepts ours and gives the same fields
        back = store.deserialize_cdr(mine, type_name)
        assert store.serialize_cdr(back, type_name) == mine
        # rclpy reads ours back to an equal message
        assert deserialize_message(mine, type(msg)) == msg, type_name
        # mcap_ros2 generic decoder
        dec = bags.decode_message(type_name, mine)
        if type_name == JS:
            assert list(dec.name) == list(msg.name)
            assert list(dec.position) == list(msg.position)


def test_cdr_roundtrip_rosbags_from_dicts() -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    for vel, eff in (((), ()), ((1.0, 2.0, 3.0), ()), ((), (4.0, 5.0, 6.0))):
        data = cdr.joint_state(1_700_000_000_123_456_789, ["a", "bb", "ccc"], [1.0, 2.0, 3.0],
                               vel, eff, frame_id="f")
        m = store.deserialize_cdr(data, JS)
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
        assert m.name == ["a", "bb", "ccc"] and list(m.velocity) == list(vel)
        assert list(m.effort) == list(eff) and m.header.frame_id == "f"
        assert cdr.parse_joint_state(data) == (1_700_000_000, 123_456_789, ("a", "bb", "ccc"),
                                               (1.0, 2.0, 3.0), vel, eff)
    data = cdr.pose_stamped(5, (1.0, 2.0, 3.0), (0.0, 0.0, 0.6, 0.8))
    m = store.deserialize_cdr(data, PS)
    assert m.pose.orientation.z == 0.6 and m.header.frame_id == "world"
    assert cdr.parse_pose_stamped(data) == (0, 5, "world", (1.0, 2.0, 3.0, 0.0, 0.0, 0.6, 0.8))


def test_cdr_unknown_type() -> None:
    with pytest.raises(SudsBagError, match=r"no CDR encoder for 'foo/msg/Bar'"):
        cdr.serialize("foo/msg/Bar", {})


def test_fast_parsers_read_big_endian() -> None:
    be = (b"\x00\x00\x00\x00" + (3).to_bytes(4, "big") + (7).to_bytes(4, "big")
          + (1).to_bytes(4, "big") + b"\x00\x00\x00\x00"
          + (1).to_bytes(4, "big") + (2).to_bytes(4, "big") + b"a\x00\x00\x00"
          + (1).to_bytes(4, "big") + np.array([2.5], ">f8").tobytes()
          + (0).to_bytes(4, "big") + (0).to_bytes(4, "big"))
    assert cdr.parse_joint_state(be) == (3, 7, ("a",), (2.5,), (), ())


# --------------------------------------------------------------------------- shared bags
@pytest.mark.parametrize("name", BAGS)
def test_read_shared_bags(name: str) -> None:
    path = shared(name)
    t0 = time.perf_counter()
    rec = bags.read_recording(path)
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


def test_shared_bag_info_and_raw() -> None:
    path = shared("purcell3_nominal")
    info = bags.bag_info(path)
    assert info["topics"]["/suds/shape"] == {"type": JS, "count": 6000,
                                             "message_encoding": "cdr"}
    assert info["topics"]["/suds/body_pose"]["count"] == 6000
    assert info["compression"] == ["zstd"] and info["has_summary"] and not info["truncated"]
    assert info["duration_s"] == pytest.approx(59.99)
    assert bags.read_metadata(path)["suds"]["system"] == "purcell3"
    msgs = list(bags.iter_raw_messages(path, ["/suds/body_pose"]))
    assert len(msgs) == 6000 and {m.type_name for m in msgs} == {PS}
    assert all(a.log_time_ns <= b.log_time_ns for a, b in zip(msgs, msgs[1:]))
    m = bags.decode_message(PS, msgs[0].data)
    assert m.header.frame_id == "world" and m.header.stamp.sec == 1_700_000_000


def test_shared_bag_rewrite_equal(tmp_path: Path) -> None:
    rec = bags.read_recording(shared("swimmer9_nominal"))
    out = tmp_path / "copy.mcap"
    bags.write_recording(out, rec)
    assert_rec_equal(bags.read_recording(out), rec)


# --------------------------------------------------------------------------- roundtrip
@pytest.mark.parametrize("effort", [False, True])
@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_roundtrip(tmp_path: Path, effort: bool, compression: str) -> None:
    rec = make_rec(effort=effort)
    path = tmp_path / "rec.mcap"
    bags.write_recording(path, rec, compression=compression)
    back = bags.read_recording(path)
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
    info = bags.bag_info(path)
    assert info["compression"] == [compression] and info["has_summary"]
    assert info["metadata"]["suds"] == {"system": "swimmer4", "actuated": "joint_1",
                                        "passive": "joint_2,joint_3", "gait_hz": "1.5"}


def test_roundtrip_unaligned_streams_and_truth_not_written(tmp_path: Path) -> None:
    rec = make_rec(n=30, pose_t=1.7e9 + 0.005 + 0.02 * np.arange(20),
                   pose=np.zeros((20, 3)), truth={"xi": np.zeros((30, 3))})
    path = tmp_path / "rec.mcap"
    bags.write_recording(path, rec)
    back = bags.read_recording(path)
    back_pose = back.pose
    np.testing.assert_allclose(back_pose, rec.pose, atol=1e-12)
    assert back.truth == {}
    np.testing.assert_array_equal(back.pose_t, rec.pose_t)
    np.testing.assert_array_equal(back.r, rec.r)
    logs = [m.log_time_ns for m in bags.iter_raw_messages(path)]
    assert logs == sorted(logs)


def test_our_files_open_with_rosbags(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    rec = make_rec(effort=True)
    path = tmp_path / "rec.mcap"
    bags.write_recording(path, rec)
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


# --------------------------------------------------------------------------- robustness
def test_truncated_copies_read_up_to_last_complete_record(tmp_path: Path) -> None:
    rec = make_rec(n=400)
    full = tmp_path / "full.mcap"
    with bags.BagWriter(full, chunk_size=2048) as w:
        w.add_topic("/suds/shape", JS)
        w.add_topic("/suds/body_pose", PS)
        w.write_metadata("suds", {"system": "s", "actuated": "joint_1"})
        for k in range(rec.n_samples):
            ns = cdr.ns_from_seconds(rec.t[k])
            w.write_raw("/suds/shape", cdr.joint_state(ns, rec.joint_names, rec.r[k]), ns)
            w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (k, 0, 0), (0, 0, 0, 1)), ns)
    data = full.read_bytes()
    footer = len(data) - 8 - 29
    summary_start = int.from_bytes(data[footer + 9:footer + 17], "little")
    seen = []
    for frac in (0.3, 0.55, 0.8, 0.97):
        cut = tmp_path / f"cut{frac}.mcap"
        cut.write_bytes(data[: int(summary_start * frac)])
        info = bags.bag_info(cut)
        assert info["truncated"]
        back = bags.read_recording(cut)
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
    assert bags.read_recording(cut).n_samples == rec.n_samples


def test_flush_makes_complete_records(tmp_path: Path) -> None:
    path = tmp_path / "live.mcap"
    w = bags.BagWriter(path)
    w.add_topic("/suds/shape", JS)
    w.add_topic("/suds/body_pose", PS)
    for ns in STAMPS[:5]:
        w.write_raw("/suds/shape", js(ns), ns)
        w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (0, 0, 0), (0, 0, 0, 1)), ns)
    w.flush()
    assert len(list(bags.iter_raw_messages(path))) == 10  # file still open, no summary
    w.close()
    w.close()
    with pytest.raises(SudsBagError, match="closed"):
        w.write_raw("/suds/shape", js(1), 1)
    assert bags.bag_info(path)["has_summary"]


@pytest.mark.parametrize("compression", [CompressionType.LZ4, CompressionType.NONE,
                                         CompressionType.ZSTD])
@pytest.mark.parametrize("summary", [True, False])
def test_foreign_layouts(tmp_path: Path, compression: CompressionType, summary: bool) -> None:
    path = tmp_path / "foreign.mcap"
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, compression=compression,
            summary=summary, meta=META)
    rec = bags.read_recording(path)
    assert rec.n_samples == 20 and rec.system == "purcell3"
    np.testing.assert_allclose(rec.pose[:, 0], 0.1 * np.arange(20))
    assert bags.bag_info(path)["has_summary"] is summary


def test_unchunked_file(tmp_path: Path) -> None:
    path = tmp_path / "plain.mcap"
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, chunked=False, meta=META)
    assert bags.read_recording(path).n_samples == 20
    assert bags.bag_info(path)["compression"] == []


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
        bags.read_recording(path)
    assert str(path) in str(info.value)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(SudsBagError, match=r"nope\.mcap: no such file"):
        bags.read_recording(tmp_path / "nope.mcap")


def test_missing_topic(tmp_path: Path) -> None:
    path = tmp_path / "rec.mcap"
    bags.write_recording(path, make_rec())
    with pytest.raises(SudsBagError,
                       match=r"topic '/robot/joints' is not in the bag; topics present: "
                             r"/suds/body_pose, /suds/shape"):
        bags.read_recording(path, shape_topic="/robot/joints")
    with pytest.raises(SudsBagError, match=r"topic '/suds/shape' has type sensor_msgs/msg/Joint"
                                           r"State, expected geometry_msgs/msg/PoseStamped"):
        bags.read_recording(path, pose_topic="/suds/shape")


def test_refuses_to_overwrite(tmp_path: Path) -> None:
    path = tmp_path / "rec.mcap"
    path.write_bytes(b"precious")
    with pytest.raises(SudsBagError, match=r"rec\.mcap: file exists; refusing to overwrite"):
        bags.write_recording(path, make_rec())
    assert path.read_bytes() == b"precious"
    bags.write_recording(path, make_rec(), overwrite=True)
    assert bags.read_recording(path).n_samples == 50


def test_writer_argument_errors(tmp_path: Path) -> None:
    with pytest.raises(SudsBagError, match=r"compression: expected one of .*got 'gzip'"):
        bags.BagWriter(tmp_path / "a.mcap", compression="gzip")
    with bags.BagWriter(tmp_path / "b.mcap") as w:
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
        w.write_raw("/x", cdr.serialize("std_msgs/msg/String", {"data": "hi"}), 5)
    from mcap.reader import make_reader

    with open(tmp_path / "b.mcap", "rb") as f:
        ch = next(iter(make_reader(f).get_summary().channels.values()))
    assert ch.metadata == {"offered_qos_profiles": "- depth: 1",
                           "topic_type_hash": msgdefs.type_hash("std_msgs/msg/String")}
    [m] = bags.iter_raw_messages(tmp_path / "b.mcap")
    assert bags.decode_message(m.type_name, m.data).data == "hi"


def test_decode_message_errors() -> None:
    with pytest.raises(SudsBagError, match=r"cannot decode 'sensor_msgs/msg/JointState'"):
        bags.decode_message(JS, b"\x00\x01\x00\x00\x01")


# --------------------------------------------------------------------------- data errors
def test_joint_count_change(tmp_path: Path) -> None:
    msgs = [js(ns) for ns in STAMPS]
    msgs[7] = js(STAMPS[7], names=("joint_1", "joint_2", "joint_3"), pos=(1, 2, 3))
    path = tmp_path / "bad.mcap"
    raw_bag(path, msgs, STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"/suds/shape: sample 7 "
                                            r"\(stamp 1700000000\.070000000 s\)"
                                            r".*'joint_3'\], but sample 0 has"):
        bags.read_recording(path)


def test_joint_order_change_and_bad_lengths(tmp_path: Path) -> None:
    msgs = [js(ns) for ns in STAMPS]
    msgs[3] = js(STAMPS[3], names=("joint_2", "joint_1"))
    path = tmp_path / "bad.mcap"
    raw_bag(path, msgs, STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"sample 3 .*\['joint_2', 'joint_1'\]"):
        bags.read_recording(path)
    msgs[3] = js(STAMPS[3], vel=(1.0,))
    raw_bag(path, msgs, STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"sample 3 .*velocity has 1 values for 2 joints"):
        bags.read_recording(path)


def test_effort_only_if_in_all_samples(tmp_path: Path) -> None:
    msgs = [js(ns, eff=(1.0, 2.0)) for ns in STAMPS]
    path = tmp_path / "e.mcap"
    raw_bag(path, msgs, STAMPS, meta=META)
    assert bags.read_recording(path).effort.shape == (20, 2)
    msgs[5] = js(STAMPS[5])
    raw_bag(path, msgs, STAMPS, meta=META)
    assert bags.read_recording(path).effort is None


def test_nan_sample(tmp_path: Path) -> None:
    msgs = [js(ns) for ns in STAMPS]
    msgs[4] = js(STAMPS[4], pos=(0.1, float("nan")))
    path = tmp_path / "nan.mcap"
    raw_bag(path, msgs, STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"/suds/shape: sample 4 .*NaN"):
        bags.read_recording(path)
    poses = [cdr.pose_stamped(ns, (0, 0, 0), (0, 0, 0, 1)) for ns in STAMPS]
    poses[2] = cdr.pose_stamped(STAMPS[2], (float("nan"), 0, 0), (0, 0, 0, 1))
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta=META, pose_msgs=poses)
    with pytest.raises(SudsDataError, match=r"/suds/body_pose: sample 2 .*NaN"):
        bags.read_recording(path)


def test_duplicate_and_unsorted_stamps(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    stamps = list(STAMPS)
    msgs = [js(ns) for ns in stamps]
    msgs[6] = js(stamps[5])
    raw_bag(path, msgs, stamps, meta=META)
    with pytest.raises(SudsDataError, match=r"/suds/shape: duplicate stamp "
                                            r"1700000000\.050000000 s at "
                                            r"samples 5 and 6"):
        bags.read_recording(path)
    msgs[6] = js(stamps[2])
    raw_bag(path, msgs, stamps, meta=META)
    with pytest.raises(SudsDataError, match=r"/suds/shape: stamps are not sorted: sample 6"):
        bags.read_recording(path)


def test_stamps_are_header_stamps_not_log_time(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    header = [ns - 3_000_000_000 for ns in STAMPS]  # stamped 3 s before logging
    poses = [cdr.pose_stamped(ns, (0, 0, 0), (0, 0, 0, 1)) for ns in header]
    raw_bag(path, [js(ns) for ns in header], STAMPS, meta=META, pose_msgs=poses)
    rec = bags.read_recording(path)
    assert rec.t[0] == pytest.approx(1_699_999_997.0, abs=1e-6)


def test_yaw_from_quaternion() -> None:
    yaw = np.array([0.3, -2.9, 3.1])
    q = np.column_stack([0 * yaw, 0 * yaw, np.sin(yaw / 2), np.cos(yaw / 2)]) * 2.0
    np.testing.assert_allclose(bags.quaternion_yaw(q), yaw)
    # roll about x then yaw: yaw is still recovered
    qx = np.array([np.sin(0.2), 0, 0, np.cos(0.2)])
    qz = np.array([0, 0, np.sin(0.35), np.cos(0.35)])
    x1, y1, z1, w1 = qz
    x2, y2, z2, w2 = qx
    qzx = np.array([w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                    w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2])
    assert bags.quaternion_yaw(qzx) == pytest.approx(0.7)
    assert np.isnan(bags.quaternion_yaw(np.zeros(4)))


# --------------------------------------------------------------------------- metadata
def test_metadata_override(tmp_path: Path) -> None:
    path = tmp_path / "m.mcap"
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta=META)
    rec = bags.read_recording(path, system="mine", actuated=["joint_2"])
    assert rec.system == "mine" and rec.actuated == ("joint_2",) and rec.passive == ("joint_1",)
    rec = bags.read_recording(path, passive=[])
    assert rec.actuated == ("joint_1", "joint_2") and rec.passive == ()
    assert rec.gait_hz == 1.0


def test_missing_metadata(tmp_path: Path) -> None:
    path = tmp_path / "m.mcap"
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta=None)
    with pytest.raises(SudsBagError, match=r"no 'system': the bag has no 'suds' metadata "
                                           r"record; pass --system"):
        bags.read_recording(path)
    with pytest.raises(SudsBagError, match=r"no 'actuated' joints: the bag has no 'suds' "
                                           r"metadata record; pass --actuated"):
        bags.read_recording(path, system="purcell3")
    rec = bags.read_recording(path, system="purcell3", passive=["joint_2"])
    assert rec.actuated == ("joint_1",) and rec.gait_hz is None
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta={"system": "x"})
    with pytest.raises(SudsBagError, match=r"record has neither 'actuated' nor 'passive'"):
        bags.read_recording(path)
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta={**META, "gait_hz": "fast"})
    with pytest.raises(SudsBagError, match=r"gait_hz: expected a number, got 'fast'"):
        bags.read_recording(path)
    raw_bag(path, [js(ns) for ns in STAMPS], STAMPS, meta=META)
    with pytest.raises(SudsDataError, match=r"joints \['joint_9'\] are not among"):
        bags.read_recording(path, actuated=["joint_9"])


def test_io_does_not_import_rclpy() -> None:
    import subprocess

    code = ("import sys, suds_ros.io.bags, suds_ros.io.cdr, suds_ros.io.msgdefs; "
            "sys.exit('rclpy' in sys.modules)")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    assert subprocess.run([sys.executable, "-c", code], env=env, check=False).returncode == 0


def test_cut_at_any_offset_reads_or_raises_bag_error(tmp_path: Path) -> None:
    path = tmp_path / "rec.mcap"
    rec = make_rec(n=200)
    with bags.BagWriter(path, compression="lz4", chunk_size=1500) as w:
        w.write_metadata("suds", {"system": "s", "actuated": "joint_1"})
        w.add_topic("/suds/shape", JS)
        w.add_topic("/suds/body_pose", PS)
        for k in range(rec.n_samples):
            ns = cdr.ns_from_seconds(rec.t[k])
            w.write_raw("/suds/shape", cdr.joint_state(ns, rec.joint_names, rec.r[k]), ns)
            w.write_raw("/suds/body_pose", cdr.pose_stamped(ns, (k, 0, 0), (0, 0, 0, 1)), ns)
    data = path.read_bytes()
    counts = []
    for cut_at in np.linspace(0, len(data), 60).astype(int):
        cut = tmp_path / "cut.mcap"
        cut.write_bytes(data[:cut_at])
        try:
            counts.append(bags.read_recording(cut).n_samples)
        except SudsBagError as exc:
            assert str(cut) in str(exc)
            assert any(w in str(exc) for w in ("empty", "truncated", "not in the bag",
                                               "no messages")), str(exc)
            counts.append(0)
    assert counts == sorted(counts) and counts[-1] == 200 and 0 < counts[30] < 200
