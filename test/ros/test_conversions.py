"""Roundtrips of every to_msg/from_msg pair, with rclpy messages and rosbags typestore messages."""

from __future__ import annotations

import math

import numpy as np
import pytest

from suds_ros.core.errors import BAD_QUATERNION, SudsDataError
from suds_ros.ros import conversions as cv

pytestmark = pytest.mark.ros

rosbags_typesys = pytest.importorskip("rosbags.typesys")
STORE = rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_JAZZY)
NAMES = ["joint_1", "joint_2", "joint_3"]


@pytest.fixture(params=["rclpy", "typestore", "cdr"])
def build(request):
    """Build with rclpy classes, with typestore classes, or typestore → CDR (rosbags) → rclpy."""
    if request.param == "rclpy":
        return lambda fn, *a, **k: fn(*a, **k)
    if request.param == "typestore":
        return lambda fn, *a, **k: fn(*a, typestore=STORE, **k)

    from rclpy.serialization import deserialize_message

    def via_cdr(fn, *a, **k):
        msg = fn(*a, typestore=STORE, **k)
        data = STORE.serialize_cdr(msg, msg.__msgtype__)
        return deserialize_message(bytes(data), cv.message_class(msg.__msgtype__))
    return via_cdr


@pytest.mark.parametrize("stamp", [0.0, 1.5, 1.7e9 + 0.123456789, 1712345678.000000001, -2.25])
def test_float_stamp_roundtrip_is_exact(stamp):
    t = cv.float_to_time(stamp)
    assert 0 <= t.nanosec < 10**9
    assert cv.time_to_float(t) == stamp


@pytest.mark.parametrize("ns", [0, 1, 999_999_999, 1_700_000_000_123_456_789, -1, 2**31 * 10**9 - 1])
def test_ns_time_roundtrip_is_exact(ns):
    assert cv.time_to_ns(cv.ns_to_time(ns)) == ns
    assert cv.time_to_ns(cv.ns_to_time(ns, typestore=STORE)) == ns


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_stamp_raises(bad):
    with pytest.raises(SudsDataError, match="stamp"):
        cv.float_to_time(bad)


def test_out_of_range_stamp_raises():
    with pytest.raises(SudsDataError, match="int32"):
        cv.ns_to_time(2**31 * 10**9)


def test_joint_state_roundtrip(build):
    pos, vel, eff = np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, 3.0]), np.array([4.0, 5, 6])
    msg = build(cv.joint_state_to_msg, 1.7e9 + 0.01, NAMES, pos, vel, eff)
    s = cv.joint_state_from_msg(msg)
    assert s.stamp == 1.7e9 + 0.01 and s.names == tuple(NAMES)
    np.testing.assert_array_equal(s.position, pos)
    np.testing.assert_array_equal(s.velocity, vel)
    np.testing.assert_array_equal(s.effort, eff)


def test_joint_state_optional_fields_empty(build):
    s = cv.joint_state_from_msg(build(cv.joint_state_to_msg, 2.0, NAMES[:2], [0.5, 0.25]))
    assert s.velocity is None and s.effort is None
    np.testing.assert_array_equal(s.position, [0.5, 0.25])


def test_joint_velocity_roundtrip(build):
    msg = build(cv.joint_velocity_to_msg, 3.0, NAMES[1:], [0.7, -0.7])
    assert len(msg.position) == 0
    stamp, names, vel = cv.joint_velocity_from_msg(msg)
    assert (stamp, names) == (3.0, tuple(NAMES[1:]))
    np.testing.assert_array_equal(vel, [0.7, -0.7])


def test_joint_velocity_of_no_joint_roundtrip(build):
    """A fully actuated robot's passive predictions: an empty velocity-only JointState."""
    msg = build(cv.joint_velocity_to_msg, 3.0, (), np.empty(0))
    stamp, names, vel = cv.joint_velocity_from_msg(msg)
    assert (stamp, names, vel.shape) == (3.0, (), (0,))


@pytest.mark.parametrize("yaw", [0.0, 0.5, -3.0, math.pi - 1e-9])
def test_pose_roundtrip(build, yaw):
    p = cv.pose_from_msg(build(cv.pose_to_msg, 1.7e9, 1.25, -2.5, yaw))
    assert (p.stamp, p.x, p.y) == (1.7e9, 1.25, -2.5)
    assert p.yaw == pytest.approx(yaw, abs=1e-12)


def test_pose_frame_id(build):
    assert build(cv.pose_to_msg, 0.0, 0, 0, 0).header.frame_id == "world"


def test_twist_roundtrip(build):
    t = cv.twist_from_msg(build(cv.twist_to_msg, 5.5, 0.1, -0.2, 0.3))
    assert t == cv.BodyTwist(5.5, 0.1, -0.2, 0.3)


