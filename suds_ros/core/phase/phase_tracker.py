"""Sample-by-sample phase tracking against a fitted gait template.

After the batch :class:`~suds_ros.core.phase.phaser.Phaser` has given the phase of an
initial stretch of data and a :class:`~suds_ros.core.phase.template.FourierTemplate`
θ(φ) has been fitted to it, the live estimator follows the phase one sample at
a time:

1. **Predict** φ⁻ = φ_prev + ω·(t − t_prev).
2. **Match** the sample to the template: a few Gauss–Newton steps on
   ‖W(r − θ(φ))‖² started at φ⁻, each step and the total move bounded by
   ``max_step``, give φ*.
3. **Robustify**: the weighted mean squared residual at φ* is compared with a
   running residual scale s²; a sample that no phase explains (z² = res²/s² above
   ``outlier_threshold``²) has its correction shrunk by threshold²/z².
4. **Correct** φ = φ⁻ + gain·ρ·(φ* − φ⁻) and **adapt** the rate
   ω ← ω + gain·ρ·(φ* − φ⁻)/``omega_tau`` (a second-order phase-locked loop),
   with ω kept within [ω₀/2, 2ω₀].
"""

from __future__ import annotations

import math

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.core.estimator import check_is_fitted
from suds_ros.core.phase.template import FourierTemplate

#: Forgetting rate of the running residual scale (per accepted sample).
_SCALE_RATE = 0.02


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise SudsConfigError(f"`{name}`: expected a finite number > 0, got {value!r}")
    return v


def _complex_coefficients(coef: FloatArray, order: int) -> FloatArray:
    """Rows [C; i·m·C] (2·nj, M + 1) of θ and dθ/dφ from real Fourier coefficients (2M + 1, nj)."""
    coef = np.asarray(coef, dtype=float)
    C = np.empty((order + 1, coef.shape[1]), dtype=complex)
    C[0] = coef[0]
    C[1:] = coef[1::2] - 1j * coef[2::2]
    m = np.arange(order + 1)[:, None]
    return np.concatenate([C, 1j * m * C], axis=1).T


