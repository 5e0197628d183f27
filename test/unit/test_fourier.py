"""The one Fourier basis in phase and the one normal-equations accumulator."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsDataError
from suds_ros.core.fourier import NormalEquations, fourier_basis, fourier_basis_and_derivative, n_coefficients


def test_basis_layout() -> None:
    B = fourier_basis(np.array([0.0, np.pi / 2]), 2)
    np.testing.assert_allclose(B, [[1, 1, 0, 1, 0], [1, 0, 1, -1, 0]], atol=1e-15)
    assert fourier_basis(np.zeros(3), 0).shape == (3, 1) and n_coefficients(3) == 7
    assert fourier_basis(0.3, 2).shape == (1, 5)


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5])
def test_derivatives_match_finite_differences(k: int) -> None:
    phi, h = np.linspace(-3.0, 9.0, 41), 1e-4
    num = (fourier_basis(phi + h, 3, k - 1) - fourier_basis(phi - h, 3, k - 1)) / (2 * h)
    np.testing.assert_allclose(fourier_basis(phi, 3, k), num, atol=1e-6 * 3**k)
    assert np.all(fourier_basis(phi, 3, k)[:, 0] == 0.0)


def test_basis_and_derivative_agree_with_the_basis() -> None:
    phi = np.linspace(0, 7, 13)
    B, dB = fourier_basis_and_derivative(phi, 4)
    np.testing.assert_array_equal(B, fourier_basis(phi, 4))
    np.testing.assert_allclose(dB, fourier_basis(phi, 4, 1), atol=1e-15)


def test_bad_phase_or_derivative() -> None:
    with pytest.raises(SudsDataError, match=r"`phase`: expected a 1-D array"):
        fourier_basis(np.zeros((2, 2)), 1)
    with pytest.raises(SudsDataError, match="`derivative`"):
        fourier_basis(np.zeros(2), 1, -1)


def _rows(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, 4))
    Y = X @ rng.normal(size=(4, 2)) + 0.1 * rng.normal(size=(n, 2))
    return X, Y, rng.uniform(0.5, 2.0, n)


def test_chunks_and_merge_equal_one_pass() -> None:
    X, Y, w = _rows(90)
    whole = NormalEquations(4, 2).add(X, Y, w)
    chunked = NormalEquations(4, 2)
    for a in range(0, 90, 17):
        chunked.add(X[a:a + 17], Y[a:a + 17], w[a:a + 17])
    merged = NormalEquations(4, 2).add(X[:40], Y[:40], w[:40]).merge(NormalEquations(4, 2).add(X[40:], Y[40:], w[40:]))
    for acc in (chunked, merged):
        np.testing.assert_allclose(acc.xtx, whole.xtx, rtol=1e-12)
        np.testing.assert_allclose(acc.xty, whole.xty, rtol=1e-12)
        np.testing.assert_allclose(acc.yty, whole.yty, rtol=1e-12)
        assert acc.n == 90 and acc.sw == pytest.approx(whole.sw)


def test_solve_is_weighted_least_squares_and_residuals_follow() -> None:
    X, Y, w = _rows(200, seed=1)
    acc = NormalEquations(4, 2).add(X, Y, w)
    sw = np.sqrt(w)[:, None]
    ref = np.linalg.lstsq(X * sw, Y * sw, rcond=None)[0]
    coef = acc.solve()
    np.testing.assert_allclose(coef, ref, rtol=1e-10)
    np.testing.assert_allclose(acc.residual_ss(coef), (w[:, None] * (Y - X @ coef) ** 2).sum(axis=0), rtol=1e-8)
    assert acc.well_posed(1e-12)
    assert np.abs(acc.solve(ridge=10.0)).sum() < np.abs(coef).sum()  # the ridge shrinks


def test_decay_forgets_old_rows() -> None:
    X, Y, _ = _rows(20)
    acc = NormalEquations(4, 2).add(X[:10], Y[:10]).add(X[10:], Y[10:], decay=0.5)
    np.testing.assert_allclose(acc.xtx, 0.5 * X[:10].T @ X[:10] + X[10:].T @ X[10:])
    assert acc.sw == pytest.approx(15.0)


def test_underdetermined_and_shape_errors() -> None:
    X, Y, _ = _rows(3)
    acc = NormalEquations(4, 2).add(X, Y)
    assert not acc.well_posed(1e-12)
    with pytest.raises(SudsDataError, match=r"expected shapes \(m, 4\) and \(m, 2\)"):
        acc.add(X[:, :3], Y)
    with pytest.raises(SudsDataError, match="expected statistics of shape"):
        acc.merge(NormalEquations(4, 3))
