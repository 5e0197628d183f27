"""End to end: the optimizer node (own process) runs run → fit → step on the simulator node (own
process): it commands gaits on ``suds/gait_command``, places each run by the simulator's
``suds/gait_switch`` stamp, reports every run on ``suds/optimizer``, publishes each gait as a
JointTrajectory, and leaves the best gait running when its budget is spent."""

from __future__ import annotations

import json

import numpy as np
import pytest

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import stop, wait_for
except ImportError:
    from _ros_helpers import stop, wait_for

pytestmark = pytest.mark.ros


def _stamp(t) -> float:  # type: ignore[no-untyped-def]
    return t.sec + 1e-9 * t.nanosec


def test_optimizer_node_runs_the_loop_on_the_simulator(start_process, node_command, probe):
    from std_msgs.msg import String
    from trajectory_msgs.msg import JointTrajectory

    from suds_ros.core.physics.gait import check_constraints, gait_limits, loads_gait, nominal_gait, same_gait
    from suds_ros.core.physics.systems import make_system
    from suds_ros.ros.conversions import gait_switch_from_msg
    from suds_ros.ros.qos import GAIT_QOS, STATUS_QOS, SWITCH_QOS

    system = make_system("purcell3")
    limits = gait_limits(system)
    status = probe.listen("/suds/optimizer", String, STATUS_QOS)
    trajectories = probe.listen("/suds/gait_trajectory", JointTrajectory, GAIT_QOS)
    switches = probe.listen("/suds/gait_switch", String, SWITCH_QOS)
    # budget 14: the start gait (1 settling + 4 measured cycles) and one candidate (1 + 4), then done
    opt = start_process(node_command("optimizer_node", "system:=purcell3", "budget_cycles:=14", "seed:=0"),
                        "optimizer")
    # the status is not latched: its subscription must match before the stream (and the start run) begins
    wait_for(lambda: status.publishers() >= 1, 120, lambda: f"the optimizer's status publisher\n{opt.output()}")
    sim = start_process(node_command("simulator_node", "system:=purcell3", "real_time_factor:=4.0", "seed:=1"),
                        "simulator")

    def runs() -> list[dict]:
        return [json.loads(m.data) for m in status.messages()]

    wait_for(lambda: any(r["done"] for r in runs()), 300,
             lambda: f"the optimizer's last message\n{opt.output()}\n{sim.output()}")
    measured = [r for r in runs() if not r["done"]]
    final = [r for r in runs() if r["done"]][-1]
    assert measured[0]["kind"] == "start" and same_gait(loads_gait(measured[0]["gait"]), nominal_gait(system))
    assert len(measured) >= 2, opt.output()  # the start gait and at least one candidate were measured
    assert final["cycles_requested"] <= 14 and final["cycles_elapsed"] > final["cycles_requested"]
    assert final["motion_warning"] is None or "cannot be told from none" in final["motion_warning"]
    switched = [gait_switch_from_msg(m) for m in switches.messages()]
    for run in measured:
        gait = loads_gait(run["gait"])
        check_constraints(gait, limits)  # never a gait outside the joint range and speed bounds
        # placed by the simulator's own stamp of the switch to this gait, settling cycle skipped
        assert any(abs(t - run["switched"]) < 1e-6 and same_gait(g, gait) for t, g in switched), (run, switched)
        start, end = run["window"]
        assert start == pytest.approx(run["switched"] + 1.0, abs=1e-6)
        assert end - start == pytest.approx(4.0, abs=1e-6)  # the start's measured cycles too (first_cycles)
        assert np.isfinite(run["measured"]) and run["measured"] > 0
    # the rotation the straight-course bound was judged on: the model of the run's own cycles (purcell3: straight)
    assert any(run["model_rotation"] is not None for run in measured)
    assert all(abs(run["model_rotation"]) < 0.05 for run in measured if run["model_rotation"] is not None)
    best = loads_gait(final["gait"])
    # the best gait is commanded last, as a trajectory of one cycle for the actuated joint
    wait_for(lambda: trajectories.messages()
             and np.allclose([p.positions[0] for p in trajectories.messages()[-1].points],
                             best.r(np.arange(51) / 50.0)[:, 0], atol=1e-12),
             60, lambda: f"the best gait's trajectory\n{opt.output()}")
    traj = trajectories.messages()[-1]
    assert list(traj.joint_names) == ["joint_1"] and len(traj.points) == 51
    assert _stamp(traj.points[-1].time_from_start) == pytest.approx(1.0, abs=1e-9)
    assert max(abs(p.positions[0]) for p in traj.points) <= limits.limit[0] + 1e-9
    assert np.allclose([p.velocities[0] for p in traj.points], best.rdot(np.arange(51) / 50.0)[:, 0], atol=1e-12)
    assert stop(opt) == 0, opt.output()
    assert "Traceback" not in opt.output(), opt.output()
    assert stop(sim) == 0, sim.output()


