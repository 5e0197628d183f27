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

Long recordings: the designs may be given as :class:`LazyDesign` (rows built on demand).  A
design small enough (:data:`DENSE_LIMIT` elements) is built whole and scored as above; a larger
one is streamed in blocks of :data:`BLOCK_ROWS` rows, twice: once to accumulate every fold
block's Gram matrix, once to add up each candidate's absolute held-out errors (all layouts and
ridges from each block of rows).  Memory is then bounded by one block of the largest design,
whatever the length of the recording; the scores are the same sums, added in another order.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Union

import numpy as np

from suds_ros.core._typing import FloatArray, IntArray
from suds_ros.core.fourier import ridge_solve
from suds_ros.core.ident.sysid import FeatureLayout, SudsConfig, feature_layout


#: designs with at most this many elements are built whole (80 MB of float64)
DENSE_LIMIT = 10_000_000
#: rows per block when a design is streamed (a block of the largest swimmer9 design: ~60 MB)
BLOCK_ROWS = 5_000


@dataclass(frozen=True)
class LazyDesign:
    """Design rows built a block at a time: ``rows(r0, r1)`` gives rows r0 … r1 − 1 (r1 − r0, P)."""

    n_rows: int
    n_columns: int
    rows: Callable[[int, int], FloatArray]

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, columns), as an array's."""
        return self.n_rows, self.n_columns

    def dense(self) -> FloatArray:
        """All rows at once."""
        return self.rows(0, self.n_rows)

    def blocks(self, r0: int = 0, r1: int | None = None):  # type: ignore[no-untyped-def]
        """(start, rows) of consecutive blocks of at most :data:`BLOCK_ROWS` rows within [r0, r1)."""
        r1 = self.n_rows if r1 is None else r1
        for a in range(r0, r1, BLOCK_ROWS):
            b = min(a + BLOCK_ROWS, r1)
            yield a, self.rows(a, b)


Design = Union[FloatArray, LazyDesign]


@dataclass(frozen=True)
class AveragedRows:
    """Outputs measured as averages over pose intervals, for cross-validation.

    Attributes
    ----------
    A : (q, P) averaged design rows of the largest candidate (an array or a :class:`LazyDesign`).
    y : (q, k) measured averages; ``template`` (q, k) the template's averages.
    columns : the k outputs (indices into the full output vector) they measure.
    fold_frac : (q, n_folds) the fraction of each averaged row's time inside each fold block.
    """

    A: Design
    y: FloatArray
    template: FloatArray
    columns: tuple[int, ...]
    fold_frac: FloatArray


@dataclass(frozen=True)
class CVProblem:
    """The data one model selection runs on.

    Attributes
    ----------
    A : (m, P) design rows of the largest candidate (one per shape interval, in time order; an
        array or a :class:`LazyDesign`).
    y : (m, d) outputs fitted row by row; ``template`` (m, d) their phase-only template.
    columns : the d outputs (indices into the full output vector) of ``y``.
    groups : output groups scored separately (lists of full-output indices).
    edges : (n_folds + 1,) row indices delimiting the contiguous fold blocks.
    averaged : optional :class:`AveragedRows`.
    """

    A: Design
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


def _dense(A: Design) -> FloatArray:
    return A.dense() if isinstance(A, LazyDesign) else A


def _small(A: Design) -> bool:
    return not isinstance(A, LazyDesign) or A.n_rows * A.n_columns <= DENSE_LIMIT


#: per layout, per fold: (ridges, outputs) sums of absolute held-out errors
_Errors = dict[tuple[int, int, int], list[FloatArray]]


