"""``suds_estimator``: identify the SUDS model live from /suds/shape and /suds/body_pose.

Samples go to :class:`~suds_ros.core.ident.online.OnlineSudsEstimator`.  A shape
sample is handed over once the pose stream has covered its stamp (or after
``pose_wait`` wall-clock seconds), so the order in which the two topics are
delivered — e.g. a burst of transient-local history after a restart — never
changes the result.

* Joint roles: the ``actuated`` parameter (joint names from the first shape
  message), else the ``system`` parameter (registry), else the latched
  ``/suds/system`` topic of the simulator, else a resumed checkpoint's.
* Subscriptions are created once the topic's publishers are seen, with a QoS
  that matches all of them (reliable/transient local when they all are, depth
  ``history_depth``), so a restarted estimator receives the simulator's history.
* A bad sample (NaN, duplicate or out-of-order stamp, wrong joint names or
  count, ...) is skipped, logged once per reason and counted per reason in
  /suds/status; after a resume, samples at or before the checkpoint's last
  stamps are skipped silently (``replayed``).  The node never stops on traffic.
* ``/suds/model`` (std_msgs/String, the SudsModel JSON, latched): after each
  fitted chunk (``model_period`` = 0) or every ``model_period`` s, and once the
  stream has been idle for ``idle_flush`` s (the last partial chunk).
* ``/suds/status`` (diagnostic_msgs/DiagnosticArray) every ``status_period`` s.
* ``checkpoint``: saved atomically every ``checkpoint_period`` s and at
  shutdown; resumed from at start when the file exists.
"""

from __future__ import annotations

import math
import sys
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rclpy.node import Node

from suds_ros.core.errors import SudsConfigError, SudsError, SudsPhaseError
from suds_ros.core.ident.online import OnlineConfig, OnlineSudsEstimator
from suds_ros.core.ident.sysid import SudsConfig
from suds_ros.ros.conversions import (
    diagnostics_to_msg,
    joint_state_from_msg,
    model_to_msg,
    pose_from_msg,
    system_info_from_msg,
)
from suds_ros.ros.params import add_validator, config_from_parameters
from suds_ros.ros.qos import MODEL_QOS, STATUS_QOS, overriding_options, subscription_qos_for
from suds_ros.ros.runner import run_node

SHAPE, POSE, SYSTEM = "/suds/shape", "/suds/body_pose", "/suds/system"


def reason_key(exc: Exception) -> str:
    """Short category of a rejected sample, for counting (the full text is logged once)."""
    text = str(exc)
    for key, needles in (
        ("nan_or_inf", ("NaN", "not finite", "finite number")),
        ("duplicate_stamp", ("duplicate",)),
        ("out_of_order_stamp", ("out-of-order",)),
        ("wrong_joint_names", ("has joints", "not unique", "joint names")),
        ("wrong_joint_count", ("positions for", "values (one per joint name)")),
        ("bad_stamp", ("nanosec", "stamp")),
        ("bad_quaternion", ("quaternion",)),
        ("queue_full", ("queue_full",)),
    ):
        if any(n in text for n in needles):
            return key
    return "invalid" if isinstance(exc, SudsError) else f"internal_error_{type(exc).__name__}"


