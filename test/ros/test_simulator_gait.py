"""End to end: the simulator node (own process) switches to a new gait file at a cycle boundary
without a jump in the actuated angle, keeps streaming, and publishes the gait in force latched
on ``/suds/gait``; a gait of another robot is refused with the reason."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import set_simulator_parameter, stop, wait_for
except ImportError:
    from _ros_helpers import set_simulator_parameter, stop, wait_for

pytestmark = pytest.mark.ros

T0 = 1.7e9  # the simulator's first stamp when not in real time
RATE = 50.0  # samples per second = per cycle at 1 Hz


def set_gait_file(probe, value: str):
    """Set the simulator's ``gait_file``; returns the SetParametersResult."""
    return set_simulator_parameter(probe, "gait_file", value)


def test_gait_switch_without_a_jump(start_process, node_command, probe, tmp_path: Path):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    from suds_ros.core.physics.gait import nominal_gait, save_gait
    from suds_ros.core.physics.systems import make_system
    from suds_ros.ros.conversions import gait_from_msg
    from suds_ros.ros.qos import GAIT_QOS, latched_state_qos

    nominal = nominal_gait(make_system("purcell3"))
    new = nominal.from_vector(np.array([0.0, 1.0, 0.0, 0.0, 0.4, 0.0, 0.1]), 3)  # r(0) = 1.0, nominal's 0
    path = tmp_path / "new.yaml"
    save_gait(new, path)
    other = tmp_path / "s9.yaml"
    save_gait(nominal_gait(make_system("swimmer9")), other)

    shape = probe.listen("/suds/shape", JointState, latched_state_qos(100_000))
    gaits = probe.listen("/suds/gait", String, GAIT_QOS)
    sim = start_process(node_command("simulator_node", "system:=purcell3", "real_time_factor:=3.0",
                                     f"rate:={RATE}", "noise:=0.0", "seed:=2"), "simulator")
    wait_for(lambda: len(gaits) >= 1, 60, lambda: f"the nominal gait on /suds/gait\n{sim.output()}")
    assert gait_from_msg(gaits.messages()[0]) == nominal
    wait_for(lambda: len(shape) >= 2 * RATE, 60, lambda: f"two cycles\n{sim.output()}")

    refused = set_gait_file(probe, str(other))
    assert not refused.successful and "the gait is for 'swimmer9'" in refused.reason
    assert set_gait_file(probe, str(path)).successful
    found = re.compile(r"gait \S+ on from stamp ([0-9.]+)")
    wait_for(lambda: found.search(sim.output()), 60, lambda: f"the switch\n{sim.output()}")
    onset = float(found.search(sim.output()).group(1))
    assert (onset - T0) * 1.0 == pytest.approx(round(onset - T0), abs=1e-6)  # a cycle boundary
    wait_for(lambda: len(gaits) >= 2, 30, lambda: f"the new gait on /suds/gait\n{sim.output()}")
    assert gait_from_msg(gaits.messages()[-1]) == new

    def stamps() -> np.ndarray:
        return np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in shape.messages()])

    wait_for(lambda: stamps().max() >= onset + 2.0, 60, lambda: f"two cycles after the switch\n{sim.output()}")
    msgs = shape.messages()
    t = stamps()
    r1 = np.array([m.position[0] for m in msgs])
    assert np.all(np.diff(t) > 0) and np.allclose(np.diff(t), 1 / RATE, atol=1e-6)  # the stream went on
    k = int(np.argmin(np.abs(t - onset)))
    assert abs(t[k] - onset) < 1e-6
    # without the fade the set-point would jump by r_new(0) − r_old(1 − 1/50) ≈ 1.18 rad; with it the
    # step is the nominal gait's (0.18 rad) plus the OU perturbation's (std ≈ 0.1 rad)
    assert abs(r1[k] - r1[k - 1]) < 0.6, (r1[k - 3:k + 3])
    # a cycle after the switch the new gait holds (up to the OU perturbation, std 0.175 rad)
    after = (t >= onset + 1.0) & (t < onset + 2.0)
    dev = r1[after] - new.r(t[after] - onset)[:, 0]
    assert np.sqrt(np.mean(dev**2)) < 0.35
    assert stop(sim) == 0, sim.output()


