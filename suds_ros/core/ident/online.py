"""Streaming SUDS identification: the algorithm behind the live estimator.

Samples arrive one at a time on two streams (shape and body pose).  The
estimator

1. pairs each shape sample with the pose interpolated at its stamp (a shape
   sample waits until a pose at or after its stamp has arrived);
2. buffers the first ``init_cycles`` gait cycles, then runs the batch phaser
   on them to obtain the phase, the nominal gait θ(φ) and the mean phase rate
   ω̄ — all three are frozen from then on, so every later regressor row is
   final when computed;
3. tracks the phase of each new sample with :class:`PhaseTracker`;
4. turns consecutive samples into interval rows (forward differences,
   midpoint states) and adds them to the SUDS regression with ``partial_fit``
   in chunks;
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

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError, SudsPhaseError
from suds_ros.core.ident.identify import BODY_CHANNELS
from suds_ros.core.recording import Recording
from suds_ros.core.ident.sysid import SudsConfig, SudsRegressor

CHECKPOINT_VERSION = 1


@dataclass(frozen=True)
class OnlineConfig:
    """Settings of the streaming estimator.

    Parameters
    ----------
    suds : SudsConfig
        Regression hyperparameters (fixed online: no order selection).
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
        Seconds a shape sample may wait for a pose covering its stamp before it is dropped.
    """

    suds: SudsConfig = field(default_factory=lambda: SudsConfig(linear_order=6, bilinear_order=3))
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


@dataclass(frozen=True)
class SudsModel:
    """A snapshot of an identified model, enough to predict without the estimator.

    Attributes
    ----------
    joint_names, actuated, passive : joint bookkeeping.
    template_coef : (2·To + 1, nj) Fourier coefficients of θ(φ).
    template_residual_var : (nj,) residual variance of the shape about θ (phase-tracking weights).
    template_order : int
    omega : mean phase rate ω̄, rad/s.
    suds : SudsConfig
    coef : (p, n_out) regression coefficients.
    output_template_coef : (2·To + 1, n_out) phase-only template of the outputs.
    channels : output names.
    n_samples : interval rows the model was fitted on.
    """

    joint_names: tuple[str, ...]
    actuated: tuple[str, ...]
    passive: tuple[str, ...]
    template_coef: FloatArray
    template_residual_var: FloatArray
    template_order: int
    omega: float
    suds: SudsConfig
    coef: FloatArray
    output_template_coef: FloatArray
    channels: tuple[str, ...]
    n_samples: int

    def _theta(self, phase: FloatArray) -> tuple[FloatArray, FloatArray]:
        from suds_ros.core.ident.sysid import fourier_basis

        B = fourier_basis(phase, self.template_order)
        m = np.arange(1, self.template_order + 1)
        dB = np.zeros_like(B)
        ang = phase[:, None] * m
        dB[:, 1::2] = -m * np.sin(ang)
        dB[:, 2::2] = m * np.cos(ang)
        return B @ self.template_coef, dB @ self.template_coef

    def predict(self, phase: FloatArray, r: FloatArray, rdot: FloatArray) -> FloatArray:
        """Outputs (n, n_out) at interval midpoints: phase (n,), r (n, nj), ṙ (n, nj)."""
        from suds_ros.core.ident.sysid import design_matrix

        phase = np.atleast_1d(np.asarray(phase, dtype=float))
        theta, dtheta = self._theta(phase)
        delta = np.atleast_2d(r) - theta
        ddelta = np.atleast_2d(rdot) - dtheta * self.omega
        act = [self.joint_names.index(j) for j in self.actuated]
        return design_matrix(self.suds, phase, delta, ddelta[:, act]) @ self.coef

    def template(self, phase: FloatArray) -> FloatArray:
        """Phase-only template prediction (n, n_out)."""
        from suds_ros.core.ident.sysid import fourier_basis

        return fourier_basis(np.atleast_1d(phase), self.template_order) @ self.output_template_coef

    def to_dict(self) -> dict[str, object]:
        """JSON-ready description (coefficients as nested lists)."""
        return {
            "joint_names": list(self.joint_names),
            "actuated": list(self.actuated),
            "passive": list(self.passive),
            "template_order": self.template_order,
            "template_coef": self.template_coef.tolist(),
            "template_residual_var": self.template_residual_var.tolist(),
            "omega": self.omega,
            "suds": {
                "regressors": self.suds.regressors,
                "intercept_order": self.suds.intercept_order,
                "linear_order": self.suds.linear_order,
                "bilinear_order": self.suds.bilinear_order,
                "ridge": self.suds.ridge,
                "forgetting": self.suds.forgetting,
            },
            "coef": self.coef.tolist(),
            "output_template_coef": self.output_template_coef.tolist(),
            "channels": list(self.channels),
            "n_samples": self.n_samples,
        }

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> "SudsModel":
        """Inverse of :meth:`to_dict`."""
        s = dict(d["suds"])  # type: ignore[call-overload]
        return cls(
            joint_names=tuple(d["joint_names"]),  # type: ignore[arg-type]
            actuated=tuple(d["actuated"]),  # type: ignore[arg-type]
            passive=tuple(d["passive"]),  # type: ignore[arg-type]
            template_coef=np.asarray(d["template_coef"], dtype=float),
            template_residual_var=np.asarray(d["template_residual_var"], dtype=float),
            template_order=int(d["template_order"]),  # type: ignore[call-overload]
            omega=float(d["omega"]),  # type: ignore[arg-type]
            suds=SudsConfig(**s),
            coef=np.asarray(d["coef"], dtype=float),
            output_template_coef=np.asarray(d["output_template_coef"], dtype=float),
            channels=tuple(d["channels"]),  # type: ignore[arg-type]
            n_samples=int(d["n_samples"]),  # type: ignore[call-overload]
        )


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
    """

    def __init__(self, joint_names: tuple[str, ...], actuated: tuple[str, ...], config: OnlineConfig = OnlineConfig()) -> None:
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
        self.initialised = False
        self.template_coef: FloatArray | None = None
        self.omega = float("nan")
        self._tracker = None
        self._prev: tuple[float, FloatArray, FloatArray, float] | None = None  # t, r, pose, phase
        self._rows_X: list[FloatArray] = []
        self._rows_Y: list[FloatArray] = []
        self.regressor = SudsRegressor(len(self.joint_names), len(self.actuated), config.suds)
        self._out_gram: FloatArray | None = None
        self._out_moment: FloatArray | None = None
        # bookkeeping
        self.phase = float("nan")
        self.n_shape = 0
        self.n_pose = 0
        self.n_rows = 0
        self.dropped_no_pose = 0
        self.sum_err_model = np.zeros(len(self.channels))
        self.sum_err_template = np.zeros(len(self.channels))
        self.last_residual = np.full(len(self.channels), np.nan)

    # ------------------------------------------------------------------ input
    def add_pose(self, t: float, x: float, y: float, yaw: float) -> int:
        """Add a pose sample; returns the number of shape samples it released.

        Raises
        ------
        SudsDataError
            NaN values, or a stamp not after the previous pose stamp.
        """
        if not np.all(np.isfinite([t, x, y, yaw])):
            raise SudsDataError(f"pose sample at {t!r} s contains NaN or Inf")
        if t <= self.last_pose_stamp:
            kind = "duplicate" if t == self.last_pose_stamp else "out-of-order"
            raise SudsDataError(f"{kind} pose stamp {t:.6f} s (last {self.last_pose_stamp:.6f} s)")
        yaw_u = yaw if self._yaw_prev is None else _unwrap_next(self._yaw_prev, yaw)
        self._yaw_prev = yaw_u
        self.last_pose_stamp = t
        self._pose_t.append(t)
        self._pose.append(np.array([x, y, yaw_u]))
        self.n_pose += 1
        return self._release()

    def add_shape(self, t: float, names: tuple[str, ...], position: FloatArray) -> int:
        """Add a shape sample; returns the number of shape samples released for processing.

        Raises
        ------
        SudsDataError
            Wrong joint names/count, NaN, duplicate or out-of-order stamp.
        """
        names = tuple(names)
        position = np.asarray(position, dtype=float)
        if names != self.joint_names:
            raise SudsDataError(
                f"shape sample at {t:.6f} s has joints {list(names)}; expected {list(self.joint_names)}"
            )
        if position.shape != (len(self.joint_names),):
            raise SudsDataError(
                f"shape sample at {t:.6f} s has {position.size} positions for {len(self.joint_names)} joints"
            )
        if not (np.isfinite(t) and np.all(np.isfinite(position))):
            raise SudsDataError(f"shape sample at {t!r} s contains NaN or Inf")
        if t <= self.last_shape_stamp:
            kind = "duplicate" if t == self.last_shape_stamp else "out-of-order"
            raise SudsDataError(f"{kind} shape stamp {t:.6f} s (last {self.last_shape_stamp:.6f} s)")
        self.last_shape_stamp = t
        self._pending.append((t, position))
        self.n_shape += 1
        return self._release()

    def already_seen(self, t: float) -> bool:
        """True for a shape stamp at or before the last one accepted (e.g. replayed after a restart)."""
        return t <= self.last_shape_stamp

    def _release(self) -> int:
        released = 0
        while self._pending:
            t, r = self._pending[0]
            if not self._pose_t or self._pose_t[-1] < t:
                # wait for the pose stream; drop samples that waited too long
                if self._pose_t and self.last_shape_stamp - t > self.config.max_pose_wait:
                    self._pending.popleft()
                    self.dropped_no_pose += 1
                    continue
                if not self._pose_t and self.last_shape_stamp - t > self.config.max_pose_wait:
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
            if self._buf_t[-1] - self._buf_t[0] >= self.config.init_cycles / self.config.gait_hz:
                self._initialise()
            return
        phase = float(self._tracker.update(t, r))  # type: ignore[union-attr]
        self._add_interval(t, r, pose, phase)

    def _initialise(self) -> None:
        from suds_ros.core.phase.phase_tracker import PhaseTracker
        from suds_ros.core.phase.phaser import Phaser, PhaserConfig
        from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig

        T = np.asarray(self._buf_t)
        R = np.asarray(self._buf_r)
        P = np.asarray(self._buf_p)
        try:
            phase = Phaser(PhaserConfig(order=self.config.phaser_order)).fit_transform(R)
        except SudsPhaseError:
            if T[-1] - T[0] > 4 * self.config.init_cycles / self.config.gait_hz:
                raise
            # not yet enough cycles for the phaser: keep buffering
            self.config = _with_init(self.config, self.config.init_cycles + 1)
            return
        omega = float((phase[-1] - phase[0]) / (T[-1] - T[0]))
        if not omega > 0:
            raise SudsPhaseError(f"the initial cycles give a non-advancing phase (rate {omega:.3g} rad/s)")
        tmpl = FourierTemplate(FourierTemplateConfig(order=self.config.template_order)).fit(phase, R)
        self.template = tmpl
        self.omega = omega
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
        if prev is None:
            return
        X, Y = interval_row(self.template, self.omega, self._act, self._pas, prev, (t, r, pose, phase))
        self._rows_X.append(X)
        self._rows_Y.append(Y)
        if len(self._rows_X) >= self.config.chunk:
            self.flush()

    def flush(self) -> None:
        """Fit the rows waiting in the current chunk (the node calls this before publishing)."""
        if not self._rows_X:
            return
        X = np.asarray(self._rows_X)
        Y = np.asarray(self._rows_Y)
        self._rows_X, self._rows_Y = [], []
        from suds_ros.core.ident.sysid import fourier_basis

        Bt = fourier_basis(X[:, 0], self.config.template_order)
        if hasattr(self.regressor, "coef_"):
            err_m = np.abs(self.regressor.predict(X) - Y)
            err_t = np.abs(Bt @ self._output_template_coef() - Y)
            self.sum_err_model += err_m.sum(axis=0)
            self.sum_err_template += err_t.sum(axis=0)
            self.last_residual = np.sqrt((err_m**2).mean(axis=0))
        self.regressor.partial_fit(X, Y)
        G, h = Bt.T @ Bt, Bt.T @ Y
        self._out_gram = G if self._out_gram is None else self._out_gram + G
        self._out_moment = h if self._out_moment is None else self._out_moment + h
        self.n_rows += X.shape[0]

    def _output_template_coef(self) -> FloatArray:
        assert self._out_gram is not None and self._out_moment is not None
        G = self._out_gram
        reg = G + 1e-9 * float(np.mean(np.diag(G))) * np.eye(G.shape[0])
        return np.linalg.solve(reg, self._out_moment)

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
        """Snapshot of the current model (flushes the pending chunk first)."""
        self.flush()
        if not hasattr(self.regressor, "coef_"):
            raise SudsDataError("no model yet: the estimator has not finished initialising")
        return SudsModel(
            joint_names=self.joint_names,
            actuated=self.actuated,
            passive=self.passive,
            template_coef=np.asarray(self.template.coef_, dtype=float),  # type: ignore[union-attr]
            template_residual_var=np.asarray(self.template.residual_var_, dtype=float),  # type: ignore[union-attr]
            template_order=self.config.template_order,
            omega=self.omega,
            suds=self.regressor.config,
            coef=self.regressor.coef_.copy(),
            output_template_coef=self._output_template_coef(),
            channels=self.channels,
            n_samples=self.regressor.n_samples_seen_,
        )

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
            raise SudsDataError(f"checkpoint {str(path)!r} is not a suds_ros estimator state (version {CHECKPOINT_VERSION})")
        return obj


