"""SUDS regression: (g°, ṙ_p) ~ C + C_r δ + B δ̇_a + B_r δ⊗δ̇_a, coefficients smooth in phase.

Choice of phase dependence
--------------------------
Each coefficient is a truncated Fourier series in the gait phase φ, so the
whole model is one linear least-squares problem on the design

    X = [ F_g(δ, δ̇_a) ⊗ (1, cos φ, sin φ, …, cos M_g φ, sin M_g φ) ]_g

over feature groups g (intercept, linear, bilinear, …).  Compared with
kernel-weighted phase bins this (a) gives coefficients that are smooth and
periodic by construction, (b) makes the sufficient statistics a single pair
XᵀX, XᵀY, so ``partial_fit`` on chunks reproduces ``fit`` exactly and
supports an exponential forgetting factor, and (c) lets each group have its own
bandwidth: the intercept C(φ) is the template velocity and needs many
harmonics, while the perturbation gains vary slowly along the gait and need
few (fewer parameters, less variance).  A small relative ridge keeps the
normal equations well conditioned for short training sets.

Regressor sets (paper §"Estimation for SUDS"; ṙ_p is never a regressor — it is
an output, and using it as an input would leak the answer):

1. ``[1, δ, δ̇_a]``                    — first order, O(n) per output and harmonic
2. ``[1, δ, δ̇_a, δ⊗δ̇_a]``            — SUDS structure, O(n·n_a)
3. set 2 plus ``δ⊗δ`` and ``δ̇_a⊗δ̇_a`` — full second order, O(n²)

δ = r − θ(φ) and δ̇ = ṙ − θ'(φ)·ω̄ with θ the phase-averaged gait and ω̄ the
mean phase rate (rad/s).

Sampled-data state
------------------
The outputs are averages over a sampling interval k → k + 1 (ṙ_p = (r_p,k+1 − r_p,k)/Δt and
the body twist between the two poses), and a stiff passive mode can relax within one
interval (swimmer9's stiffest relaxes at ≈ 135 s⁻¹: λ·Δt ≈ 1.35 at 100 Hz).  Such an average
is set by the state the interval *starts* from and the drive over it, which is what the
exact one-step map of the dynamics takes; the midpoint r̄ = (r_k + r_k+1)/2 already contains
half of the answer's end point and blurs the map.  ``state="start"`` (the default) regresses
on δ at the interval's first sample, ``"midpoint"`` on δ at r̄ (the instantaneous affine map
at the midpoint, the convention of models saved before it existed).  The phase of a row is
the interval's midpoint phase in both; δ̇_a is the interval's mean actuated rate, so the
outputs stay affine in it.  :func:`interval_state` (a whole interval) and :func:`segment_state`
(part of an interval, for outputs averaged over a pose interval) are the one place this
choice is made.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.config import check_settings, setting
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.estimator import BaseEstimator, check_is_fitted
from suds_ros.core.fourier import NormalEquations, fourier_basis
from suds_ros.core.ident.shape_kernel import KernelScale, kernel_features


#: most design values built at once by :meth:`SudsRegressor.partial_fit` and ``predict`` (40 MB)
BLOCK_ELEMENTS = 5_000_000

#: the interval states a regression row can be built on (see "Sampled-data state")
STATES = ("start", "midpoint")


def interval_state(config: "SudsConfig", r_start: FloatArray, r_end: FloatArray) -> FloatArray:
    """The joint state a regression row of the interval r_start → r_end uses (``config.state``)."""
    if config.state == "start":
        return np.asarray(r_start, dtype=float)
    return 0.5 * (np.asarray(r_start, dtype=float) + np.asarray(r_end, dtype=float))


def segment_state(config: "SudsConfig", phase_start: FloatArray, phase_end: FloatArray, r_start: FloatArray,
                  r_end: FloatArray, frac: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Phase (s,) and joint state (s, nj) of the rows of segments of sampling intervals.

    A segment is the part of the shape interval start → end (phases (s,), joint values
    (s, nj)) that a pose interval covers; ``frac`` (s,) is the position of the segment's
    midpoint in its interval (0 at the start, 1 at the end).  With ``state="start"`` a row
    predicts the mean over a whole interval from the state it starts in, so a segment takes
    its interval's row (midpoint phase, start state); with ``"midpoint"`` the instantaneous
    map is evaluated at the segment's own midpoint (phase and shape interpolated there).
    """
    phase_start, phase_end = np.asarray(phase_start, dtype=float), np.asarray(phase_end, dtype=float)
    r_start, r_end = np.asarray(r_start, dtype=float), np.asarray(r_end, dtype=float)
    if config.state == "start":
        return 0.5 * (phase_start + phase_end), r_start
    frac = np.asarray(frac, dtype=float)
    return phase_start + (phase_end - phase_start) * frac, r_start + (r_end - r_start) * frac[:, None]