def test_prediction_messages_are_refilled_and_carry_an_input_stamp_exactly():
    # the predictor reuses its two output messages and stamps them with the shape message's own
    # Time: a float of a wall-clock stamp is only good to ~200 ns, the Time is copied to the ns
    stamp = cv.ns_to_time(1_795_000_000_123_456_789)
    assert cv.float_to_time(cv.time_to_float(stamp)).nanosec != stamp.nanosec  # why floats will not do
    twist = cv.twist_to_msg(stamp, 0.1, -0.2, 0.3, frame_id="base")
    again = cv.twist_to_msg(cv.ns_to_time(7), 1.0, 2.0, 3.0, frame_id="body", out=twist)
    assert again is twist
    assert cv.twist_from_msg(again) == cv.BodyTwist(7e-9, 1.0, 2.0, 3.0)
    assert again.header.frame_id == "body" and again.twist.linear.z == 0.0
    rates = cv.joint_velocity_to_msg(stamp, NAMES[:2], [0.5, -0.5])
    assert (rates.header.stamp.sec, rates.header.stamp.nanosec) == (stamp.sec, stamp.nanosec)
    again = cv.joint_velocity_to_msg(2.5, NAMES[1:], [1.0, 2.0], out=rates)
    assert again is rates
    t, names, vel = cv.joint_velocity_from_msg(again)
    assert (t, names, list(vel)) == (2.5, tuple(NAMES[1:]), [1.0, 2.0])
    with pytest.raises(SudsDataError, match="`wz`"):
        cv.twist_to_msg(0.0, 0.0, 0.0, math.nan, out=twist)
    with pytest.raises(SudsDataError, match="`velocity`"):
        cv.joint_velocity_to_msg(0.0, NAMES[1:], [1.0, math.inf], out=rates)


@pytest.mark.parametrize("level", [0, 1, 2, 3, "WARN"])
def test_diagnostics_roundtrip(build, level):
    values = {"r2": "0.98", "n_samples": "1200"}
    msg = build(cv.diagnostics_to_msg, 7.0, "suds/estimator", values, level=level,
                message="fit ok", hardware_id="sim")
    (rep,) = cv.diagnostics_from_msg(msg)
    assert rep == cv.DiagnosticReport(7.0, "suds/estimator", 1 if level == "WARN" else level,
                                      "fit ok", "sim", values)


def test_message_class_resolves_and_rejects():
    from sensor_msgs.msg import JointState

    assert cv.message_class("sensor_msgs/msg/JointState") is JointState
    with pytest.raises(SudsDataError, match="not installed"):
        cv.message_class("nope_msgs/msg/Nothing")
    with pytest.raises(SudsDataError, match="pkg/msg/Type"):
        cv.message_class("JointState")


