"""Streaming SUDS identification: the algorithm behind the live estimator.

Samples arrive one at a time on two streams (shape and body pose).  The
estimator, one job per module:

1. checks each sample once and pairs shape with pose by stamps
   (:mod:`~suds_ros.core.ident.pairing`);
2. buffers the first ``init_cycles`` gait cycles, then runs the batch phaser on
   them for the phase, the nominal gait θ(φ) and the mean phase rate ω̄, all
   frozen from then on (:mod:`~suds_ros.core.ident.phase_init`);
3. tracks the phase of each new sample with :class:`PhaseTracker`;
4. turns each block of ``chunk`` shape intervals into rows, vectorised
   (:mod:`~suds_ros.core.ident.featurise`): interval rows for the passive
   velocities and one averaged row per pose interval for the body velocity, as
   in the batch identifier;
5. scores each chunk *before* learning from it (prequential evaluation), giving
   a running Γ on data the model has not seen, then adds it to every candidate
   regression (:mod:`~suds_ros.core.ident.prequential`).

Per sample the work is O(1): checks, pairing, one phase-tracker step and a list
append; the rows of a chunk are built and fitted together.  :func:`fit_streaming`
feeds a whole recording through the same path; the regression's sufficient
statistics are additive, so any chunking gives the same fit to round-off.
Checkpoints are written and read by :mod:`suds_ros.io.checkpoint` (data only);
samples at or before the last processed stamp count as already seen.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
import scipy.sparse

from suds_ros.core._typing import FloatArray
from suds_ros.core.config import check_settings, setting
from suds_ros.core.errors import TOO_LITTLE_DATA, SudsConfigError, SudsDataError
from suds_ros.core.estimator import is_fitted
from suds_ros.core.fourier import NormalEquations, fourier_basis
from suds_ros.core.resample import BRIDGED_RUN, LiveGrid
from suds_ros.core.ident.featurise import Rows, StreamFeaturiser
from suds_ros.core.ident.model import SudsModel, check_shape_sample, check_stamp
from suds_ros.core.ident.pairing import FRAME_PROBE, FRAME_PROBE_MAX, FrameJoiner, StampPairer, check_pose_sample
from suds_ros.core.ident.phase_init import GaitInitialiser, GaitStart
from suds_ros.core.ident.prequential import PrequentialSelector
from suds_ros.core.ident.scoring import BODY_CHANNELS
from suds_ros.core.ident.shape_kernel import gait_kernel_scale
from suds_ros.core.ident.sysid import AveragedTargets, SudsConfig, SudsRegressor
from suds_ros.core.phase.phase_tracker import PhaseTracker
from suds_ros.core.phase.template import FourierTemplate
from suds_ros.core.recording import Recording, stream_period
#: relative ridge of the phase-only output template's normal equations
_OUTPUT_TEMPLATE_RIDGE = 1e-9
#: fewest interval rows in a chunk (a chunk is at most one gait cycle of rows, see ``OnlineConfig.chunk``)
MIN_CHUNK = 10


@dataclass(frozen=True)
class OnlineConfig:
    """Settings of the streaming estimator.

    Parameters
    ----------
    suds : SudsConfig
        Regression hyperparameters of the first candidate model (current at the start).
    alternatives : tuple of SudsConfig
        Further candidates fitted side by side; the one published is the candidate with the
        lowest discounted prequential loss (:mod:`~suds_ros.core.ident.prequential`).  With
        ``suds`` (set 2) the defaults are three: set 3 with a smaller ridge, which wins once
        some 15–20 cycles support it (``docs/results/peers.md``), and a small model (set 1,
        gains of Fourier order 1, no products; the batch identifier's cross-validated choice on
        the tracked animals of ``docs/results/organisms.md``) for thin data.  Video of an animal
        at 25 fps with frames lost has some 10–20 rows a cycle against set 2's hundreds of
        parameters per output: on the real tracked worm (7 joints, 9 training cycles) the
        published model's held-out Γ body was 0.34 with the pair, 0.84 with the small model
        beside it (batch: 0.83).  At 100 Hz it wins the first few cycles of purcell3 (lab
        recording, 10 cycles: Γ body / passive 0.81 / 0.90 against the pair's 0.83 / 0.96; the
        same model from 20 on) and none of swimmer9's.
    selection_memory : float
        Chunks after which a chunk's prequential loss counts half in that choice (5: a candidate
        that starts badly can take over within a few cycles once it fits better).
    init_cycles : float
        Gait cycles buffered before the batch phaser initialises phase and template.
    gait_hz : float
        Nominal gait frequency, Hz, used only to count the initial cycles.
    template_order : int
        Fourier order of θ(φ) and of the phase-only output template.
    phaser_order : int
        Fourier order of the phaser's correction.
    chunk : int
        Interval rows per ``partial_fit`` call, and per prequential score: at most this many, and
        at most one gait cycle's (rows a cycle at ``gait_hz`` and the stream's period; at least
        :data:`MIN_CHUNK`).  A 50 fps fish at 5 Hz gives some 10 rows a cycle: 12 training
        cycles made one chunk of 100 rows and a 5-row flush, on which the candidates were chosen.
    max_pose_wait : float
        Stamp seconds a shape sample may wait for a pose covering its stamp while later shape
        samples arrive, before it is dropped (``dropped_no_pose``): longer than the lag of a
        history catch-up after a restart or of a pose stream that stalls and resumes.
    """

    suds: SudsConfig = setting(default_factory=lambda: SudsConfig(linear_order=6, bilinear_order=3),
                               description="regression hyperparameters of the first candidate model")
    alternatives: tuple[SudsConfig, ...] = setting(
        (SudsConfig(regressors=3, linear_order=6, bilinear_order=3, ridge=1e-7),
         SudsConfig(regressors=1, linear_order=1, bilinear_order=0)),
        "further candidate models fitted side by side")
    selection_memory: float = setting(5.0, "chunks after which a chunk's prequential loss counts half",
                                      gt=0.0, le=1e6)
    init_cycles: float = setting(5.0, "gait cycles buffered before the phase is initialised (the phaser "
                                      "needs ≥ 3)", ge=3.0, le=1000.0)
    gait_hz: float = setting(1.0, "nominal gait frequency, Hz (counts the initial cycles)", gt=0.0, le=1000.0)
    template_order: int = setting(8, "Fourier order of the gait template θ(φ)", ge=1, le=64)
    phaser_order: int = setting(10, "Fourier order of the phaser correction", ge=1, le=64)
    chunk: int = setting(100, "most interval rows per regression update and prequential score (and at most one "
                              "gait cycle's)", ge=1, le=1_000_000)
    max_pose_wait: float = setting(60.0, "stamp s a shape sample may wait for a covering pose while later "
                                         "shape samples arrive, before it is dropped", gt=0.0, le=3600.0)
    regrid: bool = setting(True, "bring a shape stream with stamp jitter onto its fitted uniform grid before "
                                 "pairing (a uniform stream passes unchanged and without delay)")

    def __post_init__(self) -> None:
        check_settings(self)

    @property
    def candidates(self) -> tuple[SudsConfig, ...]:
        """Every candidate configuration, ``suds`` first."""
        return (self.suds,) + tuple(self.alternatives)


def _mean_sq(e: FloatArray) -> FloatArray:
    """Mean square of each column (NaN for no rows)."""
    return (e**2).sum(axis=0) / e.shape[0] if e.shape[0] else np.full(e.shape[1], np.nan)


class OnlineSudsEstimator:
    """Streaming phase tracking and incremental SUDS regression (see module docstring).

    Parameters
    ----------
    joint_names : sequence of str
        Expected joint names in message order.
    actuated : sequence of str
        Actuated joints; the others are passive.
    config : OnlineConfig

    Attributes
    ----------
    init_cycles_ : float
        Gait cycles the initialisation buffer must span; starts at ``config.init_cycles``
        and grows by one each time the phaser finds the buffer too short.
    template_ : FourierTemplate
        Gait template θ(φ) fitted on the initial cycles; set at initialisation (absent before,
        as scikit-learn's learned attributes are before ``fit``).
    omega_ : float
        Mean phase rate ω̄ of the initial cycles, rad/s; set at initialisation.
    regressor : SudsRegressor
        The incremental SUDS regression published now.
    frames : FrameJoiner or None
        With ``regrid``, when the pose stream shares the shape stream's stamps (one frame, one stamp:
        decided on the first stamps, :meth:`_decide_frames`): each frame's shape and pose go through
        the grid stage together, so a stamp it takes to its tick takes both, as the batch
        identifier does (:meth:`~suds_ros.core.resample.Grid.pose_stamps`).  None otherwise.
    """

    def __init__(
        self, joint_names: tuple[str, ...], actuated: tuple[str, ...], config: OnlineConfig = OnlineConfig()
    ) -> None:
        self.config = config
        self.joint_names = tuple(joint_names)
        unknown = [j for j in actuated if j not in self.joint_names]
        if unknown:
            raise SudsConfigError(f"`actuated`: {unknown} are not among the joints {list(self.joint_names)}")
        self.actuated = tuple(actuated)
        self.passive = tuple(j for j in self.joint_names if j not in self.actuated)
        self._act = np.array([self.joint_names.index(j) for j in self.actuated], dtype=int)
        self._pas = np.array([self.joint_names.index(j) for j in self.passive], dtype=int)
        self.channels = tuple(BODY_CHANNELS) + tuple(f"rdot_{j}" for j in self.passive)
        self.pairer = StampPairer(config.max_pose_wait)
        self.regrid: LiveGrid | None = LiveGrid() if config.regrid else None
        # with the grid stage: the first samples of both streams, held (in arrival order) until their
        # stamps say whether the two are one frame's (then joined, and the pose goes through the stage
        # with the shape: a stamp taken to its tick takes both); None once that is decided
        self._probe: list[tuple[str, float, object]] | None = [] if config.regrid else None
        self.frames: FrameJoiner | None = None  # the joiner, when the streams share their stamps
        self._last_shape = -np.inf  # newest shape / pose stamps accepted (as given)
        self._last_pose = -np.inf
        self.initialiser: GaitInitialiser | None = GaitInitialiser(
            config.init_cycles, config.gait_hz, config.template_order, config.phaser_order)
        self._early_poses: list[tuple[float, tuple[float, float, float]]] = []  # poses before the start
        self._init_cycles = float(config.init_cycles)
        self._phase0 = float("nan")
        self._tracker: PhaseTracker | None = None
        self._rows: StreamFeaturiser | None = None
        self._chunk = int(config.chunk)  # set from the gait cycle at the start
        self.selector = self._selector(None)
        nb = len(BODY_CHANNELS)
        self._out_normal = NormalEquations(2 * config.template_order + 1, len(self.channels) - nb)
        self._out_normal_body = NormalEquations(2 * config.template_order + 1, nb)
        self._measured: deque[tuple[float, FloatArray]] = deque(maxlen=self.MEASURED_KEPT)
        # bookkeeping
        self.phase = float("nan")
        self.n_shape = 0
        self.n_pose = 0
        self.n_rows = 0
        self.sum_err_model = np.zeros(len(self.channels))
        self.sum_err_template = np.zeros(len(self.channels))
        self.last_residual = np.full(len(self.channels), np.nan)

    def _selector(self, scale: object) -> PrequentialSelector:
        na = len(self.actuated)
        regs = [SudsRegressor(c, n_actuated=na, kernel_scale=scale)  # type: ignore[arg-type]
                for c in self.config.candidates]
        return PrequentialSelector(regs, self.config.selection_memory)

    @property
    def regressor(self) -> SudsRegressor:
        """The candidate regression published now (the lowest prequential loss)."""
        return self.selector.current

    @property
    def initialised(self) -> bool:
        """True once phase, template and rate are fixed."""
        return self.initialiser is None

    @property
    def init_cycles_(self) -> float:
        """Gait cycles the initialisation needed (or needs now)."""
        return self._init_cycles if self.initialiser is None else self.initialiser.init_cycles_

    @property
    def last_shape_stamp(self) -> float:
        """Newest shape stamp accepted, s (as given: before any regridding)."""
        return self.pairer.last_shape_stamp if self.regrid is None else self._last_shape

    @property
    def held(self) -> int:
        """Shape samples held by the regridding stage (released a few grid points late, or by :meth:`drain`).

        With it, also the first samples while the streams' stamps are compared (frames waiting for
        their pose count in :attr:`waiting_for_pose`).
        """
        if self.regrid is None:
            return 0
        probe = sum(kind == "shape" for kind, _, _ in self._probe) if self._probe is not None else 0
        return self.regrid.held + probe

    @property
    def last_pose_stamp(self) -> float:
        """Newest pose stamp accepted, s (as given)."""
        return self.pairer.last_pose_stamp if self.regrid is None else self._last_pose

    @property
    def dropped_no_pose(self) -> int:
        """Shape samples dropped for want of a covering pose."""
        return self.pairer.dropped_no_pose + (self.frames.dropped_shapes if self.frames is not None else 0)

    @property
    def waiting_for_pose(self) -> int:
        """Shape samples waiting for a covering pose."""
        return self.pairer.waiting + (self.frames.waiting if self.frames is not None else 0)

    # ------------------------------------------------------------------ input
    def add_pose(self, t: float, x: float, y: float, yaw: float) -> int:
        """Add a pose sample; returns the number of shape samples it released.

        Raises
        ------
        SudsDataError
            NaN values, or a stamp not after the previous pose stamp.
        """
        t, x, y, yaw = float(t), float(x), float(y), float(yaw)
        if self.regrid is None:
            self._to_pairer(t, x, y, yaw)
            self.n_pose += 1
            return self._release()
        check_pose_sample(t, x, y, yaw, self._last_pose)
        self._last_pose = t
        self.n_pose += 1
        if self._probe is not None:
            self._probe.append(("pose", t, (x, y, yaw)))
            return self._decide_frames()
        self._route("pose", t, (x, y, yaw))
        return self._released()

    def _to_pairer(self, t: float, x: float, y: float, yaw: float) -> None:
        """A pose (at the time it belongs to) to the pairer and the body-velocity rows."""
        self.pairer.add_pose(t, x, y, yaw)
        pose = self.pairer.last_pose
        if self._rows is None:
            self._early_poses.append((t, pose))
        else:
            self._rows.add_pose(t, pose)

    def add_shape(self, t: float, names: tuple[str, ...], position: FloatArray) -> int:
        """Add a shape sample; returns the number of shape samples released for processing.

        Raises
        ------
        SudsDataError
            Wrong joint names/count, NaN, duplicate or out-of-order stamp.
        """
        r = check_shape_sample(t, names, position, self.joint_names)
        if self.regrid is None:
            self.pairer.add_shape(float(t), r)
            self.n_shape += 1
            return self._release()
        t = float(t)
        check_stamp("shape", t, self._last_shape)
        self._last_shape = t
        self.n_shape += 1
        if self._probe is not None:
            self._probe.append(("shape", t, r))
            return self._decide_frames()
        self._route("shape", t, r)
        return self._released()

    def _route(self, kind: str, t: float, value: object) -> None:
        """A checked sample past the frame probe: to the frame joiner when joined, else on its own way.

        A pose (x, y, yaw) goes to the pairer; a shape sample through the grid stage to the pairer.
        """
        if kind == "pose":
            if self.frames is not None:
                self.frames.add_pose(t, *value)  # type: ignore[misc]
            else:
                self._to_pairer(t, *value)  # type: ignore[misc]
        elif self.frames is not None:
            self.frames.add_shape(t, value)  # type: ignore[arg-type]
        else:
            self._pair_shapes(*self.regrid.add(t, value))  # type: ignore[union-attr, arg-type]

    def _released(self) -> int:
        """Samples released now: the joined frames through the grid stage, or the pairer's pairs."""
        return self._push_frames() if self.frames is not None else self._release()

    def _decide_frames(self, final: bool = False) -> int:
        """Whether the two streams are one frame's, joined or apart; returns the samples released.

        Joined once :data:`FRAME_PROBE` stamps matched; apart at once when a stamp of one stream is
        passed by the other without a match.  Apart too when one stream has given
        :data:`FRAME_PROBE_MAX` samples first, and at a ``final`` drain.  The held samples then go
        on, in their order.
        """
        probe = self._probe
        assert probe is not None
        shapes = [t for kind, t, _ in probe if kind == "shape"]
        poses = [t for kind, t, _ in probe if kind == "pose"]
        both = set(shapes) & set(poses)
        apart = bool(shapes and poses) and (any(t < shapes[-1] and t not in both for t in poses)
                                            or any(t < poses[-1] and t not in both for t in shapes))
        joined = not apart and len(both) >= FRAME_PROBE
        if not (apart or joined or final or max(len(shapes), len(poses)) >= FRAME_PROBE_MAX):
            return 0
        self._probe = None
        if joined:
            self.frames = FrameJoiner(self.config.max_pose_wait)
        for kind, t, v in probe:
            self._route(kind, t, v)
        return self._released()

    def _push_frames(self) -> int:
        """The joined frames complete now through the grid stage (pose values beside the joints), then paired."""
        assert self.frames is not None and self.regrid is not None
        for t, r, pose in self.frames.frames():
            self._pair_frames(*self.regrid.add(t, np.concatenate([r, pose])))
        return self._release()

    def _pair_frames(self, ts: list[float], vs: list[FloatArray]) -> None:
        """Frames the grid stage released, at its times: the pose first, then the shape it covers exactly."""
        nj = len(self.joint_names)
        for tg, v in zip(ts, vs):  # (the yaw is continuous already: the joiner unwrapped it)
            self._to_pairer(tg, float(v[nj]), float(v[nj + 1]), float(v[nj + 2]))
            self.pairer.add_shape(tg, v[:nj])

    def drain(self) -> int:
        """Release the shape samples the regridding stage holds (the stream ended or paused); returns how many."""
        if self.regrid is None:
            return 0
        n = self._decide_frames(final=True) if self._probe is not None else 0
        ts, rs = self.regrid.drain()
        if self.frames is not None:
            self._pair_frames(ts, rs)
        else:
            self._pair_shapes(ts, rs)
        return n + (self._release() if ts else 0)

    def _pair_shapes(self, ts: list[float], rs: list[FloatArray]) -> None:
        """The samples the regridding released, to the pairer."""
        for tg, rg in zip(ts, rs):
            self.pairer.add_shape(tg, rg)

    def already_seen(self, t: float) -> bool:
        """True for a shape stamp at or before the last one accepted (e.g. replayed after a restart)."""
        return t <= self.last_shape_stamp

    def _release(self) -> int:
        ts, rs, ps = self.pairer.release()
        for t, r, pose in zip(ts, rs, ps):
            self._process(t, r, pose)
        return len(ts)

    # ------------------------------------------------------------- processing
    def _process(self, t: float, r: FloatArray, pose: FloatArray) -> None:
        if self.initialiser is not None:
            start = self.initialiser.add(t, r, pose)
            if start is not None:
                self._start(start)
            return
        phase = self._tracker.update(t, r)  # type: ignore[union-attr]
        self._add(t, r, pose, phase)

    def _start(self, s: GaitStart) -> None:
        """Fix phase, template and rate; featurise the buffered samples."""
        self._init_cycles = self.initialiser.init_cycles_  # type: ignore[union-attr]
        self.initialiser = None
        self.template_: FourierTemplate = s.template
        self.omega_: float = s.omega
        self.selector = self._selector(gait_kernel_scale(s.template, s.omega, self._act))
        self._tracker = PhaseTracker(s.template, s.omega, float(s.phase[-1]), float(s.t[-1]))
        self._phase0 = float(s.phase[0])
        # a shape interval over a run of BRIDGED_RUN or more lost samples is not measured
        period = stream_period(s.t)
        # a chunk is at most one nominal gait cycle of rows, so the candidates are compared cycle by cycle
        per_cycle = int(round(1.0 / (self.config.gait_hz * period)))
        self._chunk = max(MIN_CHUNK, min(self.config.chunk, per_cycle))
        self._rows = StreamFeaturiser(self.config.suds, s.template, s.omega, self._act, self._pas,
                                      max_interval=(BRIDGED_RUN + 0.5) * period)
        for tp, pose in self._early_poses:
            self._rows.add_pose(tp, pose)
        self._early_poses = []
        for k in range(s.t.size):
            self._add(float(s.t[k]), s.r[k], s.pose[k], float(s.phase[k]))

    def _add(self, t: float, r: FloatArray, pose: FloatArray, phase: float) -> None:
        self.phase = phase
        self._rows.add(t, r, pose, phase)  # type: ignore[union-attr]
        if self._rows.pending >= self._chunk:  # type: ignore[union-attr]
            self.flush()

    def flush(self) -> None:
        """Turn the pending samples into rows and fit them (the node calls this before publishing)."""
        if self._rows is None or not self._rows.pending:
            return
        rows = self._rows.rows()
        self._measured.extend(zip(rows.t.tolist(), rows.Y))
        nb = len(BODY_CHANNELS)
        X, Y = rows.X, rows.Y[:, nb:]
        avg = self._averaged(rows)
        order = self.config.template_order
        Bt = fourier_basis(X[:, 0], order)
        Bb = np.asarray(avg.weights @ fourier_basis(avg.X[:, 0], order))  # type: ignore[operator]
        # scored once the phase-only template of the outputs has two rows per coefficient: on fewer
        # it can be wild, and its errors, the denominators, would swamp the running sums for good
        if is_fitted(self.regressor) and self.n_rows >= 2 * (2 * order + 1):
            tc = self._output_template_coef()
            pred = self.regressor.predict(avg.X)[:, :nb]
            err_m = np.abs(np.asarray(avg.weights @ pred) - avg.y)  # type: ignore[operator]
            err_t = np.abs(Bb @ tc[:, :nb] - avg.y)
            err_mp = np.abs(self.regressor.predict(X)[:, nb:] - Y)
            err_tp = np.abs(Bt @ tc[:, nb:] - Y)
            self.sum_err_model += np.concatenate([err_m.sum(axis=0), err_mp.sum(axis=0)])
            self.sum_err_template += np.concatenate([err_t.sum(axis=0), err_tp.sum(axis=0)])
            self.last_residual = np.sqrt(np.concatenate([_mean_sq(err_m), _mean_sq(err_mp)]))
            self.selector.score_then_fit(X, Y, avg, err_t, err_tp)
        else:
            self.selector.score_then_fit(X, Y, avg, np.zeros(0), np.zeros(0))
        self._out_normal.add(Bt, Y)
        self._out_normal_body.add(Bb, avg.y)
        self.n_rows += X.shape[0]

    @staticmethod
    def _averaged(rows: Rows) -> AveragedTargets:
        """The pose-interval rows of a block: segment features, block weights, measured ξ."""
        q, s = rows.xi.shape[0], rows.seg_w.size
        W = scipy.sparse.csr_matrix((rows.seg_w, (rows.seg_row, np.arange(s))), shape=(q, s))
        return AveragedTargets(X=rows.seg_X, weights=W, y=rows.xi, columns=tuple(range(len(BODY_CHANNELS))))

    def _output_template_coef(self) -> FloatArray:
        return np.concatenate([self._out_normal_body.solve(_OUTPUT_TEMPLATE_RIDGE),
                               self._out_normal.solve(_OUTPUT_TEMPLATE_RIDGE)], axis=1)

    # ---------------------------------------------------------------- results
    @property
    def chunk_rows(self) -> int:
        """Interval rows per chunk in force (``config.chunk``, or one gait cycle's once started)."""
        return self._chunk

    @property
    def cycles_seen(self) -> float:
        """Gait cycles processed (by phase once initialised, by time before)."""
        if self.initialiser is None:
            return float((self.phase - self._phase0) / (2 * np.pi))
        return self.initialiser.cycles_buffered

    def running_gamma(self) -> dict[str, float | None]:
        """Prequential Γ over body and passive channels.

        NaN before two chunks; None for a group without channels (``passive`` of a fully
        actuated chain: the score does not apply).
        """
        out: dict[str, float | None] = {}
        for name, pfx in (("body", "xi_"), ("passive", "rdot_")):
            cols = [i for i, c in enumerate(self.channels) if c.startswith(pfx)]
            if not cols:
                out[name] = None
                continue
            den = self.sum_err_template[cols].sum()
            out[name] = float(1 - self.sum_err_model[cols].sum() / den) if den > 0 else float("nan")
        return out

    def model(self) -> SudsModel:
        """Snapshot of the current model, flushing the pending chunk first."""
        self.flush()
        if not is_fitted(self.regressor):
            raise SudsDataError("no model yet: the estimator has not finished initialising",
                                code=TOO_LITTLE_DATA)
        return SudsModel(
            joint_names=self.joint_names,
            actuated=self.actuated,
            passive=self.passive,
            template_coef=np.asarray(self.template_.coef_, dtype=float),
            template_residual_var=np.asarray(self.template_.residual_var_, dtype=float),
            template_order=self.config.template_order,
            omega=self.omega_,
            suds=self.regressor.config,
            coef=self.regressor.coef_.copy(),
            kernel_scale=self.regressor.kernel_scale,
            output_template_coef=self._output_template_coef(),
            channels=self.channels,
            n_samples=self.regressor.n_samples_seen_,
        )

    # ------------------------------------------------------------ measured outputs (for publishing)
    #: most measured rows kept for :meth:`pop_measured` (older ones are dropped when nobody takes them)
    MEASURED_KEPT = 10_000

    def pop_measured(self) -> list[tuple[float, FloatArray]]:
        """The measured outputs of the intervals fitted since the last call, oldest first.

        Each is ``(t, y)``: ``t`` the stamp of the interval's end sample (s, the stamp the
        predictor gives its prediction of the same interval) and ``y`` = [ξ (vx, vy m/s,
        wz rad/s), ṙ_p (rad/s, in ``passive`` order)], the row the regression fits on.  Rows
        come out a chunk at a time, when they are fitted.
        """
        out = list(self._measured)
        self._measured.clear()
        return out


def fit_streaming(rec: Recording, config: OnlineConfig = OnlineConfig()) -> OnlineSudsEstimator:
    """Feed a whole recording through :class:`OnlineSudsEstimator` in stamp order (shape and pose interleaved)."""
    est = OnlineSudsEstimator(rec.joint_names, rec.actuated, config)
    events = [(t, 1, k) for k, t in enumerate(rec.t)] + [(t, 0, k) for k, t in enumerate(rec.pose_t)]
    events.sort()
    for t, kind, k in events:
        if kind == 0:
            x, y, yaw = rec.pose[k]
            est.add_pose(float(t), float(x), float(y), float(yaw))
        else:
            est.add_shape(float(t), rec.joint_names, rec.r[k])
    est.drain()
    est.flush()
    return est