@dataclass(frozen=True)
class SudsConfig:
    """Hyperparameters of :class:`SudsRegressor`.

    Parameters
    ----------
    regressors : int
        Regressor set 1, 2 or 3 (see module docstring).
    intercept_order : int
        Fourier order of C(φ).
    linear_order : int
        Fourier order of the gains on δ and δ̇_a.
    bilinear_order : int
        Fourier order of the gains on the products (δ⊗δ̇_a, and set 3's squares).
    ridge : float
        Relative Tikhonov weight: λ = ridge · mean(diag XᵀX) added to the diagonal.
    forgetting : float
        Per-sample forgetting factor in (0, 1]; 1 keeps all data equally.
    state : str
        Which state of a sampling interval the rows regress on: ``"start"`` (its first
        sample) or ``"midpoint"`` (see the module docstring).
    kernel_features : int
        M random features of the whole shape for coefficients C(r), B(r)
        (:mod:`~suds_ros.core.ident.shape_kernel`); 0 leaves them out.
    kernel_gamma : float
        Their Gaussian-kernel width γ on the standardised shape.
    kernel_seed : int
        Seed of their random directions and offsets.
    """

    regressors: int = setting(2, "SUDS regressor set 1, 2 or 3", ge=1, le=3)
    intercept_order: int = setting(8, "Fourier order of the intercept C(φ)", ge=0, le=64)
    linear_order: int = setting(3, "Fourier order of the linear gains", ge=0, le=64)
    bilinear_order: int = setting(1, "Fourier order of the bilinear gains", ge=0, le=64)
    ridge: float = setting(1e-6, "relative Tikhonov weight", ge=0.0, le=1e6)
    forgetting: float = setting(1.0, "per-sample forgetting factor in (0, 1]", gt=0.0, le=1.0)
    state: str = setting("start", "interval state the rows regress on: start or midpoint", choices=STATES)
    kernel_features: int = setting(0, "random features of the whole shape (0: none)", ge=0, le=100_000)
    kernel_gamma: float = setting(0.1, "Gaussian-kernel width of the random features", gt=0.0)
    kernel_seed: int = setting(0, "seed of the random features", ge=0, le=2**32 - 1)

    def __post_init__(self) -> None:
        check_settings(self)


def _upper_products(a: FloatArray) -> FloatArray:
    i, j = np.triu_indices(a.shape[1])
    return a[:, i] * a[:, j]


@dataclass(frozen=True)
class FeatureLayout:
    """Column bookkeeping of the SUDS design matrix.

    ``groups`` lists (name, n_features, fourier_order) in column order.
    """

    groups: tuple[tuple[str, int, int], ...]

    @property
    def n_columns(self) -> int:
        """Total number of design columns (parameters per output)."""
        return sum(f * (2 * m + 1) for _, f, m in self.groups)

    @property
    def max_order(self) -> int:
        """The highest Fourier order of any group (the basis every group's columns are cut from)."""
        return max(m for _, _, m in self.groups)

    def slices(self) -> dict[str, slice]:
        """Column slice of each group."""
        out: dict[str, slice] = {}
        start = 0
        for name, f, m in self.groups:
            stop = start + f * (2 * m + 1)
            out[name] = slice(start, stop)
            start = stop
        return out


