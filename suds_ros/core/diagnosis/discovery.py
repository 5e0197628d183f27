"""Discovery: a candidate formula for a passive-joint torque no catalogue effect explains.

The equation-error residual of passive joint j (:class:`~suds_ros.core.diagnosis.naming.Scorer`,
after the named effects, if any) is the torque missing from its balance: with an extra torque τ_x
the balance −(D q̇)_j + τ_spring + τ_x = 0 leaves the residual (D q̇)_j − τ_spring = τ_x.  It is
regressed per joint on a library of physically meaningful terms (e = r_j − rest_j, ṙ = ṙ_j):

    1, e, e², e³, ṙ, sign(ṙ), |ṙ|ṙ, e·ṙ, and the actuated angles r_a and rates ṙ_a

by forward selection with a backward check (:func:`_select`): the training residual orders the
terms (columns standardised), and a set is kept if its held-out log-likelihood gain, minus the BIC
penalty ½·log n per term, exceeds ``config.evidence_threshold`` per term, each member earning that
much on its own account; residual and terms are averaged over
non-overlapping blocks of ``config.eq_window`` intervals first (the same evidence rule as the effect selection).
Coefficients and their standard errors come from ordinary least squares on the training half
(units: N·m per unit of the term).  The terms are built from each interval's own samples, as the
residual is (:func:`_library` says why and what that costs).
Recognisable terms get physics words.  Each formula carries the held-out fraction of the joint's
residual power it removes; the pipeline then re-simulates the formulas inside the simulator
(:mod:`.resimulate`) and reports the held-out improvement of that replay.  The report keeps
``unexplained`` (the physics is outside the catalogue and the model).
"""

from __future__ import annotations

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.diagnosis.data import Data
from suds_ros.core.diagnosis.naming import Candidate, Scorer, equation_terms
from suds_ros.core.diagnosis.report import DiagnoseConfig, Discovered
from suds_ros.core.physics.rft import ChainModel

#: physics words for the recognisable library terms (sign: the torque the term adds, on r_j)
PHYSICS = {
    "1": "rest offset (constant torque)",
    "e": "spring constant error (linear spring)",
    "e^2": "asymmetric spring (quadratic)",
    "e^3": "cubic spring (hardening if its coefficient is negative)",
    "rdot": "viscous damping",
    "sign(rdot)": "dry (Coulomb) friction",
    "|rdot|rdot": "quadratic (form) drag",
    "e*rdot": "angle-dependent damping",
}
MAX_TERMS = 4


def _library(eq: object, j: int, rest: float, act_names: list[str]) -> tuple[list[str], FloatArray]:
    """Term names and columns (nint, m) for the passive joint at rank ``j`` of an equation-error half.

    The terms are built from each interval's own samples, as the residual is: midpoint shape r̄ and
    rate ṙ = Δr/Δt.  A passive joint's rate can change within a few samples (the stiff passive
    modes relax in about one sample period), so terms taken from any other samples would not
    describe the interval's torque (with the neighbours k−1, k+2 a pure |ṙ|ṙ torque kept only
    ≈ 57 % of its power per interval).  The noise shared with the residual (the rate's noise enters
    both through (D q̇)_j) biases a coefficient by about D_jj·σ²(ṙ)/var(ṙ) and adds evidence of
    order ½·n·σ²(ṙ)/var(ṙ) after the block means: a few nats on 60-cycle nulls, far below the
    threshold (measured: ≤ 9 nats on purcell3 and swimmer9 nulls).
    """
    rbar, rdot = eq.rbar, eq.rdot  # type: ignore[attr-defined]
    pas, act = eq.pas, eq.act  # type: ignore[attr-defined]
    e = rbar[:, pas[j]] - rest
    v = rdot[:, pas[j]]
    cols = {
        "1": np.ones_like(e), "e": e, "e^2": e**2, "e^3": e**3, "rdot": v, "sign(rdot)": np.sign(v),
        "|rdot|rdot": np.abs(v) * v, "e*rdot": e * v,
    }
    for k, a in enumerate(act):
        cols[f"r({act_names[k]})"] = rbar[:, a]
        cols[f"rdot({act_names[k]})"] = rdot[:, a]
    return list(cols), np.stack(list(cols.values()), axis=1)