def _with_init(cfg: OnlineConfig, cycles: float) -> OnlineConfig:
    from dataclasses import replace

    return replace(cfg, init_cycles=cycles)


def interval_row(
    template: object,
    omega: float,
    act: FloatArray,
    pas: FloatArray,
    a: tuple[float, FloatArray, FloatArray, float],
    b: tuple[float, FloatArray, FloatArray, float],
) -> tuple[FloatArray, FloatArray]:
    """One regression row from consecutive samples a, b = (t, r, pose, phase).

    Returns X = [φ̄, δ, δ̇_a] and Y = [ξ, ṙ_p] at the interval midpoint.
    """
    from suds_ros.core import se2

    ta, ra, pa, fa = a
    tb, rb, pb, fb = b
    dt = tb - ta
    ph = np.array([0.5 * (fa + fb)])
    rm = 0.5 * (ra + rb)
    rdot = (rb - ra) / dt
    xi = se2.log(se2.relative(pa, pb)) / dt
    theta = template.predict(ph)[0]  # type: ignore[attr-defined]
    dtheta = template.derivative(ph)[0]  # type: ignore[attr-defined]
    delta = rm - theta
    ddelta = rdot - dtheta * omega
    X = np.concatenate([ph, delta, ddelta[act]])
    Y = np.concatenate([xi, rdot[pas]])
    return X, Y


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


