"""Simulated runs of a SUDS driven along a (perturbed) gait.

The actuated joints follow set-points given at the sample times and are linearly interpolated
between them (a servo set-point stream); the passive joints and the pose are integrated by
:func:`suds_ros.core.physics.integrate.integrate_batch` (RK4 and a commutator-free Lie-group
step).  A uniform background flow does not rotate the chain, so it is added exactly as U·t to
the world position.

The drive is r_a = r_ref(t) + η(t), η an Ornstein–Uhlenbeck process
dη = −κη dt + σ dW discretised exactly at the sample times and started from its
stationary law, independent per actuated joint.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.physics.integrate import integrate_batch
from suds_ros.core.recording import Recording
from suds_ros.core.physics.system import SudsSystem


@dataclass(frozen=True)
class SimConfig:
    """How to drive, integrate and sample a simulated run.

    Parameters
    ----------
    cycles : int
        Recorded gait cycles.
    samples_per_cycle : int
        Samples per gait cycle (100 → 100 Hz at a 1 Hz gait).
    gait_hz : float
        Gait frequency, Hz; the reference r_ref is evaluated at gait time t·gait_hz/f_nominal.
    kappa : float
        OU attraction rate κ, 1/s.
    ou_std : float
        Stationary standard deviation of η, rad (σ = ou_std·√(2κ)).
    noise_std : float
        Std of i.i.d. Gaussian measurement noise on recorded joints (rad or m), x, y (m), yaw (rad).
    substeps : int or None
        RK4 steps per sample interval; None picks them from the system's fastest
        passive relaxation rate (:func:`auto_substeps`).
    warmup : float
        Seconds simulated before the first recorded sample (passive joints start at rest).
    t0 : float
        Stamp of the first recorded sample, s.
    seed : int
        Seed: ``SeedSequence(seed).spawn(2)`` gives the OU and the noise streams.
    pose_delay : float
        Pose stamps late by this much, s (``sensor_time_offset``): the pose stamped s is the true pose at s − delay.
    """

    cycles: int = 60
    samples_per_cycle: int = 100
    gait_hz: float = 1.0
    kappa: float = 8.0
    ou_std: float = 0.175
    noise_std: float = 1e-3
    substeps: int | None = None
    warmup: float = 5.0
    t0: float = 1.7e9
    seed: int = 0
    pose_delay: float = 0.0

    def __post_init__(self) -> None:
        checks = [
            ("cycles", self.cycles >= 1),
            ("samples_per_cycle", self.samples_per_cycle >= 8),
            ("gait_hz", self.gait_hz > 0),
            ("kappa", self.kappa > 0),
            ("ou_std", self.ou_std >= 0),
            ("noise_std", self.noise_std >= 0),
            ("substeps", self.substeps is None or self.substeps >= 1),
            ("warmup", self.warmup >= 0),
        ]
        for name, ok in checks:
            if not ok:
                raise SudsConfigError(f"`{name}`: value {getattr(self, name)!r} is out of range")

    @property
    def dt(self) -> float:
        """Sample interval, s."""
        return 1.0 / (self.gait_hz * self.samples_per_cycle)


def ou_path(rng: np.random.Generator, n: int, dim: int, dt: float, kappa: float, std: float) -> FloatArray:
    """Exactly discretised stationary OU samples, shape (n, dim)."""
    a = np.exp(-kappa * dt)
    b = std * np.sqrt(1.0 - a * a)
    z = rng.standard_normal((n, dim))
    eta = np.empty((n, dim))
    eta[0] = std * z[0]
    for k in range(1, n):
        eta[k] = a * eta[k - 1] + b * z[k]
    return eta


def passive_rate(system: SudsSystem, n_shapes: int = 16, seed: int = 0) -> float:
    """Largest |eigenvalue| of ∂ṙ_p/∂r_p (1/s) over random shapes: the fastest passive relaxation."""
    act, pas = list(system.actuated), list(system.passive)
    if not pas:
        return 0.0
    nj = len(act) + len(pas)
    rng = np.random.default_rng(seed)
    base = rng.normal(scale=0.8, size=(n_shapes, nj))
    model = getattr(system, "model", None)
    rest = getattr(model, "rest", None)
    if rest is not None:
        base = base + np.asarray(rest)
    h = 1e-6
    cols = []
    for j in pas:
        plus, minus = base.copy(), base.copy()
        plus[:, j] += h
        minus[:, j] -= h
        zero = np.zeros((n_shapes, len(act)))
        cols.append((system.velocities(plus, zero)[1] - system.velocities(minus, zero)[1]) / (2 * h))
    jac = np.stack(cols, axis=2)  # (shapes, np, np)
    return float(np.abs(np.linalg.eigvals(jac)).max())


def auto_substeps(system: SudsSystem, dt: float, accuracy: float = 0.2) -> int:
    """RK4 steps per sample so that h·λ_max ≤ ``accuracy`` (≈1e-5 rad local error), at least 2."""
    return max(2, int(np.ceil(dt * passive_rate(system) / accuracy)))


@dataclass(frozen=True)
class Trajectory:
    """Noise-free integration result at the sample times.

    Attributes
    ----------
    r : (n, nj) joint values at the samples.
    pose : (n, 3) still-fluid world pose plus flow drift (x, y, yaw).
    """

    r: FloatArray
    pose: FloatArray
    extras: dict[str, FloatArray] = field(default_factory=dict)


def integrate(
    system: SudsSystem,
    r_a: FloatArray,
    dt: float,
    r_p0: FloatArray,
    pose0: FloatArray | None = None,
    substeps: int | None = None,
    flow: tuple[float, float] = (0.0, 0.0),
    progress: Callable[[int, int], None] | None = None,
) -> Trajectory:
    """Integrate the passive joints and the pose under piecewise-linear actuated set-points.

    Parameters
    ----------
    system : SudsSystem
        The physics (its ``velocities`` must be the still-fluid solution; pass ``flow`` separately).
    r_a : (n, na) float
        Actuated set-points at the n sample times (spacing ``dt``).
    dt : float
        Sample interval, s.
    r_p0 : (np,) float
        Passive joint values at the first sample.
    pose0 : (3,) float, optional
        World pose (x, y, yaw) at the first sample; default zeros.
    substeps : int or None
        RK4 steps per interval; None: :func:`auto_substeps`.
    flow : (vx, vy)
        Uniform world-frame flow, m/s, added as U·t to the position.
    progress : callable, optional
        Called as ``progress(done, total)`` about every 1 % of the samples.

    Returns
    -------
    Trajectory
        ``r`` (n, nj) and ``pose`` (n, 3) at the samples.
    """
    r_a = np.asarray(r_a, dtype=float)
    if r_a.ndim != 2 or r_a.shape[1] != len(system.actuated):
        raise SudsDataError(
            f"`r_a`: expected shape (n, {len(system.actuated)}), got {r_a.shape}"
        )
    n = r_a.shape[0]
    act = np.asarray(system.actuated, dtype=int)
    pas = np.asarray(system.passive, dtype=int)
    rp0 = np.asarray(r_p0, dtype=float).reshape(1, -1)
    if rp0.shape[1] != pas.size:
        raise SudsDataError(f"`r_p0`: expected {pas.size} values, got {rp0.shape[1]}")
    pose = np.zeros((1, 3)) if pose0 is None else np.asarray(pose0, dtype=float).reshape(1, 3)
    if substeps is None:
        substeps = auto_substeps(system, dt)
    RP, PP = integrate_batch(system.velocities, act, pas, r_a[None], rp0, pose, dt, substeps, progress)
    R = np.empty((n, act.size + pas.size))
    R[:, act] = r_a
    R[:, pas] = RP[0]
    P = PP[0]
    if flow != (0.0, 0.0):
        tt = dt * np.arange(n)
        P[:, 0] += flow[0] * tt
        P[:, 1] += flow[1] * tt
    return Trajectory(r=R, pose=P)


def _still(system: SudsSystem) -> tuple[SudsSystem, tuple[float, float]]:
    """Split a system into its still-fluid physics and its background flow."""
    model = getattr(system, "model", None)
    flow = getattr(model, "flow", (0.0, 0.0))
    if flow == (0.0, 0.0):
        return system, (0.0, 0.0)
    still = type(system)(model.with_(flow=(0.0, 0.0)))  # type: ignore[union-attr,call-arg]
    return still, flow


def simulate(
    system: SudsSystem,
    config: SimConfig = SimConfig(),
    *,
    r_a: FloatArray | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Recording:
    """Simulate a run and return it as a :class:`Recording` (noisy) with ground truth attached.

    Parameters
    ----------
    system : SudsSystem
        The physics and its nominal gait (``system.reference``).
    config : SimConfig
        Drive, integration and sampling settings.
    r_a : (n_warm + n, na) float, optional
        Explicit actuated set-points (warm-up included) instead of reference + OU.
    progress : callable, optional
        Progress callback ``progress(done, total)`` passed to :func:`integrate`.

    Returns
    -------
    Recording
        Noisy measurements.  ``truth`` holds ``"r"`` (n, nj) and ``"pose"`` (n, 3) noise free,
        ``"phase"`` (n,) gait phase 2π·f·t of the reference, rad, and ``"effort"`` (n, na): the
        actuator effort averaged over the sample period ending at each sample, N·m.
    """
    dt = config.dt
    n = config.cycles * config.samples_per_cycle
    nw = int(round(config.warmup / dt))
    ss = np.random.SeedSequence(config.seed)
    rng_ou, rng_noise = (np.random.default_rng(s) for s in ss.spawn(2))
    k = np.arange(-nw, n)
    t_gait = k * dt
    if r_a is None:
        ref = system.reference(t_gait * config.gait_hz)
        eta = ou_path(rng_ou, k.size, ref.shape[1], dt, config.kappa, config.ou_std)
        r_a = ref + eta
    else:
        r_a = np.asarray(r_a, dtype=float)
        if r_a.shape != (k.size, len(system.actuated)):
            raise SudsDataError(f"`r_a`: expected shape {(k.size, len(system.actuated))}, got {r_a.shape}")
    still, flow = _still(system)
    rest = _rest_angles(system)
    traj = integrate(still, r_a, dt, rest, substeps=config.substeps, progress=progress)
    r_true = traj.r[nw:]
    pose_all = traj.pose.copy()
    pose_all[:, 0] += flow[0] * t_gait  # uniform flow drifts the chain by U·t (t = 0 at the first sample)
    pose_all[:, 1] += flow[1] * t_gait
    tt = dt * np.arange(n)
    stamps = config.t0 + tt
    pose_stamps = stamps
    if config.pose_delay != 0.0:
        pose_true = _delay_pose(pose_all, t_gait, tt, config.pose_delay)
    else:
        pose_true = pose_all[nw:]
    sd = config.noise_std
    r_meas = r_true + sd * rng_noise.standard_normal(r_true.shape)
    pose_noise = sd * rng_noise.standard_normal(pose_true.shape)
    if not getattr(system, "planar", True):  # motion along x only: y and yaw are not measured, stay 0
        pose_noise[:, 1:] = 0.0
    pose_meas = pose_true + pose_noise
    names = system.joint_names
    lo = max(nw - 1, 0)
    effort = _effort_at_samples(still, r_a[lo:], traj.r[lo:], dt)
    if nw == 0:  # no set-point before the first sample: repeat the first period's effort
        effort = np.concatenate([effort[:1], effort], axis=0)
    truth = {
        "r": r_true,
        "pose": pose_true,
        "phase": 2 * np.pi * config.gait_hz * tt,
        "effort": effort,
    }
    return Recording(
        t=stamps,
        r=r_meas,
        joint_names=names,
        actuated=tuple(names[i] for i in system.actuated),
        passive=tuple(names[i] for i in system.passive),
        pose_t=pose_stamps,
        pose=pose_meas,
        system=system.name,
        gait_hz=config.gait_hz,
        effort=None,
        truth=truth,
    )


def _rest_angles(system: SudsSystem) -> FloatArray:
    model = getattr(system, "model", None)
    rest = getattr(model, "rest", None)
    if rest is None:
        rest_fn = getattr(system, "rest_state", None)
        if rest_fn is None:
            return np.zeros(len(system.passive))
        return np.asarray(rest_fn(), dtype=float)
    return np.asarray(rest, dtype=float)[list(system.passive)]


def _delay_pose(pose: FloatArray, t_all: FloatArray, tt: FloatArray, delay: float) -> FloatArray:
    """Pose stamped s carries the true pose at s − delay (linear interpolation; warm-up covers s < delay)."""
    if delay > t_all[-1] - t_all[0]:
        raise SudsConfigError(f"`pose_delay`: {delay} s exceeds the simulated span")
    return np.stack([np.interp(tt - delay, t_all, pose[:, i]) for i in range(3)], axis=1)


def _effort_at_samples(system: SudsSystem, r_a: FloatArray, r: FloatArray, dt: float) -> FloatArray:
    """Actuator effort (n, na) at each sample: the effort over the sample period that ends there.

    Evaluated at the midpoint state of the interval (k − 1, k) with its set-point rate — the
    reading of a torque/current sensor averaged over the control period.  ``r_a`` holds one
    set-point before the first sample: shape (n + 1, na); ``r`` (n + 1, nj) likewise.
    """
    va = np.diff(r_a, axis=0) / dt
    mid = 0.5 * (r[1:] + r[:-1])
    act = list(system.actuated)
    pas = list(system.passive)
    _, rdot_p = system.velocities(mid, va)
    rdot = np.zeros_like(mid)
    rdot[:, act] = va
    rdot[:, pas] = rdot_p
    return system.actuator_effort(mid, rdot)