def _blocks(x: FloatArray, w: int) -> FloatArray:
    """Means over consecutive non-overlapping blocks of ``w`` rows.

    The drag torque's rate noise telescopes in the mean, so the residual's noise drops about w-fold.
    """
    n = (x.shape[0] // w) * w
    return x[:n].reshape(n // w, w, *x.shape[1:]).mean(axis=1)


def _select(X: FloatArray, y: FloatArray, Xt: FloatArray, yt: FloatArray, threshold: float) -> list[int]:
    """Columns chosen by forward selection along the training path, then a backward check.

    The forward path adds, up to ``MAX_TERMS``, the column that lowers the training residual most.
    Its prefix with the largest held-out evidence beyond ``threshold`` per term is kept (the
    evidence of a set S: ½·n·log(RSS_∅ / RSS_S) − |S|·½·log n on the held-out blocks), so a term
    that earns little alone but much with the next one is not lost: after a fitted viscous damping,
    a quadratic drag leaves −c·|ṙ|ṙ + d·ṙ, where neither term alone removes much.  The backward
    check then drops, one at a time, a kept term whose removal costs less than ``threshold``.
    """
    sd = X.std(axis=0)
    mu = X.mean(axis=0)
    mu[sd == 0] = 0.0  # keep the constant column
    sd[sd == 0] = 1.0
    Z, Zt = (X - mu) / sd, (Xt - mu) / sd
    n_t = yt.size
    pen = 0.5 * np.log(max(n_t, 2))
    rss_0 = max(float(np.sum(yt**2)), 1e-300)

    def evidence(cols: list[int]) -> float:
        if not cols:
            return 0.0
        coef = np.linalg.lstsq(Z[:, cols], y, rcond=None)[0]
        rss = float(np.sum((yt - Zt[:, cols] @ coef) ** 2))
        return 0.5 * n_t * np.log(rss_0 / max(rss, 1e-300)) - len(cols) * pen

    path: list[int] = []
    for _ in range(min(MAX_TERMS, X.shape[1])):
        rss = {c: float(np.sum((y - Z[:, path + [c]] @ np.linalg.lstsq(Z[:, path + [c]], y, rcond=None)[0]) ** 2))
               for c in range(X.shape[1]) if c not in path}
        path.append(min(rss, key=rss.__getitem__))
    scores = [evidence(path[:k]) - k * threshold for k in range(len(path) + 1)]
    chosen = path[:int(np.argmax(scores))]
    while chosen:
        base = evidence(chosen)
        loss = {c: base - evidence([d for d in chosen if d != c]) for c in chosen}
        weakest = min(loss, key=loss.__getitem__)
        if loss[weakest] >= threshold:
            break
        chosen.remove(weakest)
    return chosen


def discover(
    data: Data, model: ChainModel, config: DiagnoseConfig, sig_rp: FloatArray,
    cand: Candidate = Candidate(()), x: FloatArray | None = None,
) -> tuple[Discovered, ...]:
    """Candidate formulas for the torque missing from each passive joint (module docstring).

    None on a fully actuated chain: with no passive joint there is no torque balance to complete.
    """
    if data.pas.size == 0:
        return ()
    scorer = Scorer(data, model, config.eq_window, sig_rp)
    p = equation_terms(cand, np.zeros(0) if x is None else np.asarray(x, dtype=float), data, model)
    # with a named Coulomb friction on a joint, its intervals that may be stuck carry any torque in
    # [−mu, mu]: they are left out of that joint's rows (residual and terms zeroed, see below)
    thr = np.where(np.asarray(p.mu) != 0.0, scorer.rdot_thr, 0.0)
    y_tr, _ = scorer.train.residuals(p, thr)
    y_te, _ = scorer.test.residuals(p, thr)
    # the rows the residuals kept; zeroed rows add 0 = 0·β to a block mean, so the means stay consistent
    kept_tr = (np.abs(scorer.train.rdot_p) > thr) & scorer.train.measured[:, None]
    kept_te = (np.abs(scorer.test.rdot_p) > thr) & scorer.test.measured[:, None]
    rest = np.asarray(model.rest)[data.pas] + p.offset
    act_names = [data.names[a] for a in data.act]
    out = []
    for j, jp in enumerate(data.pas):
        names, X = _library(scorer.train, j, float(rest[j]), act_names)
        _, Xt = _library(scorer.test, j, float(rest[j]), act_names)
        X, Xt = X * kept_tr[:, j:j + 1], Xt * kept_te[:, j:j + 1]
        w = config.eq_window
        X, Xt = _blocks(X, w), _blocks(Xt, w)
        y, yt = _blocks(y_tr[:, j], w), _blocks(y_te[:, j], w)
        chosen = _select(X, y, Xt, yt, config.evidence_threshold)
        if not chosen:
            continue
        A, At = X[:, chosen], Xt[:, chosen]
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        res = y - A @ coef
        s2 = float(res @ res) / max(y.size - len(chosen), 1)
        cov = s2 * np.linalg.pinv(A.T @ A)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        red = 1.0 - float(np.sum((yt - At @ coef) ** 2)) / max(float(np.sum(yt**2)), 1e-300)
        terms = {names[c]: float(v) for c, v in zip(chosen, coef)}
        out.append(Discovered(
            joint=data.names[jp], terms=terms, stderr={names[c]: float(v) for c, v in zip(chosen, se)},
            physics=tuple(PHYSICS[n] for n in terms if n in PHYSICS), heldout_reduction=red,
        ))
    return tuple(out)


def formula(d: Discovered) -> str:
    """The discovered torque as text, e.g. ``τ(joint_2) = -0.31·|rdot|rdot + 0.02·1``."""
    body = " + ".join(f"{v:.4g}·{k}" for k, v in d.terms.items())
    return f"τ({d.joint}) = {body}"
