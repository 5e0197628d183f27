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
trajectory at their own jittered stamps (cubic Hermite interpolation with the physics' own
rates at the grid points, 2.5 ms apart at 100 Hz: :class:`~suds_ros.core.physics.sim.DenseRun`),
then measurement noise is added and messages dropped.
:func:`simulate_lab_blocks` does all of this a few cycles at a time, with the same result.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.physics.sim import (
    BLOCK_CYCLES,
    DenseRun,
    OUDrive,
    SimBlock,
    SimConfig,
    Window,
    YawUnwrap,
    _rest_angles,
    _still,
    auto_substeps,
    block_stops,
    recording_from_blocks,
    skip_normals,
    trajectory,
)
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
    stamping : str
        How the shape stream's stamps relate to its values.  ``"read"``: each value is read
        at its stamp (the recording contract's meaning, and a host that reads the joints at
        irregular times).  ``"arrival"``: each value is sampled at its nominal grid point (a
        device on its own regular clock) and the stamp is that tick plus the jitter: a host
        stamping messages as they arrive (a serial encoder, a USB servo bus), which
        :func:`~suds_ros.core.resample.values_on_grid` recognises.
    latency : float
        Added to every shape stamp, s (≥ 0): with ``"arrival"`` the transport's mean delay,
        which the shape stream alone cannot reveal (only against the pose stream).
    """

    pose_hz: float | None = 120.0
    pose_phase: float = 0.0037
    jitter: float = 0.0004
    drop: float = 0.01
    oversample: int = 4
    stamping: str = "read"
    latency: float = 0.0

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
        if self.stamping not in STAMPINGS:
            raise SudsConfigError(f"`stamping`: expected one of {list(STAMPINGS)}, got {self.stamping!r}")
        if not 0 <= self.latency < 1.0:
            raise SudsConfigError(f"`latency`: expected 0 ≤ latency < 1 s, got {self.latency!r}")


#: :attr:`LabConditions.stamping` values
STAMPINGS = ("read", "arrival")


#: stamps (and drop decisions) drawn per call
_CHUNK = 4096


def _stamp_chunks(rng: np.random.Generator, start: float, period: float, end: float, jitter: float,
                  chunk: int = _CHUNK) -> Iterator[FloatArray]:
    """Nominal grid start + i·period up to ``end`` with clipped Gaussian jitter, ``chunk`` stamps at a time."""
    n = int(np.floor((end - start) / period)) + 1
    for a in range(0, n, chunk):
        nominal = start + period * np.arange(a, min(n, a + chunk))
        yield nominal + np.clip(jitter * rng.standard_normal(nominal.size), -0.4 * period, 0.4 * period)


def _kept(rng: np.random.Generator, pos: int, m: int, n: int, drop: float) -> np.ndarray:
    """Which of the stream's messages pos … pos + m − 1 (of n) arrive; the first and the last always do."""
    keep = rng.random(m) >= drop
    idx = pos + np.arange(m)
    keep[(idx == 0) | (idx == n - 1)] = True
    return keep


@dataclass
class _Stream:
    """One stream's stamps in order, a chunk at a time: jitter, the span it must lie in, drops."""

    chunks: Iterator[FloatArray]
    keep_rng: np.random.Generator
    inside: Callable[[FloatArray], np.ndarray]
    n_inside: int
    drop: float
    pos: int = 0
    pending: FloatArray = field(default_factory=lambda: np.empty(0))
    done: bool = False

    def fill(self, last: float, lag: float) -> None:
        """Draw stamps until one (less ``lag``) is past ``last`` or the stream ends."""
        while not self.done and (self.pending.size == 0 or self.pending[-1] - lag <= last):
            t = next(self.chunks, None)
            if t is None:
                self.done = True
                break
            t = t[self.inside(t)]
            keep = _kept(self.keep_rng, self.pos, t.size, self.n_inside, self.drop)
            self.pos += t.size
            self.pending = np.concatenate([self.pending, t[keep]])

    def take(self, last: float | None, lag: float) -> FloatArray:
        """The pending stamps s with s − ``lag`` ≤ ``last`` (all of them for None)."""
        k = self.pending.size if last is None else int(np.count_nonzero(self.pending - lag <= last))
        out, self.pending = self.pending[:k], self.pending[k:]
        return out

    def next_needed(self, lag: float) -> float:
        """The earliest time (less ``lag``) still to be read; inf when the stream is through."""
        return float(self.pending[0] - lag) if self.pending.size else np.inf


