"""End to end: publisher / player → recorder → MCAP, each node in its own process."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import numpy as np
import pytest

from suds_ros.io.mcap import BagWriter, bag_info, iter_raw_messages
from suds_ros.io.recording_bag import read_recording

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import header_stamp, recorded_so_far, stop, wait_for
except ImportError:
    from _ros_helpers import header_stamp, recorded_so_far, stop, wait_for

pytestmark = pytest.mark.ros

PUBLISHER = Path(__file__).with_name("_publisher.py")
META = ("system:=purcell3", "actuated:=joint_1", "passive:=joint_2")


def record(start_process, node_command, out: Path, count: int, *params: str, hz: float = 100.0):
    """Start a recorder (flushing every 0.2 s) and the test publisher of ``count`` samples at ``hz`` (0: a burst)."""
    rec = start_process(node_command("recorder_node", f"output:={out}", "flush_period:=0.2", *META, *params),
                        "recorder")
    pub = start_process([sys.executable, PUBLISHER, str(count), str(hz), "--wait"], "publisher")
    return rec, pub


def wait_recorded(bag: Path, expected: dict[str, int], rec, timeout: float = 60.0) -> None:
    """Wait until the recorder has flushed at least ``expected`` messages per topic into ``bag``."""
    def done() -> bool:
        counts = recorded_so_far(bag)[0]
        return all(counts[t] >= n for t, n in expected.items())

    wait_for(done, timeout, lambda: f"{expected} in {bag}; got {dict(recorded_so_far(bag)[0])}\n{rec.output()}",
             interval=0.2)


def test_record_then_read_with_suds_and_rosbags(start_process, node_command, tmp_path):
    out = tmp_path / "run.mcap"
    rec, pub = record(start_process, node_command, out, 40)
    assert pub.wait(60) == 0, pub.output()
    wait_recorded(out, {"/suds/shape": 40, "/suds/body_pose": 40}, rec)
    assert stop(rec) == 0, rec.output()

    info = bag_info(out)
    assert info.has_summary and not info.truncated
    assert {t: v.count for t, v in info.topics.items()} == {
        "/suds/shape": 40, "/suds/body_pose": 40}
    assert info.metadata["suds"] == {
        "system": "purcell3", "actuated": "joint_1", "passive": "joint_2"}
    rec_ = read_recording(out)
    i = np.arange(40)
    np.testing.assert_allclose(rec_.t, 1.7e9 + i / 100.0)
    np.testing.assert_allclose(rec_.r, np.stack([np.sin(i / 10), np.cos(i / 10)], axis=1))
    np.testing.assert_allclose(rec_.pose, np.stack([i / 1000, -i / 1000, i / 100], axis=1),
                               atol=1e-12)

    # the strict rosbags MCAP reader: schemas, QoS metadata and CDR must all parse
    from rosbags.rosbag2.storage_mcap import McapReader
    from rosbags.typesys import Stores, get_typestore

    from suds_ros.ros.conversions import joint_state_from_msg, pose_from_msg

    store = get_typestore(Stores.ROS2_JAZZY)
    reader = McapReader(out)
    reader.open()
    try:
        conns = {c.topic: c for c in reader.connections}
        assert conns["/suds/shape"].msgtype == "sensor_msgs/msg/JointState"
        qos = {t: c.ext.offered_qos_profiles for t, c in conns.items()}
        assert qos["/suds/shape"][0].reliability.name.lower() == "best_effort"
        assert qos["/suds/body_pose"][0].reliability.name.lower() == "reliable"
        shapes, poses = [], []
        for conn, _, data in reader.messages(reader.connections):
            msg = store.deserialize_cdr(data, conn.msgtype)
            (shapes if conn.topic == "/suds/shape" else poses).append(msg)
    finally:
        reader.close()
    assert len(shapes) == len(poses) == 40
    assert joint_state_from_msg(shapes[5]).names == ("joint_1", "joint_2")
    assert pose_from_msg(poses[7]).yaw == pytest.approx(0.07)


def test_recorder_keeps_every_message_of_a_burst(start_process, node_command, tmp_path):
    """20000 reliable poses published at once (like the estimator's initial measured velocities).

    A subscription keeping the last 1000 lost most of them; the recorder keeps all, and its
    SIGINT, sent the moment the publisher has them all acknowledged (so they are in the
    recorder's queues, most not yet written), writes the backlog before closing the bag.
    """
    out, n = tmp_path / "burst.mcap", 20000
    rec, pub = record(start_process, node_command, out, n, "drain_timeout:=30.0", hz=0)
    assert pub.wait(180) == 0, pub.output()  # exits once every pose is acknowledged
    assert stop(rec, timeout=60) == 0, rec.output()
    stamps = [header_stamp(m) for m in iter_raw_messages(out, topics=["/suds/body_pose"])]
    np.testing.assert_allclose(stamps, 1.7e9 + np.arange(n) / 100.0)  # each pose once, none missing
    assert bag_info(out).has_summary


def test_sigkilled_recorder_leaves_readable_file(start_process, node_command, tmp_path):
    out = tmp_path / "killed.mcap"
    rec, pub = record(start_process, node_command, out, 0)
    wait_recorded(out, {"/suds/shape": 20}, rec)  # flushed data in the file
    before = recorded_so_far(out)[0]["/suds/shape"]
    rec.send_signal(signal.SIGKILL)
    assert rec.wait(10) == -signal.SIGKILL

    info = bag_info(out)
    assert not info.has_summary
    shapes = [m for m in iter_raw_messages(out) if m.topic == "/suds/shape"]
    assert len(shapes) >= before >= 20, info  # what was flushed before the kill is still there
    rec_ = read_recording(out)  # metadata written at start, data up to the last flush
    assert rec_.n_samples == len(shapes)
    assert np.all(np.diff(rec_.t) > 0)


def test_recorder_refuses_to_overwrite(start_process, node_command, tmp_path):
    out = tmp_path / "exists.mcap"
    out.write_bytes(b"precious")
    rec = start_process(node_command("recorder_node", f"output:={out}"), "recorder")
    assert rec.wait(30) == 1
    assert "refusing to overwrite" in rec.output()
    assert out.read_bytes() == b"precious"


def test_recorder_without_output_stops_with_reason(start_process, node_command):
    rec = start_process(node_command("recorder_node"), "recorder")
    assert rec.wait(30) == 1
    assert "`output`" in rec.output()


def _make_bag(path: Path, n: int = 30) -> list[bytes]:
    from rclpy.serialization import serialize_message

    from suds_ros.ros.conversions import joint_state_to_msg, pose_to_msg

    datas = []
    with BagWriter(path) as w:
        w.add_topic("/suds/shape", "sensor_msgs/msg/JointState")
        w.add_topic("/suds/body_pose", "geometry_msgs/msg/PoseStamped")
        w.write_metadata("suds", {"system": "purcell3", "actuated": "joint_1", "passive": "joint_2"})
        for i in range(n):
            t = 1.7e9 + i * 0.02
            data = serialize_message(joint_state_to_msg(t, ["joint_1", "joint_2"], [i, -i]))
            datas.append(data)
            w.write_raw("/suds/shape", data, 10**18 + i * 20_000_000)
            w.write_raw("/suds/body_pose", serialize_message(pose_to_msg(t, i, 0.0, 0.0)),
                        10**18 + i * 20_000_000 + 1)
    return datas


def test_player_replays_bytes_with_timing(start_process, node_command, tmp_path):
    src, out = tmp_path / "src.mcap", tmp_path / "replayed.mcap"
    datas = _make_bag(src)
    rec = start_process(node_command("recorder_node", f"output:={out}", "topics:=['/suds/shape']",
                                     "flush_period:=0.2"), "recorder")
    wait_for(lambda: "recording [" in rec.output(), 30, "the recorder to start")
    player = start_process(node_command("player_node", f"bag:={src}", "rate:=2.0", "delay:=0.5", "wait_subscribers:=1",
                                        "topics:=['/suds/shape']", "start_offset:=0.1"), "player")
    assert player.wait(60) == 0, player.output()
    wait_recorded(out, {"/suds/shape": len(datas) - 5}, rec)
    assert stop(rec, signal.SIGTERM) == 0, rec.output()

    got = list(iter_raw_messages(out))
    assert bag_info(out).has_summary
    assert [m.data for m in got] == datas[5:]  # start_offset 0.1 s skips 5 samples at 50 Hz
    assert {m.topic for m in got} == {"/suds/shape"}
    span = (got[-1].log_time_ns - got[0].log_time_ns) * 1e-9
    assert span == pytest.approx(24 * 0.02 / 2.0, abs=0.1)  # rate 2: twice as fast


@pytest.mark.parametrize(
    ("params", "reason"),
    [(("rate:=0.0",), "rate"), (("topics:=['/nope']",), "/nope"), ((), "`bag`")],
)
def test_player_rejects_bad_parameters(start_process, node_command, tmp_path, params, reason):
    src = tmp_path / "src.mcap"
    _make_bag(src, 3)
    bag = () if reason == "`bag`" else (f"bag:={src}",)
    player = start_process(node_command("player_node", *bag, *params), "player")
    assert player.wait(30) == 1, player.output()
    assert reason in player.output()
