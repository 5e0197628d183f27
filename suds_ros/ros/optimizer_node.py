"""``suds_optimizer``: optimise the gait live, run → fit → step, on the robot's own streams.

A thin adapter around :class:`~suds_ros.core.optimize.live.LiveGaitSearch` (which places each run's
measured cycles by stamps) and :class:`~suds_ros.core.optimize.loop.GaitSearch` (the same search as
``suds optimize --simulate``: the model of the incumbent gait fitted to its own cycles, one
trust-region step, accepted only when the measurement confirms it).

Topics (relative names: ``--ros-args -r __ns:=/robot1`` moves them all)
------------------------------------------------------------------------
* subscribes ``suds/shape`` (sensor_msgs/JointState; joints matched by name) and
  ``suds/body_pose`` (geometry_msgs/PoseStamped), paired by stamps, and ``suds/gait_switch``
  (the stamp from which the robot runs a commanded gait; the simulator node publishes it; a
  robot that does not: ``wait_for_switch`` false, see
  :class:`~suds_ros.core.optimize.live.LiveGaitSearch`);
* publishes ``suds/gait_command`` (std_msgs/String, latched: the ``suds-gait/1`` text of the gait to
  run; the simulator node switches to it at its next cycle boundary);
* ``suds/gait_trajectory`` (trajectory_msgs/JointTrajectory, latched): one cycle of the same gait
  for the actuated joints, ``trajectory_points`` + 1 points with positions and velocities, the
  message a ros2_control joint trajectory controller takes (a driver loops it);
* ``suds/optimizer`` (std_msgs/String, JSON): one message per run measured: ``index``, ``kind``
  (start / candidate / rerun), ``accepted``, ``measured`` and ``predicted`` objective,
  ``measured_rotation``, ``cycles_requested`` (what the search asked for) and ``cycles_elapsed``
  (what the robot ran, from the stamps: the wait for a cycle boundary and the time spent deciding
  included), ``window`` (stamps), ``note``, and ``gait`` (text); a last message with ``done``: true
  and the best gait when the budget is spent or the search converged, with ``motion_warning`` (text,
  or null) when its measured motion cannot be told from none (:func:`~suds_ros.core.optimize.loop.motion_doubt`).
  The best gait is then commanded and left running.

A changed robot: with ``watch`` (default) the node keeps re-measuring its incumbent after it
converged, and a re-measurement ``change_sigmas`` standard errors off its standing value, or one
whose passive shapes differ from the standing runs' (``passive_alpha``; on a robot without passive
joints, whose motion the model of the standing data cannot explain: ``model_miss``), drops
the old data and starts the search afresh on the robot as it is now (see
:class:`~suds_ros.core.optimize.loop.GaitSearch`); with ``listen_monitor`` a ``suds/mismatch``
channel of the monitor node entering ERROR says so directly.

The model is local to a gait, so the node fits its own from each run's window (it does not use
the estimator's model, which spans the switches). The fit and the step run in one spawned worker
process, so the node keeps taking samples meanwhile. The start gait is ``start_gait`` (a gait
file) or the robot's nominal gait, commanded at the first shape sample.

System
------
``system`` (built-in id) or ``model_file`` (robot model file, wins when set): the joints, their
roles, the joint range and speed bounds (``joints[j].limit`` / ``speed_limit``), and the nominal
gait.  The robot never sees more of it than the gait commands.
"""

from __future__ import annotations

import math
import multiprocessing
import sys
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from suds_ros.core.config import check_settings, setting
from suds_ros.core.errors import SudsError
from suds_ros.core.json_text import dumps
from suds_ros.core.optimize.data import FRAMES
from suds_ros.core.optimize.live import LiveGaitSearch, decide
from suds_ros.core.optimize.loop import GaitSearch, LoopConfig, LoopIteration, RunRequest, motion_doubt
from suds_ros.core.physics.gait import Gait, check_gait, dump_gait, gait_limits, load_gait, nominal_gait
from suds_ros.core.physics.systems import load_system
from suds_ros.ros.conversions import (
    LEVELS,
    diagnostics_from_msg,
    gait_switch_from_msg,
    gait_to_msg,
    gait_trajectory_msg,
    joint_state_from_msg,
    pose_from_msg,
    select_joints,
)
from suds_ros.ros.params import config_from_parameters
from suds_ros.ros.qos import GAIT_QOS, STATUS_QOS, SWITCH_QOS
from suds_ros.ros.runner import run_node
from suds_ros.ros.topics import GAIT_COMMAND, GAIT_SWITCH, GAIT_TRAJECTORY, MISMATCH, OPTIMIZER, POSE, SHAPE


