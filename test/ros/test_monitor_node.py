"""End to end, each node in its own process: simulator → monitor, friction switched on mid-run.

The test sets the simulator's ``effects`` parameter through its parameter service once the
monitor has seen 19.5 nominal cycles; the simulator applies it from its next gait cycle and logs
the stamp of the first sample simulated with it (the onset).  Expected: no alarm (every channel
OK) on ``/suds/mismatch`` before the onset, ERROR within 5 cycles after it, and on
``/suds/diagnosis`` the named effect with its parameter within 25 %.
"""

from __future__ import annotations

import json
import re

import pytest

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import set_simulator_parameter, stop, wait_for
except ImportError:
    from _ros_helpers import set_simulator_parameter, stop, wait_for

pytestmark = pytest.mark.ros

T0 = 1.7e9  # the simulator's first stamp when not in real time
MU = 0.5
FRICTION = [{"name": "joint_coulomb_friction", "joint": "joint_2", "mu": MU}]


def set_effects(probe, value: str):
    """Set the simulator's ``effects``; returns the SetParametersResult."""
    return set_simulator_parameter(probe, "effects", value)


def test_friction_appearing_mid_run_is_flagged_and_named(start_process, node_command, probe):
    from diagnostic_msgs.msg import DiagnosticArray
    from std_msgs.msg import String

    from suds_ros.ros.conversions import diagnostics_from_msg
    from suds_ros.ros.qos import MODEL_QOS, STATUS_QOS

    mismatch = probe.listen("/suds/mismatch", DiagnosticArray, STATUS_QOS)
    diagnosis = probe.listen("/suds/diagnosis", String, MODEL_QOS)
    mon = start_process(node_command("monitor_node", "system:=purcell3"), "monitor")
    graph = probe.node
    wait_for(lambda: graph.count_subscribers("/suds/body_pose") >= 1, 60, lambda: f"the monitor\n{mon.output()}")
    sim = start_process(node_command("simulator_node", "system:=purcell3", "real_time_factor:=2.0", "seed:=3",
                                     "cycles:=60"), "simulator")

    def reports():
        return [rep for m in mismatch.messages() for rep in diagnostics_from_msg(m)]

    def newest() -> float:
        return max((r.stamp for r in reports()), default=0.0)

    wait_for(lambda: newest() >= T0 + 19.5, 120,
             lambda: f"19.5 monitored cycles (newest {newest() - T0:.2f})\n{mon.output()}\n{sim.output()}")
    refused = set_effects(probe, json.dumps([dict(FRICTION[0], joint="joint_1")]))
    assert not refused.successful and "actuated" in refused.reason
    assert set_effects(probe, json.dumps(FRICTION)).successful
    found = re.compile(r"effects .* on from stamp ([0-9.]+)")
    wait_for(lambda: found.search(sim.output()), 60, lambda: f"the switch\n{sim.output()}")
    onset = float(found.search(sim.output()).group(1))
    assert onset >= T0 + 20.0
    wait_for(lambda: any(r.level == 2 for r in reports()) or newest() > onset + 5.0, 120,
             lambda: f"an alarm\n{mon.output()}")
    before = [r for r in reports() if r.stamp < onset]
    assert len({r.name for r in before}) == 4 and all(r.level == 0 for r in before), \
        [r for r in before if r.level][:3]
    first_error = min(r.stamp for r in reports() if r.level == 2)
    assert onset <= first_error < onset + 5.0, (onset, first_error)

    wait_for(lambda: len(diagnosis) >= 1, 300, lambda: f"the diagnosis\n{mon.output()}")
    report = json.loads(diagnosis.messages()[0].data)
    print(json.dumps(report["effects"]), report["monitor"])
    assert report["mismatch"] and report["effects"], report
    effect = report["effects"][0]
    assert (effect["name"], effect["target"]) == ("joint_coulomb_friction", "joint_2"), report
    assert effect["parameters"]["mu"] == pytest.approx(MU, rel=0.25)
    assert report["monitor"]["window"][0] >= onset
    assert stop(sim) == 0 or sim.poll() == 0, sim.output()
    assert stop(mon) == 0, mon.output()


