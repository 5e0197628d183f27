"""suds_ros.io.cdr: the CDR encoder and the fast decoders, against rclpy and rosbags."""

from __future__ import annotations

import numpy as np
import pytest
from _bags import JS, PS

from suds_ros.core.errors import SudsBagError
from suds_ros.io import cdr
from suds_ros.io.mcap import decode_message


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
        dec = decode_message(type_name, mine)
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
