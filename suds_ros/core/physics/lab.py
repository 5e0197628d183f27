"""Recordings made the way a lab records a robot: separate streams, own rates, jitter, drops.

A lab's encoders and motion capture run at their own rates on their own clocks:
shape at e.g. 100 Hz, pose at 120 Hz from another start time; every stamp is the
true acquisition time but wanders around the nominal grid; a few messages of each
stream are lost.  :func:`simulate_lab` produces such a :class:`Recording` from the
same physics, drive and seed as :func:`~suds_ros.core.physics.sim.simulate` — its
*aligned twin* — so the two can be compared sample for sample.

How: the actuated set-points are the twin's (reference + OU at the nominal shape
grid, the joint moving on the straight line between set-points).  The run is
integrated on a grid ``oversample`` times finer than the shape grid, so every kink
of the drive is a grid point, and both streams are read off that dense, noise-free
trajectory at their own jittered stamps (linear interpolation between points
0.8 ms apart at the default), then measurement noise is added and messages dropped.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.sim import SimConfig, ou_path, simulate
from suds_ros.core.physics.system import SudsSystem
from suds_ros.core.recording import Recording


@dataclass(frozen=True)
class LabConditions:
    """Recording conditions of the two streams.

    Parameters
    ----------
    pose_hz : float or None
        Pose (motion capture) rate, Hz; None: the shape rate.
    pose_phase : float
        Start of the pose stream after the shape stream, s (e.g. 0.0037).
    jitter : float
        Standard deviation of each stamp around its nominal grid point, s (clipped at
        ±0.4 sampling periods so each stream stays in order).
    drop : float
        Probability that a message is lost, per message and stream (the first and last
        message of each stream are kept).
    oversample : int
        Integration grid points per shape sampling period.
    """

    pose_hz: float | None = 120.0
    pose_phase: float = 0.0037
    jitter: float = 0.0004
    drop: float = 0.01
    oversample: int = 4

    def __post_init__(self) -> None:
        if self.pose_hz is not None and not self.pose_hz > 0:
            raise SudsConfigError(f"`pose_hz`: expected a rate > 0 Hz or None, got {self.pose_hz!r}")
        if not 0 <= self.pose_phase < 1.0:
            raise SudsConfigError(f"`pose_phase`: expected 0 ≤ phase < 1 s, got {self.pose_phase!r}")
        if not self.jitter >= 0:
            raise SudsConfigError(f"`jitter`: expected ≥ 0 s, got {self.jitter!r}")
        if not 0 <= self.drop < 0.5:
            raise SudsConfigError(f"`drop`: expected a probability in [0, 0.5), got {self.drop!r}")
        if self.oversample < 1:
            raise SudsConfigError(f"`oversample`: expected ≥ 1, got {self.oversample!r}")


def _stamps(rng: np.random.Generator, start: float, period: float, end: float, jitter: float) -> FloatArray:
    """Nominal grid start + i·period up to ``end`` with clipped Gaussian jitter."""
    n = int(np.floor((end - start) / period)) + 1
    nominal = start + period * np.arange(n)
    j = np.clip(jitter * rng.standard_normal(n), -0.4 * period, 0.4 * period)
    return nominal + j


def _keep(rng: np.random.Generator, n: int, drop: float) -> np.ndarray:
    keep = rng.random(n) >= drop
    keep[0] = keep[-1] = True
    return keep


def _interp(t: FloatArray, tf: FloatArray, values: FloatArray) -> FloatArray:
    return np.stack([np.interp(t, tf, values[:, i]) for i in range(values.shape[1])], axis=1)


def simulate_lab(system: SudsSystem, config: SimConfig = SimConfig(), lab: LabConditions = LabConditions()
                 ) -> Recording:
    """Simulate a run recorded under lab conditions (see the module docstring).

    ``config`` is the aligned twin's: its ``cycles``, ``samples_per_cycle`` and ``gait_hz`` fix the
    nominal shape grid, ``seed`` the drive (identical to the twin's) and the noise, ``pose_delay``
    a sensor time offset of the pose stream (any value, not only multiples of the period).

    Returns
    -------
    Recording
        Shape and pose at their own stamps.  ``truth`` holds ``"r"`` (n, nj) and ``"pose"`` (n, 3),
        noise free at the shape stamps, and ``"phase"`` (n,), the reference gait phase there.
    """
    dt = config.dt
    f = lab.oversample
    n = config.cycles * config.samples_per_cycle + 1  # one set-point past the end covers late stamps
    nw = int(round(config.warmup / dt))
    ss = np.random.SeedSequence(config.seed)
    rng_ou, rng_noise = (np.random.default_rng(s) for s in ss.spawn(2))
    k = np.arange(-nw, n)
    ref = system.reference(k * dt * config.gait_hz)
    r_a = ref + ou_path(rng_ou, k.size, ref.shape[1], dt, config.kappa, config.ou_std)
    kf = np.arange(-nw * f, (n - 1) * f) / f
    r_a_fine = _interp(kf, k.astype(float), r_a)
    # the same run on a grid f times finer: nw·f warm-up points, then (n − 1)·f recorded points
    fine_cfg = replace(config, samples_per_cycle=config.samples_per_cycle * f, noise_std=0.0,
                       pose_delay=0.0, warmup=nw * dt)
    dense = simulate(system, fine_cfg, r_a=r_a_fine)
    tf = dense.t - dense.t[0]  # fine grid, 0 at the first recorded sample
    r_true_f, pose_true_f = dense.truth["r"], dense.truth["pose"]
    span = tf[-1]
    rng_streams = np.random.default_rng(rng_noise.integers(2**63))
    t_shape = _stamps(rng_streams, 0.0, dt, span - 0.5 * dt, lab.jitter)
    t_shape = t_shape[(t_shape >= 0) & (t_shape <= span)]
    pose_period = dt if lab.pose_hz is None else 1.0 / lab.pose_hz
    t_pose = _stamps(rng_streams, lab.pose_phase, pose_period, span - 0.5 * pose_period, lab.jitter)
    late = t_pose - config.pose_delay  # the pose stamped s is the true pose at s − delay
    t_pose = t_pose[(t_pose >= 0) & (t_pose <= span) & (late >= 0) & (late <= span)]
    t_shape = t_shape[_keep(rng_streams, t_shape.size, lab.drop)]
    t_pose = t_pose[_keep(rng_streams, t_pose.size, lab.drop)]
    if abs(config.pose_delay) > 0.5 * span:
        raise SudsConfigError(f"`pose_delay`: expected |delay| < {0.5 * span:g} s, got {config.pose_delay!r}")
    r_true = _interp(t_shape, tf, r_true_f)
    pose_true = _interp(t_pose - config.pose_delay, tf, pose_true_f)
    sd = config.noise_std
    r_meas = r_true + sd * rng_noise.standard_normal(r_true.shape)
    pose_noise = sd * rng_noise.standard_normal(pose_true.shape)
    if not getattr(system, "planar", True):
        pose_noise[:, 1:] = 0.0
    names = system.joint_names
    truth = {
        "r": r_true,
        "pose": _interp(t_shape, tf, pose_true_f),
        "phase": 2 * np.pi * config.gait_hz * t_shape,
    }
    return Recording(
        t=config.t0 + t_shape, r=r_meas, joint_names=names,
        actuated=tuple(names[i] for i in system.actuated), passive=tuple(names[i] for i in system.passive),
        pose_t=config.t0 + t_pose, pose=pose_true + pose_noise, system=system.name, gait_hz=config.gait_hz,
        effort=None, truth=truth,
    )
