"""Physics of the RFT chain: kinematics, metric, force balance, energy, friction, symmetry."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.rft import ChainModel, RFTChain, flow_in_body
from suds_ros.core.physics.systems import make_system, nlink_model, purcell3_model, swimmer9_model


def world_links(model: ChainModel, g: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Independent forward kinematics: (N, 3) world centre x, y and angle of every link."""
    n, m = model.n_links, model.body_link
    L = np.asarray(model.link_length)
    theta = np.zeros(n)
    theta[m] = g[2]
    for i in range(m + 1, n):
        theta[i] = theta[i - 1] + r[i - 1]
    for i in range(m - 1, -1, -1):
        theta[i] = theta[i + 1] - r[i]
    pos = np.zeros((n, 2))
    pos[m] = g[:2]
    e = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    for i in range(m + 1, n):
        pos[i] = pos[i - 1] - L[i - 1] / 2 * e[i - 1] - L[i] / 2 * e[i]
    for i in range(m - 1, -1, -1):
        pos[i] = pos[i + 1] + L[i + 1] / 2 * e[i + 1] + L[i] / 2 * e[i]
    return np.concatenate([pos, theta[:, None]], axis=1)


@pytest.mark.parametrize("model", [purcell3_model(), swimmer9_model(), nlink_model(6, 2)])
def test_jacobian_matches_finite_differences(model: ChainModel) -> None:
    rng = np.random.default_rng(0)
    chain = RFTChain(model)
    nj = model.n_joints
    g = np.array([0.3, -0.2, 0.7])
    r = rng.normal(scale=0.6, size=nj)
    qdot = rng.normal(size=3 + nj)
    h = 1e-6
    # body velocity ξ moves g by g·exp(ξ h): to first order, world velocity R(θ)ξ
    c, s = np.cos(g[2]), np.sin(g[2])
    gdot = np.array([c * qdot[0] - s * qdot[1], s * qdot[0] + c * qdot[1], qdot[2]])
    fwd = world_links(model, g + h * gdot, r + h * qdot[3:])
    bwd = world_links(model, g - h * gdot, r - h * qdot[3:])
    v_world = (fwd - bwd) / (2 * h)
    J = chain.jacobians(r[None])[0]
    V = J @ qdot  # link frame
    ang = world_links(model, g, r)[:, 2]
    ca, sa = np.cos(ang), np.sin(ang)
    v_link = np.stack([ca * v_world[:, 0] + sa * v_world[:, 1],
                       -sa * v_world[:, 0] + ca * v_world[:, 1],
                       v_world[:, 2]], 1)
    np.testing.assert_allclose(V, v_link, atol=1e-7)


def test_metric_symmetric_positive_definite() -> None:
    chain = make_system("swimmer9")
    r = np.random.default_rng(1).normal(size=(20, 8))
    D = chain.drag_metric(r)
    np.testing.assert_allclose(D, D.transpose(0, 2, 1), atol=1e-12)
    assert np.linalg.eigvalsh(D).min() > 0


@pytest.mark.parametrize("name", ["purcell3", "swimmer9"])
def test_solution_satisfies_balances_and_is_affine(name: str) -> None:
    chain = make_system(name)
    rng = np.random.default_rng(2)
    nj, na = len(chain.joint_names), len(chain.actuated)
    r = rng.normal(scale=0.5, size=(7, nj))
    u, v = rng.normal(size=(7, na)), rng.normal(size=(7, na))
    qdot, D = chain.full_rates(r, u)
    F = np.einsum("bij,bj->bi", D, qdot)
    np.testing.assert_allclose(F[:, :3], 0, atol=1e-10)  # zero net drag wrench
    pas = 3 + np.array(chain.passive)
    np.testing.assert_allclose(-F[:, pas] + chain.passive_torque(r), 0, atol=1e-10)
    f = lambda a: np.concatenate(chain.velocities(r, a), axis=1)  # noqa: E731
    np.testing.assert_allclose(f(2 * u - 3 * v), 2 * f(u) - 3 * f(v) + 2 * f(0 * u), atol=1e-10)


