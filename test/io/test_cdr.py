"""suds_ros.io.cdr: encoding and decoding through rosbags, and the fast decoders, against rclpy."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from _bags import JS, PS

from suds_ros.core.errors import SudsBagError
from suds_ros.io import cdr, msgdefs
from suds_ros.io.mcap import decode_message


def _ros_messages() -> list[tuple[str, object]]:
    pytest.importorskip("rclpy.serialization", reason="rclpy not installed")
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    full = JointState(name=["joint_1", "j2"], position=[1.0, -2.5], velocity=[0.5, 0.25],
                      effort=[3.0, 4.0])
    full.header.stamp.sec, full.header.stamp.nanosec = 1_700_000_000, 990_000_000
    full.header.frame_id = "base"
    odd = JointState(name=["abc"], position=[0.125])  # 3-byte name: the doubles need padding
    odd.header.frame_id = "xy"
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
        (JS, JointState()), (JS, JointState(name=["a"], position=[1.0])), (JS, full), (JS, odd),
        (PS, PoseStamped()), (PS, pose),
        ("geometry_msgs/msg/TwistStamped", tw), ("geometry_msgs/msg/TwistStamped", TwistStamped()),
        ("diagnostic_msgs/msg/DiagnosticArray", DiagnosticArray()),
        ("diagnostic_msgs/msg/DiagnosticArray", diag),
        ("rosgraph_msgs/msg/Clock", clock), ("std_msgs/msg/String", String(data="héllo")),
        ("std_msgs/msg/String", String()),
    ]


def test_every_schema_type_is_covered() -> None:
    assert {t for t, _ in _ros_messages()} == set(msgdefs.known_types())


def test_encode_matches_rclpy_byte_for_byte() -> None:
    """What rosbag2 records is rclpy's serialization; ours equals it except in padding."""
    from rclpy.serialization import deserialize_message, serialize_message

    for type_name, msg in _ros_messages():
        mine = cdr.encode(type_name, msg)
        theirs = serialize_message(msg)
        # rclpy leaves alignment padding uninitialised and may append trailing padding:
        # every byte where the two differ must be padding, which we write as zero
        assert len(theirs) >= len(mine), type_name
        a = np.frombuffer(mine, np.uint8)
        b = np.frombuffer(theirs[:len(mine)], np.uint8)
        assert np.all(a[a != b] == 0), (type_name, mine.hex(), theirs.hex())
        # rclpy's bytes decode (through rosbags) and re-encode to exactly ours
        assert cdr.encode(type_name, cdr.decode(type_name, theirs)) == mine, type_name
        # and rclpy reads ours back to an equal message
        assert deserialize_message(mine, type(msg)) == msg, type_name


def test_encode_is_rosbags_and_mcap_ros2_reads_it() -> None:
    from mcap.records import Schema
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.typesys import Stores, get_typestore

    jazzy = get_typestore(Stores.ROS2_JAZZY)  # rosbags' own Jazzy definitions, not ours
    for type_name, msg in _ros_messages():
        mine = cdr.encode(type_name, msg)
        assert bytes(jazzy.serialize_cdr(jazzy.deserialize_cdr(mine, type_name), type_name)) == mine
        text = msgdefs.schema_text(type_name).encode()
        dec = DecoderFactory().decoder_for("cdr", Schema(1, text, "ros2msg", type_name))
        other = dec(mine)  # a second, independent decoder
        if type_name == JS:
            assert list(other.name) == list(msg.name)
            assert list(other.position) == list(msg.position)
            assert list(other.effort) == list(msg.effort)


def test_encode_from_mappings_with_ros_defaults() -> None:
    data = cdr.encode(PS, {"header": {"frame_id": "f"}, "pose": {"position": {"x": 2.0}}})
    m = cdr.decode(PS, data)
    assert m.header.frame_id == "f" and m.header.stamp.sec == 0
    assert (m.pose.position.x, m.pose.position.y) == (2.0, 0.0)
    assert (m.pose.orientation.z, m.pose.orientation.w) == (0.0, 1.0)  # identity quaternion
    diag = cdr.decode("diagnostic_msgs/msg/DiagnosticArray", cdr.encode(
        "diagnostic_msgs/msg/DiagnosticArray",
        {"status": [{"level": b"\x01", "name": "n", "values": [{"key": "k", "value": "v"}]}]}))
    [s] = diag.status
    assert (s.level, s.name, s.message, s.values[0].key, s.values[0].value) == (1, "n", "", "k", "v")


def test_joint_state_and_pose_helpers_round_trip() -> None:
    for vel, eff in (((), ()), ((1.0, 2.0, 3.0), ()), ((), (4.0, 5.0, 6.0))):
        data = cdr.joint_state(1_700_000_000_123_456_789, ["a", "bb", "ccc"], [1.0, 2.0, 3.0],
                               vel, eff, frame_id="f")
        m = cdr.decode(JS, data)
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
        assert m.name == ["a", "bb", "ccc"] and list(m.velocity) == list(vel)
        assert list(m.effort) == list(eff) and m.header.frame_id == "f"
        assert cdr.parse_joint_state(data) == (1_700_000_000, 123_456_789, ("a", "bb", "ccc"),
                                               (1.0, 2.0, 3.0), vel, eff)
        assert data == cdr.encode(JS, m)
    data = cdr.pose_stamped(5, (1.0, 2.0, 3.0), (0.0, 0.0, 0.6, 0.8))
    m = cdr.decode(PS, data)
    assert m.pose.orientation.z == 0.6 and m.header.frame_id == "world"
    assert cdr.parse_pose_stamped(data) == (0, 5, "world", (1.0, 2.0, 3.0, 0.0, 0.0, 0.6, 0.8))