@dataclass(frozen=True)
class OptimizerNodeConfig:
    """Parameters of the optimizer node (all read-only)."""

    system: str = setting("purcell3", "robot: built-in system id (purcell3, swimmer9, nlinkN)")
    model_file: str = setting("", "robot model file (suds-robot/1); when set it is the robot and `system` is ignored")
    objective: str = setting("speed", "what to maximise (efficiency needs the actuator effort on suds/shape, e.g. "
                                      "the simulator's effort:=true)", choices=("speed", "turn", "efficiency"))
    budget_cycles: int = setting(200, "gait cycles the search may ask for in all", ge=6)
    start_gait: str = setting("", "gait file (suds-gait/1) to start from (empty: the robot's nominal gait)")
    order: int = setting(3, "harmonics of the proposed gaits", ge=1, le=8)
    first_cycles: int = setting(4, "measured cycles of the start gait", ge=4)
    step_cycles: int = setting(4, "measured cycles of each candidate gait", ge=4)
    settle_cycles: int = setting(1, "cycles discarded after each switch (the fade and the transient)", ge=1)
    samples_per_cycle: int = setting(100, "pose samples per cycle the measurement interpolates onto", ge=8)
    seed: int = setting(0, "seed of the model's predictive draws", ge=0)
    watch: bool = setting(True, "at convergence keep re-measuring the incumbent (until the budget is spent), so a "
                                "changed robot is noticed")
    change_sigmas: float = setting(2.5, "a re-measured incumbent this many standard errors off its standing value "
                                        "means the robot changed", gt=0.0)
    model_miss: float = setting(0.15, "a run whose motion misses the model's prediction along its own shapes by "
                                      "this much (fraction of its translation, or rad of yaw per cycle) means the "
                                      "robot changed (on a robot without passive joints)", gt=0.0)
    passive_alpha: float = setting(0.01, "a re-measured incumbent whose passive shapes differ from its standing runs' "
                                         "at this significance (no model) means the robot changed; 0: never (the "
                                         "model's miss instead)", ge=0.0, lt=1.0)
    half_wave: bool = setting(True, "from a half-wave symmetric incumbent (a travelling sine) measured on course, "
                                    "steps move only the odd harmonics: a straight course on a mirror-symmetric "
                                    "robot whatever the model's yaw says (speed, efficiency)")
    rotation_sigmas: float = setting(1.0, "a measured rotation counts as over the straight-course bound only when "
                                          "over it by more than this many standard errors", ge=0.0)
    rotation_margin: float = setting(LoopConfig.rotation_margin, "each step asks the model for a rotation within "
                                                                 "this fraction of the straight-course bound "
                                                                 "(speed)", gt=0.0, le=1.0)
    scale_step: float = setting(1.25, "right after the start, a start whose oscillation can grow this much inside "
                                      "the joint bounds is run scaled to them (speed, turn; .inf: never)", gt=1.0)
    reverse_trial: bool = setting(True, "once, after the (scaled) start, when its model predicts it better, run the "
                                        "incumbent backwards in time (the travelling wave the other way) and go on "
                                        "from whichever measures better")
    rotation_from_model: bool = setting(True, "judge the straight-course bound on the rotation of the SUDS model "
                                              "fitted to each run's own cycles, where it fits (else the mean of "
                                              "the cycles)")
    body_frame: str = setting("shape", "the body frame the models are fitted in: shape (the recorded yaw turned by "
                                       "the joint angles it follows) or pose (the recorded frame)",
                              choices=FRAMES)
    pool_incumbents: int = setting(0, "also fit each step's model to the newest this many stretches of the gaits "
                                      "that were the incumbent before (0: none; dropped when the robot changes)",
                                   ge=0, le=1_000_000)
    listen_monitor: bool = setting(True, "a suds/mismatch channel entering ERROR (the monitor node) says the robot "
                                         "changed")
    wait_for_switch: bool = setting(True, "place each run by the robot's suds/gait_switch stamp (false: assume "
                                          "the switch one cycle after the command, for a robot that does not "
                                          "publish it)")
    switch_timeout_cycles: float = setting(5.0, "cycles of stamps after a command without its suds/gait_switch, "
                                                "then it is commanded again", gt=1.0)
    trajectory_points: int = setting(50, "points per cycle of suds/gait_trajectory", ge=4, le=10_000)
    depth: int = setting(1000, "subscription queue depth of shape and pose", ge=1, le=10_000_000)
    best_effort: bool = setting(False, "subscribe best effort (sensor-data publishers) instead of reliable")

    def __post_init__(self) -> None:
        check_settings(self)

    @property
    def system_spec(self) -> str:
        """What :func:`~suds_ros.core.physics.systems.load_system` builds: ``model_file``, else ``system``."""
        return self.model_file or self.system

    def loop_config(self) -> LoopConfig:
        """The search's settings (the simulated-robot fields of :class:`LoopConfig` are unused live)."""
        return LoopConfig(budget_cycles=self.budget_cycles, seed=self.seed, objective=self.objective,
                          first_cycles=self.first_cycles, step_cycles=self.step_cycles,
                          settle_cycles=self.settle_cycles, order=self.order,
                          samples_per_cycle=self.samples_per_cycle, watch=self.watch,
                          change_sigmas=self.change_sigmas, model_miss=self.model_miss,
                          passive_alpha=self.passive_alpha, half_wave=self.half_wave,
                          rotation_sigmas=self.rotation_sigmas, scale_step=self.scale_step,
                          reverse_trial=self.reverse_trial, rotation_from_model=self.rotation_from_model,
                          pool_incumbents=self.pool_incumbents, body_frame=self.body_frame,
                          rotation_margin=self.rotation_margin)


