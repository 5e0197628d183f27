"""The live mismatch monitor's core (no ROS) and the streaming simulator's run-time effects."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.diagnosis.monitor import ERROR, OK, MismatchMonitor, MonitorConfig
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.stream import StreamingSimulator
from suds_ros.core.physics.systems import load_system

FRICTION = {"name": "joint_coulomb_friction", "joint": "joint_2", "mu": 0.5}


def run(system, cycles, seed, onset=None, effect=FRICTION, config=MonitorConfig()):
    """Stream ``cycles`` cycles into a monitor; returns (monitor, [(stamp, statuses)], requests)."""
    sim = StreamingSimulator(system, SimConfig(seed=seed))
    mon = MismatchMonitor(system, config)
    history, requests = [], []
    for c in range(cycles):
        if c == onset:
            sim.set_effects([effect])
        ch = sim.step(100)
        for i in range(ch.t.size):
            before = mon.updated
            mon.add_pair(ch.t[i], ch.r[i], ch.pose[i])
            if mon.updated != before:
                history.append((ch.t[i] - 1.7e9, mon.statuses))
            req = mon.take_request()
            if req is not None:
                requests.append((ch.t[i] - 1.7e9, req))
    return mon, history, requests


@pytest.fixture(scope="module")
def purcell3():
    return load_system("purcell3")


@pytest.mark.parametrize("seed", [0, 5])
def test_nominal_60_cycles_never_alarm(purcell3, seed):
    mon, history, requests = run(purcell3, 60, seed)
    assert len(history) > 500
    levels = {s.level for _, sts in history for s in sts}
    assert levels == {OK}, max(s.statistic for _, sts in history for s in sts)
    F = np.array([[s.statistic for s in sts] for _, sts in history])
    # F is the residual power in noise-floor units: about 1 when the physics matches
    assert np.all((F.mean(axis=0) > 0.7) & (F.mean(axis=0) < 1.4)), F.mean(axis=0)
    assert requests == []
    assert mon.channels == ("joint_2", "xi_x", "xi_y", "xi_theta")


def test_nominal_swimmer9_never_errs():
    """Stiff passive joints: the calibrated discretisation error keeps F near 1 (max ≈ 3.8 seen)."""
    swimmer9 = load_system("swimmer9")
    mon, history, requests = run(swimmer9, 60, seed=1)
    F = np.array([[s.statistic for s in sts] for _, sts in history])
    assert F.max() < MonitorConfig().error and requests == []
    assert np.all(np.median(F, axis=0) < 1.6), np.median(F, axis=0)


def test_friction_onset_alarms_fast_and_requests_one_diagnosis(purcell3):
    cfg = MonitorConfig()
    mon, history, requests = run(purcell3, 30, seed=2, onset=20, config=cfg)
    before = [s for t, sts in history if t < 20.0 for s in sts]
    assert before and all(s.level == OK for s in before)
    first = min(t for t, sts in history for s in sts if s.level == ERROR)
    assert 20.0 <= first < 25.0
    joint = [sts[0] for t, sts in history if t >= 21.0]
    assert all(s.level == ERROR for s in joint) and joint[-1].since < 1.7e9 + 21.0
    assert len(requests) == 1  # one per episode
    t_req, req = requests[0]
    rec = req.recording
    assert "joint_2" in req.channels
    assert rec.n_samples == cfg.persist_cycles * cfg.samples_per_cycle
    assert rec.t[0] >= req.since >= 1.7e9 + 20.0  # the window lies after the change
    assert t_req - (req.since - 1.7e9) == pytest.approx(cfg.persist_cycles, abs=0.11)


def test_pairing_by_stamps_not_arrival(purcell3):
    """Pose arriving in late bursts (and a missing pose sample) pairs exactly as the direct feed."""
    sim = StreamingSimulator(purcell3, SimConfig(seed=1))
    chunks = [sim.step(100) for _ in range(4)]
    t = np.concatenate([c.t for c in chunks])
    r = np.concatenate([c.r for c in chunks])
    pose = np.concatenate([c.pose for c in chunks])
    direct = MismatchMonitor(purcell3)
    for k in range(t.size):
        direct.add_pair(t[k], r[k], pose[k])
    fed = MismatchMonitor(purcell3)
    names = ("extra", "joint_2", "joint_1")  # other order, an extra joint
    pending = []
    for k in range(t.size):
        fed.on_shape(t[k], names, np.array([9.0, r[k, 1], r[k, 0]]))
        pending.append(k)
        if len(pending) == 37 or k == t.size - 1:  # the pose stream comes in bursts, behind
            for j in pending:
                fed.on_pose(t[j], *pose[j])
            pending = []
    assert fed.paired == direct.paired == t.size
    assert [s[:2] for s in fed.statuses] == [s[:2] for s in direct.statuses]
    np.testing.assert_allclose([s.statistic for s in fed.statuses],
                               [s.statistic for s in direct.statuses], rtol=1e-6)


def test_config_is_checked():
    with pytest.raises(SudsConfigError, match="`error`: expected a threshold > warn"):
        MonitorConfig(warn=5.0, error=4.0)
    with pytest.raises(SudsConfigError, match="`persist_cycles`: expected an integer ≥ 4"):
        MonitorConfig(persist_cycles=2)
    with pytest.raises(SudsConfigError, match="`rate`: rate / gait_hz must be an integer"):
        MonitorConfig(rate=105.5)


# ------------------------------------------------------------------ streaming effects
def test_stream_effects_change_the_physics_from_the_switch_on(purcell3):
    a = StreamingSimulator(purcell3, SimConfig(seed=4))
    b = StreamingSimulator(purcell3, SimConfig(seed=4))
    for _ in range(2):
        ca, cb = a.step(100), b.step(100)
        np.testing.assert_array_equal(ca.r, cb.r)
    b.set_effects([FRICTION])
    ca, cb = a.step(100), b.step(100)
    assert np.abs(ca.r_true[:, 1] - cb.r_true[:, 1]).max() > 0.05
    np.testing.assert_array_equal(ca.r_true[:, 0], cb.r_true[:, 0])  # the drive is the same
    b.set_effects([])  # back to nominal physics (from the friction run's state)
    assert b.system is b.nominal and b.effects == ()


def test_stream_flow_switched_on_keeps_the_pose_continuous(purcell3):
    sim = StreamingSimulator(purcell3, SimConfig(seed=0, noise_std=0.0))
    c0 = sim.step(100)
    sim.set_effects([{"name": "background_flow", "vx": 0.3, "vy": 0.0}])
    c1 = sim.step(100)
    inside = np.abs(np.diff(c0.pose_true[:, :2], axis=0)).max()
    switch = np.abs(c1.pose_true[0, :2] - c0.pose_true[-1, :2]).max()
    assert switch < inside + 0.3 * 0.01  # a step of the swimmer plus the flow's, no jump
    drift = c1.pose_true[-1, 0] - c1.pose_true[0, 0]
    sim2 = StreamingSimulator(purcell3, SimConfig(seed=0, noise_std=0.0))
    sim2.step(100)
    c2 = sim2.step(100)
    assert drift - (c2.pose_true[-1, 0] - c2.pose_true[0, 0]) == pytest.approx(0.3 * 0.99, abs=1e-9)


def test_stream_effects_are_checked(purcell3):
    sim = StreamingSimulator(purcell3, SimConfig())
    with pytest.raises(SudsConfigError, match="joint 'joint_1' is actuated"):
        sim.set_effects([{"name": "joint_coulomb_friction", "joint": "joint_1", "mu": 0.5}])
    with pytest.raises(SudsConfigError, match="sensor_time_offset is not supported while streaming"):
        sim.set_effects([{"name": "sensor_time_offset", "dt": 0.02}])
    with pytest.raises(SudsConfigError, match="unknown effect"):
        sim.set_effects([{"name": "glue"}])
    assert sim.effects == ()
