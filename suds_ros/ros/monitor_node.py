"""``suds_monitor``: watch live shape and pose for a mismatch with the nominal simulator.

A thin adapter around :class:`~suds_ros.core.diagnosis.monitor.MismatchMonitor` (the
residuals, the noise floor, the levels and when to diagnose are described there).

Topics (relative names: ``--ros-args -r __ns:=/robot1`` moves them all)
------------------------------------------------------------------------
* subscribes ``suds/shape`` (sensor_msgs/JointState; joints matched by name, extra joints
  ignored) and ``suds/body_pose`` (geometry_msgs/PoseStamped), paired by stamps only;
* ``suds/mismatch`` (diagnostic_msgs/DiagnosticArray) after every statistics update, stamped
  with the stamp of the newest sample: one status per channel (passive joints, ``xi_x``,
  ``xi_y``, ``xi_theta``) named ``suds_monitor/<channel>``, level OK / WARN / ERROR (or STALE:
  too few clean windows to test it, lost messages), values
  ``statistic`` (F = mean-square residual / noise floor), ``since`` (stamp, s, at which the
  channel entered its level), ``warn`` and ``error`` (the thresholds);
* ``suds/diagnosis`` (std_msgs/String, latched): when a channel has stayed in ERROR for
  ``persist_cycles`` cycles, the JSON report of the core diagnosis of those cycles
  (``suds diagnose --json`` schema plus a ``monitor`` object: window, channels, since), computed
  in a separate process while the node keeps up with the stream.

Nothing is published on ``suds/mismatch`` until ``floor_cycles`` cycles have been seen (the noise
floor needs them); from that first report on the statistic is right whatever the robot did
before: the nominal model's own discretisation error and noise gain come from replays of the
nominal physics, nothing from the robot's first cycles.  ``suds monitor BAG`` runs the same core
offline over a recording.  A shape stream with stamp jitter is held by the monitor's grid stage
(its first 256 samples or more, then its newest few); after ``idle_flush`` s without a shape
message what it holds is passed on.

System
------
``system`` (built-in id) or ``model_file`` (robot model file, wins when set) is the nominal
physics; ``gait_hz`` defaults to the model's.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from suds_ros.core.diagnosis.monitor import (
    LEVEL_NAMES,
    STALE,
    DiagnosisWorker,
    MismatchMonitor,
    MonitorConfig,
    chain_model,
)
from suds_ros.core.config import check_settings, setting
from suds_ros.core.errors import SudsError
from suds_ros.core.physics.systems import load_system
from suds_ros.ros.conversions import diagnostics_to_msg, joint_state_from_msg, pose_from_msg
from suds_ros.ros.params import config_from_parameters
from suds_ros.ros.qos import MODEL_QOS, STATUS_QOS
from suds_ros.ros.runner import run_node
from suds_ros.ros.topics import DIAGNOSIS, MISMATCH, POSE, SHAPE


@dataclass(frozen=True)
class MonitorNodeConfig:
    """Parameters of the monitor node (all read-only): the core :class:`MonitorConfig`'s (flat names) and its own."""

    system: str = setting("purcell3", "nominal system id (purcell3, swimmer9, nlinkN) or robot model file path")
    model_file: str = setting("", "robot model file (suds-robot/1); when set it is the nominal model and "
                                  "`system` is ignored")
    monitor: MonitorConfig = setting(default_factory=MonitorConfig, description="the monitor's settings",
                                     parameters={"flatten": True, "unset": {"gait_hz": "the model's gait_hz"}})
    diagnose: bool = setting(True, "diagnose persistent mismatches and publish suds/diagnosis")
    depth: int = setting(1000, "subscription queue depth of shape and pose", ge=1, le=10_000_000)
    best_effort: bool = setting(False, "subscribe best effort (matches sensor-data publishers, e.g. motion "
                                       "capture) instead of reliable")
    idle_flush: float = setting(2.0, "s without a shape message after which the shape samples the monitor's "
                                     "grid stage holds (a jittered stream's newest few) are passed on",
                                gt=0.0, le=3600.0)

    def __post_init__(self) -> None:
        check_settings(self)

    @property
    def system_spec(self) -> str:
        """What :func:`~suds_ros.core.physics.systems.load_system` builds: ``model_file``, else ``system``."""
        return self.model_file or self.system


def _model_gait_hz(system: object) -> float:
    return float(getattr(chain_model(system), "gait_hz", 1.0))  # type: ignore[arg-type]


