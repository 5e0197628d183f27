"""Streaming SUDS identification: the algorithm behind the live estimator.

Samples arrive one at a time on two streams (shape and body pose).  The
estimator

1. releases each shape sample once a pose at or after its stamp has arrived
   (pairing by stamps only);
2. buffers the first ``init_cycles`` gait cycles, then runs the batch phaser
   on them to obtain the phase, the nominal gait θ(φ) and the mean phase rate
   ω̄ — all three are frozen from then on, so every later regressor row is
   final when computed;
3. tracks the phase of each new sample with :class:`PhaseTracker`;
4. turns consecutive shape samples into interval rows (forward differences,
   states at the interval start by default) for the passive velocities, and each pose interval — once
   the shape intervals it overlaps have been featurised — into one averaged row
   for the body velocity (its pose displacement against the duration-weighted
   mean of the model over its segments, as in the batch identifier), and adds
   both to the SUDS regression with ``partial_fit`` in chunks;
5. scores each chunk *before* learning from it (prequential evaluation), giving
   a running Γ on data the model has not seen.

:func:`fit_streaming` runs the same computation as one batch over a whole
recording; because the regression's sufficient statistics are additive the two
agree to round-off.  The estimator pickles completely (:meth:`state_bytes`),
so a process can checkpoint it and resume after a crash; samples at or before
the last processed stamp are recognised as already seen and skipped.
"""

from __future__ import annotations

import os
import pickle
import tempfile
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import NAN_OR_INF, TOO_LITTLE_DATA, SudsConfigError, SudsDataError, SudsPhaseError
from suds_ros.core.estimator import is_fitted
from suds_ros.core.fourier import NormalEquations, fourier_basis
from suds_ros.core.ident.model import SudsModel, check_shape_sample, check_stamp
from suds_ros.core.ident.intervals import interval_features, interval_row, overlap_segments
from suds_ros.core.ident.scoring import BODY_CHANNELS
from suds_ros.core.ident.prequential import PrequentialSelector
from suds_ros.core.ident.shape_kernel import gait_kernel_scale
from suds_ros.core.ident.sysid import AveragedTargets, SudsConfig, SudsRegressor
from suds_ros.core.phase.phase_tracker import PhaseTracker
from suds_ros.core.phase.phaser import Phaser, PhaserConfig
from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig
from suds_ros.core.recording import Recording

CHECKPOINT_VERSION = 5
#: relative ridge of the phase-only output template's normal equations
_OUTPUT_TEMPLATE_RIDGE = 1e-9


@dataclass(frozen=True)
class OnlineConfig:
    """Settings of the streaming estimator.

    Parameters
    ----------
    suds : SudsConfig
        Regression hyperparameters of the first candidate model (current at the start).
    alternatives : tuple of SudsConfig
        Further candidates fitted side by side; the one published is the candidate with the
        lowest discounted prequential loss (:mod:`~suds_ros.core.ident.prequential`).  The
        default pair: set 2, which wins the first cycles, and set 3 with a smaller ridge, which
        wins once some 15–20 cycles support it (``docs/results/peers.md``).
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
        Interval rows per ``partial_fit`` call.
    max_pose_wait : float
        Stamp seconds a shape sample handed to the estimator may wait for a pose covering
        its stamp (while later shape samples arrive) before it is dropped (``dropped_no_pose``).
    """

    suds: SudsConfig = field(default_factory=lambda: SudsConfig(linear_order=6, bilinear_order=3))
    alternatives: tuple[SudsConfig, ...] = (SudsConfig(regressors=3, linear_order=6, bilinear_order=3, ridge=1e-7),)
    selection_memory: float = 5.0
    init_cycles: float = 5.0
    gait_hz: float = 1.0
    template_order: int = 8
    phaser_order: int = 10
    chunk: int = 100
    max_pose_wait: float = 1.0

    def __post_init__(self) -> None:
        if not self.init_cycles >= 3:
            raise SudsConfigError(f"`init_cycles`: the phaser needs ≥ 3 cycles, got {self.init_cycles!r}")
        if not self.gait_hz > 0:
            raise SudsConfigError(f"`gait_hz`: expected > 0, got {self.gait_hz!r}")
        if self.chunk < 1:
            raise SudsConfigError(f"`chunk`: expected ≥ 1, got {self.chunk!r}")
        if not self.max_pose_wait > 0:
            raise SudsConfigError(f"`max_pose_wait`: expected > 0, got {self.max_pose_wait!r}")
        if not self.selection_memory > 0:
            raise SudsConfigError(f"`selection_memory`: expected > 0, got {self.selection_memory!r}")

    @property
    def candidates(self) -> tuple[SudsConfig, ...]:
        """Every candidate configuration, ``suds`` first."""
        return (self.suds,) + tuple(self.alternatives)


