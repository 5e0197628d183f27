"""Phaser: phase recovery on synthetic oscillators with known phase, held-out data, edge cases, errors.

Measured on the default synthetic set (4 non-sinusoidal channels + 1 noise
channel, OU perturbation 12 % of amplitude, phase diffusion, 40 cycles at
100 Hz), seeds 0–2: RMS phase error ≈ 0.077–0.083 rad on the training data and
0.078–0.090 rad on held-out data; without the OU perturbation and diffusion the
error is ≈ 0.0015 rad (algorithmic bias only).
"""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import NotFittedError, SudsConfigError, SudsDataError, SudsPhaseError
from suds_ros.core.phase.phaser import Phaser, PhaserConfig

FS = 100.0


def oscillator(
    cycles: float = 40, seed: int = 0, ou_std: float = 0.12, diffusion: float = 0.01, noise_channel: bool = True
):
    """Channels A_i·f_i(φ + c_i) + offset_i + OU + 1e-3 noise, φ = 2πt + diffusion; returns t, φ, X."""
    rng = np.random.default_rng(seed)
    n = int(round(cycles * FS))
    dt = 1 / FS
    t = np.arange(n) * dt
    phi = 2 * np.pi * t + np.cumsum(np.sqrt(2 * diffusion * dt) * rng.normal(size=n))
    amps = np.array([1.0, 2.0, 0.5, 1.5])
    shifts = np.array([0.0, 1.1, 2.5, 4.0])
    offsets = np.array([0.3, -1.0, 5.0, 0.0])
    harmonics = np.array([[0.3, 0.5, 0.1, 1.0], [0.2, 2.0, 0.15, 0.3], [0.35, -1.0, 0.0, 0.0], [0.1, 0.0, 0.2, 2.0]])
    x = phi[:, None] + shifts
    a2, b2, a3, b3 = harmonics.T
    f = np.cos(x) + a2 * np.cos(2 * x + b2) + a3 * np.cos(3 * x + b3)
    f *= amps / np.sqrt(2) / f.std(axis=0)
    # Ornstein–Uhlenbeck perturbation, κ = 8/s, stationary std ou_std·A
    a = np.exp(-8.0 * dt)
    e = rng.normal(size=(n, amps.size)) * ou_std * amps
    ou = np.empty_like(e)
    ou[0] = e[0]
    for k in range(1, n):
        ou[k] = a * ou[k - 1] + np.sqrt(1 - a * a) * e[k]
    X = f + offsets + ou + 1e-3 * rng.normal(size=(n, amps.size))
    if noise_channel:
        X = np.column_stack([X, 0.7 * rng.normal(size=n)])
    return t, phi, X


def phase_rms(est: np.ndarray, true: np.ndarray) -> float:
    """RMS circular error after removing one constant offset (rad)."""
    d = est - true
    e = np.angle(np.exp(1j * (d - np.angle(np.mean(np.exp(1j * d))))))
    return float(np.sqrt(np.mean(e**2)))


@pytest.fixture(scope="module")
def fitted():
    t, phi, X = oscillator(seed=0)
    return t, phi, X, Phaser().fit(X)


def test_recovers_phase(fitted) -> None:
    t, phi, X, p = fitted
    assert p.phase_.shape == (t.size,)
    assert phase_rms(p.phase_, phi) < 0.1  # measured 0.080
    assert 0 <= p.phase_[0] < 2 * np.pi


def test_phase_monotone_on_average_at_gait_rate(fitted) -> None:
    t, phi, X, p = fitted
    rate = p.omega_per_sample_ * FS
    assert rate == pytest.approx(2 * np.pi, rel=0.02)  # diffusion moves it by < 1 %
    assert p.n_cycles_ == pytest.approx((phi[-1] - phi[0]) / (2 * np.pi), abs=0.3)
    per_cycle = np.diff(p.phase_[:: int(FS)])
    assert np.all(per_cycle > 0)
    assert np.mean(np.diff(p.phase_) > 0) > 0.9  # measured 0.969: per-sample noise can step back


def test_noise_channel_gets_no_weight(fitted) -> None:
    *_, p = fitted
    assert p.weights_[-1] == 0
    assert p.coherence_[-1] < 0.1
    assert np.all(p.weights_[:-1] > 0.1)
    assert p.weights_.sum() == pytest.approx(1.0)


def test_without_noise_is_nearly_exact() -> None:
    t, phi, X = oscillator(seed=5, ou_std=0.0, diffusion=0.0, noise_channel=False)
    assert phase_rms(Phaser().fit_transform(X), phi) < 0.005  # measured 0.0015


def test_transform_held_out(fitted) -> None:
    *_, p = fitted
    t2, phi2, X2 = oscillator(cycles=20, seed=100)
    est = p.transform(X2)
    assert phase_rms(est, phi2) < 0.1  # measured 0.078
    assert np.all(np.diff(est[:: int(FS)]) > 0)


