"""Tiny publisher of predictions for the Foxglove bridge test (run as a separate process).

``python _twist_publisher.py HZ``: publishes TwistStamped on ``suds/predicted/body_velocity``
(the predictor's QoS) at HZ until interrupted; sample i has stamp 1.7e9 + i/100 s and
velocity (vx, vy, wz) = (i, -i, i/10).  Prints ``publishing`` when it starts.
"""

import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException

from suds_ros.ros.conversions import twist_to_msg
from suds_ros.ros.qos import ESTIMATE_QOS
from suds_ros.ros.topics import PREDICTED_BODY


def main() -> int:
    hz = float(sys.argv[1])
    rclpy.init()
    node = rclpy.create_node("test_twist_publisher")
    from geometry_msgs.msg import TwistStamped

    pub = node.create_publisher(TwistStamped, PREDICTED_BODY, ESTIMATE_QOS)
    i = 0
    try:
        print("publishing", flush=True)
        while True:
            pub.publish(twist_to_msg(1.7e9 + i / 100.0, float(i), float(-i), i / 10.0))
            i += 1
            time.sleep(1.0 / hz)  # the publishing rate, not a wait for an event
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
