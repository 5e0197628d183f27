"""Integrator, drive and agreement with the independent implementation's recordings."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core import se2
from suds_ros.core.errors import SudsConfigError, SudsDataError, SudsSimulationError
from suds_ros.core.physics.rft import RFTChain
from suds_ros.core.physics.sim import SimConfig, auto_substeps, integrate, ou_path, simulate, simulate_actuator_lag
from suds_ros.core.physics.systems import make_system, purcell3_model, swimmer9_model


def test_se2_step_is_exact_for_constant_twist() -> None:
    pose = np.array([[1.0, 2.0, 0.3]])
    v, w, T = 0.7, 1.3, 0.9
    out = se2.exp_step(pose, np.array([[v * T, 0.0, w * T]]))
    # circle of radius v/w
    R = v / w
    th = 0.3 + w * T
    expect = [1.0 + R * (np.sin(th) - np.sin(0.3)), 2.0 - R * (np.cos(th) - np.cos(0.3)), th]
    np.testing.assert_allclose(out[0], expect, atol=1e-12)


def test_ou_statistics() -> None:
    rng = np.random.default_rng(0)
    eta = ou_path(rng, 200_000, 1, 0.01, 8.0, 0.175)[:, 0]
    assert eta.std() == pytest.approx(0.175, rel=0.03)
    rho = np.corrcoef(eta[:-1], eta[1:])[0, 1]
    assert rho == pytest.approx(np.exp(-8.0 * 0.01), abs=0.005)


@pytest.mark.parametrize("name", ["purcell3", "swimmer9"])
def test_integrator_converges(name: str) -> None:
    """The automatic step agrees with a 4x finer one to far below the 1e-3 measurement noise."""
    sys_ = make_system(name)
    na, npas = len(sys_.actuated), len(sys_.passive)
    t = np.arange(400) * 0.01
    r_a = sys_.reference(t) + ou_path(np.random.default_rng(1), 400, na, 0.01, 8.0, 0.175)
    n_auto = auto_substeps(sys_, 0.01)
    a = integrate(sys_, r_a, 0.01, np.zeros(npas))
    b = integrate(sys_, r_a, 0.01, np.zeros(npas), substeps=4 * n_auto)
    assert np.abs(a.r - b.r).max() < 5e-5
    assert np.abs(a.pose - b.pose).max() < 5e-5


def test_auto_substeps_follow_stiffness() -> None:
    assert auto_substeps(make_system("purcell3"), 0.01) == 2
    assert auto_substeps(make_system("swimmer9"), 0.01) > auto_substeps(make_system("purcell3"), 0.01)


def test_simulation_is_seeded(purcell3_run) -> None:
    again = simulate(make_system("purcell3"), SimConfig(cycles=20, seed=11))
    np.testing.assert_array_equal(again.r, purcell3_run.r)
    other = simulate(make_system("purcell3"), SimConfig(cycles=20, seed=12))
    assert np.abs(other.r - purcell3_run.r).max() > 0.1


def test_simulated_recording_layout(purcell3_run) -> None:
    rec = purcell3_run
    assert rec.n_samples == 2000
    assert rec.joint_names == ("joint_1", "joint_2")
    assert rec.actuated == ("joint_1",) and rec.passive == ("joint_2",)
    np.testing.assert_allclose(np.diff(rec.t), 0.01, atol=1e-6)
    assert rec.t[0] == pytest.approx(1.7e9)
    noise = rec.r - rec.truth["r"]
    assert noise.std() == pytest.approx(1e-3, rel=0.1)
    # the passive joint is excited (README of the public bags: std 0.36 rad nominal)
    assert 0.25 < rec.truth["r"][:, 1].std() < 0.45


def test_pose_delay_shifts_pose_only() -> None:
    base = simulate(make_system("purcell3"), SimConfig(cycles=2, seed=3, noise_std=0))
    late = simulate(make_system("purcell3"), SimConfig(cycles=2, seed=3, noise_std=0, pose_delay=0.03))
    np.testing.assert_array_equal(base.r, late.r)
    np.testing.assert_allclose(late.pose[3:], base.pose[:-3], atol=1e-12)


def test_bad_config_and_inputs() -> None:
    with pytest.raises(SudsConfigError, match="cycles"):
        SimConfig(cycles=0)
    with pytest.raises(SudsConfigError, match="kappa"):
        SimConfig(kappa=-1.0)
    with pytest.raises(SudsDataError, match="r_a"):
        integrate(make_system("purcell3"), np.zeros((10, 2)), 0.01, np.zeros(1))
    with pytest.raises(SudsDataError, match="r_p0"):
        integrate(make_system("purcell3"), np.zeros((10, 1)), 0.01, np.zeros(3))


# ---------------------------------------------------------------------------------------------
# Agreement with the independent implementation: replaying a public recording's actuated angles
# from its initial passive state must reproduce its passive angles and pose to the measurement
# noise (1e-3), i.e. the README's baseline residuals; with the effect the README names, the
# "real" recordings must fall to the same floor.
def _replay_residual(path, model) -> tuple[np.ndarray, float]:
    from suds_ros.io.recording_bag import read_recording

    rec = read_recording(path)
    chain = RFTChain(model)
    tr = integrate(chain, rec.r_a, 0.01, rec.r_p[0], pose0=rec.pose[0])
    rms = np.sqrt(((tr.r[:, rec.passive_index] - rec.r_p) ** 2).mean(axis=0))
    end = float(np.abs(tr.pose[-1, :2] - rec.pose[-1, :2]).max())
    return rms, end


@pytest.mark.slow
@pytest.mark.parametrize(
    "bag, model, baseline",
    [
        ("purcell3_nominal.mcap", purcell3_model(), [0.0012]),
        ("swimmer9_nominal.mcap", swimmer9_model(), [0.0022, 0.0016, 0.0012, 0.0011]),
    ],
)
def test_nominal_physics_matches_independent_recordings(shared_bag, bag, model, baseline) -> None:
    rms, end = _replay_residual(shared_bag(bag), model)
    np.testing.assert_allclose(rms, baseline, rtol=0.15)
    assert end < 0.1  # metres after 60 cycles (the swimmer travels tens of metres)


@pytest.mark.slow
@pytest.mark.parametrize(
    "bag, nominal_rms, model",
    [
        ("purcell3_real_friction.mcap", 0.158, purcell3_model().with_(coulomb=(0.0, 0.7))),
        ("swimmer9_real_rest_offset.mcap", 0.199, swimmer9_model().with_(rest=(0, 0, 0, 0, 0, 0.25, 0, 0))),
    ],
)
def test_effect_physics_matches_independent_recordings(shared_bag, bag, nominal_rms, model) -> None:
    rms_nominal, _ = _replay_residual(shared_bag(bag), make_system(model.name).model)
    assert rms_nominal.max() == pytest.approx(nominal_rms, rel=0.05)
    rms, _ = _replay_residual(shared_bag(bag), model)
    assert rms.max() < 0.003  # measurement noise is 1e-3


def test_chain_without_passive_joints_simulates():
    """Every joint driven (nlink3 with 2 actuators): no passive state, the body still swims."""
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import make_system

    rec = simulate(make_system("nlink3", n_actuated=2), SimConfig(cycles=3, seed=1))
    assert rec.passive == () and rec.r.shape == (300, 2)
    assert np.all(np.isfinite(rec.pose)) and np.ptp(rec.pose[:, 0]) + np.ptp(rec.pose[:, 1]) > 0.05


def test_an_unstable_softening_spring_is_refused_with_the_reason() -> None:
    """A passive joint that runs away is a SudsSimulationError that says why, with friction or without.

    Without friction the run once ended in NaN joint angles, refused later as a NaN sample; with
    friction in a FloatingPointError of the stick/slip solver.
    """
    for extra in ({}, {"coulomb": (0.0, 0.3)}):
        model = purcell3_model().with_(k3=(0.0, -40.0), **extra)
        with pytest.raises(SudsSimulationError, match="softening cubic spring") as info:
            simulate(RFTChain(model), SimConfig(cycles=4, seed=1))
        assert info.value.code == "simulation_failed" and isinstance(info.value, FloatingPointError)


def test_actuator_lag_records_the_commands_while_the_joints_follow_them_late() -> None:
    """The recorded actuated angles lead the true ones by the lag; the truth is a lagged run."""
    chain = RFTChain(purcell3_model())
    cfg = SimConfig(cycles=2, seed=5)
    rec = simulate_actuator_lag(chain, cfg, 3)
    act = [rec.joint_names.index(n) for n in rec.actuated]
    recorded = rec.r[:, act] - (rec.r[:, act] - rec.truth["r"][:, act]).mean(axis=0)
    true = rec.truth["r"][:, act]
    shift = [float(np.sqrt(np.mean((recorded[: recorded.shape[0] - k] - true[k:]) ** 2))) for k in range(6)]
    assert int(np.argmin(shift)) == 3, shift  # true(t) = command(t − 3 dt)
    assert shift[3] < 0.2 * shift[0], shift
    with pytest.raises(SudsConfigError, match="lag_samples"):
        simulate_actuator_lag(chain, cfg, 0)