@dataclass(frozen=True)
class EstimatorNodeConfig:
    """Parameters of the estimator node (periods and ``pose_stall`` can change at runtime)."""

    system: str = field(default="", metadata={
        "description": "system id giving the joint roles (empty: `actuated`, else /suds/system)"})
    actuated: tuple[str, ...] = field(default=(), metadata={
        "description": "actuated joint names (empty: from `system` or /suds/system)"})
    gait_hz: float = field(default=0.0, metadata={
        "description": "nominal gait frequency, Hz (0: from /suds/system, else 1)", "range": (0.0, 1000.0)})
    init_cycles: float = field(default=5.0, metadata={
        "description": "gait cycles buffered before the phase is initialised", "range": (3.0, 1000.0)})
    chunk: int = field(default=100, metadata={
        "description": "interval rows per regression update", "range": (1, 1_000_000)})
    max_pose_wait: float = field(default=1.0, metadata={
        "description": "stamp s a shape sample may wait for a covering pose before it is dropped",
        "range": (1e-3, 3600.0)})
    regressors: int = field(default=2, metadata={"description": "SUDS regressor set 1, 2 or 3",
                                                  "range": (1, 3)})
    intercept_order: int = field(default=8, metadata={
        "description": "Fourier order of the intercept C(φ)", "range": (0, 64)})
    linear_order: int = field(default=6, metadata={
        "description": "Fourier order of the linear gains", "range": (0, 64)})
    bilinear_order: int = field(default=3, metadata={
        "description": "Fourier order of the bilinear gains", "range": (0, 64)})
    ridge: float = field(default=1e-6, metadata={
        "description": "relative Tikhonov weight", "range": (0.0, 1e6)})
    forgetting: float = field(default=1.0, metadata={
        "description": "per-sample forgetting factor in (0, 1]", "range": (0.0, 1.0)})
    template_order: int = field(default=8, metadata={
        "description": "Fourier order of the gait template θ(φ)", "range": (1, 64)})
    phaser_order: int = field(default=10, metadata={
        "description": "Fourier order of the phaser correction", "range": (1, 64)})
    history_depth: int = field(default=6000, metadata={
        "description": "subscription depth of shape/pose (≥ the simulator's history to catch up)",
        "range": (1, 10_000_000)})
    checkpoint: str = field(default="", metadata={
        "description": "checkpoint file: resumed from at start if it exists (empty: none)"})
    checkpoint_period: float = field(default=5.0, metadata={
        "description": "wall s between checkpoints", "range": (0.01, 86400.0), "read_only": False})
    model_period: float = field(default=0.0, metadata={
        "description": "wall s between /suds/model updates (0: after each fitted chunk)",
        "range": (0.0, 86400.0), "read_only": False})
    status_period: float = field(default=1.0, metadata={
        "description": "wall s between /suds/status messages", "range": (0.05, 3600.0), "read_only": False})
    pose_wait: float = field(default=1.0, metadata={
        "description": "wall s a shape sample waits in the node for the pose stream to cover it",
        "range": (0.0, 3600.0), "read_only": False})
    pose_stall: float = field(default=2.0, metadata={
        "description": "wall s without pose (while shapes arrive) before the pose stream counts as stalled",
        "range": (0.01, 3600.0), "read_only": False})
    idle_flush: float = field(default=2.0, metadata={
        "description": "wall s without samples before the partial chunk is fitted and published",
        "range": (0.01, 3600.0), "read_only": False})

    def __post_init__(self) -> None:
        if not 0 < self.forgetting <= 1:
            raise SudsConfigError(f"`forgetting`: expected a value in (0, 1], got {self.forgetting!r}")
        if self.system and self.actuated:
            raise SudsConfigError("`system` and `actuated`: give one of them, not both")

    def online_config(self, gait_hz: float) -> OnlineConfig:
        """The :class:`OnlineConfig` these parameters describe."""
        suds = SudsConfig(regressors=self.regressors, intercept_order=self.intercept_order,
                          linear_order=self.linear_order, bilinear_order=self.bilinear_order,
                          ridge=self.ridge, forgetting=self.forgetting)
        return OnlineConfig(suds=suds, init_cycles=self.init_cycles, gait_hz=gait_hz,
                            template_order=self.template_order, phaser_order=self.phaser_order,
                            chunk=self.chunk, max_pose_wait=self.max_pose_wait)


