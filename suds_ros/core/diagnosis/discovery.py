"""Discovery: a candidate formula for a passive-joint torque no catalogue effect explains.

The equation-error residual of passive joint j (:class:`~suds_ros.core.diagnosis.naming.Scorer`,
after the named effects, if any) is the torque missing from its balance: with an extra torque τ_x
the balance −(D q̇)_j + τ_spring + τ_x = 0 leaves the residual (D q̇)_j − τ_spring = τ_x.  It is
regressed per joint on a library of physically meaningful terms (e = r_j − rest_j, ṙ = ṙ_j):

    1, e, e², e³, ṙ, sign(ṙ), |ṙ|ṙ, e·ṙ, and the actuated angles r_a and rates ṙ_a

by forward selection: each step adds the term that lowers the training residual most (columns
standardised), and keeps it if the held-out log-likelihood gain it adds, minus the BIC penalty
½·log n, exceeds ``config.evidence_threshold``; residual and terms are averaged over
non-overlapping blocks of ``config.eq_window`` intervals first (the same evidence rule as the effect selection).
Coefficients and their standard errors come from ordinary least squares on the training half
(units: N·m per unit of the term).  The terms are built from the samples next to each interval,
not from its own two, so their noise is independent of the residual's (:func:`_library`).
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
    """Term names and columns (n − 2, m) for the passive joint at rank ``j`` of an equation-error half.

    The residual of interval k → k+1 carries the noise of samples k and k+1 (through ṙ and r̄), so
    terms built from them would be correlated with it (errors in variables: a noisy ṙ inside
    |ṙ|ṙ biases everything).  The terms are built from the neighbouring samples k−1 and k+2
    instead (r̄ ≈ (r_{k−1} + r_{k+2})/2, ṙ ≈ (r_{k+2} − r_{k−1})/(3 dt)), whose noise is independent
    of the residual's; the first and last intervals are dropped (see :func:`_trim`).
    """
    rbar, rdot, dt = eq.rbar, eq.rdot, eq.dt  # type: ignore[attr-defined]
    pas, act = eq.pas, eq.act  # type: ignore[attr-defined]
    r = np.concatenate([rbar - 0.5 * dt * rdot, rbar[-1:] + 0.5 * dt * rdot[-1:]], axis=0)  # samples
    r_mid = 0.5 * (r[:-3] + r[3:])
    r_dot = (r[3:] - r[:-3]) / (3 * dt)
    e = r_mid[:, pas[j]] - rest
    v = r_dot[:, pas[j]]
    cols = {
        "1": np.ones_like(e), "e": e, "e^2": e**2, "e^3": e**3, "rdot": v, "sign(rdot)": np.sign(v),
        "|rdot|rdot": np.abs(v) * v, "e*rdot": e * v,
    }
    for k, a in enumerate(act):
        cols[f"r({act_names[k]})"] = r_mid[:, a]
        cols[f"rdot({act_names[k]})"] = r_dot[:, a]
    return list(cols), np.stack(list(cols.values()), axis=1)


def _trim(y: FloatArray) -> FloatArray:
    """The residuals of the intervals :func:`_library` has terms for (all but the first and last)."""
    return y[1:-1]


def _blocks(x: FloatArray, w: int) -> FloatArray:
    """Means over consecutive non-overlapping blocks of ``w`` rows.

    The drag torque's rate noise telescopes in the mean, so the residual's noise drops about w-fold.
    """
    n = (x.shape[0] // w) * w
    return x[:n].reshape(n // w, w, *x.shape[1:]).mean(axis=1)


def _forward(X: FloatArray, y: FloatArray, Xt: FloatArray, yt: FloatArray, threshold: float) -> list[int]:
    """Forward selection of columns: training residual picks, held-out evidence keeps."""
    sd = X.std(axis=0)
    sd[sd == 0] = 1.0
    mu = X.mean(axis=0)
    mu[X.std(axis=0) == 0] = 0.0  # keep the constant column
    Z, Zt = (X - mu) / sd, (Xt - mu) / sd
    chosen: list[int] = []
    n_t = yt.size
    rss_t = float(np.sum(yt**2))
    pen = 0.5 * np.log(max(n_t, 2))
    for _ in range(min(MAX_TERMS, X.shape[1])):
        best, best_rss = None, np.inf
        for c in range(X.shape[1]):
            if c in chosen:
                continue
            A = Z[:, chosen + [c]]
            coef = np.linalg.lstsq(A, y, rcond=None)[0]
            rss = float(np.sum((y - A @ coef) ** 2))
            if rss < best_rss:
                best, best_rss = c, rss
        if best is None:
            break
        A = Z[:, chosen + [best]]
        coef = np.linalg.lstsq(A, y, rcond=None)[0]
        new_t = float(np.sum((yt - Zt[:, chosen + [best]] @ coef) ** 2))
        gain = 0.5 * n_t * np.log(rss_t / max(new_t, 1e-300)) - pen
        if gain <= threshold:
            break
        chosen.append(best)
        rss_t = new_t
    return chosen


def discover(
    data: Data, model: ChainModel, config: DiagnoseConfig, sig_rp: FloatArray,
    cand: Candidate = Candidate(()), x: FloatArray | None = None,
) -> tuple[Discovered, ...]:
    """Candidate formulas for the torque missing from each passive joint (module docstring)."""
    scorer = Scorer(data, model, config.eq_window, sig_rp)
    p = equation_terms(cand, np.zeros(0) if x is None else np.asarray(x, dtype=float), data, model)
    zero = np.zeros_like(scorer.rdot_thr)
    y_tr, _ = scorer.train.residuals(p, zero)
    y_te, _ = scorer.test.residuals(p, zero)
    rest = np.asarray(model.rest)[data.pas] + p.offset
    act_names = [data.names[a] for a in data.act]
    out = []
    for j, jp in enumerate(data.pas):
        names, X = _library(scorer.train, j, float(rest[j]), act_names)
        _, Xt = _library(scorer.test, j, float(rest[j]), act_names)
        w = config.eq_window
        X, Xt = _blocks(X, w), _blocks(Xt, w)
        y, yt = _blocks(_trim(y_tr[:, j]), w), _blocks(_trim(y_te[:, j]), w)
        chosen = _forward(X, y, Xt, yt, config.evidence_threshold)
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
