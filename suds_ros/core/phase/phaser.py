"""Asymptotic phase of a noisy multichannel rhythm from the data alone (the *phaser* idea).

Method (after Revzen & Guckenheimer 2008, Phys. Rev. E 78:051907; written from
the published description):

1. **Normalise.**  Each channel is z-scored with the training mean and standard
   deviation.  Constant channels are dropped.
2. **Protophase.**  The analytic signal x + i·H[x] of every channel (H the
   Hilbert transform) winds around the origin once per cycle; its unwrapped
   angle is a *protophase* ψ_i(t), which advances by 2π per cycle but not
   uniformly within it.  The FFT-based Hilbert transform assumes a periodic
   record, so each channel is padded on both ends with copies of its own first
   and last cycle, which pushes the wrap-around discontinuity away from the data.
3. **Per-channel correction.**  The true phase advances uniformly, so
   ψ_i − (uniform phase) is a periodic function of ψ_i.  The uniform phase is
   taken as the moving average of ψ_i over one cycle (this follows slow phase
   diffusion, unlike a single straight line), the deviation is regressed on a
   Fourier series P_i of order ``order`` in ψ_i, and Φ_i = ψ_i − P_i(ψ_i).
4. **Align and combine.**  Φ_i = Φ + c_i + noise.  The offsets c_i are circular
   means of Φ_i − Φ_ref; each channel is weighted by the inverse circular
   variance −1/(2 ln R_i) of that difference (R_i the mean resultant length), so
   noise-only channels (R_i ≈ 0) and channels at another frequency get weight ≈ 0
   (exactly 0 below ``min_coherence``).  The combined phase is the weighted
   circular mean, iterated a few times with the consensus as reference.
5. **Final correction and zero.**  The combined phase is corrected once more
   the same way; then phase zero is set where the first harmonic of a
   reference signal crosses upward through its mean: the first principal
   component of the used channels (sign chosen so its largest loading is
   positive) or ``zero_channel``.

``transform`` applies steps 1–5 with every learned quantity (normalisation,
cycle lengths, corrections, offsets, weights, zero) to a new segment.  It needs
the whole segment at once because of the Hilbert transform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal

from suds_ros.core._typing import BoolArray, FloatArray, IntArray
from suds_ros.core.errors import SudsConfigError, SudsDataError, SudsPhaseError
from suds_ros.core.estimator import BaseEstimator, check_is_fitted
from suds_ros.core.fourier import fourier_basis

_TWO_PI = 2.0 * np.pi
#: A channel whose standard deviation is below this fraction of the largest is "constant".
_CONSTANT_RTOL = 1e-9
#: Consensus iterations of the weighted circular mean.
_N_CONSENSUS = 3


@dataclass(frozen=True)
class PhaserConfig:
    """Hyperparameters of :class:`Phaser`.

    Parameters
    ----------
    order : int
        Fourier order (≥ 1) of the protophase corrections.
    min_cycles : float
        Fewest gait cycles (> 0) in the training data; fewer raise :class:`SudsPhaseError`.
    min_coherence : float
        Channels whose phase-locking value R ∈ [0, 1] to the consensus phase is
        below this get weight 0.  In [0, 1).
    zero_channel : int or None
        Channel whose mean upward crossing (of its first harmonic) defines phase
        zero; ``None`` uses the first principal component of the used channels.
    pad_cycles : float
        Periodic padding (in cycles, ≥ 0) on each end before the Hilbert transform.
    """

    order: int = 10
    min_cycles: float = 3.0
    min_coherence: float = 0.3
    zero_channel: int | None = None
    pad_cycles: float = 2.0

    def __post_init__(self) -> None:
        if isinstance(self.order, bool) or not isinstance(self.order, (int, np.integer)) or self.order < 1:
            raise SudsConfigError(f"`order`: expected an integer ≥ 1, got {self.order!r}")
        if not (np.isfinite(self.min_cycles) and self.min_cycles > 0):
            raise SudsConfigError(f"`min_cycles`: expected a finite number > 0, got {self.min_cycles!r}")
        if not 0 <= self.min_coherence < 1:
            raise SudsConfigError(f"`min_coherence`: expected a value in [0, 1), got {self.min_coherence!r}")
        if self.zero_channel is not None and (
            isinstance(self.zero_channel, bool)
            or not isinstance(self.zero_channel, (int, np.integer))
            or self.zero_channel < 0
        ):
            raise SudsConfigError(f"`zero_channel`: expected None or an integer ≥ 0, got {self.zero_channel!r}")
        if not (np.isfinite(self.pad_cycles) and self.pad_cycles >= 0):
            raise SudsConfigError(f"`pad_cycles`: expected a finite number ≥ 0, got {self.pad_cycles!r}")


# ---------------------------------------------------------------- helpers
def _check_X(X: FloatArray, n_features: int | None = None) -> FloatArray:
    X = np.asarray(X, dtype=float)
    if X.ndim != 2:
        raise SudsDataError(
            f"`X`: expected a 2-D array of shape (n_samples, n_channels), got shape {X.shape}"
            + (" (use X[:, None] for one channel)" if X.ndim == 1 else "")
        )
    if n_features is not None and X.shape[1] != n_features:
        raise SudsDataError(f"`X`: expected {n_features} channels as in fit, got {X.shape[1]}")
    if not np.all(np.isfinite(X)):
        row = int(np.flatnonzero(~np.all(np.isfinite(X), axis=1))[0])
        raise SudsDataError(f"`X`: expected finite values, got NaN/inf in row {row}: {X[row]!r}")
    return X


def _spectral_period(Z: FloatArray) -> FloatArray:
    """Period (samples) of the strongest non-DC spectral line of each column of Z (n, c)."""
    n = Z.shape[0]
    P = np.abs(np.fft.rfft(Z - Z.mean(axis=0), axis=0)) ** 2
    P[0] = 0.0
    k = np.argmax(P, axis=0)
    # parabolic interpolation of the log power around the peak
    kk = np.clip(k, 1, P.shape[0] - 2)
    cols = np.arange(Z.shape[1])
    lo, mid, hi = (np.log(P[kk + s, cols] + 1e-300) for s in (-1, 0, 1))
    den = lo - 2 * mid + hi
    shift = np.where(np.abs(den) > 0, 0.5 * (lo - hi) / np.where(den == 0, 1, den), 0.0)
    freq = np.clip(kk + np.clip(shift, -0.5, 0.5), 0.5, None)
    return np.asarray(n / freq, dtype=float)


def _protophase(Z: FloatArray, period: IntArray, pad_cycles: float) -> FloatArray:
    """Unwrapped Hilbert protophase (rad), shape like Z (n, c), with periodic end padding."""
    n, c = Z.shape
    per = np.clip(period, 2, n)
    L = int(round(pad_cycles * float(np.median(per))))
    if L > 0:
        cols = np.arange(c)
        left = np.mod(np.arange(-L, 0)[:, None], per[None, :])  # x(t) ≈ x(t + P): first cycle repeated
        right = n - per[None, :] + np.mod(np.arange(L)[:, None], per[None, :])
        Zp = np.concatenate([Z[left, cols], Z, Z[right, cols]], axis=0)
    else:
        Zp = Z
    analytic = scipy.signal.hilbert(Zp, axis=0)[L : L + n]
    return np.unwrap(np.angle(analytic), axis=0)


def _correction(psi: FloatArray, order: int) -> FloatArray:
    """Fourier coefficients (2·order + 1,) of ψ − (one-cycle moving average of ψ) as a function of ψ."""
    n = psi.size
    rate = (psi[-1] - psi[0]) / max(n - 1, 1)
    P = int(round(_TWO_PI / rate)) if rate > 0 else n
    P = max(3, min(P, n - 2 * order - 2))
    P += 1 - P % 2  # odd window, centred on a sample
    h = P // 2
    c = np.concatenate([[0.0], np.cumsum(psi - psi[0])])
    trend = (c[P:] - c[:-P]) / P + psi[0]
    centre = psi[h : n - h]
    B = fourier_basis(centre, order)
    coef, *_ = np.linalg.lstsq(B, centre - trend, rcond=None)
    coef[0] = 0.0  # keep only the periodic part: a constant is an offset, handled later
    return np.asarray(coef, dtype=float)


def _apply_correction(psi: FloatArray, coef: FloatArray, order: int) -> FloatArray:
    """Φ = ψ − P(ψ), with ψ of shape (n,) and coefficients (2·order + 1,)."""
    return np.asarray(psi - fourier_basis(psi, order) @ coef, dtype=float)


def _combine(Phi: FloatArray, offsets: FloatArray, weights: FloatArray, anchor: int) -> FloatArray:
    """Weighted circular mean over channels of Φ_i − c_i, unwrapped along the anchor channel."""
    ref = Phi[:, anchor] - offsets[anchor]
    D = np.exp(1j * (Phi - offsets[None, :] - ref[:, None]))
    return np.asarray(ref + np.angle(D @ weights), dtype=float)


def _coherence_weights(R: FloatArray, min_coherence: float) -> FloatArray:
    """Inverse circular variance −1/(2 ln R), 0 below ``min_coherence``."""
    Rc = np.clip(R, 1e-300, 1 - 1e-12)
    w = -1.0 / (2.0 * np.log(Rc))
    return np.asarray(np.where(R >= max(min_coherence, 1e-12), w, 0.0), dtype=float)


# ----------------------------------------------------------------- phaser
class Phaser(BaseEstimator):
    """Data-driven asymptotic phase estimator for multichannel quasi-periodic signals.

    Parameters
    ----------
    config : PhaserConfig
        Hyperparameters.

    Attributes
    ----------
    phase_ : ndarray, shape (n,)
        Unwrapped phase (rad) of the training samples, increasing with time;
        ``phase_[0]`` lies in [0, 2π).
    n_cycles_ : float
        Cycles spanned by the training data, (phase_[-1] − phase_[0]) / 2π.
    omega_per_sample_ : float
        Least-squares slope of ``phase_`` against sample index (rad/sample).
    n_features_in_ : int
        Number of channels.
    mean_, scale_ : ndarray, shape (n_channels,)
        Normalisation of each channel (units of X).
    used_ : ndarray of bool, shape (n_channels,)
        Channels that are not constant (they get a protophase).
    weights_ : ndarray, shape (n_channels,)
        Combination weights (0 for constant or incoherent channels).
    offsets_ : ndarray, shape (n_channels,)
        Phase offset c_i (rad) of each channel from the combined phase.
    coherence_ : ndarray, shape (n_channels,)
        Phase-locking value R_i ∈ [0, 1] of each channel to the combined phase.
    channel_coef_ : ndarray, shape (n_channels, 2·order + 1)
        Per-channel protophase corrections.
    period_ : ndarray of int, shape (n_channels,)
        Cycle length (samples) of each channel used for the Hilbert padding.
    combined_coef_ : ndarray, shape (2·order + 1,)
        Correction of the combined phase.
    zero_offset_ : float
        Phase (rad) added so that phase zero is the reference signal's upward crossing.
    zero_loadings_ : ndarray, shape (n_channels,), or None
        Channel loadings of the reference signal (None with ``zero_channel``).
    anchor_ : int
        Channel along which the combined phase is unwrapped.
    """

    def __init__(self, config: PhaserConfig = PhaserConfig()) -> None:
        self.config = config

    # --------------------------------------------------------------- fit
    def fit(self, X: FloatArray) -> "Phaser":
        """Learn the phase model from uniformly sampled data.

        Parameters
        ----------
        X : ndarray, shape (n_samples, n_channels)
            Uniformly sampled multichannel signal covering at least
            ``config.min_cycles`` cycles.

        Returns
        -------
        Phaser
            ``self``.

        Raises
        ------
        SudsDataError
            ``X`` is not 2-D or contains NaN/inf.
        SudsPhaseError
            Too few samples or cycles, or no channel oscillates.
        SudsConfigError
            ``zero_channel`` does not name a non-constant channel of ``X``.
        """
        self._reset_learned()
        cfg = self.config
        if not isinstance(cfg, PhaserConfig):
            raise SudsConfigError(f"`config`: expected a PhaserConfig, got {cfg!r}")
        X = _check_X(X)
        n, C = X.shape
        n_min = 4 * cfg.order + 4
        if n < n_min:
            raise SudsPhaseError(
                f"too little data to find a phase: `X` has {n} samples, need ≥ {n_min} for order {cfg.order}"
            )
        mean = X.mean(axis=0)
        scale = X.std(axis=0)
        used = scale > _CONSTANT_RTOL * max(float(scale.max()), np.finfo(float).tiny)
        if not used.any():
            raise SudsPhaseError("too little data to find a phase: every channel of `X` is constant")
        if cfg.zero_channel is not None:
            if cfg.zero_channel >= C:
                raise SudsConfigError(
                    f"`zero_channel`: expected a channel index < {C}, got {cfg.zero_channel!r}"
                )
            if not used[cfg.zero_channel]:
                raise SudsConfigError(
                    f"`zero_channel`: expected a non-constant channel, got channel {cfg.zero_channel} which is constant"
                )
        idx = np.flatnonzero(used)
        Z = (X[:, idx] - mean[idx]) / scale[idx]

        period = np.maximum(np.round(_spectral_period(Z)).astype(np.int64), 2)
        psi = _protophase(Z, period, cfg.pad_cycles)

        # coherence of the raw protophases picks the anchor and checks the amount of data
        E = np.exp(1j * psi)
        Rpair = np.abs(E.conj().T @ E) / n
        anchor0 = int(np.argmax(Rpair.sum(axis=1)))
        cycles = (psi[-1, anchor0] - psi[0, anchor0]) / _TWO_PI
        if not cycles >= cfg.min_cycles:
            raise SudsPhaseError(
                f"too little data to find a phase: {cycles:.2f} cycles detected, need ≥ {cfg.min_cycles:g}"
            )

        coef = np.stack([_correction(psi[:, j], cfg.order) for j in range(idx.size)])
        Phi = np.stack([_apply_correction(psi[:, j], coef[j], cfg.order) for j in range(idx.size)], axis=1)

        offsets, w, R = self._align(Phi, anchor0)
        anchor = int(np.argmax(w))
        combined = _combine(Phi, offsets, w, anchor)

        combined_coef = _correction(combined, cfg.order)
        phase = _apply_correction(combined, combined_coef, cfg.order)

        zero, loadings = self._zero_reference(Z, idx, w, phase)

        full = np.zeros(C)
        self.n_features_in_ = C
        self.mean_ = mean
        self.scale_ = np.where(used, scale, 1.0)
        self.used_ = np.asarray(used, dtype=np.bool_)
        self.period_ = np.zeros(C, dtype=np.int64)
        self.period_[idx] = period
        self.channel_coef_ = np.zeros((C, 2 * cfg.order + 1))
        self.channel_coef_[idx] = coef
        self.offsets_ = full.copy()
        self.offsets_[idx] = offsets
        self.weights_ = full.copy()
        self.weights_[idx] = w
        self.coherence_ = full.copy()
        self.coherence_[idx] = R
        self.anchor_ = int(idx[anchor])
        self.combined_coef_ = combined_coef
        self.zero_offset_ = zero
        self.zero_loadings_ = None if loadings is None else self._expand(loadings, idx, C)

        self.phase_ = self._finish(phase)
        self.n_cycles_ = float((self.phase_[-1] - self.phase_[0]) / _TWO_PI)
        k = np.arange(n, dtype=float)
        self.omega_per_sample_ = float(np.polyfit(k, self.phase_, 1)[0])
        return self

    def _zero_reference(self, Z: FloatArray, idx: FloatArray, w: FloatArray, phase: FloatArray
                        ) -> tuple[float, FloatArray | None]:
        """Phase offset of the reference event and the channel loadings that define it.

        The event is the upward mean crossing of the first harmonic of the reference signal:
        the ``zero_channel`` if configured, else the first principal component of the
        channels with weight.
        """
        cfg = self.config
        if cfg.zero_channel is not None:
            y = Z[:, int(np.flatnonzero(idx == cfg.zero_channel)[0])]
            loadings = None
        else:
            keep = w > 0
            _, _, Vt = np.linalg.svd(Z[:, keep], full_matrices=False)
            v = Vt[0]
            v = v * np.sign(v[np.argmax(np.abs(v))])
            loadings = np.zeros(idx.size)
            loadings[keep] = v
            y = Z @ loadings
        B = fourier_basis(phase, 1)
        (a0, a, b), *_ = np.linalg.lstsq(B, y, rcond=None)
        return float(np.arctan2(a, b)), loadings  # y ≈ a0 + A sin(φ + zero)

    def _align(self, Phi: FloatArray, anchor0: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Offsets c_i (rad), normalised weights and leave-one-out phase locking R_i of the channels.

        Starting from equal weights and offsets relative to ``anchor0``, each
        round measures every channel against the weighted consensus of the
        *other* channels (so a channel cannot lock to itself), and reweights.
        """
        n, c = Phi.shape
        U = np.exp(1j * Phi)
        m = (U * np.exp(-1j * Phi[:, anchor0])[:, None]).mean(axis=0)
        offsets = np.angle(m)
        w = np.ones(c)
        R = np.abs(m)
        for _ in range(_N_CONSENSUS):
            V = U * np.exp(-1j * offsets)[None, :]  # aligned unit phasors
            S = V @ w
            others = S[:, None] - V * w[None, :]
            mag = np.abs(others)
            ok = mag > 1e-12 * max(float(mag.max()), np.finfo(float).tiny)
            ref = np.where(ok, others / np.where(ok, mag, 1.0), 0.0)
            m = (U * ref.conj()).mean(axis=0)
            R = np.abs(m)
            offsets = np.angle(m) if c > 1 else np.zeros(1)
            w_new = _coherence_weights(R, self.config.min_coherence) if c > 1 else np.ones(1)
            if not np.any(w_new > 0):  # nothing locks to anything: keep the anchor alone
                w_new = (np.arange(c) == anchor0).astype(float)
            w = w_new / w_new.sum()
        if c == 1:
            R = np.ones(1)
        # express offsets relative to the final consensus of all channels
        V = U * np.exp(-1j * offsets)[None, :]
        S = V @ w
        m = (V * (S / np.maximum(np.abs(S), 1e-300)).conj()[:, None]).mean(axis=0)
        offsets = offsets + np.angle(m)
        return offsets, w, R

    @staticmethod
    def _expand(v: FloatArray, idx: IntArray, C: int) -> FloatArray:
        out = np.zeros(C)
        out[idx] = v
        return out

    def _finish(self, phase: FloatArray) -> FloatArray:
        phase = phase + self.zero_offset_
        return np.asarray(phase - _TWO_PI * np.floor(phase[0] / _TWO_PI), dtype=float)

    # --------------------------------------------------------- transform
    def transform(self, X: FloatArray) -> FloatArray:
        """Phase of a new segment using the learned corrections.

        Parameters
        ----------
        X : ndarray, shape (n_samples, n_channels)
            Uniformly sampled segment with the channels and sample rate of the
            training data (n_samples ≥ 2; longer segments give better edges).

        Returns
        -------
        ndarray, shape (n_samples,)
            Unwrapped phase in rad, first value in [0, 2π).
        """
        check_is_fitted(self)
        X = _check_X(X, self.n_features_in_)
        if X.shape[0] < 2:
            raise SudsDataError(f"`X`: expected at least 2 samples, got {X.shape[0]}")
        order = self.config.order
        idx = np.flatnonzero(self.used_)
        Z = (X[:, idx] - self.mean_[idx]) / self.scale_[idx]
        psi = _protophase(Z, self.period_[idx], self.config.pad_cycles)
        Phi = np.stack(
            [_apply_correction(psi[:, j], self.channel_coef_[i], order) for j, i in enumerate(idx)], axis=1
        )
        anchor = int(np.flatnonzero(idx == self.anchor_)[0])
        combined = _combine(Phi, self.offsets_[idx], self.weights_[idx], anchor)
        return self._finish(_apply_correction(combined, self.combined_coef_, order))

    def fit_transform(self, X: FloatArray) -> FloatArray:
        """Fit on ``X`` and return its phase (rad), shape (n_samples,)."""
        return np.asarray(self.fit(X).phase_.copy(), dtype=float)

    @property
    def used_channels(self) -> BoolArray:
        """Channels with non-zero combination weight, shape (n_channels,)."""
        check_is_fitted(self)
        return np.asarray(self.weights_ > 0, dtype=np.bool_)