class PhaseTracker:
    """Online phase estimate by matching each shape sample to a gait template.

    Parameters
    ----------
    template : FourierTemplate
        Template θ(φ) fitted on phase (rad) → shape r, with d = nj channels.
    omega : float
        Initial phase rate (rad/s), > 0.
    phase0 : float
        Phase (rad, unwrapped) at time ``t0``.
    t0 : float
        Time (s) of the last sample covered by the initialisation.
    gain : float
        Fraction in (0, 1] of the template-matching correction applied per sample.
    omega_tau : float
        Time constant (s) of the rate adaptation; larger adapts ω more slowly.
    max_step : float
        Largest phase correction (rad) per sample, > 0.
    n_iter : int
        Gauss–Newton steps per sample, ≥ 1.
    weights : ndarray, shape (nj,), optional
        Channel weights W (1/units of r).  Default: 1/√(template residual variance),
        i.e. the channels the template fits best count most.
    outlier_threshold : float
        Normalised residual z above which a sample is down-weighted, > 0.

    Attributes
    ----------
    phase : float
        Current unwrapped phase (rad).
    omega : float
        Current rate estimate (rad/s).
    t : float
        Time (s) of the last update.
    n_updates_ : int
        Samples processed.
    n_outliers_ : int
        Samples whose correction was down-weighted.
    """

    def __init__(
        self,
        template: FourierTemplate,
        omega: float,
        phase0: float,
        t0: float,
        *,
        gain: float = 0.1,
        omega_tau: float = 5.0,
        max_step: float = 0.5,
        n_iter: int = 3,
        weights: FloatArray | None = None,
        outlier_threshold: float = 4.0,
    ) -> None:
        check_is_fitted(template, msg="`template`: expected a fitted FourierTemplate, got an unfitted %(name)s")
        self.template = template
        self.omega0 = _positive("omega", omega)
        self.omega = self.omega0
        if not (np.isfinite(phase0) and np.isfinite(t0)):
            raise SudsConfigError(f"`phase0`, `t0`: expected finite numbers, got {phase0!r}, {t0!r}")
        self.phase = float(phase0)
        self.t = float(t0)
        g = float(gain)
        if not 0 < g <= 1:
            raise SudsConfigError(f"`gain`: expected a value in (0, 1], got {gain!r}")
        self.gain = g
        self.omega_tau = _positive("omega_tau", omega_tau)
        self.max_step = _positive("max_step", max_step)
        if isinstance(n_iter, bool) or not isinstance(n_iter, (int, np.integer)) or n_iter < 1:
            raise SudsConfigError(f"`n_iter`: expected an integer ≥ 1, got {n_iter!r}")
        self.n_iter = int(n_iter)
        self.outlier_threshold = _positive("outlier_threshold", outlier_threshold)

        nj = template.coef_.shape[1]
        self.n_channels = nj
        resid = np.asarray(template.residual_var_, dtype=float)
        if weights is None:
            amp = np.var(template.predict(np.linspace(0, 2 * np.pi, 64, endpoint=False)), axis=0)
            floor = 1e-6 * max(float(amp.mean()), np.finfo(float).tiny)
            w2 = 1.0 / np.maximum(resid, floor)
        else:
            w = np.asarray(weights, dtype=float)
            if w.shape != (nj,) or not np.all(np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
                raise SudsConfigError(
                    f"`weights`: expected {nj} finite values ≥ 0, not all 0, got {weights!r}"
                )
            w2 = w**2
        self._w2 = w2
        self._w2_sum = float(np.sum(w2))
        self._complex_coef = _complex_coefficients(template.coef_, template.config.order)
        self._m = np.arange(template.config.order + 1, dtype=float)
        # expected weighted residual per channel at the template's own fit
        self._s2 = max(float(np.mean(w2 * resid)), 1e-12)
        self.n_updates_ = 0
        self.n_outliers_ = 0

    def _eval(self, phi: float) -> tuple[FloatArray, FloatArray]:
        """θ(φ) and dθ/dφ, each shape (nj,), from one evaluation of the harmonics.

        θ(φ) = Re Σ_m C_m e^{imφ} with C_m = a_m − i·b_m (the template's cos and sin
        coefficients), and dθ/dφ = Re Σ_m i·m·C_m e^{imφ}: one complex exponential and one
        matrix-vector product per evaluation (the tracker runs once per sample).
        """
        v = (self._complex_coef @ np.exp(1j * phi * self._m)).real
        n = self.n_channels
        return v[:n], v[n:]

    def _check_r(self, r: FloatArray) -> FloatArray:
        r = np.asarray(r, dtype=float)
        if r.shape != (self.n_channels,):
            raise SudsDataError(f"`r`: expected shape ({self.n_channels},), got shape {r.shape}")
        # one test for NaN, Inf and values so large that their sum overflows: the tracker's own
        # sums would overflow on those too and leave its phase NaN for every later sample
        if not math.isfinite(float(r.sum())):
            raise SudsDataError(f"`r`: expected finite values whose sum is finite, got {r!r}")
        return r

    def update(self, t: float, r: FloatArray) -> float:
        """Advance to time ``t`` with shape sample ``r``.

        Parameters
        ----------
        t : float
            Sample time (s), not earlier than the previous one.
        r : ndarray, shape (nj,)
            Shape sample in the units of the template.

        Returns
        -------
        float
            Unwrapped phase (rad) at ``t``.
        """
        t = float(t)
        dt = t - self.t
        if not (math.isfinite(t) and dt >= 0):
            raise SudsDataError(f"`t`: expected a finite time ≥ the previous {self.t!r} s, got {t!r}")
        r = self._check_r(r)
        pred = self.phase + self.omega * dt
        phi = pred
        w2 = self._w2
        eps = 1e-12 * self._w2_sum
        lo, hi, ms = pred - self.max_step, pred + self.max_step, self.max_step
        for _ in range(self.n_iter):
            theta, J = self._eval(phi)
            w2J = w2 * J
            g = float(w2J @ (r - theta))
            H = float(w2J @ J) + eps
            step = min(max(g / H, -ms), ms)
            phi = min(max(phi + step, lo), hi)
        e = r - self._eval(phi)[0]
        res2 = float(w2 @ (e * e)) / self.n_channels
        c2 = self.outlier_threshold**2
        z2 = res2 / self._s2
        rho = 1.0 if z2 <= c2 else c2 / z2
        if rho < 1.0:
            self.n_outliers_ += 1
        delta = self.gain * rho * (phi - pred)
        # the gait never runs backwards: a correction may at most cancel the predicted advance
        delta = max(delta, -self.omega * dt)
        self.phase = pred + delta
        self.omega = min(max(self.omega + delta / self.omega_tau, 0.5 * self.omega0), 2.0 * self.omega0)
        self._s2 += _SCALE_RATE * (min(res2, c2 * self._s2) - self._s2)
        self._s2 = max(self._s2, 1e-12)
        self.t = t
        self.n_updates_ += 1
        return self.phase

    def update_batch(self, t: FloatArray, R: FloatArray) -> FloatArray:
        """Apply :meth:`update` to each row.

        Parameters
        ----------
        t : ndarray, shape (n,)
            Non-decreasing sample times (s).
        R : ndarray, shape (n, nj)
            Shape samples.

        Returns
        -------
        ndarray, shape (n,)
            Unwrapped phase (rad) after each sample.
        """
        t = np.asarray(t, dtype=float)
        R = np.asarray(R, dtype=float)
        if t.ndim != 1 or R.shape != (t.size, self.n_channels):
            raise SudsDataError(
                f"`t`, `R`: expected shapes (n,) and (n, {self.n_channels}), got {t.shape} and {R.shape}"
            )
        return np.array([self.update(float(tk), R[k]) for k, tk in enumerate(t)], dtype=float)
