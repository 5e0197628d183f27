"""Tiny publisher used by the recorder tests (run as a separate process).

``python _publisher.py COUNT HZ [--wait]``: publishes COUNT JointState samples
on /suds/shape (sensor-data QoS) and COUNT PoseStamped on /suds/body_pose
(reliable) at HZ; stamps are 1.7e9 + i/100 s, joint_1 = sin(i/10),
joint_2 = cos(i/10), pose (i/1000, -i/1000, i/100).  COUNT 0 publishes until
interrupted.  With ``--wait`` it first waits (≤ 20 s) until both topics have a
subscriber.  Prints ``published N`` at the end.
"""

import math
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException

from suds_ros.ros.conversions import joint_state_to_msg, pose_to_msg
from suds_ros.ros.qos import ESTIMATE_QOS, STATE_QOS


def main() -> int:
    count, hz = int(sys.argv[1]), float(sys.argv[2])
    rclpy.init()
    node = rclpy.create_node("test_publisher")
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState

    shape = node.create_publisher(JointState, "/suds/shape", STATE_QOS)
    pose = node.create_publisher(PoseStamped, "/suds/body_pose", ESTIMATE_QOS)
    i = 0
    try:
        if "--wait" in sys.argv:
            deadline = time.monotonic() + 20.0
            while shape.get_subscription_count() < 1 or pose.get_subscription_count() < 1:
                if time.monotonic() > deadline:
                    print("no subscriber", flush=True)
                    return 2
                time.sleep(0.05)
            time.sleep(0.3)
        print("publishing", flush=True)
        while count == 0 or i < count:
            stamp = 1.7e9 + i / 100.0
            shape.publish(joint_state_to_msg(stamp, ["joint_1", "joint_2"],
                                             [math.sin(i / 10), math.cos(i / 10)]))
            pose.publish(pose_to_msg(stamp, i / 1000.0, -i / 1000.0, i / 100.0))
            i += 1
            time.sleep(1.0 / hz)
        time.sleep(0.5)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        print(f"published {i}", flush=True)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
