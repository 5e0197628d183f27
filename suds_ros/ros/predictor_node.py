"""``suds_predictor``: live body and passive-joint velocity predictions from the identified model.

For every ``suds/shape`` sample it publishes the prediction for the interval
ending at that sample: ``suds/predicted/body_velocity``
(geometry_msgs/TwistStamped, body frame ``frame_id``) and
``suds/predicted/passive_velocity`` (sensor_msgs/JointState, passive joint
names and ``velocity``), both stamped with the shape sample's stamp.  The
model's joints are taken from each shape message by name, in the model's order
(other joints, e.g. of a robot's ``/joint_states``, are ignored).  Topic names are
relative (:mod:`suds_ros.ros.topics`): ``__ns`` and remapping apply.

The model comes from the latched ``suds/model`` (std_msgs/String JSON).  A new
model replaces the old one without a gap: when its gait template and phase rate
are the old ones (always the case for one estimator run) the phase tracker and
the previous sample carry over; otherwise the new predictor is primed with the
last sample.  Before the first model, samples are only counted.  Bad samples
are skipped, logged once per reason and counted.

``executor``: ``events`` (rclpy.experimental.EventsExecutor, lower latency,
see docs/results/latency.md) or ``single`` (SingleThreadedExecutor).
"""

from __future__ import annotations

import sys
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

from suds_ros.core.config import check_settings
from suds_ros.core.errors import SudsConfigError, SudsError, error_code
from suds_ros.core.ident.predictor import StreamingPredictor, carry_over
from suds_ros.ros.conversions import (
    joint_state_from_msg,
    joint_velocity_to_msg,
    model_from_msg,
    select_joints,
    twist_to_msg,
)
from suds_ros.ros.params import config_from_parameters
from suds_ros.ros.qos import ESTIMATE_QOS, MODEL_QOS, overriding_options, subscription_qos_for
from suds_ros.ros.runner import run_node
from suds_ros.ros.topics import MODEL, PREDICTED_BODY, PREDICTED_PASSIVE, SHAPE


@dataclass(frozen=True)
class PredictorConfig:
    """Parameters of the predictor node (all read-only)."""

    frame_id: str = field(default="body", metadata={"description": "frame_id of the predicted twist"})
    depth: int = field(default=1000, metadata={
        "description": "shape subscription depth: shapes queued while the predictor is busy, each "
                       "still predicted (keep last; 100 lost 1-3 % of a 500 Hz stream on 2 busy cores, "
                       "and each gap also spoils the prediction after it)", "range": (1, 1_000_000)})
    executor: str = field(default="events", metadata={
        "description": "events (EventsExecutor, if available) or single (SingleThreadedExecutor)"})
    system: str = field(default="", metadata={"description": "unused; accepted for the pipeline"})

    def __post_init__(self) -> None:
        check_settings(self)  # the ranges in the field metadata
        if self.executor not in ("events", "single"):
            raise SudsConfigError(f"`executor`: expected 'events' or 'single', got {self.executor!r}")
        if not self.frame_id:
            raise SudsConfigError("`frame_id`: expected a frame name, got ''")


