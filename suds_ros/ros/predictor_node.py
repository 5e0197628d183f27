"""``suds_predictor``: live body and passive-joint velocity predictions from the identified model.

For every ``suds/shape`` sample it publishes the prediction for the interval
ending at that sample: ``suds/predicted/body_velocity``
(geometry_msgs/TwistStamped, body frame ``frame_id``) and
``suds/predicted/passive_velocity`` (sensor_msgs/JointState, passive joint
names and ``velocity``), both stamped with the shape sample's stamp.  A shape
stream with stamp jitter (a host-stamped servo loop) is first brought onto its
fitted uniform grid, as the estimator fits it (``regrid``,
:class:`~suds_ros.core.ident.predictor.GridPredictor`): then each prediction is
for a grid interval and stamped with its grid time (the stamps of the
estimator's ``suds/measured/*``), and comes a few grid points late (held
samples are released after ``idle_flush`` s without a sample).  A uniform stream
passes unchanged and without delay.  The
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
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

from suds_ros.core.config import check_settings
from suds_ros.core.errors import SudsConfigError, SudsError, error_code
from suds_ros.core.ident.predictor import GridPredictor
from suds_ros.ros.conversions import (
    joint_state_from_msg,
    joint_velocity_to_msg,
    model_from_msg,
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
    regrid: bool = field(default=True, metadata={
        "description": "bring a shape stream with stamp jitter onto its fitted uniform grid, as the estimator "
                       "does, and predict its intervals (a uniform stream passes unchanged and without delay)"})
    idle_flush: float = field(default=2.0, metadata={
        "description": "wall s without a shape sample before the samples held for the grid are predicted",
        "range": (0.01, 3600.0)})

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
        self.stream = GridPredictor(self.config.regrid)
        self.before_model = 0
        self.predictions = 0
        self.models = 0
        self.skipped: Counter[str] = Counter()
        self._twist: Any = None  # the prediction messages, filled in again for every sample
        self._rates: Any = None
        self._last_arrival: float | None = None  # wall (monotonic) s of the newest shape message
        self._discovery = self.create_timer(0.1, self._discover)
        self.create_timer(min(0.5, self.config.idle_flush / 2), self._on_idle_check)
        cfg = self.config
        self.get_logger().info(f"ready: frame_id {cfg.frame_id}, depth {cfg.depth}, executor {cfg.executor}, "
                               f"regrid {cfg.regrid}; waiting for publishers of {self.resolve_topic_name(SHAPE)}")
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

    @property
    def predictor(self) -> Any:
        """The streaming predictor of the newest model (None before the first)."""
        return self.stream.predictor

    def _on_model(self, msg: Any) -> None:
        first = self.stream.predictor is None
        try:
            model = model_from_msg(msg)
            how = self.stream.set_model(model)
        except Exception as exc:  # noqa: BLE001 - never die on a bad model message
            self._skip("model", exc)
            return
        if first:
            self.get_logger().info(f"first model ({model.n_samples} rows; passive {list(model.passive)}); "
                                   f"{self.before_model} samples arrived before it")
        self.models += 1
        self.get_logger().debug(f"model {self.models} ({model.n_samples} rows, continuity: {how})")

    def _on_shape(self, msg: Any) -> None:
        self._last_arrival = time.monotonic()
        try:
            s = joint_state_from_msg(msg)
            if self.stream.predictor is None:
                self.before_model += 1
            out = self.stream.add(s.stamp, s.names, s.position)
        except Exception as exc:  # noqa: BLE001 - the node never dies on traffic
            self._skip("shape", exc)
            return
        self._publish(out, s.stamp, msg.header.stamp)

    def _on_idle_check(self) -> None:
        """Predict what the grid stage holds once no shape sample has come for ``idle_flush`` s."""
        if (self._last_arrival is None or not self.stream.held
                or time.monotonic() - self._last_arrival <= self.config.idle_flush):
            return
        self._publish(self.stream.drain(), None, None)

    def _publish(self, out: list[tuple[float, Any, Any]], t_msg: float | None, header_stamp: Any) -> None:
        """Publish the released predictions (a raw sample's keeps its message's stamp to the ns)."""
        for exc in self.stream.errors:
            self._skip("shape", exc)
        self.stream.errors.clear()
        passive = self.stream.predictor.passive if self.stream.predictor is not None else ()
        for t, xi, rdot_p in out:
            stamp = header_stamp if t == t_msg else t
            try:  # the two outputs reused
                self._twist = twist_to_msg(stamp, xi[0], xi[1], xi[2], frame_id=self.config.frame_id,
                                           out=self._twist)
                self._rates = joint_velocity_to_msg(stamp, passive, rdot_p, out=self._rates)
            except SudsError as exc:  # a model that predicts NaN
                self._skip("prediction", exc)
                continue
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
