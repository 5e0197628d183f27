"""PhaseTracker: follows the true phase after a phaser/template initialisation, rejects outliers, errors.

Measured on the synthetic oscillator below (50 cycles at 100 Hz, phaser on the
first 10 cycles, tracking the remaining 40), seeds 0–3, default gain 0.1:
RMS phase error 0.067–0.076 rad relative to the initialisation's offset.
"""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import NotFittedError, SudsConfigError, SudsDataError
from suds_ros.core.phase.phase_tracker import PhaseTracker
from suds_ros.core.phase.phaser import Phaser
from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig

FS = 100.0
N_INIT = 1000


def oscillator(cycles: float = 50, seed: int = 0):
    """Four non-sinusoidal channels + OU perturbation (κ = 8/s, 12 %) + 1e-3 noise, plus a noise channel."""
    rng = np.random.default_rng(seed)
    n = int(round(cycles * FS))
    dt = 1 / FS
    t = np.arange(n) * dt
    phi = 2 * np.pi * t + np.cumsum(np.sqrt(2 * 0.01 * dt) * rng.normal(size=n))
    amps = np.array([1.0, 2.0, 0.5, 1.5])
    x = phi[:, None] + np.array([0.0, 1.1, 2.5, 4.0])
    f = np.cos(x) + 0.3 * np.cos(2 * x + 0.5) + 0.15 * np.cos(3 * x + 1.0)
    f *= amps / np.sqrt(2) / f.std(axis=0)
    a = np.exp(-8.0 * dt)
    e = rng.normal(size=(n, 4)) * 0.12 * amps
    ou = np.empty_like(e)
    ou[0] = e[0]
    for k in range(1, n):
        ou[k] = a * ou[k - 1] + np.sqrt(1 - a * a) * e[k]
    X = f + np.array([0.3, -1.0, 5.0, 0.0]) + ou + 1e-3 * rng.normal(size=(n, 4))
    return t, phi, np.column_stack([X, 0.7 * rng.normal(size=n)])


def initialise(seed: int = 0):
    t, phi, X = oscillator(seed=seed)
    ph = Phaser().fit_transform(X[:N_INIT])
    tmpl = FourierTemplate(FourierTemplateConfig(order=8)).fit(ph, X[:N_INIT])
    omega = float((ph[-1] - ph[0]) / (t[N_INIT - 1] - t[0]))
    offset = np.angle(np.mean(np.exp(1j * (ph - phi[:N_INIT]))))
    return t, phi, X, tmpl, omega, float(ph[-1]), offset


def wrapped(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


@pytest.mark.parametrize("seed", [0, 3])
def test_follows_true_phase(seed: int) -> None:
    t, phi, X, tmpl, omega, ph0, offset = initialise(seed)
    tracker = PhaseTracker(tmpl, omega, ph0, t[N_INIT - 1])
    est = tracker.update_batch(t[N_INIT:], X[N_INIT:])
    err = wrapped(est - phi[N_INIT:] - offset)  # keep the offset of the initialisation: no re-alignment
    assert np.sqrt(np.mean(err**2)) < 0.12  # measured ≈ 0.07
    assert np.max(np.abs(err)) < 0.6
    assert tracker.omega == pytest.approx(2 * np.pi, rel=0.05)
    assert np.all(np.diff(est) >= 0)
    assert tracker.n_updates_ == t.size - N_INIT


def test_recovers_after_single_outlier() -> None:
    t, phi, X, tmpl, omega, ph0, _ = initialise(1)
    Xo = X.copy()
    k = N_INIT + 1500
    Xo[k] += 20 * X.std(axis=0)
    clean = PhaseTracker(tmpl, omega, ph0, t[N_INIT - 1]).update_batch(t[N_INIT:], X[N_INIT:])
    hit = PhaseTracker(tmpl, omega, ph0, t[N_INIT - 1])
    dirty = hit.update_batch(t[N_INIT:], Xo[N_INIT:])
    d = np.abs(dirty - clean)
    assert hit.n_outliers_ >= 1
    assert d.max() < 0.05  # measured 0.005
    assert d[1500 + 200 :].max() < 1e-3  # gone two cycles later


def test_recovers_from_phase_kick() -> None:
    t, phi, X, tmpl, omega, ph0, offset = initialise(2)
    tracker = PhaseTracker(tmpl, omega, ph0 + 0.8, t[N_INIT - 1])  # start 0.8 rad ahead
    est = tracker.update_batch(t[N_INIT:], X[N_INIT:])
    err = wrapped(est - phi[N_INIT:] - offset)
    assert np.sqrt(np.mean(err[300:] ** 2)) < 0.12


def test_update_matches_update_batch() -> None:
    t, phi, X, tmpl, omega, ph0, _ = initialise(0)
    a = PhaseTracker(tmpl, omega, ph0, t[N_INIT - 1])
    b = PhaseTracker(tmpl, omega, ph0, t[N_INIT - 1])
    seq = [a.update(t[k], X[k]) for k in range(N_INIT, N_INIT + 50)]
    np.testing.assert_array_equal(seq, b.update_batch(t[N_INIT : N_INIT + 50], X[N_INIT : N_INIT + 50]))


def _fitted_template() -> FourierTemplate:
    ph = np.linspace(0, 20, 300)
    return FourierTemplate(FourierTemplateConfig(order=2)).fit(ph, np.c_[np.cos(ph), np.sin(ph)])


def test_errors() -> None:
    tmpl = _fitted_template()
    with pytest.raises(NotFittedError, match="`template`: expected a fitted FourierTemplate"):
        PhaseTracker(FourierTemplate(), 6.0, 0.0, 0.0)
    with pytest.raises(SudsConfigError, match=r"`omega`: expected a finite number > 0, got -1\.0"):
        PhaseTracker(tmpl, -1.0, 0.0, 0.0)
    with pytest.raises(SudsConfigError, match=r"`gain`: expected a value in \(0, 1\], got 1\.5"):
        PhaseTracker(tmpl, 6.0, 0.0, 0.0, gain=1.5)
    with pytest.raises(SudsConfigError, match=r"`n_iter`: expected an integer ≥ 1, got 0"):
        PhaseTracker(tmpl, 6.0, 0.0, 0.0, n_iter=0)
    with pytest.raises(SudsConfigError, match=r"`weights`: expected 2 finite values ≥ 0"):
        PhaseTracker(tmpl, 6.0, 0.0, 0.0, weights=np.array([1.0, -1.0]))
    tracker = PhaseTracker(tmpl, 6.0, 0.0, 1.0)
    with pytest.raises(SudsDataError, match=r"`t`: expected a finite time ≥ the previous 1\.0 s, got 0\.5"):
        tracker.update(0.5, np.zeros(2))
    with pytest.raises(SudsDataError, match=r"`r`: expected shape \(2,\), got shape \(3,\)"):
        tracker.update(1.1, np.zeros(3))
    with pytest.raises(SudsDataError, match="`r`: expected finite values"):
        tracker.update(1.1, np.array([0.0, np.nan]))
    with np.errstate(over="ignore"), pytest.raises(SudsDataError, match="whose sum is finite"):
        tracker.update(1.1, np.array([1e308, 1e308]))  # finite, but it would leave the phase NaN
    assert np.isfinite(tracker.update(1.1, np.zeros(2)))  # a refused sample leaves the tracker as it was
    with pytest.raises(SudsDataError, match=r"`t`, `R`: expected shapes \(n,\) and \(n, 2\)"):
        tracker.update_batch(np.zeros(3), np.zeros((3, 3)))