# ------------------------------------------------------------------ parameters (in process)
@pytest.mark.parametrize(("kind", "params", "match"), [
    ("simulator", {"effects": "[{"}, r"`effects`: expected a JSON list"),
    ("simulator", {"effects": '{"name": "joint_coulomb_friction"}'}, r"`effects`: expected a JSON list of objects"),
    ("simulator", {"effects": '[{"name": "joint_coulomb_friction", "joint": "joint_1", "mu": 0.5}]'},
     r"joint 'joint_1' is actuated"),
    ("monitor", {"warn": 5.0, "error": 4.0}, r"`error`: expected a threshold > warn"),
    ("monitor", {"persist_cycles": 2}, r"persist_cycles"),
    ("monitor", {"system": "nope"}, r"unknown system 'nope'"),
    ("monitor", {"gait_hz": 0.0}, r"`gait_hz`"),
])
def test_bad_start_parameter_is_refused_with_reason(ros_context, kind, params, match):
    from rclpy.parameter import Parameter

    from suds_ros.core.errors import SudsConfigError
    from suds_ros.ros.monitor_node import MonitorNode
    from suds_ros.ros.simulator_node import SimulatorNode

    cls = {"simulator": SimulatorNode, "monitor": MonitorNode}[kind]
    with pytest.raises(SudsConfigError, match=match):
        cls(context=ros_context, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])


def test_simulator_effects_at_run_time(ros_context):
    from rclpy.parameter import Parameter

    from suds_ros.ros.simulator_node import SimulatorNode

    node = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter("real_time_factor", value=0.0), Parameter("cycles", value=3)])
    try:
        assert node.describe_parameter("effects").read_only is False
        node._next_sample()  # the first chunk: nominal
        assert node.sim.effects == ()
        bad = node.set_parameters([Parameter("effects", value='[{"name": "glue"}]')])[0]
        assert not bad.successful and "unknown effect 'glue'" in bad.reason
        assert node.config.effects == ""
        ok = node.set_parameters([Parameter("effects", value=json.dumps(FRICTION))])[0]
        assert ok.successful and node.sim.effects == ()  # applied from the next chunk on
        for _ in range(100):
            node._next_sample()
        assert node.sim.effects == tuple(FRICTION) and node._chunk.t[0] == pytest.approx(T0 + 1.0)
    finally:
        node.destroy_node()


def test_monitor_node_publishes_per_channel_statuses(ros_context):
    """Fed in process: one status per channel from the first report (after the floor's 3 cycles) on."""
    from rclpy.parameter import Parameter

    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.stream import StreamingSimulator
    from suds_ros.ros.conversions import diagnostics_from_msg, joint_state_to_msg, pose_to_msg
    from suds_ros.ros.monitor_node import MonitorNode

    node = MonitorNode(context=ros_context, parameter_overrides=[Parameter("diagnose", value=False)])
    try:
        sim = StreamingSimulator(node.system, SimConfig(seed=0))
        for _ in range(5):
            ch = sim.step(100)
            for k in range(100):
                node._on_pose(pose_to_msg(ch.t[k], *ch.pose[k]))
                node._on_shape(joint_state_to_msg(ch.t[k], ("joint_1", "joint_2"), ch.r[k]))
        reports = diagnostics_from_msg(node.mismatch_msg())
        assert [r.name for r in reports] == [f"suds_monitor/{c}" for c in ("joint_2", "xi_x", "xi_y", "xi_theta")]
        assert all(r.level == 0 and float(r.values["statistic"]) < 4.0 for r in reports)
        assert reports[0].stamp == pytest.approx(ch.t[-1]) and float(reports[0].values["since"]) <= ch.t[-1]
        # the body channels carry the pose-lag fit (from 4 whole cycles on): about 0 for the nominal streams
        assert "pose_lag_s" not in reports[0].values
        assert all(abs(float(r.values["pose_lag_s"])) < 1e-3 and float(r.values["pose_lag_score"]) < 4.0
                   and 0.0 <= float(r.values["pose_lag_share"]) <= 1.0
                   for r in reports[1:]), [r.values for r in reports]
    finally:
        node.close()
        node.destroy_node()