def _mean_sq(e: FloatArray) -> FloatArray:
    """Mean square of each column (NaN for no rows)."""
    return (e**2).sum(axis=0) / e.shape[0] if e.shape[0] else np.full(e.shape[1], np.nan)


def _unwrap_next(prev: float, yaw: float) -> float:
    return prev + float(np.angle(np.exp(1j * (yaw - prev))))


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
        Gait template θ(φ) fitted on the initial cycles (after initialisation).
    omega_ : float
        Mean phase rate ω̄ of the initial cycles, rad/s (NaN before initialisation).
    regressor : SudsRegressor
        The incremental SUDS regression.
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
        self._act = np.array([self.joint_names.index(j) for j in self.actuated])
        self._pas = np.array([self.joint_names.index(j) for j in self.passive])
        self.channels = tuple(BODY_CHANNELS) + tuple(f"rdot_{j}" for j in self.passive)
        self.version = CHECKPOINT_VERSION
        # stream state
        self.last_shape_stamp = -np.inf
        self.last_pose_stamp = -np.inf
        self._pose_t: deque[float] = deque()
        self._pose: deque[FloatArray] = deque()
        self._pending: deque[tuple[float, FloatArray]] = deque()
        self._yaw_prev: float | None = None
        # initialisation buffer
        self._buf_t: list[float] = []
        self._buf_r: list[FloatArray] = []
        self._buf_p: list[FloatArray] = []
        # after initialisation
        self.init_cycles_ = float(config.init_cycles)
        self.initialised = False
        self.template_: FourierTemplate | None = None
        self.omega_ = float("nan")
        self._phase0 = float("nan")
        self._tracker: PhaseTracker | None = None
        self._prev: tuple[float, FloatArray, FloatArray, float] | None = None  # t, r, pose, phase
        self._rows_X: list[FloatArray] = []
        self._rows_Y: list[FloatArray] = []
        # pose intervals: poses not yet used as an interval start, featurised shape samples
        self._pose_q: deque[tuple[float, FloatArray]] = deque()
        self._shape_hist: deque[tuple[float, FloatArray, float]] = deque()  # t, r, phase
        self._first_shape = float("nan")
        self._rows_avg: list[tuple[FloatArray, FloatArray, FloatArray]] = []  # segment X, weights, ξ
        self.selector = self._selector(None)
        nb = len(BODY_CHANNELS)
        self._out_normal = NormalEquations(2 * config.template_order + 1, len(self.channels) - nb)
        self._out_normal_body = NormalEquations(2 * config.template_order + 1, nb)
        # bookkeeping
        self.phase = float("nan")
        self.n_shape = 0
        self.n_pose = 0
        self.n_rows = 0
        self.dropped_no_pose = 0
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

    # ------------------------------------------------------------------ input
    def add_pose(self, t: float, x: float, y: float, yaw: float) -> int:
        """Add a pose sample; returns the number of shape samples it released.

        Raises
        ------
        SudsDataError
            NaN values, or a stamp not after the previous pose stamp.
        """
        if not np.all(np.isfinite([t, x, y, yaw])):
            raise SudsDataError(f"pose sample at {t!r} s contains NaN or Inf", code=NAN_OR_INF)
        check_stamp("pose", t, self.last_pose_stamp)
        yaw_u = yaw if self._yaw_prev is None else _unwrap_next(self._yaw_prev, yaw)
        self._yaw_prev = yaw_u
        self.last_pose_stamp = t
        self._pose_t.append(t)
        self._pose.append(np.array([x, y, yaw_u]))
        self._pose_q.append((t, self._pose[-1]))
        self.n_pose += 1
        return self._release()

    def add_shape(self, t: float, names: tuple[str, ...], position: FloatArray) -> int:
        """Add a shape sample; returns the number of shape samples released for processing.

        Raises
        ------
        SudsDataError
            Wrong joint names/count, NaN, duplicate or out-of-order stamp.
        """
        position = self.check_shape(t, names, position)
        check_stamp("shape", t, self.last_shape_stamp)
        self.last_shape_stamp = t
        self._pending.append((t, position))
        self.n_shape += 1
        return self._release()

    def check_shape(self, t: float, names: tuple[str, ...], position: FloatArray) -> FloatArray:
        """The positions (nj,) of a shape sample with this estimator's joints (stamp order not checked).

        Raises
        ------
        SudsDataError
            Wrong joint names (code ``wrong_joint_names``) or count (``wrong_joint_count``), NaN
            (``nan_or_inf``).
        """
        return check_shape_sample(t, tuple(names), position, self.joint_names)

    def already_seen(self, t: float) -> bool:
        """True for a shape stamp at or before the last one accepted (e.g. replayed after a restart)."""
        return t <= self.last_shape_stamp

    def _release(self) -> int:
        released = 0
        while self._pending:
            t, r = self._pending[0]
            if not self._pose_t or self._pose_t[-1] < t:
                # wait for the pose stream; drop samples that waited too long (in stamp time)
                if self.last_shape_stamp - t > self.config.max_pose_wait:
                    self._pending.popleft()
                    self.dropped_no_pose += 1
                    continue
                break
            if self._pose_t[0] > t:  # shape sample before the first pose: cannot be paired
                self._pending.popleft()
                self.dropped_no_pose += 1
                continue
            pose = self._pose_at(t)
            self._pending.popleft()
            self._process(t, r, pose)
            released += 1
        return released

    def _pose_at(self, t: float) -> FloatArray:
        pt = np.fromiter(self._pose_t, dtype=float)
        i = int(np.searchsorted(pt, t))
        # keep only what later samples can still need
        while len(self._pose_t) > 2 and self._pose_t[1] <= t:
            self._pose_t.popleft()
            self._pose.popleft()
            i -= 1
        pt = np.fromiter(self._pose_t, dtype=float)
        P = np.array(self._pose)
        return np.array([np.interp(t, pt, P[:, c]) for c in range(3)])

    # ------------------------------------------------------------- processing
    def _process(self, t: float, r: FloatArray, pose: FloatArray) -> None:
        if not self.initialised:
            self._buf_t.append(t)
            self._buf_r.append(r)
            self._buf_p.append(pose)
            if self._buf_t[-1] - self._buf_t[0] >= self.init_cycles_ / self.config.gait_hz:
                self._initialise()
            return
        phase = float(self._tracker.update(t, r))  # type: ignore[union-attr]
        self._add_interval(t, r, pose, phase)

    def _initialise(self) -> None:
        T = np.asarray(self._buf_t)
        R = np.asarray(self._buf_r)
        P = np.asarray(self._buf_p)
        try:
            phase = Phaser(PhaserConfig(order=self.config.phaser_order)).fit_transform(R)
        except SudsPhaseError:
            if T[-1] - T[0] > 4 * self.config.init_cycles / self.config.gait_hz:
                raise
            # not yet enough cycles for the phaser: keep buffering one more cycle
            self.init_cycles_ += 1
            return
        omega = float((phase[-1] - phase[0]) / (T[-1] - T[0]))
        if not omega > 0:
            raise SudsPhaseError(f"the initial cycles give a non-advancing phase (rate {omega:.3g} rad/s)")
        tmpl = FourierTemplate(FourierTemplateConfig(order=self.config.template_order)).fit(phase, R)
        self.template_ = tmpl
        self.omega_ = omega
        self.selector = self._selector(gait_kernel_scale(tmpl, omega, self._act))
        self._tracker = PhaseTracker(tmpl, omega, float(phase[-1]), float(T[-1]))
        self.initialised = True
        self._phase0 = float(phase[0])
        self._buf_t, self._buf_r, self._buf_p = [], [], []
        for k in range(T.size):
            self._add_interval(float(T[k]), R[k], P[k], float(phase[k]))

    def _add_interval(self, t: float, r: FloatArray, pose: FloatArray, phase: float) -> None:
        self.phase = phase
        prev = self._prev
        self._prev = (t, r, pose, phase)
        self._shape_hist.append((t, r, phase))
        if prev is None:
            self._first_shape = t
            return
        X, Y = interval_row(self.config.suds, self.template_, self.omega_, self._act, self._pas, prev,
                            (t, r, pose, phase))
        self._note_measured(t, Y)
        self._rows_X.append(X)
        self._rows_Y.append(Y[len(BODY_CHANNELS):])
        self._pose_rows(t)
        if len(self._rows_X) >= self.config.chunk:
            self.flush()

    def _pose_rows(self, t_now: float) -> None:
        """Turn every pose interval ending by ``t_now`` into an averaged row.

        ``t_now`` is the last featurised shape stamp.  Afterwards, forget what no later pose
        interval can need.
        """
        q, hist = self._pose_q, self._shape_hist
        while len(q) >= 2 and q[1][0] <= t_now:
            (t0, g0), (t1, g1) = q[0], q[1]
            if t0 >= self._first_shape:
                while len(hist) > 2 and hist[1][0] <= t0:
                    hist.popleft()
                T = np.fromiter((h[0] for h in hist), dtype=float)
                _, k, s0, s1 = overlap_segments(T[:-1], T[1:], np.array([t0]), np.array([t1]))
                R = np.array([h[1] for h in hist])
                P = np.fromiter((h[2] for h in hist), dtype=float)
                rdot = (R[k + 1] - R[k]) / (T[k + 1] - T[k])[:, None]
                if self.config.suds.state == "start":  # a segment takes its shape interval's row
                    ph_s, r_s = 0.5 * (P[k] + P[k + 1]), R[k]
                else:  # the instantaneous map at the segment's midpoint
                    frac = (0.5 * (s0 + s1) - T[k]) / (T[k + 1] - T[k])
                    ph_s, r_s = P[k] + (P[k + 1] - P[k]) * frac, R[k] + (R[k + 1] - R[k]) * frac[:, None]
                Xs = interval_features(self.template_, self.omega_, self._act, ph_s, r_s, rdot)
                xi = se2.log(se2.relative(g0, g1)) / (t1 - t0)
                self._rows_avg.append((Xs, (s1 - s0) / (s1 - s0).sum(), xi))
            q.popleft()

    def flush(self) -> None:
        """Fit the rows waiting in the current chunk (the node calls this before publishing)."""
        if not self._rows_X and not self._rows_avg:
            return
        d = 1 + 2 * (len(self.joint_names) + len(self.actuated))
        X = np.asarray(self._rows_X).reshape(-1, d)
        Y = np.asarray(self._rows_Y).reshape(X.shape[0], len(self.passive))
        avg = self._averaged()
        self._rows_X, self._rows_Y, self._rows_avg = [], [], []
        order = self.config.template_order
        Bt = fourier_basis(X[:, 0], order)
        Bb = np.asarray(avg.weights @ fourier_basis(avg.X[:, 0], order))  # type: ignore[operator]
        if is_fitted(self.regressor):
            tc = self._output_template_coef()
            nb = len(BODY_CHANNELS)
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

    def _averaged(self) -> AveragedTargets:
        """The pending pose-interval rows: segment features, block weights, measured ξ."""
        import scipy.sparse

        d = 1 + 2 * (len(self.joint_names) + len(self.actuated))
        rows = self._rows_avg
        n = [len(w) for _, w, _ in rows]
        Xs = np.concatenate([x for x, _, _ in rows]) if rows else np.zeros((0, d))
        W = scipy.sparse.csr_matrix(
            (np.concatenate([w for _, w, _ in rows]) if rows else np.zeros(0),
             (np.repeat(np.arange(len(rows)), n), np.arange(sum(n)))), shape=(len(rows), sum(n)))
        ya = np.array([xi for _, _, xi in rows]).reshape(len(rows), len(BODY_CHANNELS))
        return AveragedTargets(X=Xs, weights=W, y=ya, columns=tuple(range(len(BODY_CHANNELS))))

    def _output_template_coef(self) -> FloatArray:
        return np.concatenate([self._out_normal_body.solve(_OUTPUT_TEMPLATE_RIDGE),
                               self._out_normal.solve(_OUTPUT_TEMPLATE_RIDGE)], axis=1)

    # ---------------------------------------------------------------- results
    @property
    def cycles_seen(self) -> float:
        """Gait cycles processed (by phase once initialised, by time before)."""
        if self.initialised:
            return float((self.phase - self._phase0) / (2 * np.pi))
        if len(self._buf_t) < 2:
            return 0.0
        return (self._buf_t[-1] - self._buf_t[0]) * self.config.gait_hz

    def running_gamma(self) -> dict[str, float]:
        """Prequential Γ over body and passive channels (NaN before two chunks)."""
        out = {}
        for name, pfx in (("body", "xi_"), ("passive", "rdot_")):
            cols = [i for i, c in enumerate(self.channels) if c.startswith(pfx)]
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
            template_coef=np.asarray(self.template_.coef_, dtype=float),  # type: ignore[union-attr]
            template_residual_var=np.asarray(self.template_.residual_var_, dtype=float),  # type: ignore[union-attr]
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

    def _note_measured(self, t: float, y: FloatArray) -> None:
        rows = self.__dict__.get("_measured")
        if rows is None:  # also for an estimator loaded from an older checkpoint
            rows = self.__dict__["_measured"] = deque(maxlen=self.MEASURED_KEPT)
        rows.append((t, y))

    def pop_measured(self) -> list[tuple[float, FloatArray]]:
        """The measured outputs of the intervals added since the last call, oldest first.

        Each is ``(t, y)``: ``t`` the stamp of the interval's end sample (s, the stamp the
        predictor gives its prediction of the same interval) and ``y`` = [ξ (vx, vy m/s,
        wz rad/s), ṙ_p (rad/s, in ``passive`` order)], the row the regression fits on.
        """
        rows = self.__dict__.get("_measured")
        if not rows:
            return []
        out = list(rows)
        rows.clear()
        return out

    # ------------------------------------------------------------ checkpoints
    def state_bytes(self) -> bytes:
        """The complete estimator state (pickle)."""
        return pickle.dumps(self, protocol=pickle.HIGHEST_PROTOCOL)

    def save(self, path: str | Path) -> None:
        """Atomically write a checkpoint (temp file, fsync, rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(self.state_bytes())
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    @staticmethod
    def load(path: str | Path) -> "OnlineSudsEstimator":
        """Read a checkpoint written by :meth:`save`."""
        path = Path(path)
        try:
            with open(path, "rb") as f:
                obj = pickle.load(f)
        except (OSError, pickle.UnpicklingError, EOFError, AttributeError) as exc:
            raise SudsDataError(f"checkpoint {str(path)!r} is unreadable: {exc}") from None
        if not isinstance(obj, OnlineSudsEstimator) or getattr(obj, "version", None) != CHECKPOINT_VERSION:
            raise SudsDataError(
                f"checkpoint {str(path)!r} is not a suds_ros estimator state (version {CHECKPOINT_VERSION})")
        return obj


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
    est.flush()
    return est
