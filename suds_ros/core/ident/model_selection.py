"""Choosing the SUDS model's size for the data at hand: blocked cross-validation on nested designs.

The candidates are regressor sets × gain Fourier orders × relative ridges.  Every candidate's
design is a column subset of the largest candidate's (set 1 ⊂ set 2 ⊂ set 3; a Fourier basis of
order m is the first 2m + 1 columns of one of order M ≥ m), so the largest design is built once,
its Gram matrix is accumulated once per fold block, and each candidate, fold and ridge costs
one Cholesky solve of its own (smaller) normal equations:

    G_train(f) = Σ_b G_b − G_f,     coef = (G_train + λ·mean diag G_train · I)⁻¹ b_train

(the same relative ridge as :meth:`~suds_ros.core.fourier.NormalEquations.solve`, so the
winner refitted on all training rows is exactly the model that was scored).

Score of a candidate: on each held-out block, for each output group (body, passive, torque),
Σ|model error| / Σ|template error|; the mean over groups and blocks.  Outputs measured as
averages over pose intervals (an asynchronous pose stream) are fitted on the averaged design
rows; an averaged row counts as training data for a fold when it does not touch the held-out
block and as test data when it lies wholly inside it (rows straddling the boundary are left
out of both).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from suds_ros.core._typing import FloatArray, IntArray
from suds_ros.core.fourier import ridge_solve
from suds_ros.core.ident.sysid import FeatureLayout, SudsConfig, feature_layout


@dataclass(frozen=True)
class AveragedRows:
    """Outputs measured as averages over pose intervals, for cross-validation.

    Attributes
    ----------
    A : (q, P) averaged design rows of the largest candidate.
    y : (q, k) measured averages; ``template`` (q, k) the template's averages.
    columns : the k outputs (indices into the full output vector) they measure.
    fold_frac : (q, n_folds) the fraction of each averaged row's time inside each fold block.
    """

    A: FloatArray
    y: FloatArray
    template: FloatArray
    columns: tuple[int, ...]
    fold_frac: FloatArray


@dataclass(frozen=True)
class CVProblem:
    """The data one model selection runs on.

    Attributes
    ----------
    A : (m, P) design rows of the largest candidate (one per shape interval, in time order).
    y : (m, d) outputs fitted row by row; ``template`` (m, d) their phase-only template.
    columns : the d outputs (indices into the full output vector) of ``y``.
    groups : output groups scored separately (lists of full-output indices).
    edges : (n_folds + 1,) row indices delimiting the contiguous fold blocks.
    averaged : optional :class:`AveragedRows`.
    """

    A: FloatArray
    y: FloatArray
    template: FloatArray
    columns: tuple[int, ...]
    groups: tuple[tuple[int, ...], ...]
    edges: IntArray
    averaged: AveragedRows | None = None


def candidates(base: SudsConfig, regressor_sets: tuple[int, ...], orders: tuple[tuple[int, int], ...],
               ridges: tuple[float, ...], kernels: tuple[int, ...] = ()) -> list[SudsConfig]:
    """Distinct candidate configurations.

    Set 1 ignores the bilinear order; random shape features (``kernels`` > 0) go with set 1 at
    the lowest gain order only (they stand in for the higher-order Fourier groups and carry
    the phase themselves).
    """
    out: list[SudsConfig] = []
    orders = orders or ((base.linear_order, base.bilinear_order),)
    for m in kernels or (base.kernel_features,):
        for reg in (regressor_sets or (base.regressors,)) if not m else (1,):
            for lin, bil in orders:
                for ridge in ridges or (base.ridge,):
                    cfg = replace(base, regressors=reg, linear_order=lin if not m else min(o[0] for o in orders),
                                  bilinear_order=bil if reg >= 2 else 0, ridge=ridge, kernel_features=m)
                    if cfg not in out:
                        out.append(cfg)
    return out


def families(cands: list[SudsConfig]) -> list[list[SudsConfig]]:
    """Candidates grouped by regressor set and random features.

    Within a group the designs nest (only the orders differ), so the group's largest design is
    no bigger than its largest candidate: one set's high orders never combine with another
    set's extra groups into a design nobody asked for.
    """
    out: dict[tuple[int, int, float, int], list[SudsConfig]] = {}
    for c in cands:
        out.setdefault((c.regressors, c.kernel_features, c.kernel_gamma, c.kernel_seed), []).append(c)
    return list(out.values())


def key(cfg: SudsConfig) -> tuple[int, int, int, float, int]:
    """The key of a candidate in the score table."""
    return (cfg.regressors, cfg.linear_order, cfg.bilinear_order, cfg.ridge, cfg.kernel_features)


def largest(cands: list[SudsConfig]) -> SudsConfig:
    """The configuration whose design holds every candidate's columns (one family)."""
    return replace(cands[0], regressors=max(c.regressors for c in cands),
                   linear_order=max(c.linear_order for c in cands),
                   bilinear_order=max(c.bilinear_order for c in cands))


