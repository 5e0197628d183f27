"""The recording contract (`shared/spec/recording.md`): topic names, message types, metadata keys.

Every module that reads, writes, publishes or subscribes a contract topic takes
its name from here.  (The reader and writer of recordings will live here too.)
"""

from __future__ import annotations

# topics of a recording, as stored in bags
SHAPE_TOPIC = "/suds/shape"
POSE_TOPIC = "/suds/body_pose"
# topics the suds_ros nodes add
SYSTEM_TOPIC = "/suds/system"
MODEL_TOPIC = "/suds/model"
STATUS_TOPIC = "/suds/status"
PREDICTED_BODY_TOPIC = "/suds/predicted/body_velocity"
PREDICTED_PASSIVE_TOPIC = "/suds/predicted/passive_velocity"

SHAPE_TYPE = "sensor_msgs/msg/JointState"
POSE_TYPE = "geometry_msgs/msg/PoseStamped"
TWIST_TYPE = "geometry_msgs/msg/TwistStamped"
STRING_TYPE = "std_msgs/msg/String"
DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"

# the MCAP metadata record and its keys
METADATA_NAME = "suds"
META_SYSTEM = "system"
META_ACTUATED = "actuated"
META_PASSIVE = "passive"
META_GAIT_HZ = "gait_hz"
