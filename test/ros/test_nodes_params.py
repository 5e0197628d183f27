"""Parameters of the simulator, estimator and predictor nodes: bad values are refused with the reason.

In-process tests build each node with ``parameter_overrides`` in its own
``Context``; a few start the node as a process to check exit codes.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import wait_for
except ImportError:
    from _ros_helpers import wait_for

pytestmark = pytest.mark.ros

EEL4 = Path(__file__).resolve().parents[1] / "data" / "robots" / "eel4.yaml"  # 4 links, gait 0.5 Hz


def make(kind: str, context, **params):
    """Build the ``kind`` node with the given parameter overrides."""
    from rclpy.parameter import Parameter

    from suds_ros.ros.estimator_node import EstimatorNode
    from suds_ros.ros.predictor_node import PredictorNode
    from suds_ros.ros.simulator_node import SimulatorNode

    cls = {"simulator": SimulatorNode, "estimator": EstimatorNode, "predictor": PredictorNode}[kind]
    overrides = [Parameter(k, value=v) for k, v in params.items()]
    return cls(context=context, parameter_overrides=overrides)


@pytest.mark.parametrize(("kind", "params", "match"), [
    ("simulator", {"rate": 50.5}, r"`rate`: rate / gait_hz must be an integer"),
    ("simulator", {"rate": 5.0}, r"`rate`.*≥ 8"),
    ("simulator", {"gait_hz": 3.0}, r"`rate`.*33.3"),
    ("simulator", {"noise": -0.1}, r"`noise`"),
    ("simulator", {"real_time_factor": -1.0}, r"`real_time_factor`"),
    ("simulator", {"cycles": -3}, r"`cycles`"),
    ("simulator", {"system": "nope"}, r"unknown system 'nope'"),
    ("simulator", {"t0": "yesterday"}, r"`t0`"),
    ("simulator", {"seed": "x"}, r"`seed`"),
    ("simulator", {"model_file": "/nonexistent/robot.yaml"}, r"robot.yaml: cannot read the model file"),
    ("simulator", {"system": str(EEL4), "gait_hz": 0.3}, r"`rate`.*333.3"),
    ("simulator", {"model_file": str(EEL4), "rate": 75.3}, r"`rate`.*150.6"),
    ("estimator", {"forgetting": 0.0}, r"`forgetting`"),
    ("estimator", {"init_cycles": 2.0}, r"`init_cycles`"),
    ("estimator", {"system": "purcell3", "actuated": ["joint_1"]}, r"`system` and `actuated`"),
    ("estimator", {"system": "nope"}, r"unknown system"),
    ("estimator", {"chunk": 0}, r"`chunk`"),
    ("predictor", {"executor": "bogus"}, r"`executor`: expected 'events' or 'single'"),
    ("predictor", {"frame_id": ""}, r"`frame_id`"),
])
def test_bad_parameter_is_refused_with_reason(ros_context, kind, params, match):
    from suds_ros.core.errors import SudsConfigError

    with pytest.raises(SudsConfigError, match=match):
        make(kind, ros_context, **params)


def test_unreadable_checkpoint_is_moved_aside_and_the_estimator_starts_afresh(ros_context, tmp_path):
    bad = tmp_path / "garbage.ckpt"
    bad.write_bytes(b"not a checkpoint")
    node = make("estimator", ros_context, checkpoint=str(bad), actuated=["joint_1"])
    try:
        aside = tmp_path / "garbage.ckpt.refused-1"
        assert node.session.refused_checkpoint == str(aside) and node.est is None
        assert aside.read_bytes() == b"not a checkpoint" and not bad.exists()
        assert node.status_values()["refused_checkpoint"] == str(aside)
    finally:
        node.destroy_node()


def test_simulator_runtime_parameters(ros_context):
    from rclpy.parameter import Parameter

    node = make("simulator", ros_context, real_time_factor=2.0, cycles=1)
    try:
        assert node.config.samples_per_cycle == 100 and node.t0 == 1.7e9  # not real time: default t0
        res = node.set_parameters([Parameter("real_time_factor", value=-2.0)])[0]
        assert not res.successful and "real_time_factor" in res.reason
        res = node.set_parameters([Parameter("real_time_factor", value=8.0)])[0]
        assert res.successful and node.config.real_time_factor == 8.0
        res = node.set_parameters([Parameter("system", value="swimmer9")])[0]
        assert not res.successful and "read-only" in res.reason
        d = node.describe_parameter("real_time_factor")
        assert d.description and not d.read_only and d.floating_point_range[0].from_value == 0.0
        assert node.describe_parameter("system").read_only
    finally:
        node.destroy_node()


def test_simulator_from_a_model_file(ros_context):
    """`model_file` (or `system` given a path) is the simulated robot; its gait_hz is the default."""
    import json

    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import String

    from suds_ros.ros.qos import MODEL_QOS

    got: list = []
    listener = Node("listener", context=ros_context)
    listener.create_subscription(String, "/suds/system", got.append, MODEL_QOS)
    node = make("simulator", ros_context, model_file=str(EEL4), rate=50.0, cycles=1, real_time_factor=0.0)
    try:
        assert node.system.name == "eel4" and node.names == ("neck", "waist", "tail")
        assert node.config.gait_hz == 0.5 and node.config.samples_per_cycle == 100
        executor = SingleThreadedExecutor(context=ros_context)
        executor.add_node(listener)
        deadline = time.monotonic() + 30
        while not got and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        executor.shutdown()
        assert got, "no /suds/system message"
        info = json.loads(got[-1].data)
        assert info["system"] == "eel4" and info["gait_hz"] == 0.5 and info["rate"] == 50.0
        assert info["actuated"] == ["neck", "waist"] and info["passive"] == ["tail"]
        chunk = node.sim.step(100)
        assert chunk.r.shape == (100, 3) and abs((chunk.t[-1] - chunk.t[0]) - 99 / 50) < 1e-6
    finally:
        node.destroy_node()
        listener.destroy_node()
    node = make("simulator", ros_context, system=str(EEL4), gait_hz=1.0)  # a path works as `system` too
    try:
        assert node.system.name == "eel4" and node.config.samples_per_cycle == 100
    finally:
        node.destroy_node()


def test_real_time_default_t0_is_now(ros_context):
    node = make("simulator", ros_context)
    try:
        assert abs(node.t0 - time.time()) < 5.0
    finally:
        node.destroy_node()


def test_real_time_stream_that_waited_starts_its_stamps_when_it_starts(ros_context):
    """A real-time stream whose start waited for subscribers stamps its first sample at the start."""
    node = make("simulator", ros_context, wait_for_subscribers=1, start_timeout=0.5)
    try:
        built = node.t0
        deadline = time.monotonic() + 30.0
        while node._waiting() and time.monotonic() < deadline:  # nobody subscribes: the timeout starts it
            time.sleep(0.05)
        assert node.t0 >= built + 0.5 and abs(node.t0 - time.time()) < 5.0
        assert node.sim.step(1).t[0] == pytest.approx(node.t0)
    finally:
        node.destroy_node()


def test_estimator_runtime_parameters_and_status(ros_context):
    from rclpy.parameter import Parameter

    node = make("estimator", ros_context, system="purcell3")
    try:
        assert node.est is not None and node.est.actuated == ("joint_1",)
        res = node.set_parameters([Parameter("pose_stall", value=-1.0)])[0]
        assert not res.successful
        res = node.set_parameters([Parameter("pose_stall", value=3.0)])[0]
        assert res.successful and node.config.pose_stall == 3.0
        res = node.set_parameters([Parameter("chunk", value=5)])[0]
        assert not res.successful and "read-only" in res.reason
        values = node.status_values()
        assert values["initialised"] == "false" and values["samples"] == "0"
    finally:
        node.destroy_node()


def test_predictor_starts_and_counts_nothing(ros_context):
    node = make("predictor", ros_context, executor="single")
    try:
        assert node.predictor is None and node.before_model == 0
    finally:
        node.destroy_node()


@pytest.mark.parametrize(("module", "params", "reason"), [
    ("simulator_node", ("rate:=5.0",), "`rate`"),
    ("estimator_node", ("forgetting:=1.5",), "forgetting"),
    ("predictor_node", ("executor:=bogus",), "`executor`"),
])
def test_node_process_exits_1_with_reason(start_process, node_command, module, params, reason):
    proc = start_process(node_command(module, *params), module)
    assert proc.wait(30) == 1, proc.output()
    assert reason in proc.output()


def test_simulator_process_runs_its_cycles_and_exits_0(start_process, node_command):
    proc = start_process(node_command("simulator_node", "cycles:=2", "real_time_factor:=0.0"), "sim")
    assert proc.wait(30) == 0, proc.output()
    assert "published 200 samples" in proc.output()


def test_simulator_waits_for_its_subscribers(start_process, node_command, probe):
    """With ``wait_for_subscribers`` the stream starts only once that many listen to suds/shape."""
    from sensor_msgs.msg import JointState

    from suds_ros.ros.qos import latched_state_qos

    proc = start_process(node_command("simulator_node", "cycles:=2", "real_time_factor:=0.0",
                                      "wait_for_subscribers:=1", "start_timeout:=120.0"), "sim")
    wait_for(lambda: probe.node.count_publishers("/suds/shape") == 1, 60, lambda: f"the simulator\n{proc.output()}")
    # at full speed two cycles take a few ticks: without the wait it would have exited by now
    wait_for(lambda: "simulating purcell3" in proc.output(), 60, proc.output)
    assert proc.poll() is None and "starting the stream" not in proc.output(), proc.output()
    inbox = probe.listen("/suds/shape", JointState, latched_state_qos(1000))
    assert proc.wait(60) == 0, proc.output()
    assert "starting the stream: 1 subscription(s) on /suds/shape" in proc.output()
    wait_for(lambda: len(inbox) == 200, 30, lambda: f"200 shapes, got {len(inbox)}")