def select(problem: CVProblem, cands: list[SudsConfig], n_joints: int, n_actuated: int
           ) -> tuple[SudsConfig, dict[tuple[int, int, int, float, int], float]]:
    """The candidate with the lowest cross-validated score, and every candidate's score.

    ``cands`` must be one of :func:`families` (``problem.A`` is their largest design).
    Scores are keyed by :func:`key`.
    """
    big = feature_layout(largest(cands), n_joints, n_actuated)
    edges = problem.edges
    k = edges.size - 1
    av = problem.averaged
    layouts: dict[tuple[int, int, int], list[float]] = {}
    for cfg in cands:  # one design (column subset) per layout, its ridges solved on the same blocks
        layouts.setdefault((cfg.regressors, cfg.linear_order, cfg.bilinear_order), []).append(cfg.ridge)
    cols = {lay: subset_columns(big, feature_layout(replace(cands[0], regressors=lay[0], linear_order=lay[1],
                                                            bilinear_order=lay[2]), n_joints, n_actuated))
            for lay in layouts}
    touch = inside = None
    if av is not None:
        touch = [av.fold_frac[:, f] > 0.0 for f in range(k)]
        inside = [av.fold_frac[:, f] >= 1.0 - 1e-12 for f in range(k)]
    if _small(problem.A) and (av is None or _small(av.A)):
        err, err_a = _dense_errors(problem, layouts, cols, touch, inside)
    else:
        err, err_a = _streamed_errors(problem, layouts, cols, touch, inside)
    test_rows = [slice(edges[f], edges[f + 1]) for f in range(k)]
    ref = [np.abs(problem.template[te] - problem.y[te]).sum(axis=0) for te in test_rows]
    ref_a = [] if av is None else [np.abs(av.template[m] - av.y[m]).sum(axis=0)
                                   for m in inside]  # type: ignore[union-attr]
    pos = {c: i for i, c in enumerate(problem.columns)}
    scores: dict[tuple[int, int, int, float, int], float] = {}
    for lay, ridges in layouts.items():
        total = np.zeros(len(ridges))
        for f in range(k):
            for i in range(len(ridges)):
                parts = []
                for g in problem.groups:
                    if av is not None and g[0] in av.columns:
                        j = [av.columns.index(c) for c in g]
                        parts.append(err_a[lay][f][i, j].sum() / max(ref_a[f][j].sum(), 1e-300))
                    else:
                        j = [pos[c] for c in g]
                        parts.append(err[lay][f][i, j].sum() / max(ref[f][j].sum(), 1e-300))
                total[i] += float(np.mean(parts))
        for i, ridge in enumerate(ridges):
            scores[(*lay, ridge, cands[0].kernel_features)] = total[i] / k
    best = min(cands, key=lambda c: scores[key(c)])
    return best, scores


def _dense_errors(problem: CVProblem, layouts: dict[tuple[int, int, int], list[float]],
                  cols: dict[tuple[int, int, int], IntArray], touch: list[FloatArray] | None,
                  inside: list[FloatArray] | None) -> tuple[_Errors, _Errors]:
    """Held-out absolute error sums with the whole designs in memory (primal or dual solves)."""
    A = _dense(problem.A)
    av = problem.averaged
    Av = None if av is None else _dense(av.A)
    m = A.shape[0]
    edges = problem.edges
    k = edges.size - 1
    test_rows = [np.zeros(m, dtype=bool) for _ in range(k)]
    for f in range(k):
        test_rows[f][edges[f]:edges[f + 1]] = True
    # fewer training rows than columns: solve each fold in the dual (same coefficients, cheaper)
    dual = m - int(np.diff(edges).max()) < A.shape[1]
    if not dual:
        G, b = _gram_blocks(A, problem.y, test_rows)
        Gt, bt = sum(G), sum(b)
        if Av is not None:
            Ga, ba = _gram_blocks(Av, av.y, touch)  # type: ignore[arg-type, union-attr]
            Gat, bat = Av.T @ Av, Av.T @ av.y  # type: ignore[union-attr]
    err: _Errors = {}
    err_a: _Errors = {}
    for lay, ridges in layouts.items():
        c = cols[lay]
        ix = np.ix_(c, c)
        err[lay], err_a[lay] = [], []
        for f in range(k):
            te = test_rows[f]
            if dual:
                path = _dual_path(A[~te][:, c], problem.y[~te])
            else:
                path = _primal_path(Gt[ix] - G[f][ix], (bt - b[f])[c])
            Ate = A[te][:, c]
            err[lay].append(np.array([np.abs(Ate @ path(r) - problem.y[te]).sum(axis=0) for r in ridges]))
            if Av is not None:
                if dual:
                    path_a = _dual_path(Av[~touch[f]][:, c], av.y[~touch[f]])  # type: ignore[index, union-attr]
                else:
                    path_a = _primal_path(Gat[ix] - Ga[f][ix], (bat - ba[f])[c])
                Aate = Av[inside[f]][:, c]  # type: ignore[index]
                ya = av.y[inside[f]]  # type: ignore[index, union-attr]
                err_a[lay].append(np.array([np.abs(Aate @ path_a(r) - ya).sum(axis=0) for r in ridges]))
    return err, err_a


