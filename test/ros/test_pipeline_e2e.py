"""End to end, each node in its own process: simulator → estimator → predictor, recorded.

The predictor's live output on the cycles after the training cycles is scored
against the velocities measured from the recorded shape and pose:
Γ = 1 − Σ|pred − meas| / Σ|template − meas|, with the template a phase-only
Fourier fit (order 8, reference gait phase) of the measured velocities on the
training cycles.
"""

from __future__ import annotations

import signal
import time
from pathlib import Path

import numpy as np
import pytest

from suds_ros.core import se2
from suds_ros.core.sysid import fourier_basis
from suds_ros.io.bags import decode_message, iter_raw_messages, read_recording

pytestmark = pytest.mark.ros

TRAIN_CYCLES, TEST_CYCLES = 30, 10
RECORD = ("topics:=['/suds/shape', '/suds/body_pose', '/suds/predicted/*', '/suds/model', "
          "'/suds/status']", "system:=purcell3", "actuated:=joint_1", "passive:=joint_2")


def wait_for(predicate, timeout: float, what: str) -> None:
    """Poll ``predicate`` every 50 ms; AssertionError after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def stop(proc, sig=signal.SIGINT, timeout: float = 20.0) -> int:
    """Send ``sig`` and wait; returns the exit code."""
    if proc.poll() is None:
        proc.send_signal(sig)
    return proc.wait(timeout)


def read_topic(bag: Path, topic: str) -> list:
    """Every message of ``topic``, decoded."""
    return [decode_message(m.type_name, m.data) for m in iter_raw_messages(bag, topics=[topic])]


def last_model(bag: Path):
    """The last /suds/model of the bag as a SudsModel."""
    from suds_ros.ros.estimator_node import model_from_msg

    msgs = read_topic(bag, "/suds/model")
    assert msgs, f"no /suds/model in {bag}"
    return model_from_msg(msgs[-1])


def measured_velocities(rec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps t_k (k ≥ 1), measured ξ (n−1, 3) and passive ṙ (n−1, np) over [t_{k−1}, t_k]."""
    pose = np.array([np.interp(rec.t, rec.pose_t, rec.pose[:, c]) for c in range(3)]).T
    dt = np.diff(rec.t)
    xi = se2.log(se2.relative(pose[:-1], pose[1:])) / dt[:, None]
    rdot = np.diff(rec.r[:, rec.passive_index], axis=0) / dt[:, None]
    return rec.t[1:], xi, rdot


def live_gamma(bag: Path, train_cycles: int, gait_hz: float = 1.0) -> dict[str, float]:
    """Γ of the recorded predictions on the cycles after ``train_cycles`` (see module doc)."""
    from suds_ros.ros.conversions import joint_velocity_from_msg, twist_from_msg

    rec = read_recording(bag)
    t, xi, rdot = measured_velocities(rec)
    meas = np.hstack([xi, rdot])
    t0 = rec.t[0]
    pred = {}
    for m in read_topic(bag, "/suds/predicted/body_velocity"):
        tw = twist_from_msg(m)
        pred.setdefault(round(tw.stamp, 6), [None, None])[0] = [tw.vx, tw.vy, tw.wz]
    for m in read_topic(bag, "/suds/predicted/passive_velocity"):
        stamp, names, vel = joint_velocity_from_msg(m)
        assert names == rec.passive
        pred.setdefault(round(stamp, 6), [None, None])[1] = list(vel)
    phase = 2 * np.pi * gait_hz * (0.5 * (t + np.concatenate([[t0], t[:-1]])) - t0)
    train = t < t0 + train_cycles / gait_hz
    B = fourier_basis(phase, 8)
    coef = np.linalg.lstsq(B[train], meas[train], rcond=None)[0]
    tmpl = B @ coef
    rows = [k for k in np.flatnonzero(~train)
            if round(t[k], 6) in pred and None not in pred[round(t[k], 6)]]
    n_test = int((~train).sum())
    print(f"test samples {n_test}, with a live prediction {len(rows)}")
    assert len(rows) >= 0.95 * n_test, f"only {len(rows)} of {n_test} test samples have a prediction"
    P = np.array([pred[round(t[k], 6)][0] + pred[round(t[k], 6)][1] for k in rows])
    M, T = meas[rows], tmpl[rows]
    out = {}
    for name, cols in (("body", slice(0, 3)), ("passive", slice(3, None))):
        out[name] = 1 - np.abs(P[:, cols] - M[:, cols]).sum() / np.abs(T[:, cols] - M[:, cols]).sum()
    return out


def test_live_pipeline_predicts_test_cycles(start_process, node_command, tmp_path):
    bag = tmp_path / "live.mcap"
    rec = start_process(node_command("recorder_node", f"output:={bag}", *RECORD), "recorder")
    est = start_process(node_command("estimator_node"), "estimator")
    pred = start_process(node_command("predictor_node"), "predictor")
    wait_for(lambda: "recording [" in rec.output(), 30, "the recorder")
    time.sleep(2.0)  # the estimator and predictor import and start
    sim = start_process(node_command(
        "simulator_node", "system:=purcell3", "real_time_factor:=5.0", "seed:=3",
        f"cycles:={TRAIN_CYCLES + TEST_CYCLES}"), "simulator")
    assert sim.wait(120) == 0, sim.output()
    wait_for(lambda: est.output().count("joints") >= 1, 5, "the estimator to start")
    time.sleep(3.0)  # idle flush of the last chunk, last predictions
    assert stop(pred) == 0, pred.output()
    assert stop(est) == 0, est.output()
    assert stop(rec) == 0, rec.output()
    print(pred.output()[-400:])
    g = live_gamma(bag, TRAIN_CYCLES)
    print(f"live Γ on {TEST_CYCLES} test cycles after {TRAIN_CYCLES} training cycles: "
          f"body {g['body']:.3f}, passive {g['passive']:.3f}")
    assert g["body"] >= 0.8 and g["passive"] >= 0.8, g
    model = last_model(bag)
    assert model.n_samples == (TRAIN_CYCLES + TEST_CYCLES) * 100 - 1
