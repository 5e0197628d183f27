"""Truncated Fourier series in the gait phase, and the normal equations of their fits.

Every phase-dependent quantity of the package (the gait template θ(φ), the
phase-only output template, the SUDS coefficients) is a truncated Fourier series

    f(φ) = a_0 + Σ_{m=1..M} (a_m cos mφ + b_m sin mφ),

evaluated through one design matrix, :func:`fourier_basis`, whose columns are
[1, cos φ, sin φ, …, cos Mφ, sin Mφ] (and their phase derivatives).  The
least-squares fits of such series keep their sufficient statistics in one
accumulator, :class:`NormalEquations`, so fitting in chunks (``add``) or in
separate processes (``merge``) gives the fit on the whole data.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsDataError


def n_coefficients(order: int) -> int:
    """Columns of the basis of order M: 2·M + 1."""
    return 2 * int(order) + 1


def _harmonics(phase: FloatArray | float, order: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    phase = np.atleast_1d(np.asarray(phase, dtype=float))
    if phase.ndim != 1:
        raise SudsDataError(f"`phase`: expected a 1-D array of shape (n,), got shape {phase.shape}")
    m = np.arange(1, order + 1, dtype=float)
    ang = phase[:, None] * m[None, :]
    return m, np.cos(ang), np.sin(ang)


def fourier_basis(phase: FloatArray | float, order: int, derivative: int = 0) -> FloatArray:
    """Design matrix [1, cos φ, sin φ, …, cos Mφ, sin Mφ] or its ``derivative``-th phase derivative.

    Parameters
    ----------
    phase : array_like, shape (n,)
        Phase φ, rad (wrapped or unwrapped).
    order : int
        Number of harmonics M ≥ 0.
    derivative : int
        Derivative order k ≥ 0 in φ (0: the basis itself).

    Returns
    -------
    ndarray, shape (n, 2·M + 1)
        In units of rad⁻ᵏ.
    """
    if derivative < 0:
        raise SudsDataError(f"`derivative`: expected an integer ≥ 0, got {derivative!r}")
    m, cos, sin = _harmonics(phase, order)
    out = np.empty((cos.shape[0], 2 * order + 1))
    out[:, 0] = 1.0 if derivative == 0 else 0.0
    if order:
        # d/dφ (cos, sin) = m (−sin, cos): the pair rotates a quarter turn per derivative
        k = derivative % 4
        c_col, s_col = ((cos, sin), (-sin, cos), (-cos, -sin), (sin, -cos))[k]
        if derivative:
            gain = m[None, :] ** derivative
            np.multiply(gain, c_col, out=out[:, 1::2])
            np.multiply(gain, s_col, out=out[:, 2::2])
        else:  # the harmonics themselves (no scaled copy)
            out[:, 1::2] = c_col
            out[:, 2::2] = s_col
    return out


def fourier_basis_and_derivative(phase: FloatArray | float, order: int) -> tuple[FloatArray, FloatArray]:
    """:func:`fourier_basis` and its first derivative from one evaluation of the harmonics."""
    m, cos, sin = _harmonics(phase, order)
    n = cos.shape[0]
    B = np.empty((n, 2 * order + 1))
    dB = np.empty((n, 2 * order + 1))
    B[:, 0], dB[:, 0] = 1.0, 0.0
    B[:, 1::2], B[:, 2::2] = cos, sin
    dB[:, 1::2], dB[:, 2::2] = -m * sin, m * cos
    return B, dB


def ridge_solve(G: FloatArray, b: FloatArray, ridge: float, scale: float | None = None) -> FloatArray:
    """Solve (G + ridge·scale·I) x = b for a symmetric G; ``scale`` defaults to mean(diag G).

    Cholesky factorisation; least squares when the matrix is not positive definite.
    """
    if scale is None:
        scale = float(np.mean(np.diag(G)))
    reg = G + (ridge * (scale or 1.0)) * np.eye(G.shape[0])
    try:
        return scipy.linalg.cho_solve(scipy.linalg.cho_factor(reg, check_finite=False), b, check_finite=False)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(reg, b, rcond=None)[0]


class NormalEquations:
    """Weighted least-squares sufficient statistics XᵀWX, XᵀWY, YᵀWY, Σw and n.

    Parameters
    ----------
    n_features : int
        Columns p of the design X.
    n_outputs : int
        Columns d of the targets Y.

    Attributes
    ----------
    xtx : (p, p) XᵀWX.
    xty : (p, d) XᵀWY.
    yty : (d,) Σ w·y² per output.
    sw : float, Σ w.
    n : int, samples added.
    """

    def __init__(self, n_features: int, n_outputs: int) -> None:
        self.xtx = np.zeros((n_features, n_features))
        self.xty = np.zeros((n_features, n_outputs))
        self.yty = np.zeros(n_outputs)
        self.sw = 0.0
        self.n = 0

    @property
    def n_features(self) -> int:
        """Columns p of the design."""
        return self.xtx.shape[0]

    @property
    def n_outputs(self) -> int:
        """Columns d of the targets."""
        return self.xty.shape[1]

    def add(self, X: FloatArray, Y: FloatArray, sample_weight: FloatArray | None = None,
            decay: float = 1.0) -> "NormalEquations":
        """Add rows X (m, p), Y (m, d) with weights (m,); earlier statistics are scaled by ``decay``."""
        if X.shape[1] != self.n_features or Y.shape[1] != self.n_outputs or X.shape[0] != Y.shape[0]:
            raise SudsDataError(
                f"`X`, `Y`: expected shapes (m, {self.n_features}) and (m, {self.n_outputs}), "
                f"got {X.shape} and {Y.shape}")
        if sample_weight is None:
            Xw, YY, sw = X, (Y * Y).sum(axis=0), float(X.shape[0])
        else:
            Xw, YY, sw = X * sample_weight[:, None], sample_weight @ (Y * Y), float(sample_weight.sum())
        if decay != 1.0:
            self.xtx, self.xty, self.yty, self.sw = (decay * self.xtx, decay * self.xty, decay * self.yty,
                                                     decay * self.sw)
        self.xtx = self.xtx + Xw.T @ X
        self.xty = self.xty + Xw.T @ Y
        self.yty = self.yty + YY
        self.sw += sw
        self.n += int(X.shape[0])
        return self

    def decay(self, factor: float) -> "NormalEquations":
        """Scale the accumulated statistics by ``factor`` (forgetting without new rows)."""
        self.xtx, self.xty, self.yty, self.sw = (factor * self.xtx, factor * self.xty, factor * self.yty,
                                                 factor * self.sw)
        return self

    def merge(self, other: "NormalEquations") -> "NormalEquations":
        """Add the statistics of ``other`` (same shapes) to these."""
        if other.xty.shape != self.xty.shape:
            raise SudsDataError(f"`other`: expected statistics of shape {self.xty.shape}, got {other.xty.shape}")
        self.xtx = self.xtx + other.xtx
        self.xty = self.xty + other.xty
        self.yty = self.yty + other.yty
        self.sw += other.sw
        self.n += other.n
        return self

    def well_posed(self, rcond: float) -> bool:
        """True when λ_min/λ_max of XᵀWX is at least ``rcond`` (the coefficients are determined)."""
        if self.n < self.n_features:
            return False
        eig = np.linalg.eigvalsh(self.xtx)
        return bool(eig[-1] > 0 and eig[0] >= rcond * eig[-1])

    def solve(self, ridge: float = 0.0) -> FloatArray:
        """Coefficients (p, d) minimising the weighted squares plus λ‖c‖², λ = ridge · mean(diag XᵀWX).

        Cholesky factorisation of the regularised normal matrix; least squares when it is
        not positive definite.
        """
        return ridge_solve(self.xtx, self.xty, ridge)

    def residual_ss(self, coef: FloatArray) -> FloatArray:
        """Weighted residual sum of squares (d,) of ``coef`` (p, d), from the statistics alone."""
        rss = (self.yty - 2 * np.einsum("pd,pd->d", coef, self.xty)
               + np.einsum("pd,pq,qd->d", coef, self.xtx, coef))
        return np.maximum(rss, 0.0)
