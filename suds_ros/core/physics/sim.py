"""Simulated runs of a SUDS driven along a (perturbed) gait.

The actuated joints follow set-points given at the sample times and are linearly interpolated
between them (a servo set-point stream); the passive joints and the pose are integrated by
:func:`suds_ros.core.physics.integrate.integrate_batch` (RK4 and a commutator-free Lie-group
step).  A uniform background flow does not rotate the chain, so it is added exactly as U·t to
the world position.

The drive is r_a = r_ref(t) + η(t), η an Ornstein–Uhlenbeck process
dη = −κη dt + σ dW discretised exactly at the sample times and started from its
stationary law, independent per actuated joint.  r_ref is the system's nominal gait, or
``SimConfig.gait`` (a :class:`~suds_ros.core.physics.gait.Gait`) when set; ``ou_std`` = 0
switches the perturbation off.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.physics.gait import Gait, check_gait
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
    gait : Gait or None
        The reference r_ref (``suds-gait/1``) instead of the system's nominal gait; its
        ``gait_hz`` must equal ``gait_hz``.  None: the nominal gait.
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
    gait: Gait | None = None

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
        if self.gait is not None and not (isinstance(self.gait, Gait) and self.gait.gait_hz == self.gait_hz):
            found = self.gait.gait_hz if isinstance(self.gait, Gait) else self.gait
            raise SudsConfigError(f"`gait`: expected a Gait at `gait_hz` = {self.gait_hz:g} Hz, got {found!r}")

    @property
    def dt(self) -> float:
        """Sample interval, s."""
        return 1.0 / (self.gait_hz * self.samples_per_cycle)


def ou_path(rng: np.random.Generator, n: int, dim: int, dt: float, kappa: float, std: float,
            prev: FloatArray | None = None) -> FloatArray:
    """Exactly discretised stationary OU samples, shape (n, dim).

    ``prev`` (dim,): the sample before the first, to continue a path (the same ``rng`` then gives
    the values one longer call would); None starts from the stationary law.
    """
    a = np.exp(-kappa * dt)
    b = std * np.sqrt(1.0 - a * a)
    z = rng.standard_normal((n, dim))
    eta = np.empty((n, dim))
    if n == 0:
        return eta
    eta[0] = std * z[0] if prev is None else a * prev + b * z[0]
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


#: gait cycles integrated, noised and handed on at a time (peak memory grows with this, not the run)
BLOCK_CYCLES = 10
#: random numbers drawn per call when a stream is advanced without keeping its values
_SKIP_CHUNK = 1 << 16


@dataclass(frozen=True)
class SimBlock:
    """Consecutive samples of a simulated run; the blocks of a run concatenated are its :class:`Recording`.

    Attributes
    ----------
    t : (m,) float
        Shape stamps, s.
    r : (m, nj) float
        Measured joint values (noisy).
    pose_t : (q,) float
        Pose stamps, s.  A block's poses need not span its shape samples: a pose that is read
        ahead of its stamp (a negative sensor time offset) waits for the integration to pass it.
    pose : (q, 3) float
        Measured pose x, y (m), yaw (rad); the yaw unwrapped continuing the previous block, as
        :class:`Recording` unwraps the whole run.
    truth : dict
        Noise-free values: ``"r"`` (m, nj), ``"phase"`` (m,) and, for aligned runs,
        ``"effort"`` (m, na) at the shape stamps; ``"pose"`` at the pose stamps (aligned runs,
        (q, 3)) or at the shape stamps (lab runs, (m, 3)).
    """

    t: FloatArray
    r: FloatArray
    pose_t: FloatArray
    pose: FloatArray
    truth: dict[str, FloatArray] = field(default_factory=dict)


def recording_from_blocks(system: SudsSystem, gait_hz: float, blocks: Iterable[SimBlock]) -> Recording:
    """Concatenate the blocks of one run into its :class:`Recording` (truth attached)."""
    blocks = list(blocks)
    if not blocks:
        raise SudsDataError("`blocks`: expected at least one block of the run, got none")
    truth = {key: np.concatenate([b.truth[key] for b in blocks]) for key in blocks[0].truth}
    names = system.joint_names
    return Recording(
        t=np.concatenate([b.t for b in blocks]),
        r=np.concatenate([b.r for b in blocks]),
        joint_names=names,
        actuated=tuple(names[i] for i in system.actuated),
        passive=tuple(names[i] for i in system.passive),
        pose_t=np.concatenate([b.pose_t for b in blocks]),
        pose=np.concatenate([b.pose for b in blocks]),
        system=system.name,
        gait_hz=gait_hz,
        effort=None,
        truth=truth,
    )


def simulate(
    system: SudsSystem,
    config: SimConfig = SimConfig(),
    *,
    r_a: FloatArray | None = None,
    progress: Callable[[int, int], None] | None = None,
    block_cycles: int = BLOCK_CYCLES,
) -> Recording:
    """Simulate a run and return it as a :class:`Recording` (noisy) with ground truth attached.

    The concatenation of :func:`simulate_blocks`; the same for every ``block_cycles``.

    Parameters
    ----------
    system : SudsSystem
        The physics and its nominal gait (``system.reference``).
    config : SimConfig
        Drive, integration and sampling settings.
    r_a : (n_warm + n, na) float, optional
        Explicit actuated set-points (warm-up included) instead of reference + OU.
    progress : callable, optional
        Progress callback ``progress(done, total)`` over the run's sample intervals.
    block_cycles : int
        Cycles integrated at a time (:func:`simulate_blocks`).

    Returns
    -------
    Recording
        Noisy measurements.  ``truth`` holds ``"r"`` (n, nj) and ``"pose"`` (n, 3) noise free,
        ``"phase"`` (n,) gait phase 2π·f·t of the reference, rad, and ``"effort"`` (n, na): the
        actuator effort averaged over the sample period ending at each sample, N·m.
    """
    blocks = simulate_blocks(system, config, r_a=r_a, progress=progress, block_cycles=block_cycles)
    return recording_from_blocks(system, config.gait_hz, blocks)


def simulate_actuator_lag(system: SudsSystem, config: SimConfig, lag_samples: int) -> Recording:
    """A run whose actuators follow their set-points ``lag_samples`` sample periods late, recording the set-points.

    Physics outside the effect catalogue, for checking that a diagnosis says "unexplained" rather
    than forcing a catalogue entry: the joints move along the commanded drive (the nominal gait +
    the OU perturbation, from ``config.seed`` + 1000) delayed, while the recording's actuated angles
    are the *commanded* ones with the same sensor noise as the run's.  ``config.gait`` is not used.
    """
    import dataclasses

    if lag_samples < 1:
        raise SudsConfigError(f"`lag_samples`: expected an integer ≥ 1, got {lag_samples!r}")
    n = config.cycles * config.samples_per_cycle
    n_warm = int(round(config.warmup / config.dt))
    k = np.arange(-n_warm, n)
    ref = system.reference(k * config.dt)
    cmd = ref + ou_path(np.random.default_rng(config.seed + 1000), k.size, ref.shape[1], config.dt,
                        config.kappa, config.ou_std)
    actual = np.concatenate([np.repeat(cmd[:1], lag_samples, axis=0), cmd[:-lag_samples]], axis=0)
    rec = simulate(system, config, r_a=actual)
    r = rec.r.copy()
    idx = [rec.joint_names.index(nm) for nm in rec.actuated]
    r[:, idx] = cmd[n_warm:] + (r[:, idx] - rec.truth["r"][:, idx])
    return dataclasses.replace(rec, r=r)


def reference_of(system: SudsSystem, config: SimConfig) -> Callable[[FloatArray], FloatArray]:
    """r_ref at gait time s (cycles) → (len(s), na): ``config.gait`` (checked against ``system``) or the nominal.

    Raises
    ------
    SudsConfigError
        (code ``model_mismatch``) a gait of another system or other joints.
    """
    if config.gait is None:
        return system.reference
    return check_gait(config.gait, system).at_phase


class OUDrive:
    """The drive r_ref(k·dt) + η_k at sample indices k = k0, k0 + 1, …, handed out in order.

    η is the exactly discretised stationary OU process of :func:`ou_path`, drawn from ``rng``;
    taking the samples in pieces gives the same values as one :func:`ou_path` call.
    """

    def __init__(self, system: SudsSystem, config: SimConfig, rng: np.random.Generator, k0: int) -> None:
        self._reference, self._config, self._rng = reference_of(system, config), config, rng
        self._k = k0
        self._eta: FloatArray | None = None
        # evaluated now, so that a system without a gait is refused before anything is written
        self.dim = int(self._reference(np.array([k0 * config.dt * config.gait_hz])).shape[1])

    def take(self, m: int) -> FloatArray:
        """The next ``m`` set-points, shape (m, na)."""
        cfg = self._config
        k = np.arange(self._k, self._k + m)
        self._k += m
        ref = self._reference(k * cfg.dt * cfg.gait_hz)
        eta = ou_path(self._rng, m, self.dim, cfg.dt, cfg.kappa, cfg.ou_std, prev=self._eta)
        if m:
            self._eta = eta[-1]
        return ref + eta


class ArrayDrive:
    """Set-points given as one array, handed out in order (the interface of :class:`OUDrive`)."""

    def __init__(self, r_a: FloatArray) -> None:
        self._r_a, self._k = r_a, 0

    def take(self, m: int) -> FloatArray:
        """The next ``m`` set-points, shape (m, na)."""
        out = self._r_a[self._k:self._k + m]
        self._k += m
        return out


class Drive(Protocol):
    """Actuated set-points at consecutive samples (:class:`OUDrive`, :class:`ArrayDrive`)."""

    def take(self, m: int) -> FloatArray:
        """The next ``m`` set-points, shape (m, na)."""


def block_stops(n_warm: int, n: int, block: int) -> list[int]:
    """Ends of the pieces integrated at a time: the warm-up, then the run, ``block`` samples each."""
    warm = [min(n_warm, s) for s in range(block, n_warm + block, block)] if n_warm else []
    return warm + [n_warm + min(n, s) for s in range(block, n + block, block)]


def trajectory(
    still: SudsSystem,
    drive: Drive,
    dt: float,
    stops: list[int],
    r_p0: FloatArray,
    substeps: int,
    progress: Callable[[int, int], None] | None = None,
) -> Iterator[tuple[int, int, FloatArray, FloatArray, FloatArray]]:
    """Integrate a run piece by piece (:func:`~suds_ros.core.physics.integrate.integrate_batch`).

    The passive joints, the pose and the last set-point are carried from piece to piece, so the
    pieces are exactly the samples of one integration of the whole run.

    Parameters
    ----------
    still : SudsSystem
        Still-fluid physics.
    drive : Drive
        Set-points at the samples 0, 1, ….
    dt : float
        Sample interval, s.
    stops : list of int
        Increasing sample indices: the pieces are [0, stops[0]), [stops[0], stops[1]), ….
    r_p0 : (np,) float
        Passive joints at sample 0 (the pose starts at zero).
    substeps : int
        RK4 steps per sample interval.
    progress : callable, optional
        ``progress(done, total)`` over the sample intervals, about every 1 %.

    Yields
    ------
    g0, g1 : int
        The piece's samples [g0, g1).
    r_a : (g1 − g0, na) float
        Set-points.
    r : (g1 − g0, nj) float
        Joint values.
    pose : (g1 − g0, 3) float
        Still-fluid world pose (x, y, yaw).
    """
    act = np.asarray(still.actuated, dtype=int)
    pas = np.asarray(still.passive, dtype=int)
    rp = np.asarray(r_p0, dtype=float).reshape(1, -1)
    if rp.shape[1] != pas.size:
        raise SudsDataError(f"`r_p0`: expected {pas.size} values, got {rp.shape[1]}")
    pose = np.zeros((1, 3))
    total = max(stops[-1] - 1, 0)
    report = _Progress(progress, total)
    last_ra: FloatArray | None = None
    g0 = 0
    for g1 in stops:
        new = np.asarray(drive.take(g1 - g0), dtype=float)
        ra = new if last_ra is None else np.concatenate([last_ra[None], new])
        offset = max(g0 - 1, 0)
        RP, PP = integrate_batch(still.velocities, act, pas, ra[None], rp, pose, dt, substeps,
                                 None if progress is None else (lambda k, _m: report(offset + k)))
        skip = 0 if last_ra is None else 1
        R = np.empty((new.shape[0], act.size + pas.size))
        R[:, act] = new
        R[:, pas] = RP[0, skip:]
        # carried as copies: the caller may change the yielded arrays in place
        last_ra, rp, pose = ra[-1].copy(), RP[:, -1].copy(), PP[:, -1].copy()
        yield g0, g1, new, R, PP[0, skip:]
        g0 = g1


class _Progress:
    """Forwards ``done`` to ``progress(done, total)`` at most about every 1 % (and at the end)."""

    def __init__(self, progress: Callable[[int, int], None] | None, total: int) -> None:
        self._progress, self._total = progress, total
        self._step = max(1, total // 100)
        self._next = 0

    def __call__(self, done: int) -> None:
        if self._progress is not None and (done >= self._next or done >= self._total):
            self._progress(done, self._total)
            self._next = done + self._step


class YawUnwrap:
    """``np.unwrap`` (period 2π) continued across blocks: equal to unwrapping their concatenation."""

    def __init__(self) -> None:
        self._last: float | None = None
        self._offset = 0.0

    def __call__(self, yaw: FloatArray) -> FloatArray:
        """The next block of raw yaws (q,) → unwrapped (q,), rad."""
        yaw = np.asarray(yaw, dtype=float)
        if yaw.size == 0:
            return yaw
        first = self._last is None
        p = yaw if first else np.concatenate([[self._last], yaw])
        dd = np.diff(p)
        ddmod = np.mod(dd + np.pi, 2 * np.pi) - np.pi  # numpy's unwrap, step by step
        np.copyto(ddmod, np.pi, where=(ddmod == -np.pi) & (dd > 0))
        corr = ddmod - dd
        np.copyto(corr, 0, where=np.abs(dd) < np.pi)
        offsets = np.cumsum(np.concatenate([[self._offset], corr]))[1:]
        out = yaw.copy()
        if first:
            out[1:] = yaw[1:] + offsets
        else:
            out = yaw + offsets
        self._last = float(yaw[-1])
        if offsets.size:
            self._offset = float(offsets[-1])
        return out


class Window:
    """The newest rows of a dense series (times, values), interpolated at increasing times.

    Interpolation on the rows kept gives exactly what :func:`numpy.interp` gives on the
    whole series, as long as each time asked for lies at or after the row before it
    (:meth:`drop_before` keeps that row) and, unless the series is complete, at or before the
    last row.
    """

    def __init__(self, width: int) -> None:
        self.t = np.empty(0)
        self.v = np.empty((0, width))

    def extend(self, t: FloatArray, v: FloatArray) -> None:
        """Append rows: times (m,) increasing past the last, values (m, width)."""
        self.t = np.concatenate([self.t, t])
        self.v = np.concatenate([self.v, v])

    def interp(self, x: FloatArray, cols: slice = slice(None)) -> FloatArray:
        """Linear interpolation of the columns ``cols`` at the times x (q,) → (q, ncols)."""
        v = self.v[:, cols]
        return np.stack([np.interp(x, self.t, v[:, i]) for i in range(v.shape[1])], axis=1)

    def drop_before(self, x: float) -> None:
        """Forget the rows no later time ≥ ``x`` needs (the row at or before x stays)."""
        j = max(int(np.searchsorted(self.t, x, side="right")) - 1, 0)
        self.t, self.v = self.t[j:], self.v[j:]


class DenseRun:
    """The newest rows of a dense run (times, joints, world pose), read at increasing times by cubic Hermite.

    Rows hold the ``nj`` joints then the world pose (x, y, yaw; a uniform flow included).  Between
    two rows the actuated joints move on a straight line (the drive bends at rows only), so each
    segment's rates at its two ends follow from the physics there under that segment's slope:
    the joints' rates and the pose's, R(yaw)·ξ + the flow.  Cubic Hermite interpolation with those
    end rates is exact for the straight actuated joints and, for the rest, errs by O(h⁴) where a
    straight line between rows errs by O(h²) — an error that repeats with the gait, so it would
    stand out against the noise over many cycles (a stiff passive joint's curvature over a 2.5 ms
    row, or the pose over a 10 ms sample when the pose stream is delayed).  The reading at a time
    depends only on the two rows around it (:meth:`drop_before` keeps the row at or before the
    time asked for), and times up to the last row can be read before the run is complete.
    """

    def __init__(self, still: SudsSystem, flow: tuple[float, float] = (0.0, 0.0)) -> None:
        self.still = still
        self.act = np.asarray(still.actuated, dtype=np.intp)
        self.pas = np.asarray(still.passive, dtype=np.intp)
        self.nj = len(still.joint_names)
        self.flow = flow
        self.t = np.empty(0)
        self.v = np.empty((0, self.nj + 3))
        self.d0 = np.empty((0, self.nj + 3))  # each segment's rates at its start
        self.d1 = np.empty((0, self.nj + 3))  # and at its end

    def _rates(self, rows: FloatArray, slope_a: FloatArray) -> FloatArray:
        xi, rdot_p = self.still.velocities(rows[:, :self.nj], slope_a)
        out = np.zeros_like(rows)
        out[:, self.act] = slope_a
        out[:, self.pas] = rdot_p
        c, s = np.cos(rows[:, self.nj + 2]), np.sin(rows[:, self.nj + 2])
        out[:, self.nj] = c * xi[:, 0] - s * xi[:, 1] + self.flow[0]
        out[:, self.nj + 1] = s * xi[:, 0] + c * xi[:, 1] + self.flow[1]
        out[:, self.nj + 2] = xi[:, 2]
        return out

    def extend(self, t: FloatArray, v: FloatArray) -> None:
        """Append rows: times (m,) increasing past the last, values (m, nj + 3)."""
        times, rows = np.concatenate([self.t[-1:], t]), np.concatenate([self.v[-1:], v])
        if times.size > 1:
            slope = np.diff(rows[:, self.act], axis=0) / np.diff(times)[:, None]
            self.d0 = np.concatenate([self.d0, self._rates(rows[:-1], slope)])
            self.d1 = np.concatenate([self.d1, self._rates(rows[1:], slope)])
        self.t = np.concatenate([self.t, t])
        self.v = np.concatenate([self.v, v])

    def interp(self, x: FloatArray, cols: slice = slice(None)) -> FloatArray:
        """The columns ``cols`` at the times x (q,), each between the rows kept → (q, ncols)."""
        if self.t.size == 1:
            return np.repeat(self.v[:1, cols], np.size(x), axis=0)
        k = np.clip(np.searchsorted(self.t, x, side="right") - 1, 0, self.t.size - 2)
        h = self.t[k + 1] - self.t[k]
        u = np.clip((np.asarray(x) - self.t[k]) / h, 0.0, 1.0)[:, None]
        h00, h01 = (1 + 2 * u) * (1 - u) ** 2, u**2 * (3 - 2 * u)
        h10, h11 = u * (1 - u) ** 2, u**2 * (u - 1)
        v, d0, d1 = self.v[:, cols], self.d0[:, cols], self.d1[:, cols]
        return h00 * v[k] + h01 * v[k + 1] + h[:, None] * (h10 * d0[k] + h11 * d1[k])

    def drop_before(self, x: float) -> None:
        """Forget the rows no later time ≥ ``x`` needs (the row at or before x stays)."""
        j = max(int(np.searchsorted(self.t, x, side="right")) - 1, 0)
        self.t, self.v, self.d0, self.d1 = self.t[j:], self.v[j:], self.d0[j:], self.d1[j:]


def skip_normals(rng: np.random.Generator, count: int) -> np.random.Generator:
    """A copy of ``rng`` advanced past ``count`` standard normals (drawn in chunks, not kept)."""
    out = copy.deepcopy(rng)
    for a in range(0, count, _SKIP_CHUNK):
        out.standard_normal(min(_SKIP_CHUNK, count - a))
    return out


def simulate_blocks(
    system: SudsSystem,
    config: SimConfig = SimConfig(),
    *,
    r_a: FloatArray | None = None,
    progress: Callable[[int, int], None] | None = None,
    block_cycles: int = BLOCK_CYCLES,
) -> Iterator[SimBlock]:
    """Simulate a run ``block_cycles`` cycles at a time; the blocks are those of :func:`simulate`.

    The integrator state, the OU drive and the random streams are carried from block to block,
    so the run is the same for every ``block_cycles`` (bit for bit), and memory does not grow
    with the run.  The arguments are checked before the first block is made.

    Parameters
    ----------
    system, config, r_a, progress
        As :func:`simulate`.
    block_cycles : int
        Recorded gait cycles per block (≥ 1).

    Yields
    ------
    SimBlock
        The run's samples in order.

    Raises
    ------
    SudsConfigError
        ``block_cycles`` < 1, a pose delay longer than the simulated span, a system without a gait.
    SudsDataError
        ``r_a`` of the wrong shape.
    """
    if not (isinstance(block_cycles, (int, np.integer)) and block_cycles >= 1):
        raise SudsConfigError(f"`block_cycles`: expected a whole number ≥ 1, got {block_cycles!r}")
    dt = config.dt
    n = config.cycles * config.samples_per_cycle
    nw = int(round(config.warmup / dt))
    ss = np.random.SeedSequence(config.seed)
    rng_ou, rng_noise = (np.random.default_rng(s) for s in ss.spawn(2))
    drive: Drive
    if r_a is None:
        drive = OUDrive(system, config, rng_ou, -nw)
    else:
        r_a = np.asarray(r_a, dtype=float)
        if r_a.shape != (nw + n, len(system.actuated)):
            raise SudsDataError(f"`r_a`: expected shape {(nw + n, len(system.actuated))}, got {r_a.shape}")
        drive = ArrayDrive(r_a)
    ends = np.array([-nw, n - 1]) * dt
    if config.pose_delay > ends[1] - ends[0]:
        raise SudsConfigError(f"`pose_delay`: {config.pose_delay} s exceeds the simulated span")
    still, flow = _still(system)
    substeps = auto_substeps(still, dt) if config.substeps is None else config.substeps
    stops = block_stops(nw, n, block_cycles * config.samples_per_cycle)
    pieces = trajectory(still, drive, dt, stops, _rest_angles(system), substeps, progress)
    return _aligned_blocks(system, still, flow, config, pieces, rng_noise, nw, n)


def _aligned_blocks(system: SudsSystem, still: SudsSystem, flow: tuple[float, float], config: SimConfig,
                    pieces: Iterator[tuple[int, int, FloatArray, FloatArray, FloatArray]],
                    rng_noise: np.random.Generator, nw: int, n: int) -> Iterator[SimBlock]:
    """The blocks of :func:`simulate_blocks` from the integrated pieces (noise, delay, effort)."""
    dt, sd, delay, spc = config.dt, config.noise_std, config.pose_delay, config.samples_per_cycle
    nj = len(system.joint_names)
    noise_r, noise_pose = rng_noise, skip_normals(rng_noise, n * nj)  # r's noise first, then the pose's
    planar = getattr(system, "planar", True)
    window = DenseRun(still, flow)  # the run's joints and pose, read at the delayed pose stamps
    next_pose = 0  # the next pose sample to produce (a delayed pose waits for the integration)
    unwrap = YawUnwrap()
    prev: tuple[FloatArray, FloatArray] | None = None  # set-point and joints of the sample before
    for g0, g1, ra, R, P in pieces:
        t_gait = (np.arange(g0, g1) - nw) * dt
        P[:, 0] += flow[0] * t_gait  # uniform flow drifts the chain by U·t (t = 0 at the first sample)
        P[:, 1] += flow[1] * t_gait
        lo = max(g0, nw) - g0  # the piece's first recorded row
        i = np.arange(g0 + lo - nw, g1 - nw)  # recorded sample numbers
        if delay != 0.0:
            window.extend(t_gait, np.concatenate([R, P], axis=1))
        if i.size == 0:
            prev = (ra[-1], R[-1])
            continue
        tt = dt * i
        r_true = R[lo:]
        effort = _effort_by_cycle(still, ra, R, lo, prev, i[0], spc, dt)
        if delay == 0.0:
            pose_i, pose_true = i, P[lo:]
        else:
            x = dt * np.arange(next_pose, g1 - nw) - delay  # the pose stamped s is the true pose at s − delay
            if g1 - nw < n:
                x = x[x <= window.t[-1]]
            pose_i = np.arange(next_pose, next_pose + x.size)
            pose_true = window.interp(x, slice(nj, None))
            next_pose += x.size
            window.drop_before(dt * next_pose - delay)
        prev = (ra[-1], R[-1])
        r_meas = r_true + sd * noise_r.standard_normal(r_true.shape)
        pose_noise = sd * noise_pose.standard_normal(pose_true.shape)
        if not planar:  # motion along x only: y and yaw are not measured, stay 0
            pose_noise[:, 1:] = 0.0
        pose_meas = pose_true + pose_noise
        pose_meas[:, 2] = unwrap(pose_meas[:, 2])
        truth = {"r": r_true, "pose": pose_true, "phase": 2 * np.pi * config.gait_hz * tt, "effort": effort}
        yield SimBlock(t=config.t0 + tt, r=r_meas, pose_t=config.t0 + dt * pose_i, pose=pose_meas, truth=truth)


def _effort_by_cycle(still: SudsSystem, ra: FloatArray, R: FloatArray, lo: int,
                     prev: tuple[FloatArray, FloatArray] | None, i0: int, spc: int, dt: float) -> FloatArray:
    """Effort at the recorded rows ``lo:`` of a piece (sample numbers from ``i0``), one cycle per call.

    One call per gait cycle whatever the block size: batched BLAS may round a row differently
    in batches of other sizes, and blocks hold whole cycles.  ``prev``: set-point and joints of
    the sample before the piece (None before the first sample of a run without warm-up, whose
    first effort repeats the first period's).
    """
    out = []
    for a in range(lo, R.shape[0], spc):
        b = min(a + spc, R.shape[0])
        if a > 0:
            ra_c, r_c = ra[a - 1:b], R[a - 1:b]
        elif prev is not None:
            ra_c, r_c = np.concatenate([prev[0][None], ra[:b]]), np.concatenate([prev[1][None], R[:b]])
        else:
            ra_c, r_c = ra[:b], R[:b]
        eff = _effort_at_samples(still, ra_c, r_c, dt)
        if a == 0 and prev is None:
            eff = np.concatenate([eff[:1], eff], axis=0)
        out.append(eff)
    return np.concatenate(out, axis=0)


def _rest_angles(system: SudsSystem) -> FloatArray:
    model = getattr(system, "model", None)
    rest = getattr(model, "rest", None)
    if rest is None:
        rest_fn = getattr(system, "rest_state", None)
        if rest_fn is None:
            return np.zeros(len(system.passive))
        return np.asarray(rest_fn(), dtype=float)
    return np.asarray(rest, dtype=float)[list(system.passive)]


def effort_by_joint(system: SudsSystem, effort: FloatArray) -> FloatArray:
    """Actuator effort (…, na) spread over all joints (…, nj) in joint order, 0 on the passive ones."""
    effort = np.asarray(effort, dtype=float)
    out = np.zeros(effort.shape[:-1] + (len(system.joint_names),))
    out[..., list(system.actuated)] = effort
    return out


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
