"""Refining a named effect inside the simulator (output error) with cluster-robust standard errors.

The standard error of a refined parameter has two parts.  The sampling part is the cluster-robust
sandwich over segments (:func:`_sandwich_stderr`).  The misfit part (:func:`misfit_spread`) is
there only when the model being refined is not the robot's: the parameter is then estimated again
from each channel and each quarter of the gait cycle alone, and when those estimates disagree
more than their own noise allows, their spread is what the data say about the parameter.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.stats

from suds_ros.core._typing import FloatArray, IntArray
from suds_ros.core.diagnosis.data import Data
from suds_ros.core.diagnosis.floor import Floors
from suds_ros.core.diagnosis.lsq import fd_jacobian, with_jacobian
from suds_ros.core.diagnosis.naming import Candidate
from suds_ros.core.diagnosis.replay import Replay, replay, window_xi
from suds_ros.core.diagnosis.report import DiagnoseConfig, FittedEffect, effect_label
from suds_ros.core.errors import SudsConfigError, SudsSimulationError
from suds_ros.core.parallel import fork_map
from suds_ros.core.physics.effects import EFFECTS, ParamSpec, apply_effects
from suds_ros.core.physics.rft import ChainModel
from suds_ros.core.resample import window_any


@dataclass(frozen=True)
class Refined:
    """A set of effects refined in the simulator.

    ``se`` is the sampling standard error, ``spread`` the misfit spread (zero where the channels
    and gait phases agree, :func:`misfit_spread`) and ``misfit_p`` the p-value of that agreement,
    per parameter in canonical order.  ``dropped`` labels the members dropped as neutral.
    """

    cand: Candidate
    x: FloatArray
    se: FloatArray
    spread: FloatArray
    misfit_p: FloatArray
    dropped: tuple[str, ...] = ()

    @property
    def stderr(self) -> FloatArray:
        """The reported standard error: the sampling error and the misfit spread in quadrature."""
        return np.hypot(self.se, self.spread)


def refine_choice(
    cand: Candidate, x0: FloatArray, model: ChainModel, data: Data, config: DiagnoseConfig,
    w: int, substeps: int, floors: Floors,
) -> Refined:
    """Refine the chosen set in the simulator.

    After refining a set of several effects, the members whose parameters all lie within
    ``config.member_z`` reported standard errors (:attr:`Refined.stderr`, the misfit spread
    included) of their neutral values are dropped and the others are refined again (nothing is
    dropped when no member would remain).  Where the channels and gait phases disagree, a value
    that their spread cannot tell from neutral is not a finding: a sensor time offset of
    -0.1 ± 0.14 ms beside a pose-frame offset is the frame offset's misfit, not a second effect.
    """
    first = _refine(cand, x0, model, data, config, w, substeps, floors)
    x, err = first.x, first.stderr
    if len(cand.parts) < 2:
        return first
    keep, drop = [], []
    neutral = cand.neutral(model)
    for part, sl in zip(cand.parts, cand.slices()):
        if is_neutral(x[sl], err[sl], neutral[sl], config.member_z):
            drop.append(effect_label(*part))
        else:
            keep.append((part, sl))
    if not keep or not drop:
        return first
    sub = Candidate(tuple(part for part, _ in keep))
    x_sub = np.concatenate([x[sl] for _, sl in keep])
    again = _refine(sub, x_sub, model, data, config, w, substeps, floors)
    return Refined(sub, again.x, again.se, again.spread, again.misfit_p, tuple(drop))


def is_neutral(x: FloatArray, se: FloatArray, neutral: FloatArray, z: float) -> bool:
    """Whether every parameter ``x`` lies within ``z`` standard errors ``se`` of its ``neutral`` value.

    An undefined (NaN) or zero standard error never makes a parameter neutral: an effect is not
    set aside on a fit that cannot say how well it knows it.
    """
    x, se, neutral = (np.asarray(a, dtype=float) for a in (x, se, neutral))
    return bool(np.all(np.isfinite(se) & (np.abs(x - neutral) < z * se)))


def fitted_effects(
    cand: Candidate, x: FloatArray, se: FloatArray, evidence: Mapping[str, float] | None = None
) -> list[FittedEffect]:
    """The candidate's effects with parameters ``x``, standard errors ``se`` and ``evidence``.

    ``x`` and ``se`` are in canonical order; ``evidence`` is by member label, in nats.
    """
    out: list[FittedEffect] = []
    ev = evidence or {}
    for (nme, tgt), sl in zip(cand.parts, cand.slices()):
        specs = EFFECTS[nme].params
        bound = {p.name: end for p, v in zip(specs, x[sl]) for end in [at_bound(p, float(v))] if end}
        out.append(FittedEffect(
            nme, tgt,
            {p.name: float(v) for p, v in zip(specs, x[sl])},
            {p.name: math.nan if p.name in bound else float(v) for p, v in zip(specs, se[sl])},
            ev.get(effect_label(nme, tgt)),
            at_bound=bound,
        ))
    return out


#: a fitted value this close to an end of its range (relative to the parameter's scale) sits on it
BOUND_TOL = 1e-6


def at_bound(spec: ParamSpec, value: float) -> str | None:
    """``"lower"`` or ``"upper"`` when ``value`` sits on that finite end of ``spec``'s range, else None."""
    tol = BOUND_TOL * max(spec.scale, abs(value))
    if math.isfinite(spec.upper) and value >= spec.upper - tol:
        return "upper"
    if math.isfinite(spec.lower) and value <= spec.lower + tol:
        return "lower"
    return None


