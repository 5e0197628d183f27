"""``suds_estimator``: identify the SUDS model live from suds/shape and suds/body_pose.

A thin adapter around :class:`~suds_ros.core.ident.session.EstimatorSession`,
which holds the logic (joint roles, pairing of shape and pose by stamps,
resume from a checkpoint, publish cadence, status counters; see its module
docstring).  This node converts messages, feeds the session and publishes what
it returns:

* Subscriptions to the shape and pose topics are created together, once both
  topics have publishers, with a QoS that matches all of them (reliable /
  transient local when they all are, depth ``history_depth``), so a restarted
  estimator receives the simulator's history on both streams at once.
* Without ``actuated`` or ``system`` the joint roles come from the latched
  ``suds/system`` topic of the simulator.
* Joints are selected by name (:func:`~suds_ros.ros.conversions.select_joints`):
  the ``joints`` parameter, else the joints of ``system``/``suds/system``, in
  that order; other joints of the message are ignored, so a robot's
  ``/joint_states`` can be remapped in (``-r suds/shape:=/joint_states``).
* ``suds/model`` (std_msgs/String, the SudsModel JSON, latched) and
  ``suds/status`` (diagnostic_msgs/DiagnosticArray) as the session decides;
  the checkpoint is saved by the session and once more at shutdown.
* ``suds/measured/body_velocity`` (TwistStamped, frame ``frame_id``) and
  ``suds/measured/passive_velocity`` (velocity-only JointState): the velocities of
  every interval the model is fitted on, stamped with the interval's end sample as
  the predictor stamps its prediction of the same interval.  (On a shape stream with
  stamp jitter the estimator fits on its grid, ``regrid``: those intervals end at grid
  times, which the predictor's raw-stamped predictions do not share.)
* ``suds/gait_switch`` (the simulator's, or a driver's: the stamp from which a new gait runs):
  on a switch to a gait other than the last one, the estimator starts afresh
  (:meth:`~suds_ros.core.ident.session.EstimatorSession.new_gait`: the template and model are
  local to one gait, so the old fit is forgotten and the fade-in cycle is skipped).

Topic names are relative (:mod:`suds_ros.ros.topics`): ``__ns`` and remapping apply.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node

from suds_ros.core.config import check_settings, setting
from suds_ros.core.errors import SudsConfigError, SudsError
from suds_ros.core.ident.model import SudsModel
from suds_ros.core.ident.online import OnlineSudsEstimator
from suds_ros.core.ident.session import EstimatorSession, SessionConfig, Status
from suds_ros.core.physics.gait import Gait, same_gait
from suds_ros.core.physics.systems import make_system
from suds_ros.io import checkpoint
from suds_ros.io.stamps import ns_to_float
from suds_ros.ros.conversions import (
    diagnostics_to_msg,
    gait_switch_from_msg,
    joint_state_from_msg,
    joint_velocity_to_msg,
    model_to_msg,
    pose_from_msg,
    select_joints,
    system_info_from_msg,
    twist_to_msg,
)
from suds_ros.ros.params import config_from_parameters, watch_parameters
from suds_ros.ros.qos import MODEL_QOS, STATUS_QOS, SWITCH_QOS, burst_qos, overriding_options, subscription_qos_for
from suds_ros.ros.runner import run_node
from suds_ros.ros.topics import GAIT_SWITCH, MEASURED_BODY, MEASURED_PASSIVE, MODEL, POSE, SHAPE, STATUS, SYSTEM


@dataclass(frozen=True)
class EstimatorNodeConfig:
    """Parameters of the estimator node: the session's (:class:`SessionConfig`, flat names) and its own."""

    session: SessionConfig = setting(default_factory=SessionConfig, description="the identification session",
                                     parameters={"flatten": True})
    joints: tuple[str, ...] = setting((), "the robot's joints in model order; other joints of a shape message "
                                          "are ignored (empty: the joints of `system` or suds/system, else the "
                                          "message's)")
    frame_id: str = setting("body", "frame_id of the measured body twist")

    def __post_init__(self) -> None:
        check_settings(self)
        if len(set(self.joints)) != len(self.joints) or not all(self.joints):
            raise SudsConfigError(f"`joints`: expected distinct joint names, got {list(self.joints)}")
        if not self.frame_id:
            raise SudsConfigError("`frame_id`: expected a frame name, got ''")
        actuated = self.session.actuated
        if self.joints and actuated and not set(actuated) <= set(self.joints):
            raise SudsConfigError(f"`actuated`: {list(actuated)} not all among `joints` {list(self.joints)}")