class MonitorNode(Node):
    """Feed a :class:`MismatchMonitor`; publish suds/mismatch and (latched) suds/diagnosis."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("suds_monitor", **kwargs)
        systems: dict[str, Any] = {}

        def system(spec: str) -> Any:
            if spec not in systems:
                systems[spec] = load_system(spec)
            return systems[spec]

        # `gait_hz` unset: the nominal model's
        params = config_from_parameters(self, MonitorNodeConfig, fill={
            "gait_hz": lambda v: _model_gait_hz(system(v["model_file"] or v["system"]))})
        self.params = params
        self.system = system(params.system_spec)
        model = chain_model(self.system)
        self.monitor = MismatchMonitor(self.system, params.monitor)
        self.worker = DiagnosisWorker(model) if (params.diagnose and model is not None) else None
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String

        self._string = String
        qos = QoSProfile(depth=params.depth, reliability=ReliabilityPolicy.BEST_EFFORT if params.best_effort
                         else ReliabilityPolicy.RELIABLE)
        self._mismatch_pub = self.create_publisher(DiagnosticArray, MISMATCH, STATUS_QOS)
        self._diagnosis_pub = self.create_publisher(String, DIAGNOSIS, MODEL_QOS)
        self.create_subscription(JointState, SHAPE, self._on_shape, qos)
        self.create_subscription(PoseStamped, POSE, self._on_pose, qos)
        self.create_timer(0.1, self._poll_worker)
        self.create_timer(min(0.5, params.idle_flush / 2), self._on_idle_check)
        self._last_arrival: float | None = None  # wall (monotonic) s of the newest shape message
        self._published = 0
        self._said_stamped_late = False
        cfg = self.monitor.config
        self.get_logger().info(
            f"monitoring {self.system.name}: channels {', '.join(self.monitor.channels)}; "
            f"{cfg.samples_per_cycle} samples/cycle, warn F > {cfg.warn:g}, error F > {cfg.error:g}, "
            f"diagnosis after {cfg.persist_cycles} cycles in ERROR"
            + ("" if self.worker else " (disabled)"))

    # ------------------------------------------------------------ traffic
    def _on_shape(self, msg: Any) -> None:
        try:
            s = joint_state_from_msg(msg)
        except SudsError:
            self.monitor.skipped += 1
            return
        self._last_arrival = time.monotonic()
        self.monitor.on_shape(s.stamp, s.names, s.position)
        self._after_input()

    def _on_idle_check(self) -> None:
        """Pass on what the grid stage holds once no shape message has come for ``idle_flush`` s."""
        if (self._last_arrival is None or not self.monitor.held
                or time.monotonic() - self._last_arrival <= self.params.idle_flush):
            return
        self.monitor.flush()
        self._after_input()

    def _on_pose(self, msg: Any) -> None:
        try:
            p = pose_from_msg(msg)
        except SudsError:
            self.monitor.skipped += 1
            return
        self.monitor.on_pose(p.stamp, p.x, p.y, p.yaw)
        self._after_input()

    def _after_input(self) -> None:
        if self.monitor.updated != self._published:
            self._published = self.monitor.updated
            self._mismatch_pub.publish(self.mismatch_msg())
            if self.monitor.stamped_late and not self._said_stamped_late:
                self._said_stamped_late = True
                self.get_logger().warning(
                    "the shape stamps look stamped late (each value on the device's clock, the jitter in the "
                    "stamps alone): from now on each shape sample is taken at its grid point; the stream's mean "
                    "delay cannot be told from its own stamps, so a misfit of the body channels may be that delay "
                    "against the pose stream (README, 'Stamped late')")
        request = self.monitor.take_request()
        if request is not None and self.worker is not None:
            channels = ", ".join(request.channels)
            if self.worker.submit(request):
                self.get_logger().warning(
                    f"mismatch on {channels} since {request.since:.3f} s persists: diagnosing the last "
                    f"{self.monitor.config.persist_cycles} cycles")
            else:
                self.get_logger().warning(f"mismatch on {channels}: a diagnosis is still running; skipped")

    def mismatch_msg(self) -> Any:
        """The DiagnosticArray of the current channel statuses (stamp: the newest sample's)."""
        cfg = self.monitor.config
        stamp = self.monitor.last_stamp
        lag = self.monitor.lag
        body = set(self.monitor.body_channels)
        msgs = []
        for s in self.monitor.statuses:
            text = (f"not tested since {s.since:.3f} s: {s.note}" if s.level == STALE
                    else f"F = {s.statistic:.3g} since {s.since:.3f} s")
            values = {"statistic": f"{s.statistic:.6g}", "since": f"{s.since:.6f}", "warn": f"{cfg.warn:g}",
                      "error": f"{cfg.error:g}"}
            if s.channel in body and math.isfinite(lag.score):  # the body channels' pose-lag fit (lag_statistic)
                values.update(pose_lag_s=f"{lag.seconds:.6g}", pose_lag_score=f"{lag.score:.6g}",
                              pose_lag_share=f"{lag.share:.6g}")
            msgs.append(diagnostics_to_msg(stamp, f"suds_monitor/{s.channel}", values, level=LEVEL_NAMES[s.level],
                                           message=text, hardware_id=self.system.name))
        out = msgs[0]
        for m in msgs[1:]:  # one array, one status per channel
            out.status.extend(m.status)
        return out

    def _poll_worker(self) -> None:
        if self.worker is None:
            return
        done = self.worker.poll()
        if done is None:
            return
        text, error = done
        if error is not None:
            self.get_logger().error(f"diagnosis failed: {error}")
            return
        self._diagnosis_pub.publish(self._string(data=text))
        self.get_logger().info(f"published the diagnosis on {DIAGNOSIS}")

    def close(self) -> None:
        """Stop the diagnosis worker."""
        if self.worker is not None:
            self.worker.close()


def main(args: list[str] | None = None) -> int:
    """Run the monitor until SIGINT/SIGTERM; 1 with the reason if it cannot start."""
    return run_node(args, name="monitor", doc=__doc__, config_cls=MonitorNodeConfig, make=MonitorNode,
                    close=lambda node: node.close())


if __name__ == "__main__":
    sys.exit(main())
