"""The one batched RK4 + Lie-group integrator (:mod:`suds_ros.core.physics.integrate`)."""

from __future__ import annotations

import numpy as np

from suds_ros.core import se2
from suds_ros.core.physics.integrate import integrate_batch
from suds_ros.core.physics.sim import integrate, ou_path
from suds_ros.core.physics.systems import make_system


def _swimmer_runs(m: int, B: int, shift: float, seed: int):  # type: ignore[no-untyped-def]
    """swimmer9, its joint columns, and B runs of m samples: drive (gait shifted by b·shift s + OU), starts, rng."""
    sys_ = make_system("swimmer9")
    act, pas = np.asarray(sys_.actuated), np.asarray(sys_.passive)
    t = np.arange(m) * 0.01
    rng = np.random.default_rng(seed)
    r_a = np.stack([sys_.reference(t + shift * b) + ou_path(rng, t.size, act.size, 0.01, 8.0, 0.1) for b in range(B)])
    rp0 = 0.1 * rng.standard_normal((B, pas.size))
    pose0 = rng.standard_normal((B, 3))
    return sys_, act, pas, r_a, rp0, pose0, rng


def test_batch_equals_each_run_alone() -> None:
    """B runs in one batch give each run's trajectory exactly (the simulator integrates B = 1)."""
    sys_, act, pas, r_a, rp0, pose0, rng = _swimmer_runs(120, 3, 0.3, 4)
    RP, P = integrate_batch(sys_.velocities, act, pas, r_a, rp0, pose0, 0.01, 3)
    assert RP.shape == (3, 120, pas.size) and P.shape == (3, 120, 3)
    for b in range(3):
        one = integrate(sys_, r_a[b], 0.01, rp0[b], pose0[b], substeps=3)
        np.testing.assert_allclose(RP[b], one.r[:, pas], rtol=0, atol=1e-13)
        np.testing.assert_allclose(P[b], one.pose, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(one.r[:, act], r_a[b])


def test_constant_twist_is_integrated_exactly() -> None:
    """With a constant body velocity the pose follows the exact SE(2) arc whatever the step."""
    twist = np.array([0.4, 0.1, 0.9])

    def velocities(r, rdot_a):  # type: ignore[no-untyped-def]
        return np.tile(twist, (r.shape[0], 1)), np.zeros((r.shape[0], 1))

    r_a = np.zeros((1, 11, 1))
    _, P = integrate_batch(velocities, np.array([0]), np.array([1]), r_a, np.zeros((1, 1)),
                           np.array([[1.0, -2.0, 0.5]]), 0.1, 1)
    expect = se2.exp_step(np.array([1.0, -2.0, 0.5]), twist * 1.0)
    np.testing.assert_allclose(P[0, -1], expect, atol=1e-12)


def test_progress_is_reported() -> None:
    sys_ = make_system("purcell3")
    calls: list[tuple[int, int]] = []
    r_a = sys_.reference(np.arange(50) * 0.01)[None]
    integrate_batch(sys_.velocities, np.asarray(sys_.actuated), np.asarray(sys_.passive), r_a,
                    np.zeros((1, 1)), np.zeros((1, 3)), 0.01, 2, progress=lambda k, n: calls.append((k, n)))
    assert calls[0] == (0, 49) and calls[-1] == (49, 49) and len(calls) == 50


def test_per_run_intervals_equal_each_run_alone() -> None:
    """``dt`` given per run: each run is integrated on its own grid, as if alone with that dt."""
    sys_ = make_system("swimmer9")
    act, pas = np.asarray(sys_.actuated), np.asarray(sys_.passive)
    rng = np.random.default_rng(7)
    dts = np.array([0.0096, 0.0104, 0.02])
    r_a = np.stack([sys_.reference(np.arange(6) * d) for d in dts])
    rp0 = 0.1 * rng.standard_normal((3, pas.size))
    pose0 = rng.standard_normal((3, 3))
    RP, P = integrate_batch(sys_.velocities, act, pas, r_a, rp0, pose0, dts, 4)
    for b, d in enumerate(dts):
        one_rp, one_p = integrate_batch(sys_.velocities, act, pas, r_a[b:b + 1], rp0[b:b + 1], pose0[b:b + 1],
                                        float(d), 4)
        np.testing.assert_allclose(RP[b], one_rp[0], rtol=0, atol=1e-13)
        np.testing.assert_allclose(P[b], one_p[0], rtol=0, atol=1e-12)
    assert np.abs(RP[2, -1] - RP[0, -1]).max() > 1e-3  # the intervals matter


def test_a_reset_restarts_the_passive_joints_there_and_the_run_continues_from_it() -> None:
    """``reset``: at a finite entry the passive joints take it, and the rest equals a run started there."""
    sys_, act, pas, r_a, rp0, pose0, rng = _swimmer_runs(80, 2, 0.2, 7)
    reset = np.full((2, 80, pas.size), np.nan)
    reset[0, 30] = 0.2 * rng.standard_normal(pas.size)  # run 0 restarts at sample 30, run 1 never
    RP, P = integrate_batch(sys_.velocities, act, pas, r_a, rp0, pose0, 0.01, 3, reset=reset)
    plain, plain_pose = integrate_batch(sys_.velocities, act, pas, r_a, rp0, pose0, 0.01, 3)
    np.testing.assert_array_equal(RP[1], plain[1])
    np.testing.assert_array_equal(RP[0, :30], plain[0, :30])
    np.testing.assert_array_equal(RP[0, 30], reset[0, 30])
    tail, tail_pose = integrate_batch(sys_.velocities, act, pas, r_a[:1, 30:], reset[:1, 30], plain_pose[:1, 30],
                                      0.01, 3)
    assert np.max(np.abs(RP[0, 30:] - tail[0])) < 1e-13
    assert np.max(np.abs(RP[0, 40:] - plain[0, 40:])) > 1e-4  # the restart did change the run