class _FineDrive:
    """The coarse drive linearly interpolated onto a grid ``f`` times finer, handed out in order."""

    def __init__(self, coarse: OUDrive, f: int, k0: int) -> None:
        self._coarse, self._f = coarse, f
        self._j = k0 * f  # next fine index
        self._k = k0  # next coarse index to take
        self._window = Window(coarse.dim)

    def take(self, m: int) -> FloatArray:
        """The next ``m`` fine set-points, shape (m, na)."""
        kf = np.arange(self._j, self._j + m) / self._f
        self._j += m
        need = int(np.ceil(kf[-1])) + 1
        if need > self._k:
            self._window.extend(np.arange(self._k, need).astype(float), self._coarse.take(need - self._k))
            self._k = need
        out = self._window.interp(kf)
        self._window.drop_before(float(kf[-1]))
        return out


def simulate_lab(system: SudsSystem, config: SimConfig = SimConfig(), lab: LabConditions = LabConditions(),
                 *, block_cycles: int = BLOCK_CYCLES) -> Recording:
    """Simulate a run recorded under lab conditions (see the module docstring).

    ``config`` is the aligned twin's: its ``cycles``, ``samples_per_cycle`` and ``gait_hz`` fix the
    nominal shape grid, ``seed`` the drive (identical to the twin's) and the noise, ``pose_delay``
    a sensor time offset of the pose stream (any value, not only multiples of the period).
    The concatenation of :func:`simulate_lab_blocks`; the same for every ``block_cycles``.

    Returns
    -------
    Recording
        Shape and pose at their own stamps.  ``truth`` holds ``"r"`` (n, nj) and ``"pose"`` (n, 3),
        noise free at the shape stamps, and ``"phase"`` (n,), the reference gait phase there.
    """
    return recording_from_blocks(system, config.gait_hz,
                                 simulate_lab_blocks(system, config, lab, block_cycles=block_cycles))


def simulate_lab_blocks(system: SudsSystem, config: SimConfig = SimConfig(),
                        lab: LabConditions = LabConditions(), *, block_cycles: int = BLOCK_CYCLES,
                        progress: Callable[[int, int], None] | None = None) -> Iterator[SimBlock]:
    """:func:`simulate_lab` ``block_cycles`` cycles at a time, memory independent of the run's length.

    The dense run is integrated a block at a time (:func:`~suds_ros.core.physics.sim.trajectory`),
    the stamps of each stream are drawn in chunks from the streams' random generators, each
    positioned where the whole-run draws would reach it, and each stamp is read off the dense
    rows around it: the blocks are exactly the samples of the whole-run recording.  Checked
    before the first block is made.

    Yields
    ------
    SimBlock
        Shape and pose samples in stamp order; ``truth``: ``"r"``, ``"pose"`` and ``"phase"`` at
        the shape stamps.

    Raises
    ------
    SudsConfigError
        ``block_cycles`` < 1, |``pose_delay``| ≥ half the span, a system without a gait.
    """
    if not (isinstance(block_cycles, (int, np.integer)) and block_cycles >= 1):
        raise SudsConfigError(f"`block_cycles`: expected a whole number ≥ 1, got {block_cycles!r}")
    dt = config.dt
    f = lab.oversample
    n = config.cycles * config.samples_per_cycle + 1  # one set-point past the end covers late stamps
    nw = int(round(config.warmup / dt))
    ss = np.random.SeedSequence(config.seed)
    rng_ou, rng_noise = (np.random.default_rng(s) for s in ss.spawn(2))
    # the same run on a grid f times finer: nw·f warm-up points, then (n − 1)·f recorded points
    fine = replace(config, samples_per_cycle=config.samples_per_cycle * f, noise_std=0.0, pose_delay=0.0,
                   warmup=nw * dt)
    dt_f = fine.dt
    n_f = fine.cycles * fine.samples_per_cycle
    nw_f = int(round(fine.warmup / dt_f))
    if nw_f + n_f != (nw + n - 1) * f:
        raise SudsDataError(f"`r_a`: expected shape {(nw_f + n_f, len(system.actuated))}, "
                            f"got {((nw + n - 1) * f, len(system.actuated))}")
    drive = _FineDrive(OUDrive(system, config, rng_ou, -nw), f, -nw)
    ends = config.t0 + dt_f * np.array([0, n_f - 1])
    span = float(ends[1] - ends[0])  # the fine grid's last stamp, 0 at the first recorded sample
    if abs(config.pose_delay) > 0.5 * span:
        raise SudsConfigError(f"`pose_delay`: expected |delay| < {0.5 * span:g} s, got {config.pose_delay!r}")
    still, flow = _still(system)
    substeps = auto_substeps(still, dt_f) if fine.substeps is None else fine.substeps
    stops = block_stops(nw_f, n_f, block_cycles * fine.samples_per_cycle)
    pieces = trajectory(still, drive, dt_f, stops, _rest_angles(system), substeps, progress)
    return _lab_blocks(system, still, config, lab, pieces, flow, rng_noise, span, nw_f, n_f, dt_f)