def test_optimizer_node_optimises_efficiency_from_the_simulators_effort(start_process, node_command, probe):
    """The simulator publishes its actuator effort (effort:=true); the optimizer measures each run's
    work from it and reports the efficiency (m/J)."""
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    from suds_ros.ros.qos import STATUS_QOS, latched_state_qos

    status = probe.listen("/suds/optimizer", String, STATUS_QOS)
    shape = probe.listen("/suds/shape", JointState, latched_state_qos(10))
    opt = start_process(node_command("optimizer_node", "system:=purcell3", "budget_cycles:=11", "seed:=0",
                                     "objective:=efficiency"), "optimizer")
    wait_for(lambda: status.publishers() >= 1, 120, lambda: f"the optimizer's status publisher\n{opt.output()}")
    sim = start_process(node_command("simulator_node", "system:=purcell3", "real_time_factor:=4.0", "seed:=1",
                                     "effort:=true"), "simulator")
    wait_for(lambda: any(json.loads(m.data)["done"] for m in status.messages()), 300,
             lambda: f"the optimizer's last message\n{opt.output()}\n{sim.output()}")
    runs = [json.loads(m.data) for m in status.messages()]
    measured = [r for r in runs if not r["done"]]
    assert [r["kind"] for r in measured] == ["start", "candidate"], opt.output()
    assert all(r["objective"] == "efficiency" and np.isfinite(r["measured"]) and r["measured"] > 0 for r in measured)
    assert not runs[-1]["stopped"].startswith("error"), runs[-1]
    efforts = [m.effort for m in shape.messages() if len(m.effort)]
    assert efforts and all(e[1] == 0.0 for e in efforts)  # joint_2 is passive: no actuator effort
    assert stop(opt) == 0, opt.output()
    assert stop(sim) == 0, sim.output()


# ------------------------------------------------------------------ in process
def test_the_monitors_alarm_says_the_robot_changed_once_per_episode(ros_context):
    from concurrent.futures import Future

    from suds_ros.ros.conversions import diagnostics_to_msg
    from suds_ros.ros.optimizer_node import OptimizerNode

    def array(*levels: str):  # type: ignore[no-untyped-def]
        msgs = [diagnostics_to_msg(5.0, f"suds_monitor/{ch}", {}, level=lv)
                for ch, lv in zip(("joint_2", "xi_x"), levels)]
        out = msgs[0]
        for m in msgs[1:]:
            out.status.extend(m.status)
        return out

    node = OptimizerNode(context=ros_context)
    try:
        said: list[str] = []
        node.live.search.robot_changed = said.append  # type: ignore[method-assign]
        node._on_mismatch(array("OK", "WARN"))
        assert said == []
        node._on_mismatch(array("ERROR", "OK"))
        node._on_mismatch(array("ERROR", "ERROR"))  # the same episode
        node._on_mismatch(array("STALE", "STALE"))  # lost messages: the monitor cannot tell, the episode goes on
        node._on_mismatch(array("ERROR", "STALE"))
        assert said == ["the monitor's joint_2 in ERROR"]
        node._on_mismatch(array("OK", "OK"))
        node._on_mismatch(array("STALE", "OK"))  # not tested is not an alarm
        assert said == ["the monitor's joint_2 in ERROR"]
        node._future = Future()  # a step is running in the worker: the change waits for its answer
        node._on_mismatch(array("OK", "ERROR"))
        assert said == ["the monitor's joint_2 in ERROR"] and node._changed == "the monitor's xi_x in ERROR"
    finally:
        node._future = None
        node.close()
        node.destroy_node()


def test_the_node_passes_its_change_tests_to_the_search() -> None:
    from suds_ros.ros.optimizer_node import OptimizerNodeConfig

    cfg = OptimizerNodeConfig(passive_alpha=0.05, model_miss=0.3, change_sigmas=3.0).loop_config()
    assert (cfg.passive_alpha, cfg.model_miss, cfg.change_sigmas) == (0.05, 0.3, 3.0)
    assert OptimizerNodeConfig().loop_config().passive_alpha == 0.01


def test_the_node_passes_how_the_rotation_is_read_to_the_search() -> None:
    from suds_ros.ros.optimizer_node import OptimizerNodeConfig

    assert OptimizerNodeConfig().loop_config().rotation_from_model
    assert not OptimizerNodeConfig(rotation_from_model=False).loop_config().rotation_from_model


def test_the_node_passes_the_pooling_of_earlier_incumbents_to_the_search() -> None:
    from suds_ros.core.errors import SudsConfigError
    from suds_ros.ros.optimizer_node import OptimizerNodeConfig

    assert OptimizerNodeConfig().loop_config().pool_incumbents == 0
    assert OptimizerNodeConfig(pool_incumbents=2).loop_config().pool_incumbents == 2
    assert OptimizerNodeConfig().loop_config().body_frame == "shape"
    assert OptimizerNodeConfig(body_frame="pose").loop_config().body_frame == "pose"
    with pytest.raises(SudsConfigError, match="body_frame"):
        OptimizerNodeConfig(body_frame="head")
    with pytest.raises(SudsConfigError, match="pool_incumbents"):
        OptimizerNodeConfig(pool_incumbents=-1)


def test_the_node_passes_the_rotation_margin_to_the_search() -> None:
    from suds_ros.core.errors import SudsConfigError
    from suds_ros.core.optimize.loop import LoopConfig
    from suds_ros.ros.optimizer_node import OptimizerNodeConfig

    assert OptimizerNodeConfig().loop_config().rotation_margin == LoopConfig(budget_cycles=10).rotation_margin
    assert OptimizerNodeConfig(rotation_margin=0.5).loop_config().rotation_margin == 0.5
    for bad in (0.0, 1.5):
        with pytest.raises(SudsConfigError, match="rotation_margin"):
            OptimizerNodeConfig(rotation_margin=bad)