def test_gait_command_topic_switches_and_reports_the_stamp(start_process, node_command, probe):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    from suds_ros.core.physics.gait import dump_gait, nominal_gait, same_gait
    from suds_ros.core.physics.systems import make_system
    from suds_ros.ros.conversions import gait_switch_from_msg
    from suds_ros.ros.qos import GAIT_QOS, SWITCH_QOS, latched_state_qos

    nominal = nominal_gait(make_system("purcell3"))
    new = nominal.from_vector(np.array([0.0, 0.2, 0.0, 0.0, 0.9, 0.0, 0.0]), 3)
    shape = probe.listen("/suds/shape", JointState, latched_state_qos(100_000))
    switches = probe.listen("/suds/gait_switch", String, SWITCH_QOS)
    command = probe.publisher("/suds/gait_command", String, GAIT_QOS)
    sim = start_process(node_command("simulator_node", "system:=purcell3", "real_time_factor:=3.0",
                                     f"rate:={RATE}", "noise:=0.0", "seed:=2"), "simulator")
    wait_for(lambda: len(shape) >= RATE, 60, lambda: f"a cycle\n{sim.output()}")
    command.publish(String(data=dump_gait(nominal_gait(make_system("swimmer9")))))  # another robot's
    wait_for(lambda: "gait command ignored" in sim.output(), 60, lambda: f"the refusal\n{sim.output()}")
    assert "the gait is for 'swimmer9'" in sim.output() and len(switches) == 0
    command.publish(String(data=dump_gait(new)))
    wait_for(lambda: len(switches) >= 1, 60, lambda: f"the switch report\n{sim.output()}")
    onset, gait = gait_switch_from_msg(switches.messages()[0])
    assert same_gait(gait, new)
    assert (onset - T0) == pytest.approx(round(onset - T0), abs=1e-6)  # a cycle boundary
    # the log line and the switch message leave the node together but reach this test by two paths (the
    # process's stdout and DDS): wait for the line, do not assume it came first
    said = f"gait from suds/gait_command on from stamp {onset:.6f}"
    wait_for(lambda: said in sim.output(), 60, lambda: f"the log line {said!r}\n{sim.output()}")
    assert stop(sim) == 0, sim.output()


# ------------------------------------------------------------------ in process
def test_gait_message_round_trip_and_refusal() -> None:
    from std_msgs.msg import String

    from suds_ros.core.errors import SudsConfigError
    from suds_ros.core.physics.gait import nominal_gait
    from suds_ros.core.physics.systems import make_system
    from suds_ros.ros.conversions import gait_from_msg, gait_to_msg

    g = nominal_gait(make_system("swimmer9"))
    assert gait_from_msg(gait_to_msg(g)) == g
    with pytest.raises(SudsConfigError, match="/suds/gait: `format`"):
        gait_from_msg(String(data="format: other\n"))


def test_start_gait_file_drives_the_stream_and_a_bad_one_stops_the_node(ros_context, tmp_path: Path):
    from rclpy.parameter import Parameter

    from suds_ros.core.errors import SudsConfigError
    from suds_ros.core.physics.gait import nominal_gait, save_gait
    from suds_ros.core.physics.systems import make_system
    from suds_ros.ros.simulator_node import SimulatorNode

    g = nominal_gait(make_system("purcell3")).from_vector(np.array([0.2, 0.0, 0.9]), 1)
    good, bad = tmp_path / "g.yaml", tmp_path / "s9.yaml"
    save_gait(g, good)
    save_gait(nominal_gait(make_system("swimmer9")), bad)
    node = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter("real_time_factor", value=0.0), Parameter("noise", value=0.0),
        Parameter("gait_file", value=str(good))])
    try:
        assert node.describe_parameter("gait_file").read_only is False
        assert node.sim.gait == g
        res = node.set_parameters([Parameter("gait_file", value=str(tmp_path / "none.yaml"))])[0]
        assert not res.successful and "cannot read the gait file" in res.reason
        assert node.set_parameters([Parameter("gait_file", value="")])[0].successful  # back to nominal
        for _ in range(101):
            node._next_sample()
        assert node.sim.gait == nominal_gait(make_system("purcell3"))
    finally:
        node.destroy_node()
    with pytest.raises(SudsConfigError, match="the gait is for 'swimmer9'"):
        SimulatorNode(context=ros_context, parameter_overrides=[Parameter("gait_file", value=str(bad))])
