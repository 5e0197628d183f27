"""``suds_predictor``: live body and passive-joint velocity predictions from the identified model.

For every ``/suds/shape`` sample it publishes the prediction for the interval
ending at that sample: ``/suds/predicted/body_velocity``
(geometry_msgs/TwistStamped, body frame ``frame_id``) and
``/suds/predicted/passive_velocity`` (sensor_msgs/JointState, passive joint
names and ``velocity``), both stamped with the shape sample's stamp.

The model comes from the latched ``/suds/model`` (std_msgs/String JSON).  A new
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

import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

from suds_ros.core.errors import SudsConfigError, SudsError
from suds_ros.core.online import StreamingPredictor
from suds_ros.ros.conversions import joint_state_from_msg, joint_velocity_to_msg, twist_to_msg
from suds_ros.ros.estimator_node import model_from_msg, reason_key
from suds_ros.ros.params import config_from_parameters, parameters_help, wants_help
from suds_ros.ros.qos import ESTIMATE_QOS, MODEL_QOS, overriding_options, subscription_qos_for

SHAPE = "/suds/shape"
BODY_TOPIC, PASSIVE_TOPIC = "/suds/predicted/body_velocity", "/suds/predicted/passive_velocity"


@dataclass(frozen=True)
class PredictorConfig:
    """Parameters of the predictor node (all read-only)."""

    frame_id: str = field(default="body", metadata={"description": "frame_id of the predicted twist"})
    depth: int = field(default=100, metadata={
        "description": "shape subscription depth", "range": (1, 1_000_000)})
    executor: str = field(default="events", metadata={
        "description": "events (EventsExecutor, if available) or single (SingleThreadedExecutor)"})
    system: str = field(default="", metadata={"description": "unused; accepted for the pipeline"})

    def __post_init__(self) -> None:
        if self.executor not in ("events", "single"):
            raise SudsConfigError(f"`executor`: expected 'events' or 'single', got {self.executor!r}")
        if not self.frame_id:
            raise SudsConfigError("`frame_id`: expected a frame name, got ''")


def carry_over(old: StreamingPredictor | None, new: StreamingPredictor, last: Any) -> str:
    """Give ``new`` the running state of ``old`` (same template and phase rate) or prime it with ``last``.

    Returns how continuity was kept: ``"tracker"``, ``"primed"`` or ``"fresh"``.
    (Uses StreamingPredictor internals; a public ``with_model`` would be cleaner.)
    """
    if old is not None and old.model.joint_names == new.model.joint_names \
            and old.model.omega == new.model.omega \
            and np.array_equal(old.model.template_coef, new.model.template_coef) \
            and getattr(old, "_tracker", None) is not None:
        new._tracker, new._prev, new.last_stamp = old._tracker, old._prev, old.last_stamp
        return "tracker"
    if last is not None:
        try:
            new.update(last.stamp, last.names, last.position)
            return "primed"
        except SudsError:
            pass
    return "fresh"


class PredictorNode(Node):
    """Publish (ξ, ṙ_p) predictions for every shape sample once a model is known."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("suds_predictor", **kwargs)
        self.config = config_from_parameters(self, PredictorConfig)
        from geometry_msgs.msg import TwistStamped
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String

        self._body_pub = self.create_publisher(TwistStamped, BODY_TOPIC, ESTIMATE_QOS,
                                               qos_overriding_options=overriding_options())
        self._passive_pub = self.create_publisher(JointState, PASSIVE_TOPIC, ESTIMATE_QOS,
                                                  qos_overriding_options=overriding_options())
        self.create_subscription(String, "/suds/model", self._on_model, MODEL_QOS)
        self._shape_cls = JointState
        self._shape_sub: Any = None
        self.predictor: StreamingPredictor | None = None
        self.before_model = 0
        self.predictions = 0
        self.models = 0
        self.skipped: Counter[str] = Counter()
        self._last: Any = None
        self._discovery = self.create_timer(0.1, self._discover)
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
        self.get_logger().info(f"subscribed to {SHAPE} ({qos.reliability.name.lower()})")

    def _skip(self, stream: str, exc: Exception) -> None:
        key = f"{stream}.{reason_key(exc)}"
        if not self.skipped[key]:
            self.get_logger().warning(f"skipping bad {stream} message(s) [{key}]: {exc} (logged once)")
        self.skipped[key] += 1

    def _on_model(self, msg: Any) -> None:
        try:
            model = model_from_msg(msg)
            new = StreamingPredictor(model)
        except Exception as exc:  # noqa: BLE001 - never die on a bad model message
            self._skip("model", exc)
            return
        how = carry_over(self.predictor, new, self._last)
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
            out = self.predictor.update(s.stamp, s.names, s.position)
        except Exception as exc:  # noqa: BLE001 - the node never dies on traffic
            self._skip("shape", exc)
            return
        self._last = s
        if out is None:
            return
        xi, rdot_p = out
        self._body_pub.publish(twist_to_msg(s.stamp, xi[0], xi[1], xi[2], frame_id=self.config.frame_id))
        self._passive_pub.publish(joint_velocity_to_msg(s.stamp, self.predictor.passive, rdot_p))
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


def main(args: list[str] | None = None) -> int:
    """Run the predictor until SIGINT/SIGTERM; 1 with the reason if it cannot start."""
    if wants_help(args):
        print(parameters_help("predictor", __doc__.strip().splitlines()[0], PredictorConfig))
        return 0
    rclpy.init(args=args)
    node = None
    try:
        node = PredictorNode()
        executor = make_executor(node.config.executor)
        executor.add_node(node)
        while rclpy.ok(context=node.context):  # EventsExecutor.spin() never returns control in Jazzy
            executor.spin_once(timeout_sec=0.2)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except SudsError as exc:
        print(f"ERROR: suds_predictor: {exc}", file=sys.stderr)
        return 1
    finally:
        if node is not None:
            node.get_logger().info(f"{node.predictions} predictions, {node.models} models, "
                                   f"{node.before_model} samples before the first model, "
                                   f"skipped {dict(node.skipped)}")
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