def test_monitor_node_says_stale_when_lost_messages_leave_nothing_to_test(ros_context):
    """30 % of each stream lost (seeded): too few clean windows for a statistic, so every channel is STALE, with
    the reason in the message, not OK and not a false ERROR."""
    import numpy as np
    from rclpy.parameter import Parameter

    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.stream import StreamingSimulator
    from suds_ros.ros.conversions import diagnostics_from_msg, joint_state_to_msg, pose_to_msg
    from suds_ros.ros.monitor_node import MonitorNode

    node = MonitorNode(context=ros_context, parameter_overrides=[Parameter("diagnose", value=False)])
    try:
        sim = StreamingSimulator(node.system, SimConfig(seed=0))
        lost = np.random.default_rng(7).random((6, 100, 2)) < 0.3
        for c in range(6):
            ch = sim.step(100)
            for k in range(100):
                if not lost[c, k, 1] or (c, k) in ((0, 0), (5, 99)):
                    node._on_pose(pose_to_msg(ch.t[k], *ch.pose[k]))
                if not lost[c, k, 0] or (c, k) in ((0, 0), (5, 99)):
                    node._on_shape(joint_state_to_msg(ch.t[k], ("joint_1", "joint_2"), ch.r[k]))
        assert node.monitor.updated > 0
        reports = diagnostics_from_msg(node.mismatch_msg())
        assert [r.level for r in reports] == [3] * 4, [(r.level, r.message) for r in reports]
        assert all("lost messages" in r.message for r in reports)
    finally:
        node.close()
        node.destroy_node()


def test_monitor_node_passes_on_what_its_grid_stage_holds_when_the_shape_stream_goes_quiet(ros_context):
    """A jittered shape stream (2 ms) waits in the monitor's grid stage; once no shape message has come for
    ``idle_flush`` the node passes the held samples on, and its status reaches the last one."""
    from rclpy.parameter import Parameter

    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.ros.conversions import diagnostics_from_msg, joint_state_to_msg, pose_to_msg
    from suds_ros.ros.monitor_node import MonitorNode

    params = [Parameter("diagnose", value=False), Parameter("idle_flush", value=0.5)]
    node = MonitorNode(context=ros_context, parameter_overrides=params)
    try:
        rec = simulate_lab(node.system, SimConfig(cycles=5, seed=3), LabConditions(jitter=0.002))
        for t, p in zip(rec.pose_t, rec.pose):
            node._on_pose(pose_to_msg(t, *p))
        for t, r in zip(rec.t, rec.r):
            node._on_shape(joint_state_to_msg(t, rec.joint_names, r))
        held, paired = node.monitor.held, node.monitor.paired
        assert held > 0 and node.monitor.updated > 0
        node._on_idle_check()  # not quiet for idle_flush yet: nothing happens
        assert node.monitor.held == held
        node._last_arrival -= 1.0  # as if the last shape message came a second ago
        node._on_idle_check()
        assert node.monitor.held == 0 and node.monitor.paired > paired
        reports = diagnostics_from_msg(node.mismatch_msg())
        assert reports[0].stamp >= rec.t[-1] - 10 * rec.dt
    finally:
        node.close()
        node.destroy_node()


def test_monitor_node_compares_the_samples_it_held_for_a_heavily_jittered_count(ros_context):
    """Stamped late with 3 ms of jitter: the grid stage's count waits ~7.7 s for a recount to confirm it; the
    node's monitor holds the samples meanwhile and then compares them all at once, so its record starts at the
    first report a steady stream would have (~3 s in), and the nominal robot stays OK."""
    from rclpy.parameter import Parameter

    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.ros.conversions import diagnostics_from_msg, joint_state_to_msg, pose_to_msg
    from suds_ros.ros.monitor_node import MonitorNode

    node = MonitorNode(context=ros_context, parameter_overrides=[Parameter("diagnose", value=False)])
    try:
        rec = simulate_lab(node.system, SimConfig(cycles=12, seed=0), LabConditions(jitter=0.003, stamping="arrival"))
        stream = sorted([(t, 0, i) for i, t in enumerate(rec.t)] + [(t, 1, i) for i, t in enumerate(rec.pose_t)])
        updates_at_6s = None
        for t, kind, i in stream:  # in stamp order, as they would arrive
            if kind:
                node._on_pose(pose_to_msg(t, *rec.pose[i]))
            else:
                node._on_shape(joint_state_to_msg(t, rec.joint_names, rec.r[i]))
            if updates_at_6s is None and t - rec.t[0] > 6.0:
                updates_at_6s = node.monitor.updated
        assert updates_at_6s == 0  # nothing compared while the count was unconfirmed
        record = node.monitor.record
        assert record.stamped_late is not None and record.unconfirmed == 0
        assert record.first_report - rec.t[0] < 4.0
        reports = diagnostics_from_msg(node.mismatch_msg())
        assert reports and all(r.level == 0 for r in reports), [(r.name, r.message) for r in reports]
    finally:
        node.close()
        node.destroy_node()