def test_strided_arrays_encode() -> None:
    """A row of a Fortran-ordered or column-picked array is not contiguous; it still encodes."""
    r = np.asfortranarray(np.arange(12.0).reshape(4, 3))[:, [1, 0, 2]]
    assert not r[2].flags.c_contiguous
    data = cdr.joint_state(7, ["a", "b", "c"], r[2], (), r[1, ::-1])
    assert cdr.parse_joint_state(data)[3:] == ((7.0, 6.0, 8.0), (), (5.0, 3.0, 4.0))
    m = cdr.decode(JS, cdr.encode(JS, {"name": ["a", "b"], "position": r[::2, 0]}))
    assert list(m.position) == [1.0, 7.0]
    assert cdr.joint_state(7, ["a"], [1.0], None, None) == cdr.joint_state(7, ["a"], [1.0])


def test_fast_decoders_agree_with_rosbags_on_random_messages() -> None:
    rng = np.random.default_rng(3)
    for _ in range(200):
        nj = int(rng.integers(0, 10))
        names = ["j" * int(rng.integers(1, 9)) + str(k) for k in range(nj)]
        vel = rng.normal(size=nj) if rng.random() < 0.5 else ()
        data = cdr.joint_state(int(rng.integers(0, 2**60)), names, rng.normal(size=nj), vel,
                               rng.normal(size=nj), frame_id="f" * int(rng.integers(0, 6)))
        m = cdr.decode(JS, data)
        s, ns, got_names, p, v, e = cdr.parse_joint_state(data)
        assert (s, ns, got_names) == (m.header.stamp.sec, m.header.stamp.nanosec, tuple(m.name))
        for fast, slow in ((p, m.position), (v, m.velocity), (e, m.effort)):
            np.testing.assert_array_equal(fast, slow)
        pose = cdr.pose_stamped(int(rng.integers(0, 2**60)), rng.normal(size=3), rng.normal(size=4),
                                frame_id="w" * int(rng.integers(0, 9)))
        mp = cdr.decode(PS, pose)
        q, o = mp.pose.position, mp.pose.orientation
        assert cdr.parse_pose_stamped(pose) == (mp.header.stamp.sec, mp.header.stamp.nanosec,
                                                mp.header.frame_id, (q.x, q.y, q.z, o.x, o.y, o.z, o.w))


def test_unknown_type_and_bad_data() -> None:
    with pytest.raises(SudsBagError, match=r"message type 'foo/msg/Bar' has no schema"):
        cdr.encode("foo/msg/Bar", {})
    with pytest.raises(SudsBagError, match=r"message type 'foo/msg/Bar' has no schema"):
        cdr.decode("foo/msg/Bar", b"\x00\x01\x00\x00")
    with pytest.raises(SudsBagError, match=r"cannot encode a 'sensor_msgs/msg/JointState' message"):
        cdr.encode(JS, {"position": ["not a number"]})
    with pytest.raises(SudsBagError, match=r"cannot decode 'sensor_msgs/msg/JointState' message \(5 bytes\)"):
        decode_message(JS, b"\x00\x01\x00\x00\x01")
    with pytest.raises(ValueError, match="not a plain CDR message"):
        cdr.parse_joint_state(b"\x07\x07\x00\x00" + bytes(40))


def test_decode_with_a_foreign_schema_text() -> None:
    """A bag's own definition (here: a String with an extra field) is used when given."""
    schema = b"string data\nint32 count\n"
    data = b"\x00\x01\x00\x00" + (3).to_bytes(4, "little") + b"hi\x00\x00" + (7).to_bytes(4, "little")
    m = cdr.decode("std_msgs/msg/String", data, schema)
    assert (m.data, m.count) == ("hi", 7)
    with pytest.raises(SudsBagError, match=r"cannot parse the bag's ros2msg schema"):
        cdr.decode("std_msgs/msg/String", data, b"string data=\n")


def test_fast_parsers_read_big_endian() -> None:
    be = (b"\x00\x00\x00\x00" + (3).to_bytes(4, "big") + (7).to_bytes(4, "big")
          + (1).to_bytes(4, "big") + b"\x00\x00\x00\x00"
          + (1).to_bytes(4, "big") + (2).to_bytes(4, "big") + b"a\x00\x00\x00"
          + (1).to_bytes(4, "big") + np.array([2.5], ">f8").tobytes()
          + (0).to_bytes(4, "big") + (0).to_bytes(4, "big"))
    assert cdr.parse_joint_state(be) == (3, 7, ("a",), (2.5,), (), ())
    m = cdr.decode(JS, be)  # rosbags reads big-endian CDR too
    assert (m.header.stamp.sec, m.name, list(m.position)) == (3, ["a"], [2.5])


def test_joint_state_parser_equals_parse_joint_state_as_names_and_frames_change() -> None:
    """The cached-names parser gives parse_joint_state's result for every message of a stream."""
    msgs = [cdr.joint_state(k, names, np.arange(len(names)) + k, (), eff, frame_id=frame)
            for k, (names, eff, frame) in enumerate([
                (["a", "bb"], (), ""), (["a", "bb"], (), ""), (["a", "bb"], (1.0, 2.0), ""),
                (["a", "bc"], (), ""), (["a", "bc"], (), "f"), (["a", "bc", "d"], (), "f"),
                (["a", "bc", "d"], (), "f")])]
    msgs.append(cdr.joint_state(9, ["a"], [1.0], frame_id="f")[:1] + b"\x00" + msgs[-1][2:])  # big endian tag
    parse = cdr.JointStateParser()
    for data in msgs:
        try:
            want = cdr.parse_joint_state(data)
        except (ValueError, struct.error) as exc:
            with pytest.raises(type(exc)):
                parse(data)
            continue
        assert parse(data) == want
        assert parse(memoryview(data)) == want
