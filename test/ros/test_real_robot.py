"""A robot's own topics remapped into the estimator and predictor (separate processes).

A stand-in robot (``_robot_publisher.py``) publishes ``/joint_states`` as ros2_control's
joint_state_broadcaster does (every joint, names in its own order, two joints the model
does not know, velocities and efforts) and a motion-capture ``/mocap/pose`` at half that
rate.  The estimator and predictor are started with ``-r suds/shape:=/joint_states``
(the estimator also ``-r suds/body_pose:=/mocap/pose``): the model's joints are picked by
name, nothing is skipped, the model fits, and the estimator's measured velocities carry
the stamps of the predictor's predictions.  With stamp jitter on the joint states (a
host stamping each message as it arrives) both nodes bring the stream onto the same fitted
grid, each sample at its grid point: the predictions and the measured velocities carry its grid
times, not the published stamps.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import stop, wait_for
except ImportError:
    from _ros_helpers import stop, wait_for

pytestmark = pytest.mark.ros

HERE = Path(__file__).resolve().parent
CYCLES = 25
N = CYCLES * 100


def node(module: str, *ros_args: str) -> list[str]:
    return [sys.executable, "-m", f"suds_ros.ros.{module}", "--ros-args", *ros_args]


def stamp(msg) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def status_values(inbox) -> dict[str, str]:
    msgs = inbox.messages()
    return {kv.key: kv.value for kv in msgs[-1].status[0].values} if msgs else {}


@pytest.mark.parametrize("jitter_ms", [0.0, 2.0])
def test_joint_states_and_mocap_remapped_into_the_pipeline(start_process, probe, jitter_ms):
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import TwistStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    qos = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
    inbox = {t: probe.listen(t, cls, qos) for t, cls in (
        ("/suds/predicted/body_velocity", TwistStamped), ("/suds/predicted/passive_velocity", JointState),
        ("/suds/measured/body_velocity", TwistStamped), ("/suds/measured/passive_velocity", JointState),
        ("/suds/status", DiagnosticArray), ("/joint_states", JointState))}
    est = start_process(node("estimator_node", "-p", "system:=purcell3", "-p", "status_period:=0.2",
                             "-r", "suds/shape:=/joint_states", "-r", "suds/body_pose:=/mocap/pose"),
                        "estimator")
    pred = start_process(node("predictor_node", "-p", f"depth:={N}", "-r", "suds/shape:=/joint_states"),
                         "predictor")
    robot = start_process([sys.executable, str(HERE / "_robot_publisher.py"), str(CYCLES), str(jitter_ms)],
                          "robot")
    assert robot.wait(180) == 0, robot.output() + est.output()
    wait_for(lambda: status_values(inbox["/suds/status"]).get("samples") == str(N), 60,
             lambda: f"all {N} samples in the estimator: {status_values(inbox['/suds/status'])}\n{est.output()}")
    # the last sample's prediction (on the grid: released once the stream has been idle for 2 s)
    last_shape = 1.7e9 + (N - 1) / 100
    wait_for(lambda: (m := inbox["/suds/predicted/body_velocity"].messages())
             and abs(stamp(m[-1]) * 1e-9 - last_shape) < (5e-3 if jitter_ms else 1e-6), 60,
             lambda: f"the prediction of the last sample\n{pred.output()}")
    values = status_values(inbox["/suds/status"])
    assert values["skipped_total"] == "0", values
    assert "/joint_states" in est.output() and "/mocap/pose" in est.output(), est.output()
    assert int(values["rows"]) >= N - 200 and int(values["model_updates"]) > 0, values  # rows: fitted chunks
    # the running Γ of the status is measured on the noisy rows: the passive one is meaningful here
    assert float(values["gamma_passive"]) >= 0.8, values
    assert {tuple(m.name) for m in inbox["/suds/predicted/passive_velocity"].messages()} == {("joint_2",)}
    assert {tuple(m.name) for m in inbox["/suds/measured/passive_velocity"].messages()} == {("joint_2",)}
    # measured velocities: one per interval fitted on, stamped as the predictor stamps that interval;
    # the estimator publishes them as it fits, so the last ones may still be on their way
    # (they go out in bursts as chunks are fitted; on a loaded machine a burst can outrun the
    # subscriber's queue, so most, not all, are required)
    try:
        wait_for(lambda: len({stamp(m) for m in inbox["/suds/measured/body_velocity"].messages()}) >= N - 5,
                 60, "all measured body velocities")
    except AssertionError:
        pass
    measured = {stamp(m): m for m in inbox["/suds/measured/body_velocity"].messages()}
    predicted = [stamp(m) for m in inbox["/suds/predicted/body_velocity"].messages()]
    assert len(measured) >= 0.6 * N, len(measured)
    # stamped identically: once the predictor has a model, the measured intervals are the ones it
    # stamped, to the nanosecond.  Seen once on a starved machine: 3 of ~2000 predictions never
    # reached this probe (its publisher keeps the last 100, so a lagging reader can lose some; not
    # confirmed as the cause), so a handful may be missing here; a stamping error misses them all.
    late = {s for s in measured if s >= min(predicted)}
    unmatched = sorted(late - set(predicted))
    assert len(late & set(predicted)) >= 0.5 * len(predicted), (len(late & set(predicted)), len(predicted))
    assert len(unmatched) <= 0.01 * len(late), (len(unmatched), len(late), unmatched[:5], pred.output())
    published = {stamp(m) for m in inbox["/joint_states"].messages()}
    on_published = sum(s in published for s in predicted)
    if jitter_ms:
        # grid times: a whole number of steps apart (a slewed clock: within µs), unlike the jittered stamps; a
        # double near 1.7e9 s resolves 0.24 µs, so a grid time can equal a published stamp by chance (one of
        # ~2000 did once): a handful at most
        gaps = np.diff(np.sort(np.array(predicted, dtype=np.int64)))
        off = np.abs(gaps - np.round(gaps / 1e7).astype(np.int64) * 10**7)
        assert np.mean(off <= 5000) > 0.99, np.sort(off)[-10:]
        assert on_published <= 0.005 * len(predicted), on_published
        # the stand-in robot stamps late (values at its regular ticks, stamps jittered): told from the data
        assert values.get("shape_grid") == "snap", values
    else:
        assert on_published == len(predicted)
    assert stop(pred) == 0, pred.output()
    assert stop(est) == 0, est.output()
