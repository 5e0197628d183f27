"""Tiny publisher used by the recorder tests (run as a separate process).

``python _publisher.py COUNT HZ [--wait]``: publishes COUNT JointState samples
on /suds/shape (sensor-data QoS) and COUNT PoseStamped on /suds/body_pose
(reliable) at HZ (0: all at once, a burst); stamps are 1.7e9 + i/100 s, joint_1 = sin(i/10),
joint_2 = cos(i/10), pose (i/1000, -i/1000, i/100).  COUNT 0 publishes until
interrupted.  With ``--wait`` it first waits (≤ 60 s) until both topics have a
subscriber.  Before exiting it waits (≤ 30 s) until every reliable sample is
acknowledged.  Prints ``publishing`` when it starts and ``published N`` at the end.

The recorder subscribes to a topic only once it has discovered its publisher,
so its reader has matched our writer when our writer counts it as matched:
no sample published after the wait can be lost to discovery, even on the
best-effort shape topic.
"""

import math
import sys
import time

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSProfile, ReliabilityPolicy

from _ros_helpers import wait_for  # this script's folder is sys.path[0]
from suds_ros.ros.conversions import joint_state_to_msg, pose_to_msg
from suds_ros.ros.qos import STATE_QOS


def pose_qos(count: int) -> QoSProfile:
    """Reliable, with a history deep enough that no unacknowledged pose is ever dropped."""
    return QoSProfile(depth=max(1000, count), reliability=ReliabilityPolicy.RELIABLE)


def main() -> int:
    count, hz = int(sys.argv[1]), float(sys.argv[2])
    rclpy.init()
    node = rclpy.create_node("test_publisher")
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState

    shape = node.create_publisher(JointState, "/suds/shape", STATE_QOS)
    pose = node.create_publisher(PoseStamped, "/suds/body_pose", pose_qos(count))
    i = 0
    try:
        if "--wait" in sys.argv:
            wait_for(lambda: shape.get_subscription_count() >= 1 and pose.get_subscription_count() >= 1,
                     60.0, "a subscriber on /suds/shape and /suds/body_pose")
        print("publishing", flush=True)
        while count == 0 or i < count:
            stamp = 1.7e9 + i / 100.0
            shape.publish(joint_state_to_msg(stamp, ["joint_1", "joint_2"],
                                             [math.sin(i / 10), math.cos(i / 10)]))
            pose.publish(pose_to_msg(stamp, i / 1000.0, -i / 1000.0, i / 100.0))
            i += 1
            if hz > 0:
                time.sleep(1.0 / hz)  # the publishing rate, not a wait for an event
        if not pose.wait_for_all_acked(Duration(seconds=30.0)):
            print("poses not acknowledged within 30 s", flush=True)
            return 3
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        print(f"published {i}", flush=True)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