def subset_columns(big: FeatureLayout, small: FeatureLayout) -> IntArray:
    """Indices of ``small``'s design columns within ``big``'s (same features, lower orders)."""
    start = {name: (s.start, f, m) for (name, f, m), s in zip(big.groups, big.slices().values())}
    cols = []
    for name, f, m in small.groups:
        b0, bf, bm = start[name]
        if bf != f or bm < m:
            raise ValueError(f"group {name!r} of {small} is not nested in {big}")
        block = b0 + np.arange(f)[:, None] * (2 * bm + 1) + np.arange(2 * m + 1)[None, :]
        cols.append(block.ravel())
    return np.concatenate(cols)


def _primal_path(G: FloatArray, b: FloatArray) -> Callable[[float], FloatArray]:
    """Ridge solutions from the normal equations G c = b."""
    return lambda ridge: ridge_solve(G, b, ridge)


def _dual_path(A: FloatArray, y: FloatArray) -> Callable[[float], FloatArray]:
    """The same ridge solutions from the rows: c = Aᵀ(AAᵀ + λ·s·I)⁻¹y, s = mean diag AᵀA = tr(AAᵀ)/p."""
    K = A @ A.T
    scale = float(np.trace(K)) / A.shape[1]

    return lambda ridge: A.T @ ridge_solve(K, y, ridge, scale)


def _gram_blocks(A: FloatArray, y: FloatArray, masks: list[FloatArray]) -> tuple[list[FloatArray], list[FloatArray]]:
    return [A[m].T @ A[m] for m in masks], [A[m].T @ y[m] for m in masks]


def select(problem: CVProblem, cands: list[SudsConfig], n_joints: int, n_actuated: int
           ) -> tuple[SudsConfig, dict[tuple[int, int, int, float, int], float]]:
    """The candidate with the lowest cross-validated score, and every candidate's score.

    ``cands`` must be one of :func:`families` (``problem.A`` is their largest design).
    Scores are keyed by :func:`key`.
    """
    big = feature_layout(largest(cands), n_joints, n_actuated)
    m = problem.A.shape[0]
    edges = problem.edges
    k = edges.size - 1
    block = np.zeros(m, dtype=int)
    for f in range(k):
        block[edges[f]:edges[f + 1]] = f
    test_rows = [block == f for f in range(k)]
    av = problem.averaged
    # fewer training rows than columns: solve each fold in the dual (same coefficients, cheaper)
    dual = m - int(np.diff(edges).max()) < problem.A.shape[1]
    if av is not None:
        touch = [av.fold_frac[:, f] > 0.0 for f in range(k)]
        inside = [av.fold_frac[:, f] >= 1.0 - 1e-12 for f in range(k)]
    if not dual:
        G, b = _gram_blocks(problem.A, problem.y, test_rows)
        Gt, bt = sum(G), sum(b)
        if av is not None:
            Ga, ba = _gram_blocks(av.A, av.y, touch)
            Gat, bat = av.A.T @ av.A, av.A.T @ av.y
    pos = {c: i for i, c in enumerate(problem.columns)}
    scores: dict[tuple[int, int, int, float, int], float] = {}
    layouts: dict[tuple[int, int, int], list[float]] = {}
    for cfg in cands:  # one design (column subset) per layout, its ridges solved on the same blocks
        layouts.setdefault((cfg.regressors, cfg.linear_order, cfg.bilinear_order), []).append(cfg.ridge)
    for (reg, lin, bil), ridges in layouts.items():
        cfg = replace(cands[0], regressors=reg, linear_order=lin, bilinear_order=bil)
        cols = subset_columns(big, feature_layout(cfg, n_joints, n_actuated))
        ix = np.ix_(cols, cols)
        total = np.zeros(len(ridges))
        for f in range(k):
            te = test_rows[f]
            if dual:
                path = _dual_path(problem.A[~te][:, cols], problem.y[~te])
            else:
                path = _primal_path(Gt[ix] - G[f][ix], (bt - b[f])[cols])
            Ate = problem.A[te][:, cols]
            ref = np.abs(problem.template[te] - problem.y[te])
            if av is not None:
                if dual:
                    path_a = _dual_path(av.A[~touch[f]][:, cols], av.y[~touch[f]])
                else:
                    path_a = _primal_path(Gat[ix] - Ga[f][ix], (bat - ba[f])[cols])
                Aate = av.A[inside[f]][:, cols]
                ra = np.abs(av.template[inside[f]] - av.y[inside[f]])
            for i, ridge in enumerate(ridges):
                err = np.abs(Ate @ path(ridge) - problem.y[te])
                if av is not None:
                    ea = np.abs(Aate @ path_a(ridge) - av.y[inside[f]])
                parts = []
                for g in problem.groups:
                    if av is not None and g[0] in av.columns:
                        j = [av.columns.index(c) for c in g]
                        parts.append(ea[:, j].sum() / max(ra[:, j].sum(), 1e-300))
                    else:
                        j = [pos[c] for c in g]
                        parts.append(err[:, j].sum() / max(ref[:, j].sum(), 1e-300))
                total[i] += float(np.mean(parts))
        for i, ridge in enumerate(ridges):
            scores[(reg, lin, bil, ridge, cands[0].kernel_features)] = total[i] / k
    best = min(cands, key=lambda c: scores[key(c)])
    return best, scores
