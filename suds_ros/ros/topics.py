"""The topic names the suds nodes use: relative, so namespaces and remapping apply.

Bags store the contract's absolute names (:mod:`suds_ros.io.recording_bag`:
``/suds/shape``, …).  A node creates its topics under the same names without
the leading ``/`` (``suds/shape``), which ROS resolves against the node's
namespace: in the root namespace they are exactly the contract's names; with
``--ros-args -r __ns:=/robot1`` they become ``/robot1/suds/shape``; and each
can be remapped on its own (``-r suds/shape:=/joint_states``).

``/clock`` stays absolute (ROS time is one per graph).
"""

from __future__ import annotations

from suds_ros.io import recording_bag as _bag


def relative(topic: str) -> str:
    """The node-relative form of a contract topic name (``/suds/shape`` → ``suds/shape``)."""
    return topic.lstrip("/")


SHAPE = relative(_bag.SHAPE_TOPIC)
POSE = relative(_bag.POSE_TOPIC)
SYSTEM = relative(_bag.SYSTEM_TOPIC)
#: the gait in force (std_msgs/String: suds-gait/1 YAML, latched) of the simulator
GAIT = relative(_bag.GAIT_TOPIC)
MODEL = relative(_bag.MODEL_TOPIC)
STATUS = relative(_bag.STATUS_TOPIC)
PREDICTED_BODY = relative(_bag.PREDICTED_BODY_TOPIC)
PREDICTED_PASSIVE = relative(_bag.PREDICTED_PASSIVE_TOPIC)
PREDICTED_PATTERN = relative(_bag.PREDICTED_PATTERN)
#: the velocities the estimator measured and fitted on (same types and stamps as the predictions)
MEASURED_BODY = "suds/measured/body_velocity"
MEASURED_PASSIVE = "suds/measured/passive_velocity"
MEASURED_PATTERN = "suds/measured/*"
#: the diagnosis report (std_msgs/String JSON, latched) of the mismatch monitor
DIAGNOSIS = "suds/diagnosis"
#: the live mismatch status (diagnostic_msgs/DiagnosticArray) of the mismatch monitor
MISMATCH = "suds/mismatch"
#: gait commands (std_msgs/String, suds-gait/1 text) the simulator switches to at its next cycle boundary
GAIT_COMMAND = "suds/gait_command"
#: a gait switch (std_msgs/String JSON: the stamp of the first sample of the new gait, and the gait)
GAIT_SWITCH = "suds/gait_switch"
#: one cycle of the commanded gait for a ros2_control trajectory controller (trajectory_msgs/JointTrajectory)
GAIT_TRAJECTORY = "suds/gait_trajectory"
#: the optimizer's progress (std_msgs/String, JSON per run)
OPTIMIZER = "suds/optimizer"
CLOCK = "/clock"

#: every topic a suds node publishes, relative (patterns excluded)
PUBLISHED = (SHAPE, POSE, SYSTEM, GAIT, MODEL, STATUS, PREDICTED_BODY, PREDICTED_PASSIVE,
             MEASURED_BODY, MEASURED_PASSIVE, DIAGNOSIS, MISMATCH, GAIT_COMMAND, GAIT_SWITCH, GAIT_TRAJECTORY,
             OPTIMIZER)
#: the recorder's default patterns (relative: resolved in the recorder's namespace)
RECORDED = (SHAPE, POSE, SYSTEM, PREDICTED_PATTERN, MEASURED_PATTERN, MODEL, STATUS, DIAGNOSIS,
            MISMATCH, GAIT, GAIT_SWITCH, OPTIMIZER)


def resolve(topic: str, namespace: str) -> str:
    """``topic`` resolved in ``namespace`` (no remapping): absolute names stay, relative ones are prefixed.

    ``~`` (private) names are not used by suds and are refused.
    """
    if topic.startswith("/"):
        return topic
    if topic.startswith("~"):
        raise ValueError(f"`topic`: expected an absolute or relative name, got the private name {topic!r}")
    ns = namespace.rstrip("/")
    return f"{ns}/{topic}" if ns else f"/{topic}"
