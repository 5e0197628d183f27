"""Generalised chain physics checked against an independent world-frame derivation.

The chain solver works in the body-link frame with Jacobians and a drag metric.  Here the
same physics is rebuilt from scratch: forward kinematics of every link in the world frame
(head link first), link velocities by central differences of a small motion along the
solved velocities, RFT drag on each link in its own frame, then Newton's balances:
- net drag force and torque on the chain are zero;
- at each passive joint the moment, about the joint, of the drag on the links behind it
  equals minus the spring, damping torque (so the joint is in balance);
- the power the actuators put in equals the dissipation plus the spring energy rate.
Random link lengths, per-link drag, body link and pose offset are used throughout.
"""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.physics.rft import ChainModel, RFTChain


def _world_links(model: ChainModel, pose: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (N, 2) and headings (N,) of the links for the pose frame at ``pose`` (x, y, yaw)."""
    n, m = model.n_links, int(model.body_link)  # type: ignore[arg-type]
    L = np.asarray(model.link_length)
    # chain built from the head link at the origin, heading 0
    th = np.concatenate([[0.0], np.cumsum(r)])
    e = np.stack([np.cos(th), np.sin(th)], axis=1)
    c = np.zeros((n, 2))
    for i in range(1, n):
        c[i] = c[i - 1] - L[i - 1] / 2 * e[i - 1] - L[i] / 2 * e[i]
    # pose frame in that provisional placement: body link centre frame, then the offset
    a, b, phi = model.pose_offset
    cm, sm = np.cos(th[m]), np.sin(th[m])
    p_frame = c[m] + np.array([cm * a - sm * b, sm * a + cm * b])
    yaw_frame = th[m] + phi
    # rigid motion that carries the provisional pose frame onto ``pose``
    rot = pose[2] - yaw_frame
    R = np.array([[np.cos(rot), -np.sin(rot)], [np.sin(rot), np.cos(rot)]])
    centres = (c - p_frame) @ R.T + pose[:2]
    return centres, th + rot


def _exp_step(pose: np.ndarray, xi: np.ndarray, h: float) -> np.ndarray:
    """Pose after moving with constant body velocity ``xi`` for time h (small h: first order is enough)."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return pose + h * np.array([c * xi[0] - s * xi[1], s * xi[0] + c * xi[1], xi[2]])


def _random_model(rng: np.random.Generator, n: int) -> ChainModel:
    nj = n - 1
    act = tuple(sorted(rng.choice(nj, size=max(1, nj // 2), replace=False).tolist()))
    return ChainModel(
        n_links=n, actuated=act,
        stiffness=tuple(rng.uniform(0.5, 5.0, nj)), rest=tuple(rng.uniform(-0.2, 0.2, nj)),
        damping=tuple(rng.uniform(0.0, 0.3, nj)), k3=tuple(rng.uniform(0.0, 1.0, nj)),
        link_length=tuple(rng.uniform(0.3, 1.5, n)), c_par=tuple(rng.uniform(0.5, 1.5, n)),
        c_perp=tuple(rng.uniform(1.5, 3.0, n)), body_link=int(rng.integers(0, n)),
        pose_offset=(float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-1, 1))),
    )


def _balances(model: ChainModel, r: np.ndarray, rdot_a: np.ndarray, pose: np.ndarray):  # type: ignore[no-untyped-def]
    chain = RFTChain(model)
    xi, rdot_p = chain.velocities(r[None], rdot_a[None], yaw=np.array([pose[2]]))
    rdot = np.zeros(model.n_joints)
    rdot[list(model.actuated)] = rdot_a
    rdot[list(model.passive)] = rdot_p[0]
    h = 1e-6
    c1, th1 = _world_links(model, _exp_step(pose, xi[0], h), r + h * rdot)
    c0, th0 = _world_links(model, _exp_step(pose, xi[0], -h), r - h * rdot)
    centres, th = _world_links(model, pose, r)
    v = (c1 - c0) / (2 * h)
    w = (th1 - th0) / (2 * h)
    L = np.asarray(model.link_length)
    cpar, cperp = np.asarray(model.c_par), np.asarray(model.c_perp)
    e = np.stack([np.cos(th), np.sin(th)], axis=1)
    nrm = np.stack([-np.sin(th), np.cos(th)], axis=1)
    v_par, v_perp = np.sum(v * e, axis=1), np.sum(v * nrm, axis=1)
    F = -(cpar * L * v_par)[:, None] * e - (cperp * L * v_perp)[:, None] * nrm
    T = -cperp * L**3 / 12 * w
    force = F.sum(axis=0)
    torque = T.sum() + np.sum(centres[:, 0] * F[:, 1] - centres[:, 1] * F[:, 0])
    # joint j sits at the tail end of link j; the links behind it are j+1 .. N-1
    joint_res = []
    for j in model.passive:
        q = centres[j] - L[j] / 2 * e[j]
        d = centres[j + 1:] - q
        moment = T[j + 1:].sum() + np.sum(d[:, 0] * F[j + 1:, 1] - d[:, 1] * F[j + 1:, 0])
        err = r[j] - model.rest[j]  # type: ignore[index]
        spring = -model.stiffness[j] * err - model.k3[j] * err**3  # type: ignore[index]
        joint_res.append(moment + spring - model.damping[j] * rdot[j])  # type: ignore[index]
    drag_power = -(np.sum(F * v) + np.sum(T * w))
    return chain, rdot, force, torque, np.array(joint_res), drag_power


@pytest.mark.parametrize("seed", range(6))
def test_world_frame_force_and_joint_balance(seed: int) -> None:
    rng = np.random.default_rng(seed)
    model = _random_model(rng, int(rng.integers(3, 8)))
    for _ in range(5):
        r = rng.uniform(-1.0, 1.0, model.n_joints)
        rdot_a = rng.uniform(-3.0, 3.0, len(model.actuated))
        pose = rng.uniform(-2.0, 2.0, 3)
        _, _, force, torque, joint_res, _ = _balances(model, r, rdot_a, pose)
        scale = 1.0 + np.abs(rdot_a).max()
        np.testing.assert_allclose(force, 0.0, atol=1e-6 * scale)
        assert abs(torque) < 1e-6 * scale
        np.testing.assert_allclose(joint_res, 0.0, atol=1e-6 * scale)


@pytest.mark.parametrize("seed", range(4))
def test_power_balance(seed: int) -> None:
    """Actuator power = drag dissipation + internal damping + spring energy rate."""
    rng = np.random.default_rng(100 + seed)
    model = _random_model(rng, int(rng.integers(3, 8)))
    r = rng.uniform(-1.0, 1.0, model.n_joints)
    rdot_a = rng.uniform(-3.0, 3.0, len(model.actuated))
    chain, rdot, _, _, _, drag_power = _balances(model, r, rdot_a, np.zeros(3))
    act, pas = list(model.actuated), list(model.passive)
    tau_a = chain.actuator_effort(r[None], rdot[None])[0]
    e = r[pas] - np.asarray(model.rest)[pas]
    spring_rate = np.sum((np.asarray(model.stiffness)[pas] * e + np.asarray(model.k3)[pas] * e**3) * rdot[pas])
    damping_power = np.sum(np.asarray(model.damping)[pas] * rdot[pas] ** 2)
    np.testing.assert_allclose(tau_a @ rdot[act], drag_power + damping_power + spring_rate,
                               rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(chain.dissipation(r[None], rdot[None])[0], drag_power + damping_power,
                               rtol=1e-6, atol=1e-8)


def test_passive_rates_do_not_depend_on_the_body_frame() -> None:
    rng = np.random.default_rng(7)
    base = _random_model(rng, 6)
    r = rng.uniform(-1, 1, (20, base.n_joints))
    rdot_a = rng.uniform(-2, 2, (20, len(base.actuated)))
    _, ref = RFTChain(base).velocities(r, rdot_a)
    for link in range(base.n_links):
        other = base.with_(body_link=link, pose_offset=tuple(rng.uniform(-0.5, 0.5, 3)))
        _, rdot_p = RFTChain(other).velocities(r, rdot_a)
        np.testing.assert_allclose(rdot_p, ref, rtol=1e-9, atol=1e-12)


def test_pose_offset_changes_only_the_frame_of_the_body_velocity() -> None:
    rng = np.random.default_rng(8)
    base = _random_model(rng, 5).with_(pose_offset=(0.0, 0.0, 0.0))
    offset = (0.2, -0.1, 0.4)
    moved = base.with_(pose_offset=offset)
    r = rng.uniform(-1, 1, (30, base.n_joints))
    rdot_a = rng.uniform(-2, 2, (30, len(base.actuated)))
    xi0, rp0 = RFTChain(base).velocities(r, rdot_a)
    xi1, rp1 = RFTChain(moved).velocities(r, rdot_a)
    np.testing.assert_allclose(rp1, rp0)
    # the adjoint of the offset, written out: ω' = ω, v' = R(−φ)(v + ω × o)
    a, b, phi = offset
    v = np.stack([xi0[:, 0] - xi0[:, 2] * b, xi0[:, 1] + xi0[:, 2] * a], axis=1)
    R = np.array([[np.cos(phi), np.sin(phi)], [-np.sin(phi), np.cos(phi)]])
    np.testing.assert_allclose(xi1[:, :2], v @ R.T, atol=1e-12)
    np.testing.assert_allclose(xi1[:, 2], xi0[:, 2])
    np.testing.assert_allclose(RFTChain(moved).to_link_frame(xi1), xi0, atol=1e-12)
    assert not np.allclose(xi1, xi0)
