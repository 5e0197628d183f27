"""Coefficients that are functions of the whole shape: random features of r, affine in ṙ_a.

The SUDS reconstruction equation makes the body velocity and the passive rates functions of the
shape alone, (g°, ṙ_p) = C(r) + B(r)·ṙ_a; the Fourier groups of :mod:`~suds_ros.core.ident.sysid`
expand C and B to first or second order in δ about the gait.  With few training cycles, or
shapes far from the gait, a smooth non-parametric C(r), B(r) does better (paper, §"Estimation
for SUDS": a richer function class for the δ-dependence).  This module gives one that keeps
everything else — linear in the parameters, exact ``partial_fit`` on accumulated normal
equations, outputs affine in the actuated rate:

    K(r, ṙ_a) = [ψ(z), ψ(z) ⊗ u],   ψ_j(z) = cos(w_jᵀ z + b_j),   j = 1 … M

with z = (r − r̄)/σ_r the standardised shape, u = (ṙ_a − ū)/σ_u the standardised actuated
rate, w_j ~ N(0, 2γ·I) and b_j ~ U(0, 2π) drawn from ``kernel_seed`` (random Fourier features
of the Gaussian kernel exp(−γ‖z − z'‖²); Rahimi & Recht 2007).  The fitted coefficients on
ψ give C(r) and those on ψ ⊗ u give B(r)/σ_u, so the model still reads as C + B·ṙ_a.  The
scales are the gait's (:func:`gait_kernel_scale`), fixed once the template is, so the features
of a row never change after it is added.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsDataError


@dataclass(frozen=True)
class KernelScale:
    """Standardisation of the shape and actuated rate for the random features.

    Attributes
    ----------
    r_mean, r_std : (nj,) rad.
    u_mean, u_std : (na,) rad/s.
    """

    r_mean: FloatArray
    r_std: FloatArray
    u_mean: FloatArray
    u_std: FloatArray

    def to_dict(self) -> dict[str, list[float]]:
        """JSON-ready lists."""
        return {k: np.asarray(getattr(self, k), dtype=float).tolist() for k in ("r_mean", "r_std", "u_mean", "u_std")}

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> "KernelScale":
        """Inverse of :meth:`to_dict`."""
        return cls(*(np.asarray(d[k], dtype=float) for k in ("r_mean", "r_std", "u_mean", "u_std")))


def gait_kernel_scale(template: object, omega: float, actuated_index: FloatArray, n_grid: int = 256) -> KernelScale:
    """Scales from a fitted gait template θ(φ) and mean phase rate ω̄.

    The shape's mean and spread over one cycle of θ plus the template's residual variance; the
    actuated rate's mean and spread over the cycle of θ'(φ)·ω̄ (floored at 1 % of the largest, so
    a joint that barely moves does not blow up its features).
    """
    ph = np.linspace(0.0, 2.0 * np.pi, n_grid, endpoint=False)
    theta = template.predict(ph)  # type: ignore[attr-defined]
    rate = template.derivative(ph)[:, actuated_index] * omega  # type: ignore[attr-defined]
    r_std = np.sqrt(theta.var(axis=0) + np.asarray(template.residual_var_, dtype=float))  # type: ignore[attr-defined]
    u_std = rate.std(axis=0)
    return KernelScale(theta.mean(axis=0), np.maximum(r_std, 1e-2 * max(r_std.max(), 1e-12)),
                       rate.mean(axis=0), np.maximum(u_std, 1e-2 * max(u_std.max(), 1e-12)))


@lru_cache(maxsize=32)
def _draws(n_features: int, gamma: float, seed: int, n_joints: int) -> tuple[FloatArray, FloatArray]:
    rng = np.random.default_rng(seed)
    W = rng.normal(scale=np.sqrt(2.0 * gamma), size=(n_features, n_joints)).T  # (nj, M)
    b = rng.uniform(0.0, 2.0 * np.pi, size=n_features)
    W.setflags(write=False)
    b.setflags(write=False)
    return W, b


def kernel_features(n_features: int, gamma: float, seed: int, scale: KernelScale | None, r: FloatArray,
                    rdot_a: FloatArray, phase: FloatArray) -> FloatArray:
    """The design block [ψ(z), ψ(z) ⊗ u] (n, M·(1 + na)) of shapes r (n, nj) and actuated rates (n, na)."""
    if scale is None:
        raise SudsDataError("`kernel_scale`: random-feature coefficients need the gait's scales, got None")
    W, b = _draws(int(n_features), float(gamma), int(seed), r.shape[1] + 2)
    z = np.concatenate([(r - scale.r_mean) / scale.r_std,
                        np.sqrt(2.0) * np.column_stack([np.cos(phase), np.sin(phase)])], axis=1)
    psi = np.cos(z @ W + b)
    u = (rdot_a - scale.u_mean) / scale.u_std
    return np.concatenate([psi, (psi[:, :, None] * u[:, None, :]).reshape(psi.shape[0], -1)], axis=1)
