"""Data-driven gait optimisation: one trust-region step on the SUDS model of a recording (``suds optimize BAG``).

The recording's fitted SUDS model (:class:`~suds_ros.core.ident.identify.SudsIdentifier`) predicts, per
sampling interval, the mean body velocity g° and passive velocity ṙ_p from the gait phase φ, the
state's offset δ = r − θ(φ) from the gait template and the actuated rate offset δ̇_a.  A candidate
gait (``suds-gait/1``, in the model's phase: gait time s ↔ φ = 2π·s) is predicted over one cycle
by that same sampled-data map (:class:`LearnedCycle`): at the recording's sample interval h, the
passive joints step by h·ṙ_p and the pose by the SE(2) exponential of h·g°
(:func:`~suds_ros.core.se2.exp_step`), the actuated joints following the candidate exactly.  The
objectives (``shared/spec/gait.md``) are read at the passive periodic steady state of the learned
map, found by the Newton shooting of :class:`~suds_ros.core.optimize.physics.PeriodicShooting`;
efficiency needs a learned torque model (the recording's ``effort``), else it is refused.

The step
--------
The model is local to the recorded gait: it was fitted on the shapes the robot visited.  The
**trust region** is the data's spread around the template: on the constraint grid, every actuated
joint's |δ_a(t)| ≤ κ·σ_δ,j and |δ̇_a(t)| ≤ κ·σ_δ̇,j, with σ the standard deviations of δ_a and δ̇_a
over the recording (κ = ``trust``, default 2; widened to hold the start gait if it lies
further out, e.g. a nominal drive the phaser's template does not follow exactly).  Both are
linear in the gait's coefficients, so they enter SLSQP as linear inequalities beside the joint
range and speed bounds (the same bounds and code as the physics optimiser,
:func:`~suds_ros.core.optimize.physics.linear_bounds`).  The start is the gait that drove the
recording, moved onto the model's phase (:func:`align_to_model`), or else the template's actuated
part truncated to K harmonics; it is scaled into the bounds if it leaves them.  The returned
gait meets the bounds on a 4096-point grid (the step is shortened towards the start until it
does); a step that is not predicted to be better is not taken.  SLSQP can break down (its
linearised constraints incompatible) after it has visited better gaits that meet every bound:
it is then restarted once from the best of them, and that gait is kept if the restart breaks
down too.

Uncertainty
-----------
The regression's coefficients have the covariance s²_c·(XᵀX + λI)⁻¹ per output channel c (s²_c its
residual variance, λ its ridge): ``draws`` coefficient sets are drawn from it and the recorded and
proposed gaits re-predicted with each; the spread of the objective and of the gain over the draws
is the reported uncertainty.  It treats the residuals as independent and the model's form as
right, so it is a lower bound on the real error (the benchmark compares it with the simulator).
Channels fitted on averaged targets (the body velocity over the pose stream's own intervals, when
motion capture runs at its own rate) are drawn from their own normal equations, (W·A)ᵀ(W·A) + λI.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg
from scipy.optimize import minimize

from suds_ros.core import se2
from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import TOO_LITTLE_DATA, SudsConfigError, SudsDataError
from suds_ros.core.fourier import fourier_basis_and_derivative
from suds_ros.core.ident.sysid import SudsConfig, regressor_design, regressor_input
from suds_ros.core.optimize.physics import (
    MARGIN,
    UNSUPPORTED_OBJECTIVE,
    CycleResult,
    OptimizeConfig,
    PeriodicShooting,
    SteadyStateProblem,
    feasible_scale,
    linear_bounds,
    objective_values,
)
from suds_ros.core.physics.gait import (
    DEFAULT_MAX_ORDER,
    MAX_ORDER,
    OBJECTIVES,
    Gait,
    GaitLimits,
    checked_extremes,
    constraint_grid,
    constraint_violations,
    half_wave_free,
    time_shifted,
    with_predicted,
)
from suds_ros.core.recording import Recording
from suds_ros.core.resample import Grid


@dataclass(frozen=True)
class DataOptimizeConfig:
    """Settings of :func:`optimize_from_data`.

    Parameters
    ----------
    objective : str
        ``speed``, ``turn`` or ``efficiency`` (``shared/spec/gait.md``).
    order : int
        Harmonics K of the proposed gait (1 ≤ K ≤ 8; the spec's default bound is 3).
    trust : float
        Trust-region radius κ in standard deviations of the data's δ_a and δ̇_a spread (> 0).
    draws : int
        Coefficient draws for the predicted objective's uncertainty (0: none).
    min_gain_sigmas : float
        With draws, the step is taken only when its predicted gain is at least this many standard
        deviations (over the draws) above zero; else the start gait is returned (0: always).
    seed : int
        Seed of the draws.
    max_rotation : float
        Bound on the net rotation per cycle for ``speed`` and ``efficiency``, rad.
    points_per_harmonic : int
        Constraint grid: this many times K points per cycle.
    maxiter : int
        SLSQP iterations.
    ftol : float
        SLSQP's tolerance on the (scaled) objective.
    fd_step : float
        Forward-difference step on the coefficients, rad.
    trust_centre : str
        ``template``: the trust region is centred on the recording's gait template θ_a(φ) (and
        widened to hold the start gait); ``start``: on the start gait itself (the gait that drove
        the recording, which the data scatter around; the radius is then exactly κ).
    half_wave : bool
        Move only the odd harmonics (the offsets and even harmonics held at the start's): from a
        half-wave symmetric start, r_a(t + T/2) = −r_a(t), the step stays in that family, whose net
        rotation per cycle is zero by symmetry on a mirror-symmetric robot
        (:func:`~suds_ros.core.physics.gait.half_wave_free`).
        The model's predicted rotation is then bounded around its prediction for the start
        (|rotation − start's| ≤ ``max_rotation``), not around zero: the model's yaw errs by more
        than the bound (swimmer9 from five cycles: −0.07 rad/cycle for the nominal gait, which runs
        straight), and along a family that cannot turn, a predicted turn measures the model's
        error, so the step stays where that error is small.
    """

    objective: str = "speed"
    order: int = DEFAULT_MAX_ORDER
    trust: float = 2.0
    draws: int = 16
    min_gain_sigmas: float = 1.0
    seed: int = 0
    max_rotation: float = 0.05
    points_per_harmonic: int = 64
    maxiter: int = 100
    ftol: float = 1e-8
    fd_step: float = 1e-6
    trust_centre: str = "template"
    half_wave: bool = False

    def __post_init__(self) -> None:
        if self.objective not in OBJECTIVES:
            raise SudsConfigError(f"`objective`: expected one of {list(OBJECTIVES)}, got {self.objective!r}")
        checks = [("order", 1 <= self.order <= MAX_ORDER, f"1..{MAX_ORDER}"),
                  ("trust", math.isfinite(self.trust) and self.trust > 0, "> 0"),
                  ("draws", self.draws >= 0, "≥ 0"),
                  ("min_gain_sigmas", math.isfinite(self.min_gain_sigmas) and self.min_gain_sigmas >= 0, "≥ 0"),
                  ("max_rotation", self.max_rotation > 0, "> 0"),
                  ("points_per_harmonic", self.points_per_harmonic >= 8, "≥ 8"),
                  ("maxiter", self.maxiter >= 1, "≥ 1"), ("ftol", self.ftol > 0, "> 0"),
                  ("fd_step", self.fd_step > 0, "> 0")]
        for name, ok, expected in checks:
            if not ok:
                raise SudsConfigError(f"`{name}`: expected {expected}, got {getattr(self, name)!r}")
        if self.trust_centre not in ("template", "start"):
            raise SudsConfigError(f"`trust_centre`: expected 'template' or 'start', got {self.trust_centre!r}")
        if self.half_wave and self.objective == "turn":
            raise SudsConfigError("`half_wave`: expected False for the turn objective (a half-wave symmetric gait "
                                  "does not turn a mirror-symmetric robot), got True")


@dataclass(frozen=True)
class LearnedModel:
    """What the data-driven optimiser needs of a fitted SUDS model and its recording.

    Attributes
    ----------
    system : str
        The recording's system id.
    joint_names, actuated, passive : joint bookkeeping (names).
    act, pas : (na,), (np,) int, column indices of the actuated and passive joints.
    template_order : int
    template_coef : (2·To + 1, nj) Fourier coefficients of θ(φ) ([1, cos φ, sin φ, …]).
    omega : float, the recording's mean phase rate ω̄, rad/s.
    dt : float, the sample interval the model maps over (the identifier's shape grid), s.
    gait_hz : float, the recording's gait frequency, Hz.
    suds : SudsConfig, kernel_scale : the regression's design.
    coef : (p, c) coefficients; channels ξx, ξy, ξθ, ṙ_p…, then τ_a… when ``torque``.
    torque : bool, whether actuator torques were learned.
    chol : (p, p) lower Cholesky factor L of XᵀX + λI (LLᵀ) of the channels fitted per sampling
        interval, or None (no draws).
    resid_std : (c,) residual standard deviation per channel.
    spread_delta, spread_rate : (na,) std of δ_a (rad) and δ̇_a (rad/s) over the recording.
    spread_passive : (np,) std of δ_p (rad).
    cycles : float, gait cycles in the recording.
    identifier : SudsIdentifier or None, the fitted identifier itself (phaser, template, regression):
        :func:`motion_miss` predicts other recordings with it.
    frame_weights : (nj,) or None, the body frame the model was fitted in (:func:`shape_frame`): the
        recorded yaw plus r·w; None: the recorded pose frame itself.  Recordings compared with the
        model go through :meth:`in_frame` first.
    avg_columns : tuple of int, the channels fitted on averaged targets (the body velocity over the
        pose stream's own intervals when it is not on the shape grid: the regression's
        ``avg_columns_``); empty: none.
    chol_avg : (p, p) or None, the factor of their own normal equations (W·A)ᵀ(W·A) + λI, which
        their draws use; None with ``avg_columns``: no draws.
    """

    system: str
    joint_names: tuple[str, ...]
    actuated: tuple[str, ...]
    passive: tuple[str, ...]
    act: FloatArray
    pas: FloatArray
    template_order: int
    template_coef: FloatArray
    omega: float
    dt: float
    gait_hz: float
    suds: SudsConfig
    kernel_scale: Any
    coef: FloatArray
    torque: bool
    chol: FloatArray | None
    resid_std: FloatArray
    spread_delta: FloatArray
    spread_rate: FloatArray
    spread_passive: FloatArray
    cycles: float
    identifier: Any = field(default=None, repr=False, compare=False)
    frame_weights: FloatArray | None = field(default=None, repr=False, compare=False)
    avg_columns: tuple[int, ...] = ()
    chol_avg: FloatArray | None = field(default=None, repr=False, compare=False)

    def theta(self, phase: FloatArray) -> tuple[FloatArray, FloatArray]:
        """θ(φ) and dθ/dφ, each (n, nj), at phases (n,) rad."""
        B, dB = fourier_basis_and_derivative(np.atleast_1d(np.asarray(phase, dtype=float)), self.template_order)
        return B @ self.template_coef, dB @ self.template_coef

    def recorded_gait(self, order: int) -> Gait:
        """The template's actuated part truncated to ``order`` harmonics, at the recording's frequency."""
        c = self.template_coef[:, self.act]
        K = min(order, self.template_order)
        cos = [tuple(c[1 + 2 * k, j] for k in range(K)) for j in range(len(self.act))]
        sin = [tuple(c[2 + 2 * k, j] for k in range(K)) for j in range(len(self.act))]
        g = Gait(system=self.system, gait_hz=self.gait_hz, joints=self.actuated, offset=tuple(c[0]),
                 cos=tuple(cos), sin=tuple(sin))
        return g if g.order == order else g.from_vector(g.to_vector(order), order)

    def in_frame(self, rec: Recording) -> Recording:
        """``rec`` with its pose in the model's body frame (:func:`reframe`; unchanged in the pose frame)."""
        return rec if self.frame_weights is None else reframe(rec, self.frame_weights)

    @property
    def has_draws(self) -> bool:
        """Whether the model carries the coefficient covariance :meth:`draw` needs (every part's factor)."""
        return self.chol is not None and (not self.avg_columns or self.chol_avg is not None)

    def draw(self, rng: np.random.Generator) -> FloatArray:
        """Coefficients (p, c) drawn from N(coef, s²_c (XᵀX + λI)⁻¹) per channel.

        XᵀX is the normal matrix the channel was fitted on: the sampling intervals' design for
        most channels, the averaged design W·A for :attr:`avg_columns` (``chol_avg``).
        """
        if not self.has_draws:
            raise SudsConfigError("`draws`: the model carries no coefficient covariance")
        z = rng.standard_normal(self.coef.shape)
        out = self.coef + scipy.linalg.solve_triangular(self.chol, z, lower=True, trans="T") * self.resid_std
        if self.avg_columns:
            cols = list(self.avg_columns)
            out[:, cols] = self.coef[:, cols] + scipy.linalg.solve_triangular(
                self.chol_avg, z[:, cols], lower=True, trans="T") * self.resid_std[cols]
        return out


def _phase_of(ident: Any, rec: Recording) -> FloatArray:
    if ident.config.phase == "truth":
        return np.asarray(rec.truth["phase"], dtype=float)
    return np.asarray(ident.phaser_.transform(rec.r), dtype=float)


def _ridge_factor(xtx: FloatArray, ridge: float) -> tuple[FloatArray | None, float]:
    """(lower Cholesky factor L of XᵀX + λI or None, the fit's effective parameters tr(X(XᵀX + λI)⁻¹Xᵀ)).

    λ = ``ridge``·mean(diag XᵀX), as the regression's own solve has it.  The effective count
    p − λ·tr((XᵀX + λI)⁻¹) = p − λ‖L⁻¹‖²_F is what the residuals' degrees of freedom lose: a
    ridge fit of more coefficients than rows (random shape features on a few cycles) uses far
    fewer than p of them, and counting p would blow the residual variance up (by n where p ≥ n).
    Without a factor (not positive definite) all p count.
    """
    p = xtx.shape[0]
    lam = ridge * (float(np.mean(np.diag(xtx))) or 1.0)
    try:
        chol = np.linalg.cholesky(xtx + lam * np.eye(p))
    except np.linalg.LinAlgError:
        return None, float(p)
    inv = scipy.linalg.solve_triangular(chol, np.eye(p), lower=True, check_finite=False)
    return chol, float(p) - lam * float(np.einsum("ij,ij->", inv, inv))


#: body frames :func:`learn_model` can fit in
FRAMES = ("shape", "pose")


def _shapes_at_pose_stamps(rec: Recording) -> FloatArray:
    """The joint angles (m, nj) linearly interpolated at the pose stamps (held at the ends)."""
    return np.column_stack([np.interp(rec.pose_t, rec.t, rec.r[:, j]) for j in range(rec.r.shape[1])])


def shape_frame(recs: Sequence[Recording]) -> FloatArray:
    """Weights w (nj,) of the body frame whose yaw, the recorded yaw plus r·w, swings least with the shape.

    Least squares over every pose sample of the stretches: the unwrapped recorded yaw on an offset
    and a steady turn per stretch and on −r·w.  The frame keeps the recorded frame's origin and
    turns it by a fixed function of the shape, so it is a body frame like the recorded one: over a
    whole cycle of a periodic gait it moves from the same points and turns by the same angle, and
    every objective (speed, turn, efficiency) is the same in it.  What changes is the share of the
    body velocity the regression must get right: a pose frame on one link of an undulating chain
    (swimmer9's head link yaws by an rms 1 rad) swings with the shape, and the net motion is a
    small difference of large velocities; in this frame it is a larger share of them
    (``docs/results/optimize_step_aim.md``).  The weights come from the data alone (no link
    lengths): least squares finds the combination of joint angles that the recorded yaw follows.
    """
    rows, yaw = [], []
    k = len(recs)
    for i, r in enumerate(recs):
        t = r.pose_t - r.pose_t[0]
        own = np.zeros((t.size, 2 * k))
        own[:, 2 * i], own[:, 2 * i + 1] = 1.0, t
        rows.append(np.concatenate([own, -_shapes_at_pose_stamps(r)], axis=1))
        yaw.append(np.unwrap(r.pose[:, 2]))
    coef, *_ = np.linalg.lstsq(np.concatenate(rows), np.concatenate(yaw), rcond=None)
    return np.asarray(coef[2 * k:], dtype=float)


def reframe(rec: Recording, weights: FloatArray) -> Recording:
    """``rec`` with its pose in the body frame of :func:`shape_frame`'s ``weights``: yaw + r·w (wrapped)."""
    pose = np.array(rec.pose, dtype=float)
    pose[:, 2] = np.angle(np.exp(1j * (pose[:, 2] + _shapes_at_pose_stamps(rec) @ np.asarray(weights))))
    return dataclasses.replace(rec, pose=pose)


def learn_model(rec: Recording | Sequence[Recording], *, torque: bool = False, config: Any = None,
                frame: str = "shape") -> LearnedModel:
    """Fit the SUDS model of a whole recording and keep what the optimiser needs (:class:`LearnedModel`).

    Parameters
    ----------
    rec : Recording or sequence of Recording
        One steady gait (its bouts, if any, are not split: pass a steady recording); or several
        separate stretches, fitted together as the identifier fits bouts (no interval spans two
        stretches; each on its own pose intervals): of one gait, or of gaits close to it (the
        loop's rejected candidates, inside the incumbent's trust region).
    torque : bool
        Also learn the actuator torques (needs ``rec.effort``); required for ``efficiency``.
    config : IdentifyConfig, optional
        The identification settings (default: the shipped model selection).
    frame : str
        The body frame the model is fitted in: ``"shape"`` (default), the recorded yaw turned by
        the combination of joint angles it follows (:func:`shape_frame`, fitted to these
        stretches), or ``"pose"``, the recorded pose frame as it is.

    Raises
    ------
    SudsConfigError
        (code ``unsupported_objective``) ``torque`` without recorded effort; an unknown ``frame``.
    SudsDataError
        (code ``too_little_data``) fewer than 3 gait cycles.
    """
    from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier

    recs = [rec] if isinstance(rec, Recording) else list(rec)
    rec = recs[0]
    if torque and any(r.effort is None for r in recs):
        raise SudsConfigError("efficiency: no learned torque model: the recording has no `effort` on /suds/shape "
                              "(record it, e.g. `suds simulate --effort`); efficiency is unavailable from this data",
                              code=UNSUPPORTED_OBJECTIVE)
    if frame not in FRAMES:
        raise SudsConfigError(f"`frame`: expected one of {list(FRAMES)}, got {frame!r}")
    hz = rec.gait_hz or 1.0
    cycles = float(sum((r.t[-1] - r.t[0] + r.dt) * hz for r in recs))
    if cycles < 3:
        raise SudsDataError(f"`rec`: expected at least 3 gait cycles to learn from, got {cycles:.2f}",
                            code=TOO_LITTLE_DATA)
    weights = shape_frame(recs) if frame == "shape" else None
    if weights is not None:
        recs = [reframe(r, weights) for r in recs]
        rec = recs[0]
    ident = SudsIdentifier(IdentifyConfig() if config is None else config, torque=torque).fit(
        rec if len(recs) == 1 else recs)
    reg = ident.regressor_
    act, pas = np.asarray(rec.actuated_index, dtype=int), np.asarray(rec.passive_index, dtype=int)
    # the data's spread around the template
    deltas, rates = [], []
    for r in recs:
        phase = _phase_of(ident, r)
        deltas.append(r.r - ident.template_.predict(phase))
        mid = 0.5 * (phase[1:] + phase[:-1])
        rates.append(np.diff(r.r, axis=0) / np.diff(r.t)[:, None] - ident.template_.derivative(mid) * ident.omega_)
    delta, rate = np.concatenate(deltas), np.concatenate(rates)
    # the interval the regression maps over: the identifier's shape grid (a recording's median stamp
    # interval is longer than the grid's when many shape samples are lost)
    dt = Grid.of(rec).dt if ident.config.regrids else rec.dt
    # the coefficients' covariance: (XᵀX + λI)⁻¹ per channel, scaled by its residual variance
    # (each part of the fit on its own normal equations: the averaged body channels on W·A)
    factors, resid = [], np.zeros(reg.coef_.shape[1])
    parts = [(reg.normal_, [c for c in range(reg.coef_.shape[1]) if c not in reg.avg_columns_])]
    if reg.normal_avg_ is not None:
        parts.append((reg.normal_avg_, list(reg.avg_columns_)))
    for ne, cols in parts:
        factor, dof = _ridge_factor(ne.xtx, reg.config.ridge)
        factors.append(factor)
        rss = ne.residual_ss(reg.coef_[:, cols])
        resid[cols] = np.sqrt(rss / max(ne.sw, 1.0) * ne.n / max(ne.n - dof, 1.0))
    return LearnedModel(
        system=rec.system, joint_names=rec.joint_names, actuated=rec.actuated, passive=rec.passive, act=act, pas=pas,
        template_order=int(ident.template_.config.order), template_coef=np.asarray(ident.template_.coef_),
        omega=float(ident.omega_), dt=float(dt), gait_hz=float(hz), suds=reg.config,
        kernel_scale=ident.kernel_scale_, coef=np.asarray(reg.coef_), torque=bool(torque), chol=factors[0],
        resid_std=resid, spread_delta=delta[:, act].std(axis=0), spread_rate=rate[:, act].std(axis=0),
        spread_passive=delta[:, pas].std(axis=0), cycles=cycles, identifier=ident, frame_weights=weights,
        avg_columns=tuple(int(c) for c in reg.avg_columns_), chol_avg=factors[1] if len(factors) > 1 else None)


@dataclass(frozen=True)
class MotionMiss:
    """How far a recording's measured body motion lies from the model's prediction along its own shapes.

    The model predicts the body velocity of every sampling interval from the shapes the robot
    actually ran (its perturbations included), so most of what makes a few cycles' speed noisy is
    predicted too: on a robot the model describes, the residual's cycle mean is a few per cent of
    the motion, also for gaits some way off the model's data (``optimize_loop``'s ``model_miss``).

    Attributes
    ----------
    translation : float, |cycle-mean residual of (ξx, ξy)| over |cycle-mean measured (ξx, ξy)|.
    rotation : float, |cycle-mean residual of ξθ| / f, rad per cycle.
    translation_sigmas, rotation_sigmas : float, those cycle means over their standard errors across
        the whole cycles (the translation's along its own direction).
    cycles : int, whole cycles compared.
    per_cycle : (cycles,) float, each cycle's own miss: the larger of its translation residual over the
        mean measured translation and its rotation residual in rad (where in a stretch a change began).
    """

    translation: float
    rotation: float
    translation_sigmas: float
    rotation_sigmas: float
    cycles: int
    per_cycle: FloatArray

    def size(self, sigmas: float = 1.0) -> float:
        """The larger miss (translation fraction, rotation rad/cycle) of those over ``sigmas`` se; 0 if none.

        The default of one standard error keeps noise on a robot that barely moves from counting.
        """
        parts = [m for m, z in ((self.translation, self.translation_sigmas), (self.rotation, self.rotation_sigmas))
                 if z > sigmas]
        return max(parts, default=0.0)


def motion_miss(model: LearnedModel, rec: Recording) -> MotionMiss:
    """Compare ``rec``'s measured body velocity with ``model``'s prediction on its own shapes, cycle by cycle.

    Raises
    ------
    SudsConfigError
        The model carries no identifier.
    SudsDataError
        Fewer than 2 whole gait cycles, or a recording the identifier refuses (other joints).
    """
    if model.identifier is None:
        raise SudsConfigError("`model`: expected a model from learn_model (with its identifier), got one without")
    hz = float(rec.gait_hz or model.gait_hz)
    whole = int(math.floor((rec.t[-1] - rec.t[0]) * hz + 1e-9))
    if whole < 2:
        raise SudsDataError(f"`rec`: expected at least 2 whole gait cycles to compare, got {whole}",
                            code=TOO_LITTLE_DATA)
    pred = model.identifier.predict(model.in_frame(rec))
    k = np.floor((pred.t - rec.t[0]) * hz).astype(int)
    keep = (k >= 0) & (k < whole)
    k = k[keep]
    n = np.bincount(k, minlength=whole).astype(float)
    if np.any(n == 0):
        raise SudsDataError(f"`rec`: a gait cycle without intervals to compare (per cycle: {n.astype(int).tolist()})",
                            code=TOO_LITTLE_DATA)

    def cycle_means(x: FloatArray) -> FloatArray:  # (whole, columns): each column's mean over each cycle
        return np.column_stack([np.bincount(k, x[:, c], whole) for c in range(x.shape[1])]) / n[:, None]

    meas = pred.truth[keep, :3]
    cyc_res = cycle_means(meas - pred.model[keep, :3])
    cyc_meas = cycle_means(meas[:, :2])
    mean_res, v = cyc_res.mean(axis=0), float(np.hypot(*cyc_meas.mean(axis=0)))
    dv = float(np.hypot(mean_res[0], mean_res[1]))
    along = cyc_res[:, :2] @ (mean_res[:2] / dv) if dv > 0 else np.zeros(whole)

    def _z(x: FloatArray) -> float:
        se = float(np.std(x, ddof=1)) / math.sqrt(x.size)
        return abs(float(np.mean(x))) / se if se > 0 else (math.inf if np.mean(x) != 0 else 0.0)

    with np.errstate(divide="ignore", invalid="ignore"):
        per_cycle = np.maximum(np.hypot(cyc_res[:, 0], cyc_res[:, 1]) / v, np.abs(cyc_res[:, 2]) / hz)
    return MotionMiss(translation=dv / v if v > 0 else math.inf, rotation=abs(float(mean_res[2])) / hz,
                      translation_sigmas=_z(along), rotation_sigmas=_z(cyc_res[:, 2]), cycles=whole,
                      per_cycle=np.nan_to_num(per_cycle, nan=math.inf))


class LearnedCycle(PeriodicShooting):
    """One gait cycle of many candidate gaits predicted by a learned SUDS model.

    The model's sampled-data map is applied at its own sample interval (``steps`` = round(1/(f·dt))
    steps of h = 1/(f·steps)): per step the regression row of the interval (state as ``suds.state``
    names it, midpoint phase, mean actuated rate over the step), then r_p += h·ṙ_p, pose ← pose·exp(h·g°),
    work += h·τ_a·ṙ_a.  Candidates are flat vectors of :meth:`Gait.to_vector` at order K.

    Parameters
    ----------
    model : LearnedModel
    gait_hz : float
        Cycle frequency of the candidates, Hz (the phase advances at 2π·f).
    order : int
        Harmonics K of the candidates.
    work : bool
        Also integrate the actuator work (needs ``model.torque``).
    coef : (p, c) array, optional
        Coefficients to predict with instead of ``model.coef`` (a draw).
    """

    def __init__(self, model: LearnedModel, gait_hz: float, order: int, work: bool = False,
                 coef: FloatArray | None = None) -> None:
        if work and not model.torque:
            raise SudsConfigError("efficiency: no learned torque model (the recording has no effort)",
                                  code=UNSUPPORTED_OBJECTIVE)
        self.model, self.gait_hz, self.order, self.with_work = model, float(gait_hz), int(order), work
        self.coef = model.coef if coef is None else np.asarray(coef, dtype=float)
        self.na, self.np = model.act.size, model.pas.size
        self.nj = self.na + self.np
        self.steps = max(8, int(round(1.0 / (self.gait_hz * model.dt))))
        self.h = 1.0 / (self.gait_hz * self.steps)
        t = self.h * np.arange(self.steps + 1)
        w = 2 * np.pi * self.gait_hz * np.arange(1, order + 1)
        th = np.outer(t, w)
        self._basis = np.concatenate([np.ones((t.size, 1)), np.cos(th), np.sin(th)], axis=1)  # (n+1, 2K+1)
        omega = 2 * np.pi * self.gait_hz
        self._phase = omega * (t[:-1] + 0.5 * self.h)  # midpoint phase of each step
        theta, dtheta = model.theta(self._phase)
        self._theta = theta  # (n, nj) at the midpoints
        self._dtheta_a = dtheta[:, model.act] * omega  # (n, na)
        self.cycles_run = 0

    def _outputs(self, i: int, r: FloatArray, rdot_a: FloatArray) -> FloatArray:
        B = r.shape[0]
        m = self.model
        X = regressor_input(np.full(B, self._phase[i]), r - self._theta[i], rdot_a - self._dtheta_a[i], r, rdot_a)
        return regressor_design(m.suds, X, self.na, m.kernel_scale) @ self.coef

    def cycle(self, X: FloatArray, rp0: FloatArray, poses: list[FloatArray] | None = None,
              passive: FloatArray | None = None, passives: list[FloatArray] | None = None
              ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Predict one cycle from r_p(0) = ``rp0`` (B, np) and the identity pose: r_p(T), g_c (B, 3), work (B,).

        ``poses``, if given, receives the pose (B, 3) after every step (``steps`` arrays), as
        :meth:`~suds_ros.core.optimize.physics.CycleEvaluator.cycle` does; ``passives`` likewise
        the passive joints (B, np) after every step.  ``passive``, if given
        ((steps + 1, B, np) rad, at the step times), prescribes the passive shapes instead of
        integrating the model's passive velocity: the model's body motion along shapes it did not
        predict (a measured cycle's, say); ``rp0`` is then ignored and r_p(T) is ``passive[-1]``.

        A model far from its data can blow up within a cycle: numpy's overflow warnings are kept
        quiet, and the non-finite state is refused at the next step by the design's own check
        (``SudsDataError``), which callers treat as no steady state.
        """
        with np.errstate(over="ignore", invalid="ignore"):
            return self._cycle(X, rp0, poses, passive, passives)

    def _cycle(self, X: FloatArray, rp0: FloatArray, poses: list[FloatArray] | None,
               passive: FloatArray | None, passives: list[FloatArray] | None
               ) -> tuple[FloatArray, FloatArray, FloatArray]:
        X = np.atleast_2d(X)
        B, m = X.shape[0], self.model
        coef = X.reshape(B, self.na, 2 * self.order + 1)
        ra = np.einsum("tc,bjc->tbj", self._basis, coef)  # (n+1, B, na)
        if passive is not None:
            passive = np.asarray(passive, dtype=float)
            if passive.shape != (self.steps + 1, B, self.np):
                raise SudsDataError(f"`passive`: expected shape {(self.steps + 1, B, self.np)} (steps + 1, "
                                    f"candidates, passive joints), got {passive.shape}")
            rp0 = passive[0]
        rp = np.array(rp0, dtype=float).reshape(B, self.np)
        pose = np.zeros((B, 3))
        work = np.zeros(B)
        r = np.empty((B, self.nj))
        h, npas = self.h, self.np
        midpoint = m.suds.state == "midpoint"
        for i in range(self.steps):
            rdot_a = (ra[i + 1] - ra[i]) / h
            r[:, m.act] = ra[i]
            r[:, m.pas] = rp
            out = self._outputs(i, r, rdot_a)
            if midpoint:  # the row's state is the interval's midpoint: two fixed-point passes on r_p(end)
                for _ in range(1 if passive is not None else 2):
                    rm = r.copy()
                    rm[:, m.act] = 0.5 * (ra[i] + ra[i + 1])
                    rm[:, m.pas] = (0.5 * (rp + passive[i + 1]) if passive is not None
                                    else rp + 0.5 * h * out[:, 3:3 + npas])
                    out = self._outputs(i, rm, rdot_a)
            rp = passive[i + 1] if passive is not None else rp + h * out[:, 3:3 + npas]
            if passives is not None:
                passives.append(rp)
            pose = se2.exp_step(pose, h * out[:, :3])
            if poses is not None:
                poses.append(pose)
            if self.with_work:
                work = work + h * np.einsum("bj,bj->b", out[:, 3 + npas:3 + npas + self.na], rdot_a)
        self.cycles_run += B
        return rp, pose, (work if self.with_work else np.full(B, np.nan))

    def start_state(self) -> FloatArray:
        """The template's passive joints at phase 0 (1, np): the guess of the steady state."""
        return self.model.theta(np.zeros(1))[0][:, self.model.pas]

    def steady_of(self, x: FloatArray) -> CycleResult:
        """The predicted periodic steady state of one gait vector ``x`` (two plain cycles, then Newton)."""
        rp = self.start_state()
        for _ in range(2):
            rp = self.cycle(x[None], rp)[0]
        return self.steady(x[None], rp)[0]


def align_to_model(model: LearnedModel, gait: Gait, n_shifts: int = 1440) -> Gait:
    """``gait`` shifted in time so that gait time s matches the model's phase 2π·s (least squares on the template).

    The phaser's phase zero is arbitrary; a gait given in the robot's own time (the drive that made
    the recording) is moved onto the model's phase by the shift that brings its actuated joints
    closest to the template θ_a: :func:`~suds_ros.core.physics.gait.time_shifted` by
    :func:`align_shift`.

    Raises
    ------
    SudsConfigError
        A gait of other joints than the model's actuated joints.
    """
    return time_shifted(gait, align_shift(model, gait, n_shifts))


def align_shift(model: LearnedModel, gait: Gait, n_shifts: int = 1440) -> float:
    """The shift s0 in cycles (on a grid of ``n_shifts``) at which ``gait``'s time s0 is the model's phase 0.

    Raises
    ------
    SudsConfigError
        A gait of other joints than the model's actuated joints.
    """
    if tuple(gait.joints) != tuple(model.actuated):
        raise SudsConfigError(f"`gait`: joints {list(gait.joints)} differ from the recording's actuated joints "
                              f"{list(model.actuated)}")
    s = np.arange(256) / 256
    target = model.theta(2 * np.pi * s)[0][:, model.act]  # (256, na)
    shifts = np.arange(n_shifts) / n_shifts
    err = [float(np.sum((gait.at_phase(s + s0) - target) ** 2)) for s0 in shifts]
    return float(shifts[int(np.argmin(err))])


def _centre(model: LearnedModel, t: FloatArray, hz: float,
            centre: Gait | None) -> tuple[FloatArray, FloatArray]:
    """Actuated centre of the trust region and its rate at times t: θ_a(2πft), θ'_a·2πf, or ``centre``'s r, ṙ."""
    if centre is not None:
        return centre.r(t), centre.rdot(t)
    omega = 2 * np.pi * hz
    theta, dtheta = model.theta(omega * t)
    return theta[:, model.act], dtheta[:, model.act] * omega


def trust_bounds(model: LearnedModel, gait: Gait, order: int, trust: float,
                 per_harmonic: int, centre: Gait | None = None) -> tuple[FloatArray, FloatArray]:
    """M (rows, p), b (rows,) with M x ≤ b: |δ_a| ≤ κσ_δ and |δ̇_a| ≤ κσ_δ̇ on the constraint grid.

    δ_a(t) = r_a(t) − θ_a(2π f t) and δ̇_a(t) = ṙ_a(t) − θ'_a·2π f are affine in the gait vector x;
    with ``centre`` (a gait in the model's phase) the offsets are taken from it instead of the template.
    """
    na = len(gait.joints)
    t = constraint_grid(order, gait.gait_hz, per_harmonic)
    omega = 2 * np.pi * gait.gait_hz
    w = omega * np.arange(1, order + 1)
    th = np.outer(t, w)
    A = np.concatenate([np.ones((t.size, 1)), np.cos(th), np.sin(th)], axis=1)
    dA = np.concatenate([np.zeros((t.size, 1)), -np.sin(th) * w, np.cos(th) * w], axis=1)
    mid, dmid = _centre(model, t, gait.gait_hz, centre)
    p = na * (2 * order + 1)
    rows, bounds = [], []
    for j in range(na):
        for basis, centre_j, sd in ((A, mid[:, j], model.spread_delta[j]), (dA, dmid[:, j], model.spread_rate[j])):
            rad = trust * max(float(sd), 1e-9)
            block = np.zeros((t.size, p))
            block[:, j * (2 * order + 1):(j + 1) * (2 * order + 1)] = basis / rad
            rows += [block, -block]
            bounds += [1.0 + centre_j / rad, 1.0 - centre_j / rad]
    return np.concatenate(rows), np.concatenate(bounds)


def trust_used(model: LearnedModel, gait: Gait, centre: Gait | None = None) -> float:
    """Largest |δ_a|/σ_δ or |δ̇_a|/σ_δ̇ of ``gait`` over a 4096-point cycle (in units of the data's spread).

    δ from the template, or from ``centre`` when given (as :func:`trust_bounds`).
    """
    t = np.arange(4096) / (4096 * gait.gait_hz)
    mid, dmid = _centre(model, t, gait.gait_hz, centre)
    d = np.abs(gait.r(t) - mid) / np.maximum(model.spread_delta, 1e-12)
    v = np.abs(gait.rdot(t) - dmid) / np.maximum(model.spread_rate, 1e-12)
    return float(max(d.max(), v.max()))


def recorded_limits(gait: Gait) -> GaitLimits:
    """Joint bounds from the recorded gait itself: its largest |r_j| and |ṙ_j| (no robot given)."""
    r_max, v_max = checked_extremes(gait)
    return GaitLimits(joints=gait.joints, limit=tuple(float(v) for v in r_max),
                      speed_limit=tuple(float(v) for v in v_max))


@dataclass(frozen=True)
class DataOptimizeResult:
    """What :func:`optimize_from_data` proposes.

    Attributes
    ----------
    gait : Gait
        The proposed gait (``objective``, ``predicted`` set), within the bounds.
    recorded : Gait
        The recorded gait it started from (the template, within the bounds).
    value, recorded_value : float
        Predicted objective of each (units of the objective; turn as |rate|).
    value_std, recorded_std, gain_std : float or None
        Their spread over the coefficient draws, and that of value − recorded_value (paired draws).
    values, recorded_values : dict
        Predicted speed, turn, rotation, efficiency, distance of each.
    trust_used : float
        Largest |δ_a|/σ or |δ̇_a|/σ of the proposed gait (≤ ``trust_radius`` up to the constraint grid).
    trust_radius : float
        The radius used: κ, or the start's own distance if that is larger.
    passive_excursion : float
        Largest predicted |δ_p|/σ_δp over the proposed gait's cycle (how far the passive joints
        leave the data; not bounded, reported).
    step_taken : bool
        False when no step was predicted to be better (the recorded gait is returned).
    message : str
        SLSQP's message and notes.
    limits : GaitLimits
    seconds : float
    """

    gait: Gait
    recorded: Gait
    value: float
    recorded_value: float
    value_std: float | None
    recorded_std: float | None
    gain_std: float | None
    values: dict[str, float]
    recorded_values: dict[str, float]
    trust_used: float
    trust_radius: float
    passive_excursion: float
    step_taken: bool
    message: str
    limits: GaitLimits
    seconds: float = 0.0
    draws: list[tuple[float, float]] = field(default_factory=list)


def _value(vals: dict[str, float], objective: str) -> float:
    return abs(vals["turn"]) if objective == "turn" else vals[objective]


def _scalars(res: CycleResult, hz: float) -> dict[str, float]:
    return {k: float(v[0]) for k, v in objective_values(res, hz).items()}


def _passive_excursion(ev: LearnedCycle, x: FloatArray, res: CycleResult) -> float:
    """Largest |δ_p|/σ_δp along the predicted steady cycle of ``x``."""
    m = ev.model
    if ev.np == 0:
        return 0.0
    # re-run the cycle recording r_p at every step
    coef = x.reshape(ev.na, 2 * ev.order + 1)
    ra = ev._basis @ coef.T
    rp = res.r_p[0].copy()
    r = np.empty((1, ev.nj))
    worst = 0.0
    t_theta = m.theta(2 * np.pi * ev.gait_hz * ev.h * np.arange(ev.steps))[0][:, m.pas]
    for i in range(ev.steps):
        worst = max(worst, float(np.max(np.abs(rp - t_theta[i]) / np.maximum(m.spread_passive, 1e-12))))
        r[0, m.act], r[0, m.pas] = ra[i], rp
        out = ev._outputs(i, r, ((ra[i + 1] - ra[i]) / ev.h)[None])
        rp = rp + ev.h * out[0, 3:3 + ev.np]
    return worst


def optimize_from_data(model: LearnedModel, config: DataOptimizeConfig = DataOptimizeConfig(), *,
                       limits: GaitLimits | None = None, gait_hz: float | None = None,
                       start: Gait | None = None) -> DataOptimizeResult:
    """One trust-region step from the recorded gait on the learned model (module docstring).

    Parameters
    ----------
    model : LearnedModel
        From :func:`learn_model`.
    config : DataOptimizeConfig
    limits : GaitLimits, optional
        The robot's joint bounds (:func:`~suds_ros.core.physics.gait.gait_limits`); default: the
        recorded gait's own range and speed (:func:`recorded_limits`).
    gait_hz : float, optional
        Frequency of the proposed gait (default the recording's).
    start : Gait, optional
        The gait that drove the recording, in the robot's time (moved onto the model's phase by
        :func:`align_to_model`); default: the template's actuated part truncated to K harmonics.

    Raises
    ------
    SudsConfigError
        (code ``unsupported_objective``) efficiency without a learned torque model; limits for
        other joints.
    """
    t0 = time.perf_counter()
    cfg = config
    K = cfg.order
    if cfg.objective == "efficiency" and not model.torque:
        raise SudsConfigError("efficiency: no learned torque model: the recording has no `effort` on /suds/shape; "
                              "efficiency is unavailable from this data", code=UNSUPPORTED_OBJECTIVE)
    if start is not None and start.order > K:
        raise SudsConfigError(f"`order`: the start gait has {start.order} harmonics, more than {K}")
    recorded = model.recorded_gait(K) if start is None else align_to_model(model, start)
    recorded = recorded.from_vector(recorded.to_vector(K), K, objective=None, predicted=())
    if gait_hz is not None:
        recorded = Gait(system=recorded.system, gait_hz=gait_hz, joints=recorded.joints, offset=recorded.offset,
                        cos=recorded.cos, sin=recorded.sin)
    limits = recorded_limits(recorded) if limits is None else limits
    if tuple(limits.joints) != tuple(recorded.joints):
        raise SudsConfigError(f"`limits`: joints {list(limits.joints)} differ from the recording's actuated "
                              f"joints {list(recorded.joints)}")
    x0 = recorded.to_vector(K)
    s0 = feasible_scale(recorded, limits)
    if s0 < 1.0:  # the template's estimate may graze a bound the robot's drive sat on
        x0 = x0 * s0 * (1 - 1e-9)
        recorded = recorded.from_vector(x0, K)
    hz = recorded.gait_hz
    ev = LearnedCycle(model, hz, K, work=cfg.objective == "efficiency")
    base = ev.steady_of(x0)
    rec_vals = _scalars(base, hz)
    rec_value = _value(rec_vals, cfg.objective)
    if cfg.objective == "efficiency" and not (np.isfinite(rec_value) and base.work[0] > 0):
        raise SudsConfigError(f"`objective`: efficiency needs a positive predicted actuator work per cycle; the "
                              f"recorded gait's is {base.work[0]!r} J", code=UNSUPPORTED_OBJECTIVE)
    scale = max(abs(rec_value), cfg.max_rotation * hz if cfg.objective == "turn" else 1e-9)
    sign = 1.0 if cfg.objective != "turn" or base.g_c[0, 2] >= 0 else -1.0
    ocfg = OptimizeConfig(objective=cfg.objective, order=K, max_rotation=cfg.max_rotation, fd_step=cfg.fd_step,
                          points_per_harmonic=cfg.points_per_harmonic)
    # no phase pinning: the model is local to the recorded phase
    free = half_wave_free(len(recorded.joints), K) if cfg.half_wave else np.arange(x0.size)

    def embed(z: FloatArray) -> FloatArray:
        x = x0.copy()
        x[free] = z
        return x

    # half-wave: the symmetry keeps the course; the model's rotation may only move as far as the bound
    prob = SteadyStateProblem(ev, ocfg, rec_vals["speed"], scale, sign, base.r_p[0], free,
                              rotation_centre=rec_vals["rotation"] if cfg.half_wave else 0.0)
    M, b = linear_bounds(recorded, K, limits, cfg.points_per_harmonic)
    centre = recorded if cfg.trust_centre == "start" else None
    radius = max(cfg.trust, trust_used(model, recorded, centre) * (1 + 1e-3))  # the region always holds the start
    T, c = trust_bounds(model, recorded, K, radius, cfg.points_per_harmonic, centre)
    L, lb = np.concatenate([M, T]), np.concatenate([b, c])
    Lf = np.ascontiguousarray(L[:, free])
    cons = [{"type": "ineq", "fun": lambda z: lb - L @ embed(z), "jac": lambda z: -Lf},
            {"type": "ineq", "fun": lambda z: prob.values(embed(z))[1:],
             "jac": lambda z: np.ascontiguousarray(prob.grads(embed(z))[:, 1:].T)}]
    best: dict[str, Any] = {}  # the best point SLSQP evaluated that meets every bound: f, x

    def fun(z: FloatArray) -> float:
        x = embed(z)
        v = prob.values(x)
        if v[0] < best.get("f", math.inf) and np.all(v[1:] >= -MARGIN) and np.all(L @ x <= lb + 1e-9):
            best.update(f=float(v[0]), x=x)
        return float(v[0])

    def shortfall(z: FloatArray) -> tuple[float, FloatArray]:
        """How far the side bound is broken (squared) at z, and its gradient."""
        x = embed(z)
        gap = np.maximum(0.0, -MARGIN - prob.values(x)[1:])
        return float(gap @ gap), -2.0 * (np.ascontiguousarray(prob.grads(x)[:, 1:]) @ gap)

    def slsqp(x_from: FloatArray) -> Any:
        return minimize(fun, x_from[free], jac=lambda z: np.ascontiguousarray(prob.grads(embed(z))[:, 0]),
                        method="SLSQP", constraints=cons, options={"maxiter": cfg.maxiter, "ftol": cfg.ftol})

    try:
        sol = slsqp(x0)
        x_end, msg = embed(np.asarray(sol.x)), f"SLSQP: {sol.message} ({sol.nit} iterations)"
        if not sol.success and "x" in best and not np.array_equal(best["x"], x0):
            # it broke down (e.g. its linearised constraints became incompatible) after finding better
            # feasible points: once more from the best of them, else that point itself
            again = slsqp(best["x"])
            x_end = embed(np.asarray(again.x)) if again.success else best["x"]
            msg += (f"; restarted from the best feasible point it visited: {again.message} ({again.nit} "
                    f"iterations){'' if again.success else ', that point taken'}")
        elif not sol.success and np.any(prob.values(x0)[1:] < -MARGIN):
            # it broke down from a start off the straight course without meeting the side bound anywhere
            # (seen on an Intel Xeon: it ended at 17.6 rad for a 1.4 rad range, where an AMD EPYC went on):
            # first back towards the bound inside the joint bounds and the trust region (least squares of
            # the shortfall), then the objective from there, else that point itself
            back = minimize(shortfall, x0[free], jac=True, method="SLSQP", constraints=cons[:1],
                            options={"maxiter": cfg.maxiter, "ftol": 1e-12})
            x_back = embed(np.asarray(back.x))
            if np.all(L @ x_back <= lb + 1e-9) and back.fun < shortfall(x0[free])[0]:
                again = slsqp(x_back)
                x_end = embed(np.asarray(again.x)) if again.success else x_back
                taken = "" if again.success else ", that point taken"
                msg += (f"; back towards the side bound first ({back.message}, {back.nit} iterations), then "
                        f"SLSQP: {again.message} ({again.nit} iterations){taken}")
    except FloatingPointError as exc:
        x_end, msg = x0, f"no step: {exc}"
    # meet the bounds on the fine grid: shorten the step towards the (feasible) start
    alpha = 1.0
    while alpha > 1e-6 and constraint_violations(recorded.from_vector(x0 + alpha * (x_end - x0), K), limits):
        alpha *= 0.8
    if alpha < 1.0:
        msg += f"; step shortened to {alpha:.3g} of its length to meet the bounds"
    x_end = x0 + alpha * (x_end - x0) if alpha > 1e-6 else x0
    vals = prob.values(x_end)
    start_vals = prob.values(x0)
    feasible = bool(np.all(vals[1:] >= -MARGIN))
    start_violation = float(np.sum(np.maximum(0.0, -MARGIN - start_vals[1:])))
    if start_violation > 0:
        # the recorded gait breaks the side bound (e.g. a robot that now curves): back within it first,
        # whatever the objective costs; failing that, any step that breaks it less
        violation = float(np.sum(np.maximum(0.0, -MARGIN - vals[1:])))
        step_taken = feasible or violation < start_violation
        if step_taken:
            msg += (f"; the recorded gait breaks the side bound (violation {start_violation:.3g}): the step "
                    + ("meets it" if feasible else f"breaks it less ({violation:.3g})"))
    else:
        step_taken = feasible and vals[0] < start_vals[0]
    if not step_taken:
        x_end, msg = x0, msg + "; no better gait predicted inside the trust region: the recorded gait is returned"
    res = ev.steady(x_end[None], base.r_p)[0]
    new_vals = _scalars(res, hz)
    value = _value(new_vals, cfg.objective)
    if step_taken and start_violation == 0 and not value > rec_value:
        # the steady state reached from the recorded gait's is not the one the search saw (a learned map
        # may have several): the step is not predicted better after all
        msg += (f"; its steady state from the recorded gait's predicts {value:.4g}, not above the recorded "
                f"{rec_value:.4g}: the recorded gait is returned")
        step_taken, x_end, res, new_vals, value = False, x0, base, rec_vals, rec_value
    # uncertainty: the recorded and proposed gaits under coefficient draws (paired)
    draws: list[tuple[float, float]] = []
    if cfg.draws and model.has_draws:
        rng = np.random.default_rng(cfg.seed)
        for _ in range(cfg.draws):
            ev_d = LearnedCycle(model, hz, K, work=ev.with_work, coef=model.draw(rng))
            try:
                both = ev_d.steady(np.stack([x0, x_end]), np.concatenate([base.r_p, res.r_p]))[0]
            except (FloatingPointError, np.linalg.LinAlgError, SudsDataError):  # (a draw whose cycle blows up)
                continue
            v = objective_values(both, hz)
            pair = (abs(v["turn"]) if cfg.objective == "turn" else v[cfg.objective])
            draws.append((float(pair[0]), float(pair[1])))
    arr = np.asarray(draws) if draws else None
    if step_taken and arr is not None and len(arr) > 1 and cfg.min_gain_sigmas > 0:
        sd = float((arr[:, 1] - arr[:, 0]).std(ddof=1))
        if value - rec_value < cfg.min_gain_sigmas * sd:
            msg += (f"; predicted gain {value - rec_value:.4g} below {cfg.min_gain_sigmas:g} σ ({sd:.3g}) of the "
                    "coefficient draws: the recorded gait is returned")
            step_taken, x_end, res, new_vals, value = False, x0, base, rec_vals, rec_value
            arr = np.stack([arr[:, 0], arr[:, 0]], axis=1)
    proposed = with_predicted(recorded.from_vector(x_end, K), cfg.objective, {cfg.objective: value})
    return DataOptimizeResult(
        gait=proposed, recorded=recorded, value=value, recorded_value=rec_value,
        value_std=None if arr is None else float(arr[:, 1].std(ddof=1)) if len(arr) > 1 else None,
        recorded_std=None if arr is None else float(arr[:, 0].std(ddof=1)) if len(arr) > 1 else None,
        gain_std=None if arr is None else float((arr[:, 1] - arr[:, 0]).std(ddof=1)) if len(arr) > 1 else None,
        values=new_vals, recorded_values=rec_vals, trust_used=trust_used(model, proposed, centre),
        trust_radius=radius,
        passive_excursion=_passive_excursion(ev, x_end, res), step_taken=step_taken, message=msg, limits=limits,
        seconds=time.perf_counter() - t0, draws=draws)