def model_template(model: SudsModel):  # type: ignore[no-untyped-def]
    """The fitted :class:`FourierTemplate` θ(φ) stored in a :class:`SudsModel`."""
    from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig

    tmpl = FourierTemplate(FourierTemplateConfig(order=model.template_order))
    tmpl.coef_ = np.asarray(model.template_coef, dtype=float)
    tmpl.residual_var_ = np.asarray(model.template_residual_var, dtype=float)
    tmpl.n_features_in_ = tmpl.coef_.shape[1]
    return tmpl


def nearest_phase(template: object, r: FloatArray, n_grid: int = 720) -> float:
    """Phase in [0, 2π) whose θ(φ) is closest to the shape ``r`` (nj,) (grid search)."""
    grid = np.linspace(0.0, 2 * np.pi, n_grid, endpoint=False)
    theta = template.predict(grid)  # type: ignore[attr-defined]
    scale = theta.std(axis=0)
    scale = np.where(scale > 1e-9, scale, 1.0)
    d = (((theta - r) / scale) ** 2).sum(axis=1)
    return float(grid[int(np.argmin(d))])


class StreamingPredictor:
    """Live predictions of (ξ, ṙ_p) from shape samples with an identified :class:`SudsModel`.

    Each shape sample closes the interval from the previous one; the prediction is the
    model's output for that interval (midpoint state and phase, forward-difference rate),
    i.e. the mean body and passive velocity over the interval ending at the sample.
    The phase is initialised at the template point nearest the first sample and then tracked.
    """

    def __init__(self, model: SudsModel) -> None:
        self.model = model
        self.template = model_template(model)
        self.passive = model.passive
        self._act = np.array([model.joint_names.index(j) for j in model.actuated])
        self._tracker = None
        self._prev: tuple[float, FloatArray, float] | None = None
        self.last_stamp = -np.inf

    def shares_phase_with(self, model: SudsModel) -> bool:
        """True when ``model`` has this predictor's joints, template and phase rate (phase carries over)."""
        return (model.joint_names == self.model.joint_names
                and model.omega == self.model.omega
                and np.array_equal(model.template_coef, self.model.template_coef))

    def with_model(self, model: SudsModel) -> StreamingPredictor:
        """A predictor for ``model`` that continues this one's stream without a restart.

        When the new model shares this one's template and phase rate (a refit of the same
        gait), the phase tracker, the last sample and the stamp check carry over, so the
        next sample is predicted at once and the phase is continuous.  Otherwise the new
        predictor is fresh: it re-initialises its phase at the next sample.
        """
        new = StreamingPredictor(model)
        if self._tracker is not None and self.shares_phase_with(model):
            new._tracker = self._tracker
            new._prev = self._prev
            new.last_stamp = self.last_stamp
        return new

    def update(self, t: float, names: tuple[str, ...], position: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """Predicted ξ (3,) and ṙ_p (np,) for the interval ending at ``t``; None for the first sample.

        Raises
        ------
        SudsDataError
            Wrong joint names or count, NaN, duplicate or out-of-order stamp.
        """
        names = tuple(names)
        r = np.asarray(position, dtype=float)
        if names != self.model.joint_names:
            raise SudsDataError(f"shape sample at {t:.6f} s has joints {list(names)}; expected {list(self.model.joint_names)}")
        if r.shape != (len(names),):
            raise SudsDataError(f"shape sample at {t:.6f} s has {r.size} positions for {len(names)} joints")
        if not (np.isfinite(t) and np.all(np.isfinite(r))):
            raise SudsDataError(f"shape sample at {t!r} s contains NaN or Inf")
        if t <= self.last_stamp:
            kind = "duplicate" if t == self.last_stamp else "out-of-order"
            raise SudsDataError(f"{kind} shape stamp {t:.6f} s (last {self.last_stamp:.6f} s)")
        self.last_stamp = t
        if self._tracker is None:
            from suds_ros.core.phase.phase_tracker import PhaseTracker

            phase = nearest_phase(self.template, r)
            self._tracker = PhaseTracker(self.template, self.model.omega, phase, t)
        else:
            phase = float(self._tracker.update(t, r))
        prev = self._prev
        self._prev = (t, r, phase)
        self.last_phase = phase
        if prev is None:
            return None
        tp, rp, php = prev
        self.last_mid_phase = 0.5 * (php + phase)
        out = self.model.predict(np.array([0.5 * (php + phase)]), (0.5 * (rp + r))[None], ((r - rp) / (t - tp))[None])[0]
        return out[:3], out[3 : 3 + len(self.passive)]


def evaluate_model(model: SudsModel, rec: Recording):  # type: ignore[no-untyped-def]
    """Run :class:`StreamingPredictor` over a recording and compare with its measured velocities.

    Returns a :class:`~suds_ros.core.ident.identify.Prediction` whose ``template`` column is the model's
    phase-only template at the tracked phases (score it with ``score_prediction``).
    """
    from suds_ros.core.ident.identify import Prediction
    from suds_ros.core.ident.intervals import make_intervals

    if rec.joint_names != model.joint_names or rec.actuated != model.actuated:
        raise SudsDataError(
            f"recording joints {list(rec.joint_names)} (actuated {list(rec.actuated)}) differ from the "
            f"model's {list(model.joint_names)} (actuated {list(model.actuated)})"
        )
    pred = StreamingPredictor(model)
    out, phases = [], []
    for k in range(rec.n_samples):
        o = pred.update(float(rec.t[k]), rec.joint_names, rec.r[k])
        if o is not None:
            out.append(np.concatenate(o))
            phases.append(pred.last_mid_phase)
    iv = make_intervals(rec)
    ph = np.asarray(phases)
    truth = np.concatenate([iv.xi, iv.rdot[:, rec.passive_index]], axis=1)
    return Prediction(
        t=iv.t, phase=ph, channels=model.channels, truth=truth,
        model=np.asarray(out), template=model.template(ph),
    )