class EstimatorNode(Node):
    """Feed the online estimator; publish /suds/model and /suds/status."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("suds_estimator", **kwargs)
        self.config = config_from_parameters(self, EstimatorNodeConfig)
        add_validator(self, lambda: self.config, on_valid=self._set_config)
        cfg = self.config
        self.est: OnlineSudsEstimator | None = None
        self.skipped: Counter[str] = Counter()
        self.replayed = 0
        self.replayed_pose = 0
        self.model_updates = 0
        self.error = ""
        self._resume = (-math.inf, -math.inf)  # last shape / pose stamps of a resumed checkpoint
        self._resumed_from = ""
        self._shapes: deque[tuple[float, float, Any]] = deque()  # (arrival wall, stamp, sample)
        self._poses: deque[Any] = deque(maxlen=cfg.history_depth)  # before the roles are known
        self._last_shape_wall = self._last_pose_wall = self._first_shape_wall = None
        self._stall_logged = False
        self._dirty = False
        self._rows_published = -1
        now = time.monotonic()
        self._last_status = self._last_ckpt = self._last_model = now
        self._saved_at = (-1, -1)
        if cfg.checkpoint and Path(cfg.checkpoint).exists():
            self._load(cfg.checkpoint)
        elif cfg.system:
            from suds_ros.core.physics.systems import make_system

            s = make_system(cfg.system)
            names = tuple(s.joint_names)
            self._start(names, tuple(names[i] for i in s.actuated), cfg.gait_hz or 1.0, cfg.system)
        from diagnostic_msgs.msg import DiagnosticArray
        from std_msgs.msg import String

        self._model_pub = self.create_publisher(String, "/suds/model", MODEL_QOS)
        self._status_pub = self.create_publisher(DiagnosticArray, "/suds/status", STATUS_QOS)
        self._subs: dict[str, Any] = {}
        if self.est is None and not cfg.actuated:
            self._subs[SYSTEM] = self.create_subscription(String, SYSTEM, self._on_system, MODEL_QOS)
        self.create_timer(0.1, self._housekeeping)
        self.create_timer(0.2, self._discover)
        self._discover()

    # ------------------------------------------------------------ setup
    def _set_config(self, new: EstimatorNodeConfig) -> None:
        self.config = new

    def _load(self, path: str) -> None:
        est = OnlineSudsEstimator.load(path)  # SudsDataError (unreadable) stops the node
        if self.config.actuated and tuple(self.config.actuated) != est.actuated:
            raise SudsConfigError(f"`actuated`: {list(self.config.actuated)} differs from the checkpoint's "
                                  f"{list(est.actuated)} ({path}); remove the checkpoint or fix the parameter")
        self.est = est
        self._resume = (est.last_shape_stamp, est.last_pose_stamp)
        self._resumed_from = path
        self._dirty = True
        self.get_logger().info(
            f"resumed from checkpoint {path}: {est.n_shape} shape samples, "
            f"{est.cycles_seen:.2f} cycles, last stamp {est.last_shape_stamp:.6f} s")

    def _start(self, names: tuple[str, ...], actuated: tuple[str, ...], gait_hz: float, source: str) -> None:
        if self.est is not None:
            return
        self.est = OnlineSudsEstimator(names, actuated, self.config.online_config(gait_hz))
        self.get_logger().info(f"joints {list(names)}, actuated {list(actuated)} (from {source}), "
                               f"gait {gait_hz:g} Hz")
        poses, self._poses = list(self._poses), deque(maxlen=self.config.history_depth)
        for p in poses:
            self._feed_pose(p)
        self._drain()

    def _on_system(self, msg: Any) -> None:
        if self.est is not None:
            return

        try:
            info = system_info_from_msg(msg)
        except SudsError as exc:
            self._skip("system", exc)
            return
        self._start(info["joint_names"], info["actuated"],
                    self.config.gait_hz or info["gait_hz"] or 1.0, f"{SYSTEM} ({info.get('system')})")

    def _discover(self) -> None:
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import JointState

        for topic, cls, cb in ((SHAPE, JointState, self._on_shape), (POSE, PoseStamped, self._on_pose)):
            if topic in self._subs:
                continue
            offered = [i.qos_profile for i in self.get_publishers_info_by_topic(topic)]
            if not offered:
                continue
            qos = subscription_qos_for(offered, depth=self.config.history_depth)
            self._subs[topic] = self.create_subscription(cls, topic, cb, qos,
                                                         qos_overriding_options=overriding_options())
            self.get_logger().info(f"subscribed to {topic} ({qos.reliability.name.lower()}, "
                                   f"{qos.durability.name.lower()}, depth {qos.depth})")

    # ------------------------------------------------------------ traffic
    def _skip(self, stream: str, exc: Exception) -> None:
        key = f"{stream}.{reason_key(exc)}"
        if not self.skipped[key]:
            self.get_logger().warning(f"skipping bad {stream} sample(s) [{key}]: {exc} "
                                      "(logged once per reason; counted in /suds/status)")
        self.skipped[key] += 1

    def _on_shape(self, msg: Any) -> None:
        now = time.monotonic()
        self._last_shape_wall = now
        if self._first_shape_wall is None:
            self._first_shape_wall = now
        try:
            sample = joint_state_from_msg(msg)
        except SudsError as exc:
            self._skip("shape", exc)
            return
        if sample.stamp <= self._resume[0]:
            self.replayed += 1  # already in the resumed checkpoint
            return
        if self.est is None and self.config.actuated and set(self.config.actuated) <= set(sample.names):
            self._start(sample.names, tuple(self.config.actuated), self.config.gait_hz or 1.0,
                        "`actuated` and the first shape message")
        if len(self._shapes) >= self.config.history_depth:
            self._skip("shape", SudsError(f"queue_full: {len(self._shapes)} samples already wait for "
                                          "the joint roles or the pose stream"))
            return
        self._shapes.append((now, sample.stamp, sample))
        self._drain()

    def _on_pose(self, msg: Any) -> None:
        self._last_pose_wall = time.monotonic()
        self._stall_logged = False
        try:
            pose = pose_from_msg(msg)
        except SudsError as exc:
            self._skip("pose", exc)
            return
        if pose.stamp <= self._resume[1]:
            self.replayed_pose += 1
            return
        if self.est is None:
            self._poses.append(pose)
            return
        self._feed_pose(pose)
        self._drain()

    def _feed_pose(self, pose: Any) -> None:
        assert self.est is not None
        try:
            self.est.add_pose(pose.stamp, pose.x, pose.y, pose.yaw)
        except SudsPhaseError as exc:
            self._phase_error(exc)
        except Exception as exc:  # noqa: BLE001 - the node never dies on traffic
            self._skip("pose", exc)
        else:
            self._dirty = True
            self._after_update()

    def _drain(self, force_before: float | None = None) -> None:
        """Hand waiting shape samples to the estimator once the pose stream covers them (or they waited)."""
        est = self.est
        if est is None:
            return
        while self._shapes:
            arrived, stamp, s = self._shapes[0]
            if stamp > est.last_pose_stamp and (force_before is None or arrived > force_before):
                break
            self._shapes.popleft()
            try:
                est.add_shape(s.stamp, s.names, s.position)
            except SudsPhaseError as exc:
                self._phase_error(exc)
            except Exception as exc:  # noqa: BLE001 - the node never dies on traffic
                self._skip("shape", exc)
            else:
                self._dirty = True
                self._after_update()

    def _phase_error(self, exc: Exception) -> None:
        if not self.error:
            self.get_logger().error(f"initialisation failed: {exc}")
        self.error = f"initialisation failed: {exc}"

    def _after_update(self) -> None:
        est = self.est
        if self.config.model_period == 0 and est is not None and est.n_rows != self._rows_published:
            self._publish_model()

    def _publish_model(self) -> None:
        est = self.est
        if est is None or not est.initialised:
            return
        try:
            model = est.model()
        except SudsError:
            return
        self._model_pub.publish(model_to_msg(model))
        self._rows_published = est.n_rows
        self._dirty = False
        self.model_updates += 1
        self._last_model = time.monotonic()

    # ------------------------------------------------------------ periodic
    def _housekeeping(self) -> None:
        cfg, now = self.config, time.monotonic()
        self._drain(force_before=now - cfg.pose_wait)
        last = max(filter(None, (self._last_shape_wall, self._last_pose_wall)), default=None)
        idle = last is not None and now - last > cfg.idle_flush
        if self._dirty and (idle or (cfg.model_period > 0 and now - self._last_model >= cfg.model_period)):
            self._publish_model()
        stalled = self._pose_stalled(now)
        if stalled is not None and not self._stall_logged:
            self.get_logger().warning(f"pose stream stalled since {stalled:.1f} s")
            self._stall_logged = True
        if now - self._last_status >= cfg.status_period:
            self._last_status = now
            self._status_pub.publish(self.status_msg(stalled))
        if cfg.checkpoint and now - self._last_ckpt >= cfg.checkpoint_period:
            self._last_ckpt = now
            self.save_checkpoint()

    def _pose_stalled(self, now: float) -> float | None:
        """Seconds since the last pose while shapes keep arriving, if longer than ``pose_stall``."""
        if self._last_shape_wall is None or now - self._last_shape_wall > self.config.pose_stall:
            return None  # nothing arrives at all: idle, not stalled
        ref = self._last_pose_wall if self._last_pose_wall is not None else self._first_shape_wall
        since = now - ref
        return since if since > self.config.pose_stall else None

    def status_values(self) -> dict[str, str]:
        """The key/values of /suds/status."""
        est = self.est
        v: dict[str, str] = {}
        if est is not None:
            g = est.running_gamma()
            v.update({
                "phase": f"{est.phase:.6g}", "cycles_seen": f"{est.cycles_seen:.3f}",
                "initialised": str(est.initialised).lower(), "samples": str(est.n_shape),
                "poses": str(est.n_pose), "rows": str(est.n_rows),
                "gamma_body": f"{g['body']:.4f}", "gamma_passive": f"{g['passive']:.4f}",
                "dropped_no_pose": str(est.dropped_no_pose),
            })
            v.update({f"residual.{c}": f"{r:.6g}" for c, r in zip(est.channels, est.last_residual)})
        else:
            v.update({"initialised": "false", "samples": "0", "joint_roles": "unknown"})
        v.update({"replayed": str(self.replayed), "replayed_pose": str(self.replayed_pose),
                  "waiting_for_pose": str(len(self._shapes)), "model_updates": str(self.model_updates),
                  "skipped_total": str(sum(self.skipped.values()))})
        v.update({f"skipped.{k}": str(n) for k, n in sorted(self.skipped.items())})
        if self._resumed_from:
            v["resumed_from"] = self._resumed_from
        return v

    def status_msg(self, stalled: float | None) -> Any:
        """DiagnosticArray: ERROR on a failed initialisation, WARN on a stalled pose stream."""
        level, message = "OK", "running"
        if self.est is None:
            message = "waiting for joint roles (`actuated`, `system` or /suds/system)"
        elif not self.est.initialised:
            message = f"initialising ({self.est.cycles_seen:.1f}/{self.est.config.init_cycles:g} cycles)"
        if stalled is not None:
            level, message = "WARN", f"pose stream stalled since {stalled:.1f} s"
        if self.error:
            level, message = "ERROR", self.error
        stamp = self.get_clock().now().nanoseconds * 1e-9
        return diagnostics_to_msg(stamp, "suds_estimator", self.status_values(), level=level,
                                  message=message, hardware_id=self.config.system or "suds")

    def save_checkpoint(self) -> None:
        """Atomically save the estimator state (if it changed since the last save)."""
        est = self.est
        if est is None or not self.config.checkpoint:
            return
        mark = (est.n_shape, est.n_pose)
        if mark == self._saved_at:
            return
        try:
            est.save(self.config.checkpoint)
        except OSError as exc:
            self.get_logger().error(f"cannot write checkpoint {self.config.checkpoint}: {exc}")
            return
        self._saved_at = mark

    def close(self) -> None:
        """Publish the final model and save the checkpoint (called at shutdown)."""
        if self._dirty:
            try:
                self._publish_model()
            except Exception:  # noqa: BLE001 - the context may already be shut down
                pass
        self.save_checkpoint()


def main(args: list[str] | None = None) -> int:
    """Run the estimator until SIGINT/SIGTERM; 1 with the reason if it cannot start."""
    return run_node(args, name="estimator", doc=__doc__, config_cls=EstimatorNodeConfig,
                    make=EstimatorNode, close=EstimatorNode.close)


if __name__ == "__main__":
    sys.exit(main())