def _lazy(A: Design) -> LazyDesign:
    return A if isinstance(A, LazyDesign) else LazyDesign(A.shape[0], A.shape[1], lambda a, b: A[a:b])


def _streamed_errors(problem: CVProblem, layouts: dict[tuple[int, int, int], list[float]],
                     cols: dict[tuple[int, int, int], IntArray], touch: list[FloatArray] | None,
                     inside: list[FloatArray] | None) -> tuple[_Errors, _Errors]:
    """Held-out absolute error sums with the designs streamed in blocks (two passes, primal solves)."""
    A = _lazy(problem.A)
    av = problem.averaged
    edges = problem.edges
    k = edges.size - 1
    P = A.n_columns
    y = problem.y
    G = [np.zeros((P, P)) for _ in range(k)]
    b = [np.zeros((P, y.shape[1])) for _ in range(k)]
    for f in range(k):  # pass 1: each fold block's Gram matrix
        for a, Ab in A.blocks(int(edges[f]), int(edges[f + 1])):
            G[f] += Ab.T @ Ab
            b[f] += Ab.T @ y[a:a + Ab.shape[0]]
    Gt, bt = sum(G), sum(b)
    if av is not None:
        Av = _lazy(av.A)
        Ga = [np.zeros((P, P)) for _ in range(k)]
        ba = [np.zeros((P, av.y.shape[1])) for _ in range(k)]
        Gat, bat = np.zeros((P, P)), np.zeros((P, av.y.shape[1]))
        for a, Ab in Av.blocks():
            yb = av.y[a:a + Ab.shape[0]]
            Gat += Ab.T @ Ab
            bat += Ab.T @ yb
            for f in range(k):
                sel = touch[f][a:a + Ab.shape[0]]  # type: ignore[index]
                if sel.any():
                    Ga[f] += Ab[sel].T @ Ab[sel]
                    ba[f] += Ab[sel].T @ yb[sel]

    def coefs(Gtot: FloatArray, Gf: FloatArray, btot: FloatArray, bf: FloatArray, c: IntArray,
              ridges: list[float]) -> FloatArray:
        path = _primal_path(Gtot[np.ix_(c, c)] - Gf[np.ix_(c, c)], (btot - bf)[c])
        return np.stack([path(r) for r in ridges], axis=-1)  # (p, d, R)

    err: _Errors = {lay: [] for lay in layouts}
    err_a: _Errors = {lay: [] for lay in layouts}
    for f in range(k):  # pass 2: every layout and ridge scored on each block of held-out rows
        C = {lay: coefs(Gt, G[f], bt, b[f], cols[lay], r) for lay, r in layouts.items()}
        sums = {lay: np.zeros((len(r), y.shape[1])) for lay, r in layouts.items()}
        for a, Ab in A.blocks(int(edges[f]), int(edges[f + 1])):
            yb = y[a:a + Ab.shape[0]]
            for lay, c in cols.items():
                pred = (Ab[:, c] @ C[lay].reshape(c.size, -1)).reshape(Ab.shape[0], y.shape[1], -1)
                sums[lay] += np.abs(pred - yb[:, :, None]).sum(axis=0).T
        for lay in layouts:
            err[lay].append(sums[lay])
        if av is not None:
            Ca = {lay: coefs(Gat, Ga[f], bat, ba[f], cols[lay], r) for lay, r in layouts.items()}
            sums_a = {lay: np.zeros((len(r), av.y.shape[1])) for lay, r in layouts.items()}
            for a, Ab in Av.blocks():
                sel = inside[f][a:a + Ab.shape[0]]  # type: ignore[index]
                if not sel.any():
                    continue
                Ab, yb = Ab[sel], av.y[a:a + sel.size][sel]
                for lay, c in cols.items():
                    pred = (Ab[:, c] @ Ca[lay].reshape(c.size, -1)).reshape(Ab.shape[0], yb.shape[1], -1)
                    sums_a[lay] += np.abs(pred - yb[:, :, None]).sum(axis=0).T
            for lay in layouts:
                err_a[lay].append(sums_a[lay])
    return err, err_a