def _lab_blocks(system: SudsSystem, still: SudsSystem, config: SimConfig, lab: LabConditions,
                pieces: Iterator[tuple[int, int, FloatArray, FloatArray, FloatArray]], flow: tuple[float, float],
                rng_noise: np.random.Generator, span: float, nw_f: int, n_f: int, dt_f: float
                ) -> Iterator[SimBlock]:
    """The blocks of :func:`simulate_lab_blocks` from the dense pieces: stamps, reading, noise."""
    dt, delay, sd = config.dt, config.pose_delay, config.noise_std
    nj = len(system.joint_names)
    # the stream generator's draws, in the whole-run order: shape jitter, pose jitter, shape drops,
    # pose drops; one generator copy placed at the start of each, found by counting in a pre-pass
    rng = np.random.default_rng(rng_noise.integers(2**63))
    pose_period = dt if lab.pose_hz is None else 1.0 / lab.pose_hz
    shape_grid = (0.0, dt, span - 0.5 * dt, lab.jitter)
    pose_grid = (lab.pose_phase, pose_period, span - 0.5 * pose_period, lab.jitter)

    arrival = lab.stamping == "arrival"
    ahead = 0.4 * dt if arrival else 0.0  # a stamp's tick lies within this of it (the jitter's clip)

    def tick(t: FloatArray) -> FloatArray:  # the time a shape value belongs to
        return dt * np.round(t / dt) if arrival else t

    def shape_inside(t: FloatArray) -> np.ndarray:
        return (tick(t) >= 0) & (tick(t) <= span)

    def pose_inside(t: FloatArray) -> np.ndarray:
        late = t - delay  # the pose stamped s is the true pose at s − delay
        return (t >= 0) & (t <= span) & (late >= 0) & (late <= span)

    shape_jitter = copy.deepcopy(rng)
    n_shape = sum(int(np.count_nonzero(shape_inside(t))) for t in _stamp_chunks(rng, *shape_grid))
    pose_jitter = copy.deepcopy(rng)
    n_pose = sum(int(np.count_nonzero(pose_inside(t))) for t in _stamp_chunks(rng, *pose_grid))
    shape_keep = copy.deepcopy(rng)
    n_kept = sum(int(np.count_nonzero(_kept(rng, a, min(_CHUNK, n_shape - a), n_shape, lab.drop)))
                 for a in range(0, n_shape, _CHUNK))
    shapes = _Stream(_stamp_chunks(shape_jitter, *shape_grid), shape_keep, shape_inside, n_shape, lab.drop)
    poses = _Stream(_stamp_chunks(pose_jitter, *pose_grid), rng, pose_inside, n_pose, lab.drop)
    noise_r, noise_pose = rng_noise, skip_normals(rng_noise, n_kept * nj)  # r's noise first, then the pose's
    planar = getattr(system, "planar", True)
    window = DenseRun(still, flow)  # the dense run's joints and pose
    unwrap = YawUnwrap()
    for g0, g1, _, R, P in pieces:
        t_gait = (np.arange(g0, g1) - nw_f) * dt_f
        P[:, 0] += flow[0] * t_gait
        P[:, 1] += flow[1] * t_gait
        if g1 <= nw_f:
            continue  # warm-up only
        lo = max(g0, nw_f) - g0
        tf = (config.t0 + dt_f * np.arange(g0 + lo - nw_f, g1 - nw_f)) - config.t0
        window.extend(tf, np.concatenate([R[lo:], P[lo:]], axis=1))
        last = None if g1 - nw_f == n_f else float(window.t[-1])
        shapes.fill(np.inf if last is None else last, -ahead)
        poses.fill(np.inf if last is None else last, delay)
        ts, tp = shapes.take(last, -ahead), poses.take(last, delay)
        at_shape = window.interp(tick(ts))
        pose_true = window.interp(tp - delay, slice(nj, None))
        window.drop_before(min(shapes.next_needed(ahead), poses.next_needed(delay)))
        r_true = at_shape[:, :nj]
        r_meas = r_true + sd * noise_r.standard_normal(r_true.shape)
        pose_noise = sd * noise_pose.standard_normal(pose_true.shape)
        if not planar:
            pose_noise[:, 1:] = 0.0
        pose_meas = pose_true + pose_noise
        pose_meas[:, 2] = unwrap(pose_meas[:, 2])
        truth = {"r": r_true, "pose": at_shape[:, nj:], "phase": 2 * np.pi * config.gait_hz * tick(ts)}
        yield SimBlock(t=config.t0 + ts + lab.latency, r=r_meas, pose_t=config.t0 + tp, pose=pose_meas, truth=truth)
