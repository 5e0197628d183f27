"""The estimator survives bad traffic: each bad sample is skipped, counted per reason, logged once.

Run as a script (``python test_bad_traffic.py``) this file is the publisher:
valid purcell3 samples at 200 Hz with, three times, one of each bad kind
(NaN shape, NaN pose, duplicate and out-of-order stamps on both streams,
wrong joint names, wrong joint count), then shapes only (the pose stream
stops) for 4 s.  It publishes once the estimator has subscribed (the
estimator subscribes only to discovered publishers, so both sides have
matched then) and, reliable with a history as deep as the whole run, loses
nothing to a slow subscriber; it exits once every sample is acknowledged.

The test listens to /suds/status itself and waits until the estimator has
counted every pose and every bad sample.
"""

from __future__ import annotations

import sys
import time

import pytest

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import stop, wait_for
except ImportError:  # also when run as a script: this file's folder is sys.path[0]
    from _ros_helpers import stop, wait_for

pytestmark = pytest.mark.ros

#: skip reason key -> how many the publisher sends
EXPECTED = {
    "shape.nan_or_inf": 3, "pose.nan_or_inf": 3,
    "shape.duplicate_stamp": 3, "shape.out_of_order_stamp": 3,
    "pose.duplicate_stamp": 3, "pose.out_of_order_stamp": 3,
    "shape.wrong_joint_names": 3, "shape.wrong_joint_count": 3,
}
GOOD, HZ, SHAPE_ONLY_S = 1000, 200.0, 4.0
N_SHAPE = int(GOOD + SHAPE_ONLY_S * HZ)  #: good shape samples (the last SHAPE_ONLY_S s without pose)


def publish() -> int:
    """The bad-traffic publisher (see module doc)."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.stream import StreamingSimulator
    from suds_ros.core.physics.systems import make_system
    from suds_ros.ros.conversions import float_to_time, joint_state_to_msg, pose_to_msg

    names = ("joint_1", "joint_2")
    qos = QoSProfile(depth=N_SHAPE + 100, reliability=ReliabilityPolicy.RELIABLE)
    rclpy.init()
    node = rclpy.create_node("bad_traffic")
    shape = node.create_publisher(JointState, "/suds/shape", qos)
    pose = node.create_publisher(PoseStamped, "/suds/body_pose", qos)
    wait_for(lambda: shape.get_subscription_count() >= 1 and pose.get_subscription_count() >= 1,
             60, "the estimator to subscribe to /suds/shape and /suds/body_pose")
    extra = StreamingSimulator(make_system("purcell3"), SimConfig(seed=2)).step(N_SHAPE)
    for i in range(N_SHAPE):
        t, r, p = float(extra.t[i]), extra.r[i], extra.pose[i]
        shape.publish(joint_state_to_msg(t, names, r))
        if i < GOOD:
            pose.publish(pose_to_msg(t, *p))
        if i in (200, 600, 800):
            nan_shape = joint_state_to_msg(t + 1e-3, names, r)
            nan_shape.position[0] = float("nan")
            shape.publish(nan_shape)
            nan_pose = pose_to_msg(t + 1e-3, *p)
            nan_pose.pose.position.x = float("nan")
            pose.publish(nan_pose)
            shape.publish(joint_state_to_msg(t, names, r))  # duplicate
            shape.publish(joint_state_to_msg(t - 0.05, names, r))  # out of order
            pose.publish(pose_to_msg(t, *p))  # duplicate
            pose.publish(pose_to_msg(t - 0.05, *p))  # out of order
            # a joint of the model missing (extra joints would be ignored: see test_real_robot.py)
            shape.publish(joint_state_to_msg(t + 2e-3, ("joint_1", "joint_3"), r))
            wrong = JointState(name=list(names), position=[*r, 0.0])  # 2 names, 3 positions
            wrong.header.stamp = float_to_time(t + 3e-3)
            shape.publish(wrong)
        time.sleep(1.0 / HZ)  # the publishing rate, not a wait for an event
    acked = all(p.wait_for_all_acked(Duration(seconds=30.0)) for p in (shape, pose))
    print(f"published {N_SHAPE} shapes" + ("" if acked else "; not all acknowledged within 30 s"), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0 if acked else 3


def test_estimator_survives_bad_traffic(start_process, node_command, probe):
    from diagnostic_msgs.msg import DiagnosticArray

    from suds_ros.ros.conversions import diagnostics_from_msg
    from suds_ros.ros.qos import STATUS_QOS

    status = probe.listen("/suds/status", DiagnosticArray, STATUS_QOS)
    est = start_process(node_command("estimator_node", "actuated:=['joint_1']", "pose_stall:=1.0",
                                     "max_pose_wait:=1.0"),
                        "estimator")
    wait_for(lambda: status.publishers() >= 1, 60, lambda: f"the estimator's /suds/status\n{est.output()}")
    pub = start_process([sys.executable, __file__], "publisher")
    assert pub.wait(120) == 0, pub.output()

    def reports() -> list:
        return [diagnostics_from_msg(m)[0] for m in status.messages()]

    def everything_counted() -> bool:
        """The last status counts every good shape and pose and every bad sample."""
        last = reports()[-1].values if len(status) else {}
        return (int(last.get("samples", 0)) >= N_SHAPE and int(last.get("poses", 0)) >= GOOD
                and int(last.get("skipped_total", 0)) >= sum(EXPECTED.values()))

    wait_for(everything_counted, 60, lambda: f"all traffic counted in /suds/status; "
             f"last {reports()[-1].values if len(status) else None}\n{est.output()}")
    assert est.poll() is None, est.output()  # still running
    assert stop(est) == 0, est.output()

    reports_ = reports()
    last = reports_[-1].values
    got = {k[len("skipped."):]: int(v) for k, v in last.items() if k.startswith("skipped.")}
    print(f"skipped per reason: {got}; samples {last['samples']}, poses {last['poses']}, "
          f"dropped_no_pose {last['dropped_no_pose']}")
    assert got == EXPECTED
    assert last["initialised"] == "true"
    assert int(last["samples"]) == N_SHAPE and int(last["poses"]) == GOOD
    log = est.output()
    for key in EXPECTED:
        assert log.count(f"[{key}]") == 1, f"{key} logged {log.count(f'[{key}]')} times\n{log}"
    assert "not finite" in log and "duplicate shape stamp" in log and "out-of-order pose stamp" in log
    stalled = [r for r in reports_ if r.level == 1 and "pose stream stalled since" in r.message]
    assert stalled, [(r.level, r.message) for r in reports_]
    assert log.count("pose stream stalled since") == 1
    assert int(last["dropped_no_pose"]) > 0  # shapes after the pose stream stopped cannot be paired


if __name__ == "__main__":
    sys.exit(publish())