class EstimatorNode(Node):
    """Feed an :class:`EstimatorSession`; publish suds/model, suds/status and the measured velocities."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("suds_estimator", **kwargs)
        self.node_config = config_from_parameters(self, EstimatorNodeConfig)
        self.config = self.node_config.session
        watch_parameters(self, lambda: self.node_config, self._set_config)
        self.session = EstimatorSession(self.config, log=self._log, now=time.monotonic(), checkpoints=checkpoint)
        if self.config.system and self.session.est is None:  # roles from the system registry or model file
            s = make_system(self.config.system)
            names = tuple(s.joint_names)
            self.session.start(names, tuple(names[i] for i in s.actuated), self.config.gait_hz or 1.0,
                               self.config.system)
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import TwistStamped
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String

        self._model_pub = self.create_publisher(String, MODEL, MODEL_QOS)
        self._status_pub = self.create_publisher(DiagnosticArray, STATUS, STATUS_QOS)
        burst = burst_qos(self.config.history_depth)  # the initial cycles come out at once
        self._measured_body_pub = self.create_publisher(TwistStamped, MEASURED_BODY, burst)
        self._measured_passive_pub = self.create_publisher(JointState, MEASURED_PASSIVE, burst)
        self._subs: dict[str, Any] = {}
        if self.session.needs_system:
            self._subs[SYSTEM] = self.create_subscription(String, SYSTEM, self._on_system, MODEL_QOS)
        self._gait: Gait | None = None
        self.create_subscription(String, GAIT_SWITCH, self._on_gait_switch, SWITCH_QOS)
        self.create_timer(0.1, self._housekeeping)
        self._discovery = self.create_timer(0.2, self._discover)
        self.get_logger().info(f"ready: waiting for publishers of {self.resolve_topic_name(SHAPE)} and "
                               f"{self.resolve_topic_name(POSE)}"
                               + (f"; joints {list(self.node_config.joints)}" if self.node_config.joints else ""))
        self._discover()

    @property
    def est(self) -> OnlineSudsEstimator | None:
        """The session's estimator (None until the joint roles are known)."""
        return self.session.est

    def _set_config(self, new: EstimatorNodeConfig) -> None:
        """Apply a config whose parameters were set (post-set: the set succeeded)."""
        self.node_config = new
        self.config = new.session
        self.session.config = new.session

    def _log(self, level: str, text: str) -> None:
        # one call site per severity: rclpy refuses a severity change at one call site
        if level == "error":
            self.get_logger().error(text)
        elif level == "warning":
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)

    def _discover(self) -> None:
        """Subscribe to shape and pose together once both have publishers."""
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import JointState

        if SHAPE in self._subs:
            return
        offered = {t: [i.qos_profile for i in self.get_publishers_info_by_topic(t)] for t in (SHAPE, POSE)}
        if not all(offered.values()):
            return
        for topic, cls, cb in ((SHAPE, JointState, self._on_shape), (POSE, PoseStamped, self._on_pose)):
            qos = subscription_qos_for(offered[topic], depth=self.config.history_depth)
            self._subs[topic] = self.create_subscription(cls, topic, cb, qos,
                                                         qos_overriding_options=overriding_options())
            self.get_logger().info(f"subscribed to {self.resolve_topic_name(topic)} ({qos.reliability.name.lower()}, "
                                   f"{qos.durability.name.lower()}, depth {qos.depth})")
        self._discovery.cancel()

    # ------------------------------------------------------------ traffic
    def _on_system(self, msg: Any) -> None:
        try:
            info = system_info_from_msg(msg)
        except SudsError as exc:
            self.session.skip("system", exc)
            return
        self.session.on_system(info)

    def _on_gait_switch(self, msg: Any) -> None:
        try:
            stamp, gait = gait_switch_from_msg(msg)
        except SudsError as exc:
            self.session.skip("gait_switch", exc)
            return
        previous, self._gait = self._gait, gait
        if previous is None or not same_gait(previous, gait):
            self.session.new_gait(gait.gait_hz, stamp)

    def joints(self) -> tuple[str, ...] | None:
        """The joints taken from a shape message, in order (None: all of the message, as they are)."""
        if self.node_config.joints:
            return self.node_config.joints
        return self.est.joint_names if self.est is not None else None

    def _on_shape(self, msg: Any) -> None:
        try:
            sample = joint_state_from_msg(msg)
            joints = self.joints()
            if joints is not None:
                sample = select_joints(sample, joints)
        except SudsError as exc:
            self.session.skip("shape", exc)
            return
        self._publish_model(self.session.on_shape(sample, time.monotonic()))

    def _on_pose(self, msg: Any) -> None:
        try:
            pose = pose_from_msg(msg)
        except SudsError as exc:
            self.session.skip("pose", exc)
            return
        self._publish_model(self.session.on_pose(pose, time.monotonic()))

    def _publish_model(self, model: SudsModel | None) -> None:
        if model is not None:
            self._model_pub.publish(model_to_msg(model))
        self._publish_measured()

    def _publish_measured(self) -> None:
        """Publish the measured velocities of the intervals the estimator added since the last call."""
        est = self.est
        if est is None:
            return
        rows = est.pop_measured()
        if not (self._measured_body_pub.get_subscription_count()
                or self._measured_passive_pub.get_subscription_count()):
            return  # nobody listens: spare the conversions (the stream keeps its rate)
        frame = self.node_config.frame_id
        for t, y in rows:
            self._measured_body_pub.publish(twist_to_msg(t, y[0], y[1], y[2], frame_id=frame))
            self._measured_passive_pub.publish(joint_velocity_to_msg(t, est.passive, y[3:]))

    # ------------------------------------------------------------ periodic
    def _housekeeping(self) -> None:
        model, status = self.session.tick(time.monotonic())
        self._publish_model(model)
        if status is not None:
            self._status_pub.publish(self.status_msg(status))

    def status_values(self) -> dict[str, str]:
        """The key/values of suds/status."""
        return self.session.status_values()

    def status_msg(self, status: Status) -> Any:
        """The DiagnosticArray of a session status."""
        stamp = ns_to_float(self.get_clock().now().nanoseconds)
        return diagnostics_to_msg(stamp, "suds_estimator", status.values, level=status.level,
                                  message=status.message, hardware_id=self.config.system or "suds")

    def close(self) -> None:
        """Publish the final model and save the checkpoint (called at shutdown)."""
        model = self.session.close()
        try:
            self._publish_model(model)
        except Exception:  # noqa: BLE001 - the context may already be shut down
            pass


def main(args: list[str] | None = None) -> int:
    """Run the estimator until SIGINT/SIGTERM; 1 with the reason if it cannot start."""
    return run_node(args, name="estimator", doc=__doc__, config_cls=EstimatorNodeConfig,
                    make=EstimatorNode, close=EstimatorNode.close)


if __name__ == "__main__":
    sys.exit(main())
