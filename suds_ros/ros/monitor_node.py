"""``suds_monitor``: watch live shape and pose for a mismatch with the nominal simulator.

A thin adapter around :class:`~suds_ros.core.diagnosis.monitor.MismatchMonitor` (the
residuals, the noise floor, the levels and when to diagnose are described there).

Topics (relative names: ``--ros-args -r __ns:=/robot1`` moves them all)
------------------------------------------------------------------------
* subscribes ``suds/shape`` (sensor_msgs/JointState; joints matched by name, extra joints
  ignored) and ``suds/body_pose`` (geometry_msgs/PoseStamped), paired by stamps only;
* ``suds/mismatch`` (diagnostic_msgs/DiagnosticArray) after every statistics update, stamped
  with the stamp of the newest sample: one status per channel (passive joints, ``xi_x``,
  ``xi_y``, ``xi_theta``) named ``suds_monitor/<channel>``, level OK / WARN / ERROR, values
  ``statistic`` (F = mean-square residual / noise floor), ``since`` (stamp, s, at which the
  channel entered its level), ``warn`` and ``error`` (the thresholds);
* ``suds/diagnosis`` (std_msgs/String, latched): when a channel has stayed in ERROR for
  ``persist_cycles`` cycles, the JSON report of the core diagnosis of those cycles
  (``suds diagnose --json`` schema plus a ``monitor`` object: window, channels, since), computed
  in a separate process while the node keeps up with the stream.

Nothing is published on ``suds/mismatch`` until ``floor_cycles`` + ``calibration_cycles`` cycles
have been seen (the noise floor and the calibration need them).

System
------
``system`` (built-in id) or ``model_file`` (robot model file, wins when set) is the nominal
physics; ``gait_hz`` defaults to the model's.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from suds_ros.core.diagnosis.monitor import (
    LEVEL_NAMES,
    DiagnosisWorker,
    MismatchMonitor,
    MonitorConfig,
    chain_model,
)
from suds_ros.core.errors import SudsConfigError, SudsError
from suds_ros.core.physics.systems import load_system
from suds_ros.ros.conversions import diagnostics_to_msg, joint_state_from_msg, pose_from_msg
from suds_ros.ros.params import config_from_parameters
from suds_ros.ros.qos import MODEL_QOS, STATUS_QOS
from suds_ros.ros.runner import run_node

from suds_ros.ros.topics import DIAGNOSIS, MISMATCH, POSE, SHAPE

_DEFAULT = MonitorConfig()


@dataclass(frozen=True)
class MonitorNodeConfig:
    """Parameters of the monitor node (all read-only)."""

    system: str = field(default="purcell3", metadata={
        "description": "nominal system id (purcell3, swimmer9, nlinkN) or robot model file path"})
    model_file: str = field(default="", metadata={
        "description": "robot model file (suds-robot/1); when set it is the nominal model and `system` is ignored"})
    gait_hz: float | None = field(default=None, metadata={
        "description": "gait frequency, Hz (unset: the model's gait_hz)"})
    rate: float = field(default=_DEFAULT.rate, metadata={
        "description": "sample rate of shape and pose, Hz (rate / gait_hz samples per cycle)",
        "range": (1.0, 100000.0)})
    diff_window: int = field(default=_DEFAULT.diff_window, metadata={
        "description": "samples per residual window", "range": (1, 10000)})
    window_cycles: float = field(default=_DEFAULT.window_cycles, metadata={
        "description": "gait cycles of the mean-square residual", "range": (0.05, 100.0)})
    floor_cycles: float = field(default=_DEFAULT.floor_cycles, metadata={
        "description": "gait cycles of data for the noise floor", "range": (0.05, 100.0)})
    calibration_cycles: float = field(default=_DEFAULT.calibration_cycles, metadata={
        "description": "cycles (assumed nominal) measuring the model's own discretisation error; 0: none",
        "range": (0.0, 1000.0)})
    warn: float = field(default=_DEFAULT.warn, metadata={
        "description": "WARN when F = mean-square residual / floor exceeds this", "range": (1.0, 1e9)})
    error: float = field(default=_DEFAULT.error, metadata={
        "description": "ERROR when F exceeds this (> warn)", "range": (1.0, 1e9)})
    persist_cycles: int = field(default=_DEFAULT.persist_cycles, metadata={
        "description": "cycles in ERROR before the recent window is diagnosed (≥ 4)", "range": (4, 10000)})
    history_cycles: float = field(default=_DEFAULT.history_cycles, metadata={
        "description": "cycles of samples kept", "range": (1.0, 10000.0)})
    update_every: int = field(default=_DEFAULT.update_every, metadata={
        "description": "samples between statistics updates (and suds/mismatch messages)", "range": (1, 100000)})
    diagnose: bool = field(default=True, metadata={
        "description": "diagnose persistent mismatches and publish suds/diagnosis"})
    depth: int = field(default=1000, metadata={
        "description": "subscription queue depth of shape and pose", "range": (1, 10_000_000)})
    best_effort: bool = field(default=False, metadata={
        "description": "subscribe best effort (matches sensor-data publishers, e.g. motion capture) "
                       "instead of reliable"})

    def __post_init__(self) -> None:
        if self.gait_hz is not None and not (isinstance(self.gait_hz, (int, float)) and math.isfinite(self.gait_hz)
                                             and 0 < self.gait_hz <= 1000):
            raise SudsConfigError(f"`gait_hz`: expected a frequency in (0, 1000] Hz, got {self.gait_hz!r}")

    def monitor_config(self, gait_hz: float) -> MonitorConfig:
        """The core settings (``gait_hz`` when the parameter is unset)."""
        return MonitorConfig(
            gait_hz=float(self.gait_hz or gait_hz), rate=self.rate, diff_window=self.diff_window,
            window_cycles=self.window_cycles, floor_cycles=self.floor_cycles,
            calibration_cycles=self.calibration_cycles, warn=self.warn,
            error=self.error, persist_cycles=self.persist_cycles, history_cycles=self.history_cycles,
            update_every=self.update_every)


class MonitorNode(Node):
    """Feed a :class:`MismatchMonitor`; publish suds/mismatch and (latched) suds/diagnosis."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("suds_monitor", **kwargs)
        params = config_from_parameters(self, MonitorNodeConfig)
        self.params = params
        self.system = load_system(params.model_file or params.system)
        model = chain_model(self.system)
        self.monitor = MismatchMonitor(self.system, params.monitor_config(getattr(model, "gait_hz", 1.0)))
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
        self._published = 0
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
        self.monitor.on_shape(s.stamp, s.names, s.position)
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
        msgs = []
        for s in self.monitor.statuses:
            text = f"F = {s.statistic:.3g} since {s.since:.3f} s"
            msgs.append(diagnostics_to_msg(
                stamp, f"suds_monitor/{s.channel}",
                {"statistic": f"{s.statistic:.6g}", "since": f"{s.since:.6f}", "warn": f"{cfg.warn:g}",
                 "error": f"{cfg.error:g}"},
                level=LEVEL_NAMES[s.level], message=text, hardware_id=self.system.name))
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
