"""A recording made ready for diagnosis: joints in model order, one uniform grid, halves, gait phase.

Shape and pose may come as separate streams with their own stamps (:mod:`.grid` brings them
onto one uniform grid at the nominal shape rate; aligned uniform recordings are used as they are).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import BoolArray, FloatArray, IntArray
from suds_ros.core.errors import TOO_LITTLE_DATA, WRONG_JOINT_NAMES, SudsConfigError, SudsDataError, SudsPhaseError
from suds_ros.core.midline import lost_runs
from suds_ros.core.resample import Grid, StreamSampling, gaps
from suds_ros.core.resample import xi_noise_gain as grid_xi_noise_gain
from suds_ros.core.phase.phaser import Phaser
from suds_ros.core.physics.rft import ChainModel
from suds_ros.core.recording import Recording, samples_per_cycle


@dataclass(frozen=True)
class Data:
    """A recording in the model's joint order, cut to whole gait cycles (first half trains).

    Samples [0, n_train) are the training half, [n_train, n_used) the held-out half.  ``t`` is a
    uniform grid (spacing ``dt``); ``pose_t``/``pose_raw`` are the recorded pose stream as received,
    timed where its values belong (:meth:`~suds_ros.core.resample.Grid.pose_stamps`: a pose stream
    sharing a stamped-late shape stream's stamps is timed at the shape samples' grid points).
    ``resampled``: the streams were brought onto the grid (:mod:`.grid`).
    """

    t: FloatArray  # (n,) stamps
    r: FloatArray  # (n, nj) in model joint order
    pose: FloatArray  # (n, 3) at the shape stamps
    pose_t: FloatArray
    pose_raw: FloatArray
    dt: float
    spc: int  # samples per cycle
    n_train: int
    n_used: int
    phase: FloatArray  # (n,) rad, unwrapped (phaser's convention, or the clock as a fallback)
    act: IntArray  # actuated joint columns of r
    pas: IntArray  # passive joint columns of r
    names: tuple[str, ...]
    phase_source: str = "phaser"
    phase_note: str = ""
    shape_gap: BoolArray | None = None  # (n,) shape unreliable: no sample within half a step (or next to such a point)
    # (the diagnosis widens it by the replay's memory of a gap; ``shape_lost`` keeps the unwidened mask,
    # the one a local (equation-error) residual needs)
    shape_lost: BoolArray | None = None
    # (k,) grid index of the first measured shape sample after each run of lost ones: the replay
    # restarts its passive joints from the recorded angles there (:func:`.replay.replay`)
    anchors: IntArray | None = None
    # noise power of the passive angles' replay residual over the measurement floor² where it is used
    # (the restarts after gaps leave their measurement error in the replay; set by the diagnosis)
    rp_noise_power: float = 1.0
    pose_gap: BoolArray | None = None  # (n,) the same for the pose stream
    resampled: bool = False  # the streams were brought onto a grid (not aligned and uniform)

    @functools.cached_property
    def pose_sampling(self) -> StreamSampling | None:
        """How the pose stream sees a signal on the grid (None: the pose is recorded on the grid itself)."""
        return StreamSampling(self.pose_t, self.t) if self.resampled else None


def prepare(rec: Recording, model: ChainModel) -> Data:
    """Check ``rec`` against ``model`` and lay it out for diagnosis (at least 4 whole gait cycles)."""
    names = model.joint_names
    if set(rec.joint_names) != set(names):
        raise SudsDataError(
            f"`rec`: joints {list(rec.joint_names)} do not match the joints {list(names)} of "
            f"`model` {model.name!r}",
            code=WRONG_JOINT_NAMES,
        )
    act = [names[i] for i in model.actuated]
    if set(rec.actuated) != set(act):
        raise SudsConfigError(
            f"`rec`: actuated joints {list(rec.actuated)} differ from the actuated joints {act} of "
            f"`model` {model.name!r}",
            code=WRONG_JOINT_NAMES,
        )
    order = [rec.joint_names.index(nm) for nm in names]
    f = rec.gait_hz or model.gait_hz or 1.0
    grid = Grid.of(rec)
    spc = samples_per_cycle(grid.dt, f)
    n_cycles = grid.t.size // spc  # whole cycles of the time the (uniform) grid spans
    if n_cycles < 4:
        raise SudsDataError(
            f"recording has {n_cycles} whole gait cycles at {f} Hz; diagnosis needs at least 4 "
            "(half to train, half held out)",
            code=TOO_LITTLE_DATA,
        )
    n_train = (n_cycles // 2) * spc
    n_used = n_cycles * spc
    t, dt = grid.t, grid.dt
    r = grid.shape(rec)[:, order]
    pose = grid.pose(rec)
    pose_t = grid.pose_stamps(rec)
    phase, source, note = gait_phase(r, t, f)
    lost = grid.unreliable(rec.t)
    anchors = None
    if grid.resampled:  # the first sample after each run of lost shape samples
        anchors = np.array([b + 1 for _, b in lost_runs(gaps(rec.t, t)) if b + 1 < t.size], dtype=np.intp)
    return Data(
        t=t,
        r=r,
        pose=pose,
        pose_t=pose_t,
        pose_raw=rec.pose,
        dt=dt,
        spc=spc,
        n_train=n_train,
        n_used=n_used,
        phase=phase,
        act=np.asarray(model.actuated, dtype=np.intp),
        pas=np.asarray(model.passive, dtype=np.intp),  # empty (0,) for a fully actuated chain
        names=names,
        phase_source=source,
        phase_note=note,
        shape_gap=lost,
        shape_lost=lost,
        anchors=anchors,
        pose_gap=grid.unreliable(pose_t),
        resampled=grid.resampled,
    )


def xi_noise_gain(data: Data, w: int) -> float:
    """Gain of the windowed body velocity's noise floor over ``w`` samples (√2 on aligned streams).

    See :func:`~suds_ros.core.resample.xi_noise_gain`.
    """
    if not data.resampled:
        return float(np.sqrt(2.0))
    lo, hi = data.t[0], data.t[data.n_used - 1]
    sel = (data.pose_t >= lo - data.dt) & (data.pose_t <= hi + data.dt)
    skip = None if data.pose_gap is None else data.pose_gap[: data.n_used]
    return grid_xi_noise_gain(data.pose_t[sel], data.t[: data.n_used], w, skip=skip)


def gait_phase(r: FloatArray, t: FloatArray, gait_hz: float) -> tuple[FloatArray, str, str]:
    """Unwrapped gait phase (rad) of every sample from the recorded shape data alone.

    The phaser (:class:`~suds_ros.core.phase.phaser.Phaser`) is fitted on the recording's joint angles
    (all joints; the simulator replay shares the recorded r_a, so the same phase serves both).
    Its zero is the upward mean crossing of the first principal component of the shape.  When the
    phaser fails (fewer than 3 detectable cycles, degenerate data) the clock phase
    2π·gait_hz·(t − t0) is used instead and the returned note says so.
    """
    try:
        ph = np.asarray(Phaser().fit_transform(r), dtype=float)
        if ph.shape != t.shape or not np.all(np.isfinite(ph)):
            raise SudsPhaseError("phaser returned a non-finite phase")
        return ph, "phaser", ""
    except (SudsPhaseError, SudsDataError, np.linalg.LinAlgError, ValueError) as exc:
        note = (
            f"phaser failed ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); "
            f"phase ranges use the clock phase 2π·{gait_hz:g} Hz·(t − t0) instead"
        )
        return 2 * np.pi * gait_hz * (t - t[0]), "clock", note
