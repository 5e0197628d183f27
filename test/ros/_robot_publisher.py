"""A stand-in for a real robot (run as a separate process by test_real_robot.py).

``python _robot_publisher.py CYCLES`` simulates purcell3 (100 samples per 1 Hz
gait cycle) and publishes it the way a robot does: ``/joint_states`` as
ros2_control's joint_state_broadcaster (every joint, names in its own order,
two joints the model does not know, positions, velocities and efforts) and
``/mocap/pose`` (PoseStamped in the ``mocap`` frame) from a motion-capture
system at half the joint rate.  It first waits (≤ 60 s) until ``/joint_states``
has 2 subscribers and ``/mocap/pose`` one, then publishes (reliable, so none is
lost), waits until every sample is acknowledged and prints ``published N``.
``python _robot_publisher.py CYCLES JITTER_MS`` stamps the joint states with
host-clock jitter (normal, sd JITTER_MS ms, clipped at ±4 ms, seeded); the
motion capture keeps its own clock.
"""

import sys
import time

import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.qos import QoSProfile, ReliabilityPolicy

from _ros_helpers import wait_for  # this script's folder is sys.path[0]
from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.stream import StreamingSimulator
from suds_ros.core.physics.systems import make_system
from suds_ros.ros.conversions import joint_state_to_msg, pose_to_msg

QOS = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
EXTRA = ("camera_pan", "gripper")


def main() -> int:
    cycles = int(sys.argv[1])
    jitter = float(sys.argv[2]) * 1e-3 if len(sys.argv) > 2 else 0.0
    rng = np.random.default_rng(7)
    system = make_system("purcell3")
    sim = StreamingSimulator(system, SimConfig(samples_per_cycle=100, gait_hz=1.0, noise_std=1e-3,
                                               seed=5, t0=1.7e9))
    names = list(system.joint_names)
    published_names = [EXTRA[0], *reversed(names), EXTRA[1]]  # not the model's order
    rclpy.init()
    node = rclpy.create_node("fake_robot")
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState

    joints = node.create_publisher(JointState, "/joint_states", QOS)
    mocap = node.create_publisher(PoseStamped, "/mocap/pose", QOS)
    wait_for(lambda: joints.get_subscription_count() >= 3 and mocap.get_subscription_count() >= 1,
             60.0, "the estimator, the predictor and the test's probe on /joint_states, the estimator on /mocap/pose")
    print("publishing", flush=True)
    sent = 0
    for c in range(cycles):
        chunk = sim.step(100)
        for k in range(chunk.t.size):
            r = dict(zip(names, chunk.r[k]))
            pos = np.array([0.3 if n == EXTRA[0] else 0.01 if n == EXTRA[1] else r[n] for n in published_names])
            t = float(chunk.t[k]) + (float(np.clip(rng.normal(0.0, jitter), -0.004, 0.004)) if jitter else 0.0)
            joints.publish(joint_state_to_msg(t, published_names, pos,
                                              velocity=np.zeros(pos.size), effort=np.zeros(pos.size)))
            if k % 2 == 0 or (c == cycles - 1 and k == chunk.t.size - 1):  # and the last sample's
                p = chunk.pose[k]
                mocap.publish(pose_to_msg(float(chunk.t[k]), p[0], p[1], p[2], frame_id="mocap"))
            sent += 1
            time.sleep(0.002)  # the publishing rate (~5x real time), not a wait for an event
    for pub in (joints, mocap):
        pub.wait_for_all_acked(Duration(seconds=30.0))
    print(f"published {sent}", flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