def _segments(lo: int, hi: int, length: int) -> list[int]:
    """Starts of consecutive whole segments of ``length`` samples in [lo, hi)."""
    return list(range(lo, hi - length + 1, length))


def _residual_vector(
    data: Data, rep: Replay, starts: Sequence[int], length: int, w: int, sig_rp: FloatArray, s_xy: float, s_th: float
) -> FloatArray:
    """Noise-floor-weighted replay residuals, (B, k): r_p per sample, ξ on non-overlapping windows.

    Samples at or after a gap of a stream (:attr:`Data.shape_gap`, :attr:`Data.pose_gap`), and
    windows that touch one, count as zero: there the recording is interpolated across a lost kink.
    """
    idx = np.asarray(starts)[:, None] + np.arange(length)[None, :]
    e_rp = (data.r[idx][:, :, data.pas] - rep.rp) / (sig_rp * np.sqrt(data.rp_noise_power))
    xi_rec = window_xi(data.pose[idx], w, data.dt)
    e_xi = (xi_rec - rep.xi) / np.array([s_xy, s_xy, s_th])
    if data.shape_gap is not None and data.pose_gap is not None:
        sg = data.shape_gap[idx]
        e_rp = np.where(sg[..., None], 0.0, e_rp)
        touches = window_any(sg | data.pose_gap[idx], w)  # window k spans samples k … k + w
        e_xi = np.where(touches[:, : e_xi.shape[1], None], 0.0, e_xi)
    e_xi = e_xi[:, ::w]
    e_xi = np.where(np.isfinite(e_xi), e_xi, 0.0)
    B = len(starts)
    return np.concatenate([e_rp.reshape(B, -1), e_xi.reshape(B, -1)], axis=1)


