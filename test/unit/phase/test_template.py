"""FourierTemplate: recovery, exact chunked partial_fit, derivatives, weights, errors."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import NotFittedError, SudsConfigError, SudsDataError
from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig


def _truth(phase: np.ndarray) -> np.ndarray:
    return np.column_stack(
        [
            1.0 + np.cos(phase) + 0.3 * np.sin(2 * phase),
            -0.5 * np.sin(phase) + 0.2 * np.cos(3 * phase),
            0.1 * np.cos(4 * phase - 0.3),
        ]
    )


def _data(n: int = 1500, seed: int = 0, noise: float = 0.05):
    rng = np.random.default_rng(seed)
    phase = np.cumsum(rng.uniform(0.0, 0.12, size=n))  # unwrapped, irregular steps
    return phase, _truth(phase) + noise * rng.normal(size=(n, 3))


def test_recovers_known_series() -> None:
    phase, Y = _data(noise=0.0)
    tmpl = FourierTemplate(FourierTemplateConfig(order=4)).fit(phase, Y)
    assert tmpl.coef_.shape == (9, 3)
    grid = np.linspace(0, 2 * np.pi, 50)
    np.testing.assert_allclose(tmpl.predict(grid), _truth(grid), atol=1e-10)
    np.testing.assert_allclose(tmpl.residual_var_, 0.0, atol=1e-12)


def test_noisy_fit_and_residual_variance() -> None:
    phase, Y = _data(noise=0.05)
    tmpl = FourierTemplate().fit(phase, Y)
    grid = np.linspace(0, 2 * np.pi, 50)
    assert np.max(np.abs(tmpl.predict(grid) - _truth(grid))) < 0.02
    np.testing.assert_allclose(tmpl.residual_var_, 0.05**2, rtol=0.15)


def test_phase_unwrapping_does_not_matter() -> None:
    phase, Y = _data()
    a = FourierTemplate().fit(phase, Y)
    b = FourierTemplate().fit(np.mod(phase, 2 * np.pi) - 2 * np.pi, Y)
    np.testing.assert_allclose(a.coef_, b.coef_, atol=1e-9)


def test_partial_fit_in_chunks_equals_fit() -> None:
    phase, Y = _data()
    w = np.random.default_rng(1).uniform(0.5, 2.0, size=phase.size)
    full = FourierTemplate().fit(phase, Y, sample_weight=w)
    inc = FourierTemplate()
    for start, stop in [(0, 5), (5, 6), (6, 400), (400, 1500)]:
        inc.partial_fit(phase[start:stop], Y[start:stop], sample_weight=w[start:stop])
    assert inc.n_samples_seen_ == full.n_samples_seen_ == 1500
    np.testing.assert_allclose(inc.coef_, full.coef_, rtol=0, atol=1e-9)
    np.testing.assert_allclose(inc.predict(phase), full.predict(phase), rtol=0, atol=1e-9)


def test_fit_resets_state() -> None:
    phase, Y = _data()
    tmpl = FourierTemplate().fit(phase[:700], Y[:700])
    tmpl.fit(phase[700:], Y[700:])
    assert tmpl.n_samples_seen_ == 800
    np.testing.assert_allclose(tmpl.coef_, FourierTemplate().fit(phase[700:], Y[700:]).coef_, atol=1e-12)


def test_partial_fit_waits_until_determined() -> None:
    phase, Y = _data()
    tmpl = FourierTemplate(FourierTemplateConfig(order=3)).partial_fit(phase[:4], Y[:4])
    with pytest.raises(NotFittedError, match="call fit or partial_fit first"):
        tmpl.predict(phase[:2])
    tmpl.partial_fit(phase[4:100], Y[4:100])
    assert tmpl.predict(phase[:2]).shape == (2, 3)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_derivative_matches_finite_differences(k: int) -> None:
    phase, Y = _data()
    tmpl = FourierTemplate().fit(phase, Y)
    grid = np.linspace(-1.0, 7.0, 40)
    h = 1e-3
    lower = tmpl.derivative(grid - h, k - 1)
    upper = tmpl.derivative(grid + h, k - 1)
    fd = (upper - lower) / (2 * h)
    scale = np.abs(tmpl.derivative(grid, k)).max()
    np.testing.assert_allclose(tmpl.derivative(grid, k), fd, rtol=0, atol=1e-5 * scale)


def test_derivative_zero_is_predict_and_scalar_phase() -> None:
    phase, Y = _data()
    tmpl = FourierTemplate().fit(phase, Y)
    np.testing.assert_allclose(tmpl.derivative(phase[:10], 0), tmpl.predict(phase[:10]))
    assert tmpl.predict(0.3).shape == (1, 3)


def test_one_dimensional_Y() -> None:
    phase, Y = _data()
    tmpl = FourierTemplate().fit(phase, Y[:, 0])
    assert tmpl.predict(phase[:3]).shape == (3, 1)


def test_not_fitted() -> None:
    with pytest.raises(NotFittedError, match="call fit or partial_fit first"):
        FourierTemplate().predict(np.zeros(3))
    with pytest.raises(NotFittedError, match="call fit or partial_fit first"):
        FourierTemplate().derivative(np.zeros(3))


def test_too_few_samples() -> None:
    phase, Y = _data()
    with pytest.raises(SudsDataError, match=r"too few samples for a Fourier template of order 8: need ≥ 17 samples"):
        FourierTemplate().fit(phase[:10], Y[:10])


def test_bunched_phases_are_rejected() -> None:
    phase = np.full(200, 0.4)
    with pytest.raises(SudsDataError, match="normal equations singular"):
        FourierTemplate(FourierTemplateConfig(order=2)).fit(phase, np.ones((200, 1)))


def test_feature_count_change() -> None:
    phase, Y = _data()
    tmpl = FourierTemplate().partial_fit(phase[:100], Y[:100])
    with pytest.raises(SudsDataError, match="`Y`: expected 3 channels as in earlier calls, got 2"):
        tmpl.partial_fit(phase[100:200], Y[100:200, :2])


@pytest.mark.parametrize(
    ("phase", "Y", "w", "match"),
    [
        (np.zeros((5, 2)), np.zeros((5, 1)), None, r"`phase`: expected a 1-D array of shape \(n,\)"),
        (np.zeros(5), np.zeros((4, 1)), None, r"`Y`: expected 5 rows to match `phase`, got shape \(4, 1\)"),
        (np.array([0.0, np.nan]), np.zeros((2, 1)), None, r"`phase`: expected finite values, got nan at index 1"),
        (np.zeros(2), np.array([[1.0], [np.nan]]), None, r"`Y`: expected finite values, got 1 NaN/inf"),
        (np.zeros(2), np.zeros((2, 1)), np.array([1.0, -1.0]), r"`sample_weight`: expected finite values ≥ 0"),
        (np.zeros(2), np.zeros((2, 1)), np.ones(3), r"`sample_weight`: expected shape \(2,\), got shape \(3,\)"),
    ],
)
def test_bad_input(phase, Y, w, match: str) -> None:
    with pytest.raises(SudsDataError, match=match):
        FourierTemplate().fit(phase, Y, sample_weight=w)


@pytest.mark.parametrize("order", [-1, 1.5, True])
def test_config_validation(order: object) -> None:
    with pytest.raises(SudsConfigError, match=r"`order`: expected an integer ≥ 0"):
        FourierTemplateConfig(order=order)  # type: ignore[arg-type]


def test_bad_derivative_order() -> None:
    phase, Y = _data()
    with pytest.raises(SudsConfigError, match=r"`k`: expected an integer ≥ 0, got -1"):
        FourierTemplate().fit(phase, Y).derivative(phase, -1)