# ------------------------------------------------------------------ malformed input
def test_joint_state_length_mismatch_raises():
    with pytest.raises(SudsDataError, match=r"`position`: expected 3 values .* got 2"):
        cv.joint_state_to_msg(0.0, NAMES, [1.0, 2.0])
    msg = cv.joint_state_to_msg(0.0, NAMES, [1.0, 2.0, 3.0])
    msg.position = [1.0, 2.0]
    with pytest.raises(SudsDataError, match=r"`position`: expected 3 values"):
        cv.joint_state_from_msg(msg)
    header = STORE.types["std_msgs/msg/Header"](
        stamp=STORE.types["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="")
    msg = STORE.types["sensor_msgs/msg/JointState"](
        header=header, name=NAMES,
        position=np.zeros(3), velocity=np.zeros(1), effort=np.zeros(0))
    with pytest.raises(SudsDataError, match=r"`velocity`: expected 3 values .* got 1"):
        cv.joint_state_from_msg(msg)


def test_nan_is_rejected():
    msg = cv.joint_state_to_msg(0.0, NAMES, [1.0, 2.0, 3.0])
    msg.position[1] = math.nan
    with pytest.raises(SudsDataError, match=r"`position`: value 1 is not finite"):
        cv.joint_state_from_msg(msg)
    with pytest.raises(SudsDataError, match="`yaw`"):
        cv.pose_to_msg(0.0, 0.0, 0.0, math.nan)
    msg = cv.twist_to_msg(0.0, 0.0, 0.0, 0.0)
    msg.twist.linear.x = math.inf
    with pytest.raises(SudsDataError, match="twist.linear.x"):
        cv.twist_from_msg(msg)


def test_missing_position_and_duplicate_names_raise():
    msg = cv.joint_velocity_to_msg(0.0, NAMES, [1.0, 2.0, 3.0])
    with pytest.raises(SudsDataError, match=r"`position`: expected 3 values .* got 0"):
        cv.joint_state_from_msg(msg)
    with pytest.raises(SudsDataError, match="not unique"):
        cv.joint_state_to_msg(0.0, ["a", "a"], [1.0, 2.0])
    with pytest.raises(SudsDataError, match=r"`velocity`: expected 2 values .* got 0"):
        cv.joint_velocity_from_msg(cv.joint_state_to_msg(0.0, ["a", "b"], [1.0, 2.0]))


def test_bad_quaternion_stamp_and_level_raise():
    msg = cv.pose_to_msg(0.0, 0.0, 0.0, 0.0)
    msg.pose.orientation.w = 0.0
    with pytest.raises(SudsDataError, match="expected a non-zero finite quaternion") as err:
        cv.pose_from_msg(msg)
    assert err.value.code == BAD_QUATERNION
    t = STORE.types["builtin_interfaces/msg/Time"](sec=1, nanosec=10**9)
    with pytest.raises(SudsDataError, match="nanosec"):
        cv.time_to_ns(t)
    with pytest.raises(SudsDataError, match="`level`"):
        cv.diagnostics_to_msg(0.0, "x", {}, level=7)
    with pytest.raises(SudsDataError, match="str keys and values"):
        cv.diagnostics_to_msg(0.0, "x", {"a": 1})  # type: ignore[dict-item]


def test_select_joints_by_name_ignores_extra_joints_and_order():
    import numpy as np
    import pytest as _pytest

    from suds_ros.core.errors import WRONG_JOINT_NAMES, SudsDataError
    from suds_ros.ros.conversions import JointSample, select_joints

    s = JointSample(1.0, ("gripper", "joint_2", "joint_1"), np.array([9.0, 2.0, 1.0]),
                    np.array([0.9, 0.2, 0.1]), None)
    got = select_joints(s, ("joint_1", "joint_2"))
    assert got.names == ("joint_1", "joint_2")
    assert got.position.tolist() == [1.0, 2.0] and got.velocity.tolist() == [0.1, 0.2]
    assert got.effort is None and got.stamp == 1.0
    assert select_joints(got, ("joint_1", "joint_2")) is got
    with _pytest.raises(SudsDataError, match=r"joint_3") as err:
        select_joints(s, ("joint_1", "joint_3"))
    assert err.value.code == WRONG_JOINT_NAMES


def test_model_of_a_fully_actuated_robot_roundtrips_as_strict_json(worm8_run):
    """suds/model of a robot with no passive joint: strict JSON (no NaN), every field back."""
    import json

    from suds_ros.core.ident.identify import split_cycles
    from suds_ros.core.ident.online import fit_streaming

    model = fit_streaming(split_cycles(worm8_run, 8)[0]).model()
    msg = cv.model_to_msg(model)
    d = json.loads(msg.data, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert d["passive"] == [] and d["channels"] == ["xi_x", "xi_y", "xi_theta"]
    back = cv.model_from_msg(msg)
    assert back.passive == () and back.channels == model.channels
    np.testing.assert_array_equal(back.coef, model.coef)


def test_gait_switch_roundtrips_to_the_nanosecond_and_refuses_other_text():
    from std_msgs.msg import String

    from suds_ros.core.errors import SudsConfigError
    from suds_ros.core.physics.gait import nominal_gait, same_gait
    from suds_ros.core.physics.systems import make_system

    gait = nominal_gait(make_system("purcell3"))
    stamp = 1_700_000_031.000_000_123
    t, back = cv.gait_switch_from_msg(cv.gait_switch_to_msg(stamp, gait))
    assert cv.float_to_time(t) == cv.float_to_time(stamp) and same_gait(back, gait)
    for text in ("not json", '{"stamp_ns": 1.5, "gait": ""}', '{"gait": "x"}', '[1, 2]'):
        with pytest.raises(SudsConfigError, match="suds/gait_switch") as exc:
            cv.gait_switch_from_msg(String(data=text))
        assert exc.value.code == "bad_gait_switch", text


def test_gait_trajectory_is_one_cycle_of_the_actuated_joints():
    from suds_ros.core.physics.gait import nominal_gait
    from suds_ros.core.physics.systems import make_system

    gait = nominal_gait(make_system("swimmer9"))  # several actuated joints
    msg = cv.gait_trajectory_msg(gait, 12.25, 8)
    t = np.arange(9) / (8 * gait.gait_hz)
    assert list(msg.joint_names) == list(gait.joints) and len(msg.points) == 9
    assert cv.time_to_float(msg.header.stamp) == 12.25
    np.testing.assert_allclose([p.positions for p in msg.points], gait.r(t), rtol=0, atol=1e-15)
    np.testing.assert_allclose([p.velocities for p in msg.points], gait.rdot(t), rtol=0, atol=1e-15)
    ends = [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in msg.points]
    np.testing.assert_allclose(ends, t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(msg.points[-1].positions, msg.points[0].positions, atol=1e-12)  # a closed cycle