@functools.lru_cache(maxsize=64)  # the predictor asks once per sample; configs are frozen
def feature_layout(config: SudsConfig, n_joints: int, n_actuated: int) -> FeatureLayout:
    """The groups of regressor set ``config.regressors`` for nj joints and na actuated joints."""
    groups: list[tuple[str, int, int]] = [
        ("C", 1, config.intercept_order),
        ("C_r", n_joints, config.linear_order),
        ("B", n_actuated, config.linear_order),
    ]
    if config.regressors >= 2:
        groups.append(("B_r", n_joints * n_actuated, config.bilinear_order))
    if config.regressors == 3:
        groups.append(("D_rr", n_joints * (n_joints + 1) // 2, config.bilinear_order))
        groups.append(("D_aa", n_actuated * (n_actuated + 1) // 2, config.bilinear_order))
    if config.kernel_features:
        groups.append(("K", config.kernel_features * (1 + n_actuated), 0))
    return FeatureLayout(tuple(groups))


def design_matrix(
    config: SudsConfig, phase: FloatArray, delta: FloatArray, ddelta_a: FloatArray,
    r: FloatArray | None = None, rdot_a: FloatArray | None = None, kernel_scale: KernelScale | None = None,
    *, basis: FloatArray | None = None,
) -> FloatArray:
    """SUDS design matrix (n, p) for phases (n,), δ (n, nj) and δ̇_a (n, na).

    With ``config.kernel_features`` the shape r (n, nj), the actuated rate (n, na) and the
    gait's :class:`~suds_ros.core.ident.shape_kernel.KernelScale` are needed too.
    ``basis``: the Fourier basis of ``phase`` (:func:`~suds_ros.core.fourier.fourier_basis`)
    of at least the highest order of the groups, when the caller has it already.
    """
    n = phase.shape[0]
    feats: dict[str, FloatArray] = {
        "C": np.ones((n, 1)),
        "C_r": delta,
        "B": ddelta_a,
    }
    if config.regressors >= 2:
        feats["B_r"] = (delta[:, :, None] * ddelta_a[:, None, :]).reshape(n, delta.shape[1] * ddelta_a.shape[1])
    if config.regressors == 3:
        feats["D_rr"] = _upper_products(delta)
        feats["D_aa"] = _upper_products(ddelta_a)
    if config.kernel_features:
        if r is None or rdot_a is None:
            raise SudsDataError("random-feature coefficients need the shape r and the actuated rate; got None")
        feats["K"] = kernel_features(config.kernel_features, config.kernel_gamma, config.kernel_seed,
                                     kernel_scale, r, rdot_a, phase)
    layout = feature_layout(config, delta.shape[1], ddelta_a.shape[1])
    # the basis of order m is the first 2m + 1 columns of the basis of any higher order
    top = layout.max_order
    if basis is None:
        basis = fourier_basis(phase, top)
    elif basis.shape[0] != n or basis.shape[1] < 2 * top + 1:
        raise SudsDataError(f"`basis`: expected shape ({n}, ≥ {2 * top + 1}), got {basis.shape}")
    out = np.empty((n, layout.n_columns))
    start = 0
    for name, _, order in layout.groups:  # each group's products written in place (no concatenated copy)
        F = feats[name]
        width = F.shape[1] * (2 * order + 1)
        np.multiply(F[:, :, None], basis[:, None, : 2 * order + 1],
                    out=out[:, start:start + width].reshape(n, F.shape[1], 2 * order + 1))
        start += width
    return out


def regressor_input(phase: FloatArray, delta: FloatArray, ddelta_a: FloatArray, r: FloatArray,
                    rdot_a: FloatArray) -> FloatArray:
    """The regressor rows X = [φ, δ, δ̇_a, r, ṙ_a] (n, 1 + 2·(nj + na))."""
    return np.concatenate([np.asarray(phase, dtype=float)[:, None], delta, ddelta_a, r, rdot_a], axis=1)


def input_joints(n_columns: int, n_actuated: int) -> int:
    """The joint count nj of rows with ``n_columns`` = 1 + 2·(nj + na) columns; -1 if no nj ≥ max(na, 1) fits."""
    nj = (n_columns - 1) // 2 - n_actuated
    return nj if (n_columns - 1) % 2 == 0 and nj >= max(n_actuated, 1) else -1


def split_regressor_input(X: FloatArray, n_actuated: int) -> tuple[FloatArray, ...]:
    """(φ (n,), δ (n, nj), δ̇_a (n, na), r (n, nj), ṙ_a (n, na)) of regressor rows X (:func:`regressor_input`).

    Raises
    ------
    SudsDataError
        X is not 2-D with 1 + 2·(nj + na) columns for some nj ≥ max(na, 1), or holds NaN/Inf.
    """
    X = np.asarray(X, dtype=float)
    na = int(n_actuated)
    nj = input_joints(X.shape[1], na) if X.ndim == 2 else -1
    if nj < 0:
        raise SudsDataError(
            f"X: expected shape (n, 1 + 2·(nj + {na})) = [phase, δ (nj), δ̇_a ({na}), r (nj), ṙ_a ({na})] "
            f"for n_actuated = {na} and nj ≥ {max(na, 1)} joints, got {X.shape}")
    if not np.all(np.isfinite(X)):
        raise SudsDataError("X contains NaN or Inf")
    a, b = 1 + nj, 1 + nj + na
    return X[:, 0], X[:, 1:a], X[:, a:b], X[:, b : b + nj], X[:, b + nj :]


def regressor_design(config: SudsConfig, X: FloatArray, n_actuated: int,
                     kernel_scale: KernelScale | None = None) -> FloatArray:
    """The SUDS design matrix (n, p) of regressor rows X (:func:`regressor_input`) with na = ``n_actuated``."""
    return design_matrix(config, *split_regressor_input(X, n_actuated), kernel_scale=kernel_scale)


def averaged_design_rows(config: SudsConfig, X: FloatArray, weights: object, n_actuated: int,
                         kernel_scale: KernelScale | None, n_columns: int, a: int, b: int) -> FloatArray:
    """Rows a … b − 1 of the averaged design W·A(X), built from the segments those rows use only."""
    import scipy.sparse

    W = scipy.sparse.csr_matrix(weights)
    used = W.indices[W.indptr[a]:W.indptr[b]]
    if not used.size:
        return np.zeros((b - a, n_columns))
    s0, s1 = int(used.min()), int(used.max()) + 1
    return np.asarray(W[a:b, s0:s1] @ regressor_design(config, X[s0:s1], n_actuated, kernel_scale))


@dataclass(frozen=True)
class AveragedTargets:
    """Outputs measured as time averages of the model's row predictions.

    For example the body velocity measured over pose intervals that straddle several shape
    intervals.

    Attributes
    ----------
    X : (m', 1 + nj + na) regressor rows whose predictions are averaged.
    weights : (q, m') dense or scipy.sparse averaging weights (rows sum to 1).
    y : (q, k) the measured averages.
    columns : the k model outputs these targets measure (indices into the full output vector;
        the remaining outputs, in order, are the columns of the ``y`` given beside).
    """

    X: FloatArray
    weights: object
    y: FloatArray
    columns: tuple[int, ...]


class SudsRegressor(BaseEstimator):
    """Phase-varying SUDS regression fitted from accumulated normal equations.

    ``X`` passed to :meth:`fit`, :meth:`partial_fit`, :meth:`predict` is (n, 1 + 2·(nj + na)):
    column 0 the phase φ (rad), then δ (nj columns), δ̇_a (na columns), the shape r (nj) and the
    actuated rate ṙ_a (na); :func:`regressor_input` builds it.  The last two blocks are read only
    by random shape features (``config.kernel_features`` > 0).  ``y`` is (n, n_out): the outputs
    (body velocity components, passive velocities, …).

    Parameters
    ----------
    config : SudsConfig
        Regression hyperparameters (regressor set, Fourier orders, ridge, forgetting, state,
        random features).
    n_actuated : int
        na, the number of actuated joints.  It is a hyperparameter because it says how to read
        the columns of X, which their count alone cannot tell: 1 + 2·(nj + na) columns fit
        several (nj, na).  The number of joints nj is learned from X (``n_joints_``).
    kernel_scale : KernelScale or None
        Standardisation of the shape and the actuated rate for random shape features (needed
        when ``config.kernel_features`` > 0, ignored otherwise).  The caller learns it from the
        gait template (:func:`~suds_ros.core.ident.shape_kernel.gait_kernel_scale`), which this
        regressor never sees; it fixes the feature map before any row is added (rows must not
        change meaning between ``partial_fit`` calls), so it is given like a hyperparameter,
        fitting never changes it, and a :func:`~suds_ros.core.estimator.clone` builds the same
        features.

    Attributes
    ----------
    coef_ : (p, n_out) fitted coefficients.
    n_features_in_ : int, the number of columns of X, 1 + 2·(nj + na).
    n_joints_ : int, nj.
    n_outputs_ : int, n_out.
    n_samples_seen_ : int, rows accumulated since the last :meth:`fit`.
    normal_ : NormalEquations, the accumulated (forgetting-weighted) XᵀX (p, p) and XᵀY of the
        outputs fitted row by row (all outputs unless averaged targets were given).
    normal_avg_ : NormalEquations or None, the same for the averaged outputs (design W·A).
    avg_columns_ : tuple of int, the outputs fitted on averaged targets (empty: none).
    layout_ : FeatureLayout

    With :class:`AveragedTargets` the averaged outputs are fitted on the averaged design rows
    W·A (the model is linear in its coefficients, so the average of the predictions is the
    prediction of the averaged row) and the other outputs on A; the two least-squares problems
    share nothing but the coefficient layout, so each keeps its own normal equations (and its
    own relative ridge).  Without averaged targets the fit is the plain one on A.
    """

    def __init__(self, config: SudsConfig = SudsConfig(), *, n_actuated: int,
                 kernel_scale: KernelScale | None = None) -> None:
        self.config = config
        self.n_actuated = n_actuated
        self.kernel_scale = kernel_scale

    def __sklearn_is_fitted__(self) -> bool:
        """Fitted once a solve has given coefficients."""
        return "coef_" in vars(self)

    def __setstate__(self, state: dict[str, object]) -> None:
        # regressors pickled before the estimator contract (checkpoint version 5) held the joint
        # count as the constructor argument ``n_joints``; their X always had the wide layout
        if "n_joints" in state:
            nj = int(state.pop("n_joints"))  # type: ignore[call-overload]
            if "normal_" in state:
                state["n_joints_"] = nj
                state["n_features_in_"] = 1 + 2 * (nj + int(state["n_actuated"]))  # type: ignore[call-overload]
        self.__dict__.update(state)

    # -------------------------------------------------------------- helpers
    def _check_params(self, n_columns: int) -> int:
        """Validate the hyperparameters for X with ``n_columns`` columns; returns nj."""
        if not isinstance(self.config, SudsConfig):
            raise SudsConfigError(f"`config`: expected a SudsConfig, got {self.config!r}")
        na = self.n_actuated
        if isinstance(na, bool) or not isinstance(na, (int, np.integer)) or na < 0:
            raise SudsConfigError(f"`n_actuated`: expected an integer ≥ 0, got {na!r}")
        nj = input_joints(n_columns, int(na))
        if self.config.kernel_features and nj > 0:
            sc = self.kernel_scale
            if not isinstance(sc, KernelScale):
                raise SudsConfigError(
                    f"`kernel_scale`: random shape features (config.kernel_features = "
                    f"{self.config.kernel_features}) need the gait's KernelScale, got {sc!r}")
            shapes = tuple(np.shape(getattr(sc, k)) for k in ("r_mean", "r_std", "u_mean", "u_std"))
            if shapes != ((nj,), (nj,), (int(na),), (int(na),)):
                raise SudsConfigError(
                    f"`kernel_scale`: expected scales of shapes ({nj},), ({nj},), ({na},), ({na},) for "
                    f"{nj} joints, {na} actuated, got {shapes}")
        return nj

    def _design(self, X: FloatArray) -> FloatArray:
        """The design of X for a fitted regressor: X as wide as in the first fit, hyperparameters unchanged."""
        return regressor_design(self.config, self._check_input(X), self.n_actuated, self.kernel_scale)

    def _check_input(self, X: FloatArray) -> FloatArray:
        """X as floats, checked: as wide as in the first fit, the layout unchanged since."""
        layout = feature_layout(self.config, self.n_joints_, int(self.n_actuated))
        if layout != self.layout_:
            raise SudsConfigError(
                f"`config`, `n_actuated`: set to a design of {layout.n_columns} columns after the first fit "
                f"laid out {self.layout_.n_columns}; call fit to start again")
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.n_features_in_:
            raise SudsDataError(
                f"X: expected shape (n, {self.n_features_in_}) = [phase, δ ({self.n_joints_}), δ̇_a "
                f"({self.n_actuated}), r ({self.n_joints_}), ṙ_a ({self.n_actuated})] as in the first fit, "
                f"got {X.shape}")
        return X

    @property
    def n_parameters(self) -> int:
        """Parameters per output."""
        check_is_fitted(self, "layout_")
        return self.layout_.n_columns

    # ----------------------------------------------------------------- API
    def fit(self, X: FloatArray, y: FloatArray, averaged: AveragedTargets | None = None) -> "SudsRegressor":
        """Fit from scratch on (X, y) and optional averaged targets (forgets everything learned)."""
        self._reset_learned()
        return self.partial_fit(X, y, averaged)

    def partial_fit(self, X: FloatArray, y: FloatArray, averaged: AveragedTargets | None = None) -> "SudsRegressor":
        """Add a chunk of samples to the sufficient statistics and re-solve.

        The first call (after construction or :meth:`fit`) validates the hyperparameters and
        learns nj from the width of X; later calls must give X as wide and y with as many outputs.
        ``averaged`` (see :class:`AveragedTargets`) must be given on the first call for the
        outputs it names to be fitted on averages; later calls may omit it (no averaged rows in
        that chunk).  With forgetting, the chunk's averaged rows are weighted as if spread
        evenly over its rows.

        Raises
        ------
        SudsConfigError
            Bad hyperparameters (first call).
        SudsDataError
            Malformed X or y, or X's column count / y's output count differs from the first call.
        """
        X = np.asarray(X, dtype=float)
        first = not hasattr(self, "n_features_in_")
        if first:
            if X.ndim != 2:
                raise SudsDataError(f"X: expected a 2-D array (n, 1 + 2·(nj + na)), got shape {X.shape}")
            nj = self._check_params(X.shape[1])
            split_regressor_input(X, self.n_actuated)  # the rows' own checks (finite, width)
            y = self._targets(y, X.shape[0], "y")
            self.n_features_in_ = X.shape[1]
            self.n_joints_ = nj
            self.layout_ = feature_layout(self.config, nj, int(self.n_actuated))
            self.avg_columns_ = () if averaged is None else tuple(int(c) for c in averaged.columns)
            self.n_outputs_ = y.shape[1] + len(self.avg_columns_)
            p = self.layout_.n_columns
            self.normal_ = NormalEquations(p, y.shape[1])
            self.normal_avg_ = NormalEquations(p, len(self.avg_columns_)) if self.avg_columns_ else None
        else:
            split_regressor_input(self._check_input(X), self.n_actuated)  # finite: no bad chunk half-added
            y = self._targets(y, X.shape[0], "y")
        if y.shape[1] != self.n_outputs_ - len(self.avg_columns_):
            raise SudsDataError(
                f"y: expected {self.n_outputs_ - len(self.avg_columns_)} outputs as before, got {y.shape[1]}")
        lam = self.config.forgetting
        m = X.shape[0]
        if averaged is not None:
            if tuple(averaged.columns) != self.avg_columns_:
                raise SudsDataError(f"averaged.columns: expected {self.avg_columns_} as on the first call, "
                                    f"got {tuple(averaged.columns)}")
            q = averaged.y.shape[0] if np.ndim(averaged.y) == 2 else np.size(averaged.y)
            ya = self._targets(averaged.y, q, "averaged.y")
            split_regressor_input(self._check_input(averaged.X), self.n_actuated)
            if lam < 1.0:
                Aa = np.asarray(averaged.weights @ self._design(averaged.X))
                wa = lam ** ((q - 1 - np.arange(q)) * (m / max(q, 1)))
                self.normal_avg_.add(Aa, ya, wa, decay=lam**m)  # type: ignore[union-attr]
            else:
                for a, b in self._blocks(q):
                    self.normal_avg_.add(self._averaged_design(averaged, a, b), ya[a:b])  # type: ignore[union-attr]
        elif self.normal_avg_ is not None and lam < 1.0 and m:
            self.normal_avg_.decay(lam**m)
        if lam < 1.0:
            self.normal_.add(self._design(X), y, lam ** np.arange(m - 1, -1, -1, dtype=float), decay=lam**m)
        else:
            for a, b in self._blocks(m):  # the design a block of rows at a time: memory bounded
                self.normal_.add(self._design(X[a:b]), y[a:b])
        self.n_samples_seen_ = self.normal_.n
        self._solve()
        return self

    def _blocks(self, n: int) -> list[tuple[int, int]]:
        """Row ranges whose designs hold at most :data:`BLOCK_ELEMENTS` values (one range if none)."""
        step = max(1, BLOCK_ELEMENTS // max(self.layout_.n_columns, 1))
        return [(a, min(a + step, n)) for a in range(0, n, step)] or [(0, 0)]

    def _averaged_design(self, averaged: AveragedTargets, a: int, b: int) -> FloatArray:
        """Rows a … b − 1 of the averaged design W·A (:func:`averaged_design_rows`)."""
        return averaged_design_rows(self.config, np.asarray(averaged.X), averaged.weights, self.n_actuated,
                                    self.kernel_scale, self.layout_.n_columns, a, b)

    @staticmethod
    def _targets(y: FloatArray, rows: int, name: str) -> FloatArray:
        y = np.asarray(y, dtype=float)
        if y.ndim == 1:
            y = y[:, None]
        if y.shape[0] != rows:
            raise SudsDataError(f"{name}: expected {rows} rows like its design, got {y.shape[0]}")
        if not np.all(np.isfinite(y)):
            raise SudsDataError(f"{name} contains NaN or Inf")
        return y

    def _solve(self) -> None:
        direct = self.normal_.solve(self.config.ridge)
        if self.normal_avg_ is None:
            self.coef_ = direct
            return
        coef = np.zeros((direct.shape[0], self.n_outputs_))
        rest = [c for c in range(self.n_outputs_) if c not in self.avg_columns_]
        coef[:, rest] = direct
        coef[:, list(self.avg_columns_)] = self.normal_avg_.solve(self.config.ridge)
        self.coef_ = coef

    def predict(self, X: FloatArray) -> FloatArray:
        """Predicted outputs (n, n_out), the design built a block of rows at a time."""
        check_is_fitted(self)
        X = np.asarray(X, dtype=float)
        blocks = self._blocks(X.shape[0]) if X.ndim == 2 else [(0, 0)]
        if len(blocks) == 1:
            return self._design(X) @ self.coef_
        return np.concatenate([self._design(X[a:b]) @ self.coef_ for a, b in blocks])

    def score(self, X: FloatArray, y: FloatArray) -> float:
        """Coefficient of determination R², averaged over outputs."""
        check_is_fitted(self)
        pred = self.predict(X)
        y = np.asarray(y, dtype=float).reshape(pred.shape)
        ss_res = ((y - pred) ** 2).sum(axis=0)
        ss_tot = ((y - y.mean(axis=0)) ** 2).sum(axis=0)
        return float(np.mean(1.0 - ss_res / np.where(ss_tot > 0, ss_tot, 1.0)))

    def coefficients(self, phase: FloatArray) -> dict[str, FloatArray]:
        """Coefficients evaluated at ``phase`` (k,).

        C (k, n_out), C_r (k, n_out, nj), B (k, n_out, na), B_r (k, n_out, nj, na), and for set 3
        D_rr, D_aa (packed upper triangles).
        """
        check_is_fitted(self)
        phase = np.asarray(phase, dtype=float)
        out: dict[str, FloatArray] = {}
        sl = self.layout_.slices()
        for name, f, order in self.layout_.groups:
            basis = fourier_basis(phase, order)  # (k, 2M+1)
            coef = self.coef_[sl[name]].reshape(f, 2 * order + 1, -1)  # (f, 2M+1, n_out)
            val = np.einsum("kb,fbo->kof", basis, coef)
            if name == "C":
                val = val[:, :, 0]
            elif name == "B_r":
                val = val.reshape(phase.size, -1, self.n_joints_, int(self.n_actuated))
            out[name] = val
        return out