def test_transform_of_training_data_equals_phase(fitted) -> None:
    *_, X, p = fitted
    np.testing.assert_allclose(p.transform(X), p.phase_, atol=1e-9)


def test_zero_is_reproducible_across_recordings() -> None:
    offsets = []
    for seed in range(3):
        _, phi, X = oscillator(seed=seed)
        d = Phaser().fit_transform(X) - phi
        offsets.append(np.angle(np.mean(np.exp(1j * d))))
    spread = np.angle(np.exp(1j * (np.array(offsets) - offsets[0])))
    assert np.max(np.abs(spread)) < 0.1  # measured < 0.05


def test_zero_channel_sets_upward_crossing() -> None:
    _, phi, X = oscillator(seed=1, noise_channel=False)
    p = Phaser(PhaserConfig(zero_channel=2)).fit(X)
    y = (X[:, 2] - p.mean_[2]) / p.scale_[2]
    b = np.c_[np.ones_like(p.phase_), np.cos(p.phase_), np.sin(p.phase_)]
    (_, a_cos, b_sin), *_ = np.linalg.lstsq(b, y, rcond=None)
    assert abs(a_cos) < 1e-6 and b_sin > 0  # first harmonic ∝ sin φ: rises through its mean at φ = 0


def test_constant_channel_is_dropped() -> None:
    _, phi, X = oscillator(seed=2)
    X = np.column_stack([X, np.full(X.shape[0], 3.0)])
    p = Phaser().fit(X)
    assert not p.used_[-1] and p.weights_[-1] == 0
    assert phase_rms(p.phase_, phi) < 0.1


def test_single_channel() -> None:
    _, phi, X = oscillator(seed=3, noise_channel=False)
    assert phase_rms(Phaser().fit_transform(X[:, :1]), phi) < 0.25  # measured 0.16: no averaging over channels


def test_too_few_cycles() -> None:
    _, _, X = oscillator(cycles=1.5, seed=4)
    with pytest.raises(SudsPhaseError, match=r"too little data to find a phase: 1\.\d+ cycles detected, need ≥ 3"):
        Phaser().fit(X)


def test_three_and_a_half_cycles_are_enough() -> None:
    _, _, X = oscillator(cycles=3.5, seed=4)
    assert Phaser().fit(X).n_cycles_ == pytest.approx(3.5, abs=0.3)


def test_all_constant() -> None:
    with pytest.raises(SudsPhaseError, match="every channel of `X` is constant"):
        Phaser().fit(np.ones((500, 3)))


def test_too_few_samples() -> None:
    with pytest.raises(SudsPhaseError, match=r"`X` has 20 samples, need ≥ 44"):
        Phaser().fit(np.random.default_rng(0).normal(size=(20, 2)))


def test_nan_raises() -> None:
    _, _, X = oscillator(cycles=5, seed=0)
    X[17, 1] = np.nan
    with pytest.raises(SudsDataError, match="`X`: expected finite values, got NaN/inf in row 17"):
        Phaser().fit(X)


@pytest.mark.parametrize("shape", [(100,), (10, 10, 2)])
def test_wrong_dims(shape: tuple[int, ...]) -> None:
    with pytest.raises(SudsDataError, match=r"`X`: expected a 2-D array of shape \(n_samples, n_channels\)"):
        Phaser().fit(np.zeros(shape))


def test_transform_channel_mismatch(fitted) -> None:
    *_, X, p = fitted
    with pytest.raises(SudsDataError, match="`X`: expected 5 channels as in fit, got 4"):
        p.transform(X[:, :4])


def test_not_fitted() -> None:
    with pytest.raises(NotFittedError, match="call fit first"):
        Phaser().transform(np.zeros((100, 2)))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"order": 0}, r"`order`: expected an integer ≥ 1, got 0"),
        ({"order": 2.5}, r"`order`: expected an integer ≥ 1, got 2\.5"),
        ({"min_cycles": 0}, r"`min_cycles`: expected a finite number > 0, got 0"),
        ({"min_coherence": 1.0}, r"`min_coherence`: expected a value in \[0, 1\), got 1\.0"),
        ({"zero_channel": -1}, r"`zero_channel`: expected None or an integer ≥ 0, got -1"),
        ({"pad_cycles": -1.0}, r"`pad_cycles`: expected a finite number ≥ 0, got -1\.0"),
    ],
)
def test_config_validation(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(SudsConfigError, match=match):
        PhaserConfig(**kwargs)  # type: ignore[arg-type]


def test_zero_channel_out_of_range() -> None:
    _, _, X = oscillator(cycles=5, seed=0)
    with pytest.raises(SudsConfigError, match="`zero_channel`: expected a channel index < 5, got 7"):
        Phaser(PhaserConfig(zero_channel=7)).fit(X)
