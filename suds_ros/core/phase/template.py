"""Phase-averaged gait template: a truncated Fourier series θ(φ) fitted by least squares.

The template of a gait is the average shape as a function of the asymptotic
phase φ (rad).  Each output channel is modelled as

    θ_j(φ) = a_0j + Σ_{k=1..M} (a_kj cos kφ + b_kj sin kφ),

which is periodic in φ by construction, so the phase may be given wrapped or
unwrapped.  The sufficient statistics are the weighted normal equations
BᵀWB, BᵀWY (B the design of :func:`~suds_ros.core.fourier.fourier_basis`), so ``partial_fit``
on chunks reproduces ``fit`` on the whole data up to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.estimator import BaseEstimator, check_is_fitted, is_fitted
from suds_ros.core.fourier import NormalEquations, fourier_basis, n_coefficients

#: Smallest accepted eigenvalue ratio λ_min/λ_max of the normal matrix.
_RCOND = 1e-12


@dataclass(frozen=True)
class FourierTemplateConfig:
    """Hyperparameters of :class:`FourierTemplate`.

    Parameters
    ----------
    order : int
        Number of harmonics M ≥ 0; the template has 2·M + 1 coefficients per channel.
    """

    order: int = 8

    def __post_init__(self) -> None:
        if isinstance(self.order, bool) or not isinstance(self.order, (int, np.integer)) or self.order < 0:
            raise SudsConfigError(f"`order`: expected an integer ≥ 0, got {self.order!r}")


def _as_phase(phase: FloatArray | float, name: str = "phase") -> FloatArray:
    """Return ``phase`` as a finite 1-D float array (a scalar becomes shape (1,))."""
    arr = np.atleast_1d(np.asarray(phase, dtype=float))
    if arr.ndim != 1:
        raise SudsDataError(f"`{name}`: expected a 1-D array of shape (n,), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise SudsDataError(f"`{name}`: expected finite values, got {float(arr[bad])!r} at index {bad}")
    return arr


class FourierTemplate(BaseEstimator):
    """Least-squares Fourier series template θ(φ) of a multichannel periodic signal.

    Parameters
    ----------
    config : FourierTemplateConfig
        Fourier order.

    Attributes
    ----------
    coef_ : ndarray, shape (2·order + 1, d)
        Coefficients in the column order of :func:`~suds_ros.core.fourier.fourier_basis`:
        [1, cos φ, sin φ, …, cos Mφ, sin Mφ].
    n_samples_seen_ : int
        Number of samples accumulated since the last reset.
    n_features_in_ : int
        Number of output channels d.
    residual_var_ : ndarray, shape (d,)
        Weighted mean squared residual of each channel (units of Y squared).
    normal_ : NormalEquations
        Accumulated weighted normal equations (p = 2·order + 1 features, d outputs).

    Examples
    --------
    >>> phi = np.linspace(0, 20 * np.pi, 1000)
    >>> tmpl = FourierTemplate(FourierTemplateConfig(order=2)).fit(phi, np.c_[np.cos(phi)])
    >>> tmpl.predict(np.array([0.0])).round(6)
    array([[1.]])
    """

    def __init__(self, config: FourierTemplateConfig = FourierTemplateConfig()) -> None:
        self.config = config

    def __sklearn_is_fitted__(self) -> bool:
        """Fitted once the accumulated data determine every coefficient (``coef_``)."""
        return "coef_" in vars(self)

    @property
    def n_coefficients(self) -> int:
        """Coefficients per channel, 2·order + 1."""
        return n_coefficients(self.config.order)

    def fit(
        self, phase: FloatArray, Y: FloatArray, sample_weight: FloatArray | None = None,
        mix: object | None = None,
    ) -> "FourierTemplate":
        """Fit the template from scratch.

        Parameters
        ----------
        phase : ndarray, shape (n,)
            Phase of each sample in rad (wrapped or unwrapped).
        Y : ndarray, shape (n, d) or (n,)
            Samples; a 1-D ``Y`` is treated as one channel (d = 1).
        sample_weight : ndarray, shape (n,), optional
            Non-negative weights of the squared residuals.
        mix : (n, m) dense or scipy.sparse weights, optional
            The samples are averages: row i of ``Y`` is Σ_k mix[i, k]·θ(φ_k) over the m
            phases given in ``phase`` (e.g. a velocity measured over an interval that spans
            several intervals of the phase's stream).

        Returns
        -------
        FourierTemplate
            ``self``.

        Raises
        ------
        SudsDataError
            Malformed input, or too few samples / too narrow a spread of phases for the order.
        """
        self._reset_learned()
        self.partial_fit(phase, Y, sample_weight, mix)
        return self.fit_check()

    def fit_check(self) -> "FourierTemplate":
        """``self`` once the data given so far determine every coefficient (else :class:`SudsDataError`)."""
        if not is_fitted(self):
            p = self.n_coefficients
            raise SudsDataError(
                f"`phase`: too few samples for a Fourier template of order {self.config.order}: "
                f"need ≥ {p} samples spread over the cycle, got {self.n_samples_seen_} samples "
                "whose phases leave the normal equations singular"
            )
        return self

    def partial_fit(
        self, phase: FloatArray, Y: FloatArray, sample_weight: FloatArray | None = None,
        mix: object | None = None,
    ) -> "FourierTemplate":
        """Accumulate a chunk into the normal equations and re-solve.

        Parameters are as for :meth:`fit`.  While the accumulated data cannot
        determine every coefficient (fewer than 2·order + 1 samples, or phases
        bunched together) the template stays unfitted and no error is raised;
        ``fit`` raises in that case.

        Returns
        -------
        FourierTemplate
            ``self``.
        """
        if not isinstance(self.config, FourierTemplateConfig):
            raise SudsConfigError(f"`config`: expected a FourierTemplateConfig, got {self.config!r}")
        phase = _as_phase(phase)
        Y = np.asarray(Y, dtype=float)
        if Y.ndim == 1:
            Y = Y[:, None]
        if Y.ndim != 2:
            raise SudsDataError(f"`Y`: expected shape (n, d) or (n,), got shape {Y.shape}")
        basis = fourier_basis(phase, self.config.order)
        if mix is not None:
            if mix.shape[1] != phase.size:  # type: ignore[attr-defined]
                raise SudsDataError(f"`mix`: expected {phase.size} columns to match `phase`, "
                                    f"got shape {mix.shape}")  # type: ignore[attr-defined]
            basis = np.asarray(mix @ basis)  # type: ignore[operator]
        rows = basis.shape[0]
        if Y.shape[0] != rows:
            raise SudsDataError(
                f"`Y`: expected {rows} rows to match `{'mix' if mix is not None else 'phase'}`, got shape {Y.shape}"
            )
        if not np.all(np.isfinite(Y)):
            raise SudsDataError(f"`Y`: expected finite values, got {int((~np.isfinite(Y)).sum())} NaN/inf entries")
        if sample_weight is None:
            w = np.ones(rows)
        else:
            w = np.asarray(sample_weight, dtype=float)
            if w.shape != (rows,):
                raise SudsDataError(f"`sample_weight`: expected shape {(rows,)}, got shape {w.shape}")
            if not np.all(np.isfinite(w)) or np.any(w < 0):
                raise SudsDataError("`sample_weight`: expected finite values ≥ 0, got negative or non-finite entries")

        if not hasattr(self, "n_samples_seen_"):
            self.n_features_in_ = Y.shape[1]
            self.normal_ = NormalEquations(self.n_coefficients, Y.shape[1])
            self.n_samples_seen_ = 0
        elif Y.shape[1] != self.n_features_in_:
            raise SudsDataError(
                f"`Y`: expected {self.n_features_in_} channels as in earlier calls, got {Y.shape[1]}"
            )

        self.normal_.add(basis, Y, w)
        self.n_samples_seen_ += rows
        self._solve()
        return self

    def _solve(self) -> None:
        if not self.normal_.well_posed(_RCOND):
            return
        self.coef_ = self.normal_.solve()
        self.residual_var_ = self.normal_.residual_ss(self.coef_) / max(self.normal_.sw, np.finfo(float).tiny)

    # ---------------------------------------------------------- predict
    def predict(self, phase: FloatArray | float) -> FloatArray:
        """Template values θ(φ).

        Parameters
        ----------
        phase : array_like, shape (n,)
            Phase in rad.

        Returns
        -------
        ndarray, shape (n, d)
        """
        check_is_fitted(self)
        return fourier_basis(_as_phase(phase), self.config.order) @ self.coef_

    def derivative(self, phase: FloatArray | float, k: int = 1) -> FloatArray:
        """k-th phase derivative d^kθ/dφ^k.

        Parameters
        ----------
        phase : array_like, shape (n,)
            Phase in rad.
        k : int
            Derivative order ≥ 0 (0 gives :meth:`predict`).

        Returns
        -------
        ndarray, shape (n, d)
            In units of Y per rad^k.
        """
        check_is_fitted(self)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 0:
            raise SudsConfigError(f"`k`: expected an integer ≥ 0, got {k!r}")
        return fourier_basis(_as_phase(phase), self.config.order, int(k)) @ self.coef_