def iteration_json(it: LoopIteration, request: RunRequest, live: LiveGaitSearch,
                   window: tuple[float, float, float], objective: str) -> str:
    """The ``suds/optimizer`` JSON of one measured run (``window``: switch stamp, window start and end)."""
    m = it.measured
    return dumps({
        "index": it.index, "kind": request.kind, "accepted": it.accepted, "objective": objective,
        "measured": m.value(objective), "measured_se": m.value_se(objective),
        "measured_rotation": m.rotation, "model_rotation": m.model_rotation,  # (the bound's reading where set)
        "predicted": it.predicted, "predicted_std": it.predicted_std,
        "cycles_requested": live.search.cycles_used, "cycles_elapsed": round(live.cycles_elapsed, 3),
        "switched": window[0], "window": list(window[1:]), "note": it.note, "gait": dump_gait(it.gait),
        "done": False}, sort_keys=True)


def warm_up() -> None:
    """Import the search's modules in the worker process (run once at start)."""
    import suds_ros.core.optimize.live  # noqa: F401


class OptimizerNode(Node):
    """Command gaits, collect their cycles by stamps, fit and step in a worker process."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("suds_optimizer", **kwargs)
        params = config_from_parameters(self, OptimizerNodeConfig)
        self.params = params
        self.system = load_system(params.system_spec)
        s = self.system
        names = tuple(s.joint_names)
        start: Gait = (check_gait(load_gait(params.start_gait, s), s, "start_gait") if params.start_gait
                       else nominal_gait(s))
        self.limits = gait_limits(s)
        search = GaitSearch(start, self.limits, params.loop_config())
        self.live = LiveGaitSearch(search, names, tuple(names[i] for i in s.actuated),
                                   tuple(names[i] for i in s.passive), s.name)
        self._executor = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
        self._executor.submit(warm_up)  # spawn and import now, not at the first decision
        self._future: Future[Any] | None = None
        self._running: tuple[RunRequest, tuple[float, float, float]] | None = None
        self.done = False
        self.skipped = 0
        self._changed: str | None = None  # a change said while the worker held the search
        self._in_error = False
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import JointState
        from std_msgs.msg import String
        from trajectory_msgs.msg import JointTrajectory

        self._string = String
        qos = QoSProfile(depth=params.depth, reliability=ReliabilityPolicy.BEST_EFFORT if params.best_effort
                         else ReliabilityPolicy.RELIABLE)
        self._command_pub = self.create_publisher(String, GAIT_COMMAND, GAIT_QOS)
        self._trajectory_pub = self.create_publisher(JointTrajectory, GAIT_TRAJECTORY, GAIT_QOS)
        self._status_pub = self.create_publisher(String, OPTIMIZER, STATUS_QOS)
        self.create_subscription(JointState, SHAPE, self._on_shape, qos)
        self.create_subscription(PoseStamped, POSE, self._on_pose, qos)
        self.create_subscription(String, GAIT_SWITCH, self._on_switch, SWITCH_QOS)
        if params.listen_monitor:
            self.create_subscription(DiagnosticArray, MISMATCH, self._on_mismatch, STATUS_QOS)
        self.create_timer(0.05, self._tick)
        self.get_logger().info(
            f"optimising {params.objective} of {s.name}: budget {params.budget_cycles} cycles, order {params.order}, "
            f"start {'gait ' + params.start_gait if params.start_gait else 'the nominal gait'}; waiting for "
            f"{self.resolve_topic_name(SHAPE)}")

    # ------------------------------------------------------------ traffic
    def _on_shape(self, msg: Any) -> None:
        try:
            sample = select_joints(joint_state_from_msg(msg), self.live.joint_names)  # finite: checked there
        except SudsError:
            self.skipped += 1
            return
        self.live.on_shape(sample.stamp, sample.position, sample.effort)

    def _on_pose(self, msg: Any) -> None:
        try:
            p = pose_from_msg(msg)
        except SudsError:
            self.skipped += 1
            return
        self.live.on_pose(p.stamp, p.x, p.y, p.yaw)

    def _on_switch(self, msg: Any) -> None:
        try:
            stamp, gait = gait_switch_from_msg(msg)
        except SudsError as exc:
            self.skipped += 1
            self.get_logger().warning(f"bad {GAIT_SWITCH} message skipped: {exc}")
            return
        w = self.live.on_switch(stamp, gait)
        if w is not None:
            self.get_logger().info(f"gait in force from stamp {stamp:.3f}: measuring [{w.start:.3f}, {w.end:.3f}] s")

    def _on_mismatch(self, msg: Any) -> None:
        try:
            reports = diagnostics_from_msg(msg)
        except SudsError:
            self.skipped += 1
            return
        bad = [r.name.split("/")[-1] for r in reports if r.level == LEVELS["ERROR"]]  # STALE: not tested, not bad
        if bad and not self._in_error:
            self.robot_changed(f"the monitor's {', '.join(bad)} in ERROR")
        if bad or not any(r.level == LEVELS["STALE"] for r in reports):  # a report that could not tell ends nothing
            self._in_error = bool(bad)

    def robot_changed(self, reason: str) -> None:
        """The robot changed: the search re-measures its incumbent afresh (after the running step, if any)."""
        self.get_logger().warning(f"robot changed ({reason}): the incumbent gait is measured afresh")
        if self._future is not None:
            self._changed = reason
        else:
            self.live.search.robot_changed(reason)

    # ------------------------------------------------------------ the search
    def _tick(self) -> None:
        if self.done:
            return
        live = self.live
        if self._future is not None:
            if self._future.done():
                self._decided()
            return
        if live.commanded is None:
            if math.isfinite(live.newest_shape):  # the stream runs: command the start gait
                req = live.search.request()
                assert req is not None
                self._command(req)
            return
        if live.window is None and self.params.wait_for_switch:
            f = live.commanded.gait.gait_hz
            if live.newest_shape > live.commanded_at + self.params.switch_timeout_cycles / f:
                self.get_logger().warning(f"no {GAIT_SWITCH} for the gait commanded at stamp "
                                          f"{live.commanded_at:.3f}; commanding it again")
                self._command(live.commanded)
            return
        if not live.complete():
            return
        w = live.window
        assert w is not None
        try:
            data = live.take()
        except SudsError as exc:  # a stalled stream: run the same request again
            self.get_logger().warning(f"{exc}; running the same gait again")
            self._command(w.request)
            return
        self._running = (w.request, (w.switched, w.start, w.end))
        self._future = self._executor.submit(decide, live.search, data)

    def _decided(self) -> None:
        """The worker's answer: publish the run's status, then command the next gait or finish."""
        fut, self._future = self._future, None
        assert fut is not None and self._running is not None
        req, window = self._running
        live = self.live
        try:
            live.search, it, nxt = fut.result()
        except Exception as exc:  # noqa: BLE001 - a failed step ends the search, never the node
            why = str(exc) if isinstance(exc, SudsError) else f"{type(exc).__name__}: {exc}"
            self.get_logger().error(f"optimizer stopped: {why}")
            self._finish(f"error: {why}")
            return
        if self._changed is not None:
            live.search.robot_changed(self._changed)
            self._changed = None
            nxt = live.search.request()
        obj = self.params.objective
        self._status_pub.publish(self._string(data=iteration_json(it, req, live, window, obj)))
        self.get_logger().info(f"run {it.index} ({req.kind}): measured {obj} {it.measured.value(obj):.4g}, "
                               f"{'accepted' if it.accepted else 'rejected'}; {it.note}")
        if nxt is None:
            self._finish(live.search.stopped or "stopped")
        else:
            self._command(nxt)

    def _command(self, req: RunRequest) -> None:
        live = self.live
        live.command(req)
        self._publish_gait(req.gait, live.commanded_at)
        text = f"{req.kind} gait commanded at stamp {live.commanded_at:.3f}"
        if not self.params.wait_for_switch:
            w = live.assume_switch()
            text += f": measuring [{w.start:.3f}, {w.end:.3f}] s"
        self.get_logger().info(text)

    def _publish_gait(self, gait: Gait, stamp: float) -> None:
        self._command_pub.publish(gait_to_msg(gait))
        self._trajectory_pub.publish(gait_trajectory_msg(gait, stamp, self.params.trajectory_points))

    def _finish(self, why: str) -> None:
        self.done = True
        live = self.live
        try:
            res = live.search.result()
        except SudsError:
            return
        self._publish_gait(res.gait, live.newest_shape)
        doubt = motion_doubt(res.measured, self.params.objective)
        self._status_pub.publish(self._string(data=dumps({
            "done": True, "stopped": why, "objective": self.params.objective, "index": res.index,
            "measured": res.measured.value(self.params.objective), "predicted": res.predicted,
            "predicted_std": res.predicted_std, "cycles_requested": res.cycles_used,
            "cycles_elapsed": round(live.cycles_elapsed, 3), "motion_warning": doubt,
            "gait": dump_gait(res.gait)}, sort_keys=True)))
        self.get_logger().info(f"done ({why}): best gait from run {res.index}, measured "
                               f"{self.params.objective} {res.measured.value(self.params.objective):.4g}; "
                               "it is commanded and left running")
        if doubt:
            self.get_logger().warning(doubt)

    def close(self) -> None:
        """Stop the worker process (a step in progress is abandoned)."""
        for proc in list((getattr(self._executor, "_processes", None) or {}).values()):
            proc.terminate()  # the executor has no public way to abandon a running call
        self._executor.shutdown(wait=True, cancel_futures=True)


def main(args: list[str] | None = None) -> int:
    """Run the optimizer until SIGINT/SIGTERM; 1 with the reason if it cannot start."""
    return run_node(args, name="optimizer", doc=__doc__, config_cls=OptimizerNodeConfig, make=OptimizerNode,
                    close=lambda node: node.close())


if __name__ == "__main__":
    sys.exit(main())