def test_power_balance() -> None:
    """Actuator power = dissipation + rate of spring energy (with internal damping)."""
    chain = RFTChain(swimmer9_model().with_(damping=0.3, rest=0.1))
    rng = np.random.default_rng(3)
    r = rng.normal(scale=0.5, size=(5, 8))
    va = rng.normal(size=(5, 4))
    qdot, _ = chain.full_rates(r, va)
    rdot = qdot[:, 3:]
    power_in = (chain.actuator_effort(r, rdot) * va).sum(axis=1)
    spring_rate = -(chain.passive_torque(r) * rdot[:, chain.passive]).sum(axis=1)
    np.testing.assert_allclose(power_in, chain.dissipation(r, rdot) + spring_rate, rtol=1e-9, atol=1e-12)
    assert np.all(chain.dissipation(r, rdot) >= 0)


def test_mirror_symmetry() -> None:
    chain = make_system("swimmer9")
    rng = np.random.default_rng(4)
    r, va = rng.normal(size=(4, 8)), rng.normal(size=(4, 4))
    xi, rp = chain.velocities(r, va)
    xim, rpm = chain.velocities(-r, -va)
    np.testing.assert_allclose(xim, xi * [1, -1, -1], atol=1e-12)
    np.testing.assert_allclose(rpm, -rp, atol=1e-12)


def test_coulomb_friction_is_consistent_stick_slip() -> None:
    mu = 0.5
    chain = RFTChain(purcell3_model().with_(coulomb=(0.0, mu)))
    free = make_system("purcell3")
    rng = np.random.default_rng(5)
    r = rng.normal(scale=0.7, size=(400, 2))
    va = rng.normal(scale=3.0, size=(400, 1))
    qdot, D = chain.full_rates(r, va)
    resid = -np.einsum("bij,bj->bi", D, qdot)[:, 4] + chain.passive_torque(r)[:, 0]  # friction torque
    rp = qdot[:, 4]
    slip = np.abs(rp) > 1e-9
    assert slip.any() and (~slip).any(), "test states should include both slip and stick"
    np.testing.assert_allclose(resid[slip], mu * np.sign(rp[slip]), atol=1e-9)
    assert np.all(np.abs(resid[~slip]) <= mu + 1e-9)
    # friction can only slow the joint compared with the frictionless solution
    _, rp_free = free.velocities(r, va)
    assert np.all(np.abs(rp) <= np.abs(rp_free[:, 0]) + 1e-9)


def test_background_flow_adds_rotated_current() -> None:
    chain = RFTChain(purcell3_model().with_(flow=(0.2, -0.1)))
    still = make_system("purcell3")
    r, va, yaw = np.array([[0.3, -0.2]]), np.array([[1.0]]), np.array([0.8])
    xi, _ = chain.velocities(r, va, yaw=yaw)
    xi0, _ = still.velocities(r, va)
    np.testing.assert_allclose(xi - xi0, flow_in_body((0.2, -0.1), yaw), atol=1e-12)
    with pytest.raises(SudsConfigError, match="heading"):
        chain.velocities(r, va)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"n_links": 1, "actuated": (0,)}, "n_links"),
        ({"n_links": 3, "actuated": ()}, "at least one"),
        ({"n_links": 3, "actuated": (5,)}, "actuated"),
        ({"n_links": 3, "actuated": (0,), "stiffness": (1.0,)}, "stiffness"),
        ({"n_links": 3, "actuated": (0,), "damping": -1.0}, "damping"),
        ({"n_links": 3, "actuated": (0,), "c_perp": 0.0}, "drag"),
    ],
)
def test_bad_models_are_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(SudsConfigError, match=match):
        ChainModel(**kwargs)


def test_unknown_system() -> None:
    with pytest.raises(SudsConfigError, match="unknown system 'fish'"):
        make_system("fish")