class PredictorNode(Node):
    """Publish (ξ, ṙ_p) predictions for every shape sample once a model is known."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("suds_predictor", **kwargs)
        self.config = config_from_parameters(self, PredictorConfig)
        from geometry_msgs.msg import TwistStamped
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String

        self._body_pub = self.create_publisher(TwistStamped, PREDICTED_BODY, ESTIMATE_QOS,
                                               qos_overriding_options=overriding_options())
        self._passive_pub = self.create_publisher(JointState, PREDICTED_PASSIVE, ESTIMATE_QOS,
                                                  qos_overriding_options=overriding_options())
        self.create_subscription(String, MODEL, self._on_model, MODEL_QOS)
        self._shape_cls = JointState
        self._shape_sub: Any = None
        self.predictor: StreamingPredictor | None = None
        self.before_model = 0
        self.predictions = 0
        self.models = 0
        self.skipped: Counter[str] = Counter()
        self._last: Any = None
        self._twist: Any = None  # the prediction messages, filled in again for every sample
        self._rates: Any = None
        self._discovery = self.create_timer(0.1, self._discover)
        cfg = self.config
        self.get_logger().info(f"ready: frame_id {cfg.frame_id}, depth {cfg.depth}, executor {cfg.executor}; "
                               f"waiting for publishers of {self.resolve_topic_name(SHAPE)}")
        self._discover()

    def _discover(self) -> None:
        if self._shape_sub is not None:
            return
        offered = [i.qos_profile for i in self.get_publishers_info_by_topic(SHAPE)]
        if not offered:
            return
        q = subscription_qos_for(offered, depth=self.config.depth)
        qos = QoSProfile(depth=self.config.depth, reliability=q.reliability,
                         durability=DurabilityPolicy.VOLATILE)  # live predictions: no history
        self._shape_sub = self.create_subscription(self._shape_cls, SHAPE, self._on_shape, qos,
                                                   qos_overriding_options=overriding_options())
        self._discovery.cancel()
        self.get_logger().info(f"subscribed to {self.resolve_topic_name(SHAPE)} ({qos.reliability.name.lower()})")

    def _skip(self, stream: str, exc: Exception) -> None:
        key = f"{stream}.{error_code(exc)}"
        if not self.skipped[key]:
            self.get_logger().warning(f"skipping bad {stream} message(s) [{key}]: {exc} (logged once)")
        self.skipped[key] += 1

    def _on_model(self, msg: Any) -> None:
        try:
            model = model_from_msg(msg)
            last = self._last
            if last is not None and set(model.joint_names) <= set(last.names):
                last = select_joints(last, model.joint_names)
            new, how = carry_over(self.predictor, model, last)
        except Exception as exc:  # noqa: BLE001 - never die on a bad model message
            self._skip("model", exc)
            return
        if self.predictor is None:
            self.get_logger().info(f"first model ({model.n_samples} rows; passive {list(model.passive)}); "
                                   f"{self.before_model} samples arrived before it")
        self.predictor = new
        self.models += 1
        self.get_logger().debug(f"model {self.models} ({model.n_samples} rows, continuity: {how})")

    def _on_shape(self, msg: Any) -> None:
        try:
            s = joint_state_from_msg(msg)
        except SudsError as exc:
            self._skip("shape", exc)
            return
        if self.predictor is None:
            self.before_model += 1
            self._last = s
            return
        try:
            s = select_joints(s, self.predictor.model.joint_names)
            out = self.predictor.update(s.stamp, s.names, s.position)
        except Exception as exc:  # noqa: BLE001 - the node never dies on traffic
            self._skip("shape", exc)
            return
        self._last = s
        if out is None:
            return
        xi, rdot_p = out
        try:  # stamped with the shape message's own stamp, to the nanosecond; the two outputs reused
            self._twist = twist_to_msg(msg.header.stamp, xi[0], xi[1], xi[2], frame_id=self.config.frame_id,
                                       out=self._twist)
            self._rates = joint_velocity_to_msg(msg.header.stamp, self.predictor.passive, rdot_p, out=self._rates)
        except SudsError as exc:  # a model that predicts NaN
            self._skip("prediction", exc)
            return
        self._body_pub.publish(self._twist)
        self._passive_pub.publish(self._rates)
        self.predictions += 1


def make_executor(kind: str) -> Any:
    """The executor named by the ``executor`` parameter (EventsExecutor falls back to single-threaded)."""
    if kind == "events":
        try:
            from rclpy.experimental import EventsExecutor

            return EventsExecutor()
        except ImportError:
            pass
    return rclpy.executors.SingleThreadedExecutor()


def _report(node: PredictorNode) -> None:
    # a logger of its own: the summary is not meant for /rosout
    log = rclpy.logging.get_logger(f"{node.get_name()}.summary")
    log.info(f"{node.predictions} predictions, {node.models} models, {node.before_model} samples "
             f"before the first model, skipped {dict(node.skipped)}")


def main(args: list[str] | None = None) -> int:
    """Run the predictor until SIGINT/SIGTERM; 1 with the reason if it cannot start."""
    return run_node(args, name="predictor", doc=__doc__, config_cls=PredictorConfig,
                    make=PredictorNode, close=_report,
                    executor=lambda node: make_executor(node.config.executor))


if __name__ == "__main__":
    sys.exit(main())