def _residual_parts(data: Data, length: int, w: int, k: int, quarters: int = 4) -> IntArray:
    """The part of the data each of a segment's ``k`` residuals (:func:`_residual_vector`) belongs to.

    A part is one channel (a passive angle, or x, y or θ of the body velocity) in one quarter of
    the gait cycle; parts are numbered channel × ``quarters`` + quarter.
    """
    n_p = data.pas.size
    n_rp = length * n_p
    t_rp = np.arange(n_rp) // max(n_p, 1)  # r_p is sample-major
    ch_rp = np.arange(n_rp) % max(n_p, 1)
    m = np.arange(k - n_rp)  # ξ: window-major, (x, y, θ) per window, one window per w samples
    t_xi = (m // 3) * w + w // 2
    ch_xi = n_p + m % 3
    t = np.concatenate([t_rp, t_xi])
    ch = np.concatenate([ch_rp, ch_xi])
    quarter = np.minimum((t % data.spc) * quarters // data.spc, quarters - 1)
    return (ch * quarters + quarter).astype(np.int64)


def _training_segments(data: Data, cfg: DiagnoseConfig) -> tuple[list[int], int]:
    """Starts and length of the training segments the refinement replays (at most ``refine_cycles``)."""
    length = cfg.segment_cycles * data.spc
    starts = _segments(0, data.n_train, length)
    if not starts:
        starts, length = [0], data.n_train
    max_seg = max(1, cfg.refine_cycles // cfg.segment_cycles)
    if len(starts) > max_seg:  # spread a subset over the training half
        pick = np.unique(np.round(np.linspace(0, len(starts) - 1, max_seg)).astype(int))
        starts = [starts[i] for i in pick]
    return starts, length


def _replay_residuals(
    cand: Candidate, x: FloatArray, base: ChainModel, data: Data, starts: Sequence[int], length: int, w: int,
    substeps: int, floors: Floors,
) -> FloatArray:
    """The weighted replay residuals of ``cand`` at ``x`` on the segments (:func:`_residual_vector`)."""
    model, delay = apply_effects(base, cand.effects(x))
    rep = replay(model, delay, data, starts, length, w, substeps)
    return _residual_vector(data, rep, starts, length, w, *floors)


def extension_gains(
    cand: Candidate, x: FloatArray, parts: Sequence[tuple[str, str | None]], model: ChainModel, data: Data,
    config: DiagnoseConfig, w: int, substeps: int, floors: Floors,
) -> list[float]:
    """Per part, what adding it to ``cand`` (fitted at ``x``) would gain in output error, to first order, nats.

    A score test on the refinement's training segments: with r the weighted replay residuals at
    ``x`` and j the part's column (forward difference from its neutral value) made orthogonal to
    the set's own columns, the linearised fit of the part and the set together removes
    (j'r)²/(j'j) of r'r, i.e. half that in log-likelihood.  One replay per parameter of each part
    and of the set, where refining each part would cost a least-squares run.
    """
    starts, length = _training_segments(data, config)

    def residuals(c: Candidate, head: FloatArray) -> Callable[[FloatArray], FloatArray]:
        """``c``'s replay residuals as a function of its parameters after ``head``."""
        return lambda z: _replay_residuals(c, np.concatenate([head, z]), model, data, starts, length, w,
                                           substeps, floors).ravel()

    r0 = residuals(cand, x[:0])(x)
    own = fd_jacobian(residuals(cand, x[:0]), x, r0, np.maximum(1e-3 * np.abs(x), 1e-2 * cand.scales()),
                      np.asarray(cand.bounds()[1], dtype=float), parallel=True)
    Q = np.linalg.qr(own)[0]

    def columns(part: tuple[str, str | None]) -> FloatArray | None:
        """The part's columns, forward differences from its neutral value (None: it cannot be replayed)."""
        c = Candidate(cand.parts + (part,))
        try:
            return fd_jacobian(residuals(c, x), c.neutral(model)[x.size:], r0, 1e-2 * c.scales()[x.size:],
                               np.asarray(c.bounds()[1][x.size:], dtype=float))
        except _TRIAL_FAILURES:
            return None

    out = []
    for J in fork_map(columns, parts):
        if J is None:
            out.append(-np.inf)
            continue
        J = J - Q @ (Q.T @ J)
        g = J.T @ r0
        drop = float(g @ np.linalg.lstsq(J.T @ J, g, rcond=None)[0]) if np.all(np.isfinite(J)) else -np.inf
        out.append(0.5 * drop)
    return out


def _refine(
    cand: Candidate,
    x0: FloatArray,
    base: ChainModel,
    data: Data,
    cfg: DiagnoseConfig,
    w: int,
    substeps: int,
    floors: Floors,
) -> Refined:
    """Output-error least squares of the candidate's parameters, with their standard errors."""
    starts, length = _training_segments(data, cfg)
    lo, hi = (np.asarray(b, dtype=float) for b in cand.bounds())
    scales = cand.scales()

    def sim(x: FloatArray) -> FloatArray:
        return _replay_residuals(cand, x, base, data, starts, length, w, substeps, floors)

    def fun(x: FloatArray) -> FloatArray:
        try:
            return sim(x).ravel()
        except _TRIAL_FAILURES:
            return np.full(n_res, 1e6)

    x0 = np.clip(x0, lo + 1e-3 * scales, hi - 1e-3 * scales)  # off the bounds (see Scorer.fit)
    x0, r0 = _replayable_start(sim, x0, np.clip(cand.neutral(base), lo, hi))
    n_res = r0.size
    c0 = float(np.sum(r0**2))
    value, jac = with_jacobian(fun, 1e-3, 1e-2 * scales, hi, parallel=True)
    sol = scipy.optimize.least_squares(
        value, x0, jac=jac, bounds=(lo, hi), x_scale=scales,
        max_nfev=cfg.refine_nfev * (x0.size + 1), method="trf",
    )
    if sol.cost * 2 <= c0 and sol.jac is not None and np.all(np.isfinite(sol.jac)):
        # least_squares leaves the (forward-difference) Jacobian and the residuals at its solution
        x, R, J = sol.x, np.asarray(sol.fun).reshape(r0.shape), np.asarray(sol.jac)
    else:
        x, R = x0, r0
        J = fd_jacobian(fun, x, R, np.maximum(1e-3 * np.abs(x), 1e-2 * scales), hi, parallel=True)
    spread, p_value = misfit_spread(J, R, _residual_parts(data, length, w, R.shape[1]), cfg.misfit_alpha)
    return Refined(cand, x, _sandwich_stderr(J, R, x.size), spread, p_value)


#: what a trial point's replay can raise: it then counts as a bad fit (the refinement) or as no gain (extensions)
_TRIAL_FAILURES = (FloatingPointError, np.linalg.LinAlgError, SudsConfigError, SudsSimulationError)
#: fractions of the way from the neutral parameters to the equation-error start tried, in order
START_SHRINK = (1.0, 0.5, 0.25, 0.125, 0.0)


def _replayable_start(sim: Callable[[FloatArray], FloatArray], x0: FloatArray,
                      neutral: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The first start towards ``neutral`` whose replay stays finite, with its residuals.

    The equation-error fit's parameters can make the simulated motion diverge (a softening
    spring, k3 < 0, fitted where the joint only reached small angles, pushes it away once the
    replay carries it further): the start is moved towards the neutral parameters, which replay
    the nominal model, by :data:`START_SHRINK`.  The last failure is raised when none replays.
    """
    for frac in START_SHRINK[:-1]:
        x = neutral + frac * (x0 - neutral)
        try:
            return x, sim(x)
        except SudsSimulationError:
            continue
    x = neutral + START_SHRINK[-1] * (x0 - neutral)
    return x, sim(x)


def _sandwich_stderr(J: FloatArray, R: FloatArray, p: int) -> FloatArray:
    """Standard errors of a least-squares fit with residuals clustered by segment.

    J (B·k, p) Jacobian, R (B, k) residuals (B clusters = independent segments).  The
    cluster-robust sandwich (J'J)⁻¹ (Σ_b g_b g_b') (J'J)⁻¹, g_b = J_b' R_b, is biased low with few
    clusters; it gets the CR1 factor B/(B − p) and the ratio of the t quantile with B − p degrees of
    freedom to the normal one (so ±2 se keeps roughly its nominal coverage with few clusters).  The
    larger of that and the model-based error (J'J)⁻¹·s², s² the residual variance with the
    segment-level autocorrelation taken into account through the cluster totals, is reported.
    """
    B = R.shape[0]
    JtJ = J.T @ J
    try:
        inv = np.linalg.inv(JtJ)
    except np.linalg.LinAlgError:
        return np.full(p, np.nan)
    Jb = J.reshape(B, -1, p)
    Rb = R.reshape(B, -1)
    G = np.einsum("bkp,bk->bp", Jb, Rb)
    meat = G.T @ G
    dof = max(B - p, 1)
    cov = inv @ meat @ inv * B / dof
    tfac = float(scipy.stats.t.ppf(0.975, dof) / scipy.stats.norm.ppf(0.975))
    se_sand = np.sqrt(np.maximum(np.diag(cov), 0.0)) * tfac
    s2 = float(np.sum(Rb**2)) / max(Rb.size - p, 1)
    se_model = np.sqrt(np.maximum(np.diag(inv), 0.0) * s2)
    return np.maximum(se_sand, se_model)


def misfit_spread(J: FloatArray, R: FloatArray, parts: IntArray, alpha: float) -> tuple[FloatArray, FloatArray]:
    """Per parameter, the spread of its estimates from the parts of the data, when they disagree.

    J (B·k, p) Jacobian and R (B, k) residuals at the fit, over B segments (clusters); ``parts``
    (k,) labels each residual of a segment with a part of the data (:func:`_residual_parts`).

    For parameter i, the column of J is first made orthogonal to the other parameters' columns
    (so each part's estimate moves parameter i alone, the others held at their fit).  Part s then
    gives the one-step estimate Δ_s = g_s / a_s, g_s = Σ_b j_sb'R_sb, a_s = j_s'j_s, with the
    cluster-robust variance v_s = B·var_b(j_sb'R_sb) / a_s².  When the model is right the Δ_s
    scatter about zero as v_s says; their agreement is tested by Σ z_s² against χ² with S − 1
    degrees of freedom (z_s the Student t statistic Δ_s/√v_s with B − 1 degrees of freedom, turned
    into a normal score).  Where the test rejects at ``alpha``, the spread is the
    DerSimonian–Laird between-part standard deviation τ (the spread beyond the noise); else 0.

    The spread is not divided by √S: an error the model lacks biases every part alike, and the
    disagreement between parts is the only measure of it the data give.  Returns (spread, p).
    """
    B, k = R.shape
    p = J.shape[1]
    spread, pval = np.zeros(p), np.ones(p)
    if B < 3:
        return spread, pval
    labels = np.unique(parts)
    member = (parts[None, :] == labels[:, None]).astype(float)  # (S, k) indicator of each part
    for i in range(p):
        col = J[:, i]
        others = np.delete(J, i, axis=1)
        if others.size:
            col = col - others @ np.linalg.lstsq(others, col, rcond=None)[0]
        jb = col.reshape(B, k)
        a = member @ np.sum(jb**2, axis=0)  # (S,)
        gb = (jb * R) @ member.T  # (B, S) per segment and part
        use = a > 1e-9 * a.sum()
        if np.count_nonzero(use) < 3:
            continue
        a, gb = a[use], gb[:, use]
        delta = gb.sum(axis=0) / a
        var = B * np.var(gb, axis=0, ddof=1) / a**2
        if not np.all(var > 0):
            continue
        t_stat = delta / np.sqrt(var)
        z = scipy.stats.norm.isf(scipy.stats.t.sf(np.abs(t_stat), B - 1))
        dof = delta.size - 1
        pval[i] = float(scipy.stats.chi2.sf(np.sum(z**2), dof))
        if pval[i] >= alpha:
            continue
        wt = 1.0 / var
        mean = np.sum(wt * delta) / wt.sum()
        q = float(np.sum(wt * (delta - mean) ** 2))
        tau2 = (q - dof) / (wt.sum() - np.sum(wt**2) / wt.sum())
        spread[i] = float(np.sqrt(max(tau2, 0.0)))
    return spread, pval
