"""Refining a named effect inside the simulator (output error) with cluster-robust standard errors."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
import scipy.optimize
import scipy.stats

from suds_ros.core._typing import FloatArray
from suds_ros.core.diagnosis.data import Data
from suds_ros.core.diagnosis.floor import Floors
from suds_ros.core.diagnosis.lsq import fd_jacobian, with_jacobian
from suds_ros.core.diagnosis.naming import Candidate
from suds_ros.core.diagnosis.replay import Replay, replay, window_xi
from suds_ros.core.diagnosis.report import DiagnoseConfig, FittedEffect, effect_label
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.parallel import fork_map
from suds_ros.core.physics.effects import EFFECTS, apply_effects
from suds_ros.core.physics.rft import ChainModel


def refine_choice(
    cand: Candidate, x0: FloatArray, model: ChainModel, data: Data, config: DiagnoseConfig,
    w: int, substeps: int, floors: Floors,
) -> tuple[Candidate, FloatArray, FloatArray, tuple[str, ...]]:
    """Refine the chosen set in the simulator; returns (candidate, x, stderr, labels of dropped members).

    After refining a set of several effects, the members whose parameters all lie within
    ``config.member_z`` standard errors of their neutral values are dropped and the others are
    refined again (nothing is dropped when no member would remain).
    """
    x, se = _refine(cand, x0, model, data, config, w, substeps, floors)
    if len(cand.parts) < 2:
        return cand, x, se, ()
    keep, drop, i = [], [], 0
    neutral = cand.neutral(model)
    for k, (nme, tgt) in enumerate(cand.parts):
        npar = len(EFFECTS[nme].params)
        z = np.abs(x[i:i + npar] - neutral[i:i + npar]) / np.maximum(se[i:i + npar], 1e-300)
        if np.nanmax(z) >= config.member_z:
            keep.append((k, i, npar))
        else:
            drop.append(effect_label(nme, tgt))
        i += npar
    if not keep or not drop:
        return cand, x, se, ()
    sub = Candidate(tuple(cand.parts[k] for k, _, _ in keep))
    x_sub = np.concatenate([x[i:i + npar] for _, i, npar in keep])
    x, se = _refine(sub, x_sub, model, data, config, w, substeps, floors)
    return sub, x, se, tuple(drop)


def fitted_effects(
    cand: Candidate, x: FloatArray, se: FloatArray, evidence: Mapping[str, float] | None = None
) -> list[FittedEffect]:
    """The candidate's effects with parameters ``x``, standard errors ``se`` and ``evidence``.

    ``x`` and ``se`` are in canonical order; ``evidence`` is by member label, in nats.
    """
    out: list[FittedEffect] = []
    i = 0
    ev = evidence or {}
    for nme, tgt in cand.parts:
        pn = EFFECTS[nme].param_names
        out.append(FittedEffect(
            nme, tgt,
            {p: float(x[i + k]) for k, p in enumerate(pn)},
            {p: float(se[i + k]) for k, p in enumerate(pn)},
            ev.get(effect_label(nme, tgt)),
        ))
        i += len(pn)
    return out


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
    e_rp = (data.r[idx][:, :, data.pas] - rep.rp) / sig_rp
    xi_rec = window_xi(data.pose[idx], w, data.dt)
    e_xi = (xi_rec - rep.xi) / np.array([s_xy, s_xy, s_th])
    if data.shape_gap is not None and data.pose_gap is not None:
        sg = data.shape_gap[idx]
        e_rp = np.where(sg[..., None], 0.0, e_rp)
        bad = np.concatenate([np.zeros((idx.shape[0], 1)), np.cumsum(sg | data.pose_gap[idx], axis=1)], axis=1)
        touches = (bad[:, w + 1:] - bad[:, : bad.shape[1] - w - 1]) > 0  # window k spans samples k … k + w
        e_xi = np.where(touches[:, : e_xi.shape[1], None], 0.0, e_xi)
    e_xi = e_xi[:, ::w]
    e_xi = np.where(np.isfinite(e_xi), e_xi, 0.0)
    B = len(starts)
    return np.concatenate([e_rp.reshape(B, -1), e_xi.reshape(B, -1)], axis=1)


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
        except (FloatingPointError, np.linalg.LinAlgError, SudsConfigError):
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
) -> tuple[FloatArray, FloatArray]:
    """Output-error least squares of the candidate's parameters; returns (x, stderr)."""
    starts, length = _training_segments(data, cfg)
    lo, hi = (np.asarray(b, dtype=float) for b in cand.bounds())
    scales = cand.scales()

    def sim(x: FloatArray) -> FloatArray:
        return _replay_residuals(cand, x, base, data, starts, length, w, substeps, floors)

    def fun(x: FloatArray) -> FloatArray:
        try:
            return sim(x).ravel()
        except (FloatingPointError, np.linalg.LinAlgError, SudsConfigError):
            return np.full(n_res, 1e6)

    x0 = np.clip(x0, lo + 1e-3 * scales, hi - 1e-3 * scales)  # off the bounds (see Scorer.fit)
    r0 = sim(x0)
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
    return x, _sandwich_stderr(J, R, x.size)


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
