"""``suds_simulator``: publish a simulated swimmer's shape and body pose, paced in (scaled) real time.

Samples come from :class:`~suds_ros.core.physics.stream.StreamingSimulator`, one gait
cycle per chunk, and are published by a wall-clock timer: sample k goes out at
``start + k / (rate * real_time_factor)`` (several per tick when needed, so the
stream keeps its rate whatever the timer resolution).

Topics
------
Relative names (:mod:`suds_ros.ros.topics`; ``/suds/...`` in the root namespace):
``suds/shape`` (sensor_msgs/JointState: names, positions) and
``suds/body_pose`` (geometry_msgs/PoseStamped, frame ``world``, yaw-only
quaternion), both stamped with the simulated sample time and published
RELIABLE + TRANSIENT_LOCAL + KEEP_LAST(``history_depth``), so an estimator that
restarts gets back the samples it missed (up to ``history_depth`` of them).
``suds/system`` (std_msgs/String, latched): JSON ``{"system", "joint_names",
"actuated", "passive", "gait_hz", "rate"}`` for downstream nodes.
``/clock`` (rosgraph_msgs/Clock): the simulated time, only when
``real_time_factor`` != 1.

System
------
``system`` is a built-in id or the path of a robot model file (``suds-robot/1``);
``model_file``, when set, names the model file instead (and ``system`` is then
ignored).  With a model file the published names, roles and system id are the
file's, and ``gait_hz`` defaults to the file's ``gait_hz`` (``rate`` / gait_hz
must still be an integer number of samples per cycle).

Time
----
With ``wait_for_subscribers`` N > 0 the first sample goes out only once N subscriptions
match ``suds/shape`` (or after ``start_timeout`` s): the ``pipeline`` sets N to the nodes it
starts beside the simulator, so the stream does not run ahead while they are still importing.
``t0`` is the stamp of the first sample; when not set, it is the wall-clock
time at start for ``real_time_factor`` = 1 (stamps then track the wall clock)
and 1.7e9 s otherwise.  ``cycles`` > 0 stops after that many gait cycles: the
node waits (≤ 5 s) for reliable subscribers to acknowledge the tail and exits
with code 0; with ``linger`` true it stays up instead (until SIGINT), so a subscriber
that joins or restarts late still gets the transient-local history of the stream.

Gait
----
``gait_file`` (settable while running) names a gait file (``suds-gait/1``) for the actuated
joints instead of the nominal gait; its ``system`` must be the simulated one and its joints the
actuated ones, and it runs at the stream's ``gait_hz`` (unset ``gait_hz`` at start: the gait's).
A new value is checked at once (refused with the reason) and applied at the next cycle boundary:
the set-points continue without a jump (the difference to the new gait fades out over one
cycle, :meth:`~suds_ros.core.physics.stream.StreamingSimulator.set_gait`) and the stream goes
on; the node logs ``gait <file> on from stamp <s>``.  Empty returns to the nominal gait.  The
gait in force is published latched on ``suds/gait`` (std_msgs/String, the gait file text;
reliable, transient local, depth 1) at start and at every switch.  A gait's text on
``suds/gait_command`` (std_msgs/String, e.g. from the ``optimizer`` node) is switched to the same
way; one for another robot, other joints or another frequency is logged and ignored.  Every
switch is also published on ``suds/gait_switch`` (std_msgs/String JSON: ``stamp_ns``, ``stamp``
and ``gait``; reliable, transient local, depth 10) with the stamp of the first sample of the new gait, before that
sample, so listeners place the switch by stamps.

Effects at run time
-------------------
``effects`` (JSON text, settable while running) lists catalogue effects
(``shared/spec/effects.md``) added to the nominal model, e.g.
``[{"name": "joint_coulomb_friction", "joint": "joint_2", "mu": 0.5}]``; ``[]`` or
empty returns to the nominal physics.  A new value is checked against the system
(unknown effect, actuated joint, out-of-range parameter: the set is refused with
the reason) and applied from the next chunk (gait cycle) on; the node logs
``effects <json> on from stamp <s>`` with the stamp of the first sample simulated
with them.  ``sensor_time_offset`` is not available while streaming.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.task import Future

from suds_ros.core.config import check_settings
from suds_ros.core.errors import SudsConfigError, SudsError
from suds_ros.core.physics.gait import Gait, check_gait, load_gait, nominal_gait
from suds_ros.core.physics.sim import SimConfig, effort_by_joint
from suds_ros.core.physics.stream import StreamingSimulator
from suds_ros.core.physics.systems import load_system
from suds_ros.core.recording import samples_per_cycle
from suds_ros.ros.conversions import (
    float_to_time,
    gait_from_msg,
    gait_switch_to_msg,
    gait_to_msg,
    joint_state_to_msg,
    pose_to_msg,
    system_info_to_msg,
)
from suds_ros.ros.params import config_from_parameters, watch_parameters
from suds_ros.ros.qos import GAIT_QOS, MODEL_QOS, SWITCH_QOS, latched_state_qos, overriding_options
from suds_ros.ros.runner import run_node
from suds_ros.ros.topics import CLOCK, GAIT, GAIT_COMMAND, GAIT_SWITCH, POSE, SHAPE, SYSTEM

#: Stamp of the first sample when not running in real time (and ``t0`` is not set).
DEFAULT_T0 = 1.7e9


@dataclass(frozen=True)
class SimulatorConfig:
    """Parameters of the simulator node (all read-only except ``real_time_factor``)."""

    system: str = field(default="purcell3", metadata={
        "description": "system id: purcell3, swimmer9, linear_passive, pushmepullyou, nlinkN, or the "
                       "path of a robot model file"})
    model_file: str = field(default="", metadata={
        "description": "robot model file (suds-robot/1); when set it is the simulated system and "
                       "`system` is ignored"})
    seed: int = field(default=0, metadata={
        "description": "seed of the drive perturbation and the measurement noise", "range": (0, 2**31 - 1)})
    noise: float = field(default=1e-3, metadata={
        "description": "std of the measurement noise on joints (rad or m), x, y (m) and yaw (rad)",
        "range": (0.0, 10.0)})
    rate: float = field(default=100.0, metadata={
        "description": "samples per second of simulated time, Hz; rate / gait_hz = samples per cycle "
                       "(an integer ≥ 8)", "range": (1.0, 100000.0)})
    gait_hz: float | None = field(default=None, metadata={
        "description": "gait frequency, Hz, in (0, 1000] (unset: the model file's gait_hz, else 1)"})
    real_time_factor: float = field(default=1.0, metadata={
        "description": "simulated seconds per wall-clock second (1: real time; 0: as fast as possible)",
        "range": (0.0, 1e6), "read_only": False})
    cycles: int = field(default=0, metadata={
        "description": "gait cycles to publish, then exit with code 0 (0: run forever)",
        "range": (0, 2**31 - 1)})
    linger: bool = field(default=False, metadata={
        "description": "with cycles > 0: after the last cycle keep the publishers and their "
                       "transient-local history up until interrupted (late or restarted subscribers "
                       "still get the stream), instead of exiting"})
    t0: float | None = field(default=None, metadata={
        "description": "stamp of the first sample, s (unset: now in real time, 1.7e9 otherwise)"})
    wait_for_subscribers: int = field(default=0, metadata={
        "description": "subscriptions to suds/shape to wait for before the first sample is published "
                       "(0: start at once), so nodes started beside the simulator are running, not "
                       "still importing, when the stream starts", "range": (0, 10_000)})
    start_timeout: float = field(default=30.0, metadata={
        "description": "wall-clock s at most to wait for wait_for_subscribers; then start anyway",
        "range": (0.0, 1e6)})
    history_depth: int = field(default=6000, metadata={
        "description": "samples kept for late-joining/restarted subscribers (transient local)",
        "range": (1, 10_000_000)})
    tick: float = field(default=0.01, metadata={
        "description": "wall-clock s between publishing timer ticks", "range": (1e-4, 1.0)})
    effects: str = field(default="", metadata={
        "description": "JSON list of effects added to the nominal model from the next gait cycle on, e.g. "
                       '[{"name": "joint_coulomb_friction", "joint": "joint_2", "mu": 0.5}] (empty: none)',
        "read_only": False})
    effort: bool = field(default=False, metadata={
        "description": "also publish the actuator effort on suds/shape (N·m or N, averaged over each sample "
                       "period; 0 on passive joints), as a torque or current sensor would"})
    gait_file: str = field(default="", metadata={
        "description": "gait file (suds-gait/1) driving the actuated joints instead of the nominal gait; "
                       "a new value takes over at the next cycle boundary without a jump (empty: nominal)",
        "read_only": False})

    def __post_init__(self) -> None:
        check_settings(self)  # the ranges in the field metadata
        parse_effects(self.effects)
        if self.gait_hz is not None:
            self._check_gait()
        if self.t0 is not None and (isinstance(self.t0, (bool, str)) or not math.isfinite(float(self.t0))
                                    or not 0 <= float(self.t0) < 2**31):
            raise SudsConfigError(f"`t0`: expected a stamp in [0, 2^31) s, got {self.t0!r}")

    def _check_gait(self) -> None:
        gait = self.gait_hz
        number = isinstance(gait, (int, float)) and not isinstance(gait, bool)
        if not (number and math.isfinite(gait) and 0 < gait <= 1000):  # type: ignore[arg-type]
            raise SudsConfigError(f"`gait_hz`: expected a frequency in (0, 1000] Hz, got {gait!r}")
        object.__setattr__(self, "gait_hz", float(gait))
        spc = self.rate / self.gait_hz
        if abs(spc - round(spc)) > 1e-9 * spc or round(spc) < 8:
            raise SudsConfigError(
                f"`rate`: rate / gait_hz must be an integer ≥ 8 (samples per cycle), got "
                f"{self.rate!r} / {gait!r} = {spc:.6g}")

    @property
    def system_spec(self) -> str:
        """What :func:`~suds_ros.core.physics.systems.load_system` builds: ``model_file``, else ``system``."""
        return self.model_file or self.system

    def resolved(self, default_gait_hz: float) -> "SimulatorConfig":
        """Return this config with ``gait_hz`` set (``default_gait_hz`` when unset), checked against ``rate``."""
        return self if self.gait_hz is not None else replace(self, gait_hz=default_gait_hz)

    @property
    def samples_per_cycle(self) -> int:
        """Samples per gait cycle (of a :meth:`resolved` config)."""
        return samples_per_cycle(1.0 / self.rate, self.gait_hz)  # type: ignore[arg-type]

    def first_stamp(self) -> float:
        """``t0``, or its default (wall clock now in real time, 1.7e9 otherwise)."""
        if self.t0 is not None:
            return float(self.t0)
        return time.time() if self.real_time_factor == 1.0 else DEFAULT_T0

    def sim_config(self, t0: float, gait: Gait | None = None) -> SimConfig:
        """The :class:`SimConfig` of the stream whose first stamp is ``t0`` (driven by ``gait`` if given)."""
        return SimConfig(samples_per_cycle=self.samples_per_cycle, gait_hz=self.gait_hz,  # type: ignore[arg-type]
                         noise_std=self.noise, seed=self.seed, t0=t0, gait=gait)


def parse_effects(text: str) -> list[dict[str, Any]]:
    """The ``effects`` parameter as a list of effect mappings (empty text: none).

    Raises
    ------
    SudsConfigError
        Text that is not a JSON list of objects each with a ``name``.
    """
    if not text.strip():
        return []
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SudsConfigError(f"`effects`: expected a JSON list of effects, got {text!r} ({exc})") from None
    if not isinstance(value, list) or not all(isinstance(e, dict) and "name" in e for e in value):
        raise SudsConfigError(f"`effects`: expected a JSON list of objects with a `name`, got {text!r}")
    return value


class SimulatorNode(Node):
    """Publish the streamed simulation on /suds/shape, /suds/body_pose (and /clock, /suds/system)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("suds_simulator", **kwargs)
        params = config_from_parameters(self, SimulatorConfig)
        self.system = load_system(params.system_spec)
        self.gait: Gait | None = load_gait(params.gait_file, self.system) if params.gait_file else None
        default_hz = self.gait.gait_hz if self.gait is not None else getattr(
            getattr(self.system, "model", None), "gait_hz", 1.0)
        self.config = params.resolved(default_hz)
        watch_parameters(self, lambda: self.config, self._on_config)  # applied after a successful set
        self.add_on_set_parameters_callback(self._check_effects)
        self.add_on_set_parameters_callback(self._check_gait)
        cfg = self.config
        self._pending_effects: list[dict[str, Any]] | None = parse_effects(cfg.effects) or None
        self._pending_gait: tuple[str, Gait] | None = None
        self._restart_at(cfg.first_stamp())  # a bad start value of `effects` stops the node here
        names = self.system.joint_names
        self.names = tuple(names)
        from geometry_msgs.msg import PoseStamped
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String

        qos = latched_state_qos(cfg.history_depth)
        self._shape_pub = self.create_publisher(JointState, SHAPE, qos,
                                                qos_overriding_options=overriding_options())
        self._pose_pub = self.create_publisher(PoseStamped, POSE, qos,
                                               qos_overriding_options=overriding_options())
        self._system_pub = self.create_publisher(String, SYSTEM, MODEL_QOS)
        self._gait_pub = self.create_publisher(String, GAIT, GAIT_QOS)
        self.create_subscription(String, GAIT_COMMAND, self._on_gait_command, GAIT_QOS)
        self._switch_pub = self.create_publisher(String, GAIT_SWITCH, SWITCH_QOS)
        in_force = self.gait if self.gait is not None else self._nominal()
        if in_force is not None:
            self._gait_pub.publish(gait_to_msg(in_force))
        self._clock_cls = Clock
        self._clock_pub = self.create_publisher(Clock, CLOCK, 10)
        self._system_pub.publish(system_info_to_msg({
            "system": self.system.name, "joint_names": list(self.names),
            "actuated": [names[i] for i in self.system.actuated],
            "passive": [names[i] for i in self.system.passive],
            "gait_hz": cfg.gait_hz, "rate": cfg.rate}))
        self._total = cfg.cycles * cfg.samples_per_cycle  # 0: forever
        self._sent = 0
        self._chunk: Any = None
        self._chunk_i = 0
        self._anchor: tuple[float, int] | None = None  # (wall monotonic, sample index) of the pacing
        self.finished: Future = Future()
        self._waiting_since: float | None = time.monotonic() if cfg.wait_for_subscribers else None
        self._timer = self.create_timer(cfg.tick, self._on_tick)
        source = f" (model file {cfg.system_spec})" if self.system.name != cfg.system_spec else ""
        self.get_logger().info(
            f"simulating {self.system.name}{source}, gait {cfg.gait_hz:g} Hz, {cfg.rate:g} Hz "
            f"({cfg.samples_per_cycle} samples/cycle), "
            f"real_time_factor {cfg.real_time_factor:g}, t0 {self.t0:.3f} s, "
            f"{'forever' if not cfg.cycles else f'{cfg.cycles} cycles'}")

    def _check_effects(self, params: list[Any]) -> Any:
        """Refuse an ``effects`` value the system cannot take (checked on a scratch simulator)."""
        from rcl_interfaces.msg import SetParametersResult

        for p in params:
            if p.name == "effects":
                try:
                    StreamingSimulator(self.system, replace(self.sim.config, warmup=0.0)).set_effects(
                        parse_effects(str(p.value)))
                except SudsConfigError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _nominal(self) -> Gait | None:
        """The system's nominal gait at the stream's frequency, None when it has no sinusoidal one."""
        try:
            return nominal_gait(self.system, self.config.gait_hz)
        except SudsConfigError:
            return None

    def _gait_of(self, path: str) -> Gait:
        """The gait of a ``gait_file`` value (empty: the nominal), checked against the system and frequency."""
        gait = load_gait(path, self.system) if path else self._nominal()
        if gait is None:
            raise SudsConfigError(f"`gait_file`: {self.system.name!r} has no nominal gait to return to")
        return self._same_rate(gait, "gait_file")

    def _same_rate(self, gait: Gait, source: str) -> Gait:
        if gait.gait_hz != self.config.gait_hz:
            raise SudsConfigError(f"`{source}`: the gait runs at {gait.gait_hz:g} Hz, the stream at "
                                  f"{self.config.gait_hz:g} Hz")
        return gait

    def _on_gait_command(self, msg: Any) -> None:
        """A gait on ``suds/gait_command``: switched to at the next cycle boundary (a bad one is logged, ignored)."""
        try:
            gait = self._same_rate(check_gait(gait_from_msg(msg), self.system, GAIT_COMMAND), GAIT_COMMAND)
        except SudsError as exc:
            self.get_logger().error(f"gait command ignored: {exc}")
            return
        self._pending_gait = (f"from {GAIT_COMMAND}", gait)

    def _check_gait(self, params: list[Any]) -> Any:
        """Refuse a ``gait_file`` that does not load, is for another robot or another frequency."""
        from rcl_interfaces.msg import SetParametersResult

        for p in params:
            if p.name == "gait_file":
                try:
                    self._gait_of(str(p.value))
                except SudsConfigError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _on_config(self, new: SimulatorConfig) -> None:
        """Apply a config whose parameters were set (post-set: every check accepted them)."""
        if new.effects != self.config.effects:
            self._pending_effects = parse_effects(new.effects)
        if new.gait_file != self.config.gait_file:
            self._pending_gait = (new.gait_file, self._gait_of(new.gait_file))
        if new.real_time_factor != self.config.real_time_factor:
            self._anchor = None  # re-anchor the pacing at the next tick
            self.get_logger().info(f"real_time_factor → {new.real_time_factor:g}")
        self.config = new

    def _due(self) -> int:
        """Number of samples due now according to the pacing."""
        rtf = self.config.real_time_factor
        if rtf == 0:
            return self.config.samples_per_cycle  # as fast as possible: one cycle per tick
        now = time.monotonic()
        if self._anchor is None:
            self._anchor = (now, self._sent)
        w0, k0 = self._anchor
        target = k0 + int(math.floor((now - w0) * self.config.rate * rtf)) + 1
        return max(0, target - self._sent)

    def _next_sample(self) -> tuple[float, np.ndarray, np.ndarray, np.ndarray | None]:
        if self._chunk is None or self._chunk_i >= self._chunk.t.size:
            effects, self._pending_effects = self._pending_effects, None
            if effects is not None:
                self.sim.set_effects(effects)
            gait, self._pending_gait = self._pending_gait, None
            if gait is not None:  # a chunk is one cycle: this is a cycle boundary
                self.sim.set_gait(gait[1])
                self.gait = gait[1]
                self._gait_pub.publish(gait_to_msg(gait[1]))
            self._chunk = self.sim.step(self.config.samples_per_cycle)
            self._chunk_i = 0
            if gait is not None:  # before the chunk's samples: a listener places the switch by its stamp
                self._switch_pub.publish(gait_switch_to_msg(float(self._chunk.t[0]), gait[1]))
            if effects is not None:
                self.get_logger().info(f"effects {json.dumps(effects)} on from stamp {self._chunk.t[0]:.6f}")
            if gait is not None:
                self.get_logger().info(f"gait {gait[0] or '(nominal)'} on from stamp {self._chunk.t[0]:.6f}")
        c, i = self._chunk, self._chunk_i
        self._chunk_i += 1
        effort = None if c.effort is None else effort_by_joint(self.system, c.effort[i])
        return float(c.t[i]), c.r[i], c.pose[i], effort

    def _waiting(self) -> bool:
        """True while the stream waits for ``wait_for_subscribers`` (at most ``start_timeout`` s)."""
        if self._waiting_since is None:
            return False
        matched = self._shape_pub.get_subscription_count()
        waited = time.monotonic() - self._waiting_since
        wanted = self.config.wait_for_subscribers
        if matched < wanted and waited < self.config.start_timeout:
            return True
        self._waiting_since = None
        if self.config.t0 is None and self.config.real_time_factor == 1.0:
            self._restart_at(self.config.first_stamp())  # stamps track the wall clock from the start
        how = "" if matched >= wanted else f" (start_timeout; {wanted} wanted)"
        self.get_logger().info(f"starting the stream: {matched} subscription(s) on "
                               f"{self.resolve_topic_name(SHAPE)} after {waited:.1f} s{how}")
        return False

    def _restart_at(self, t0: float) -> None:
        """A fresh stream whose first stamp is ``t0``, with the pending effects (nothing published yet)."""
        self.t0 = t0
        self.sim = StreamingSimulator(self.system, self.config.sim_config(t0, self.gait), effort=self.config.effort)
        if self._pending_effects:
            self.sim.set_effects(self._pending_effects)

    def _on_tick(self) -> None:
        if self.finished.done() or self._waiting():
            return
        n = self._due()
        if self._total:
            n = min(n, self._total - self._sent)
        for _ in range(n):
            t, r, pose, effort = self._next_sample()
            if self.config.real_time_factor != 1.0:
                self._clock_pub.publish(self._clock_cls(clock=float_to_time(t)))
            self._shape_pub.publish(joint_state_to_msg(t, self.names, r, effort=effort))
            self._pose_pub.publish(pose_to_msg(t, pose[0], pose[1], pose[2]))
            self._sent += 1
        if self._total and self._sent >= self._total:
            self._timer.cancel()
            for pub in (self._shape_pub, self._pose_pub):
                pub.wait_for_all_acked(Duration(seconds=5.0))
            self.get_logger().info(f"published {self._sent} samples ({self.config.cycles} cycles); done"
                                   + ("; lingering until interrupted" if self.config.linger else ""))
            if not self.config.linger:
                self.finished.set_result(self._sent)


def main(args: list[str] | None = None) -> int:
    """Run the simulator until ``cycles`` are published (or SIGINT); 1 with the reason if it cannot start."""
    return run_node(args, name="simulator", doc=__doc__, config_cls=SimulatorConfig,
                    make=SimulatorNode,
                    run=lambda node: rclpy.spin_until_future_complete(node, node.finished))


if __name__ == "__main__":
    sys.exit(main())
