"""SUDS regression: exact incremental fitting, forgetting, parameter counts, recovery, errors."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import NotFittedError, SudsConfigError, SudsDataError
from suds_ros.core.ident.scoring import gamma
from suds_ros.core.ident.sysid import SudsConfig, SudsRegressor, design_matrix, feature_layout, regressor_input


def _data(n: int = 900, nj: int = 4, na: int = 2, n_out: int = 3, seed: int = 0):
    rng = np.random.default_rng(seed)
    phase = np.cumsum(np.full(n, 2 * np.pi / 100)) + rng.normal(scale=0.01, size=n)
    delta = rng.normal(scale=0.2, size=(n, nj))
    dda = rng.normal(scale=2.0, size=(n, na))
    X = regressor_input(phase, delta, dda, delta, dda)  # r, ṙ_a unused without random features
    y = rng.normal(size=(n, n_out)) + np.sin(phase)[:, None] + delta[:, :1] * dda[:, :1]
    return X, y


@pytest.mark.parametrize("regressors", [1, 2, 3])
@pytest.mark.parametrize("forgetting", [1.0, 0.995])
def test_partial_fit_in_chunks_equals_fit(regressors: int, forgetting: float) -> None:
    X, y = _data()
    cfg = SudsConfig(regressors=regressors, forgetting=forgetting)
    full = SudsRegressor(cfg, n_actuated=2).fit(X, y)
    inc = SudsRegressor(cfg, n_actuated=2)
    for start, stop in [(0, 137), (137, 138), (138, 500), (500, 900)]:
        inc.partial_fit(X[start:stop], y[start:stop])
    assert inc.n_samples_seen_ == full.n_samples_seen_ == 900
    scale = np.abs(full.coef_).max()
    np.testing.assert_allclose(inc.coef_, full.coef_, rtol=0, atol=1e-9 * scale)


def test_forgetting_weights_old_samples_geometrically() -> None:
    X, y = _data(n=300)
    lam = 0.99
    est = SudsRegressor(SudsConfig(forgetting=lam, ridge=0.0), n_actuated=2).fit(X, y)
    w = lam ** np.arange(299, -1, -1)
    A = design_matrix(est.config, X[:, 0], X[:, 1:5], X[:, 5:7])
    ref = np.linalg.lstsq(A * np.sqrt(w)[:, None], y * np.sqrt(w)[:, None], rcond=None)[0]
    np.testing.assert_allclose(est.coef_, ref, atol=1e-7)


@pytest.mark.parametrize("nj, na", [(2, 1), (8, 4), (32, 4)])
def test_parameter_counts(nj: int, na: int) -> None:
    cfg = SudsConfig(intercept_order=8, linear_order=3, bilinear_order=1)
    h = lambda m: 2 * m + 1  # noqa: E731
    counts = {
        k: feature_layout(SudsConfig(regressors=k, intercept_order=8, linear_order=3, bilinear_order=1),
                          nj, na).n_columns
        for k in (1, 2, 3)
    }
    assert counts[1] == h(8) + (nj + na) * h(3)
    assert counts[2] == counts[1] + nj * na * h(1)
    assert counts[3] == counts[2] + (nj * (nj + 1) // 2 + na * (na + 1) // 2) * h(1)
    assert cfg.regressors == 2


def test_set2_grows_linearly_in_passive_joints_set3_quadratically() -> None:
    na = 4
    c2 = [feature_layout(SudsConfig(regressors=2), na + p, na).n_columns for p in (4, 8, 16, 32)]
    c3 = [feature_layout(SudsConfig(regressors=3), na + p, na).n_columns for p in (4, 8, 16, 32)]
    d2 = np.diff(c2) / np.diff([4, 8, 16, 32])
    assert np.allclose(d2, d2[0])  # constant increment per passive joint
    assert np.all(np.diff(np.diff(c3) / np.diff([4, 8, 16, 32])) > 0)


def test_recovers_a_model_of_its_own_form_exactly() -> None:
    rng = np.random.default_rng(1)
    cfg = SudsConfig(regressors=2, intercept_order=3, linear_order=2, bilinear_order=1, ridge=0.0)
    X, _ = _data(n=2000, seed=2)
    A = design_matrix(cfg, X[:, 0], X[:, 1:5], X[:, 5:7])
    true = rng.normal(size=(A.shape[1], 3))
    est = SudsRegressor(cfg, n_actuated=2).fit(X, A @ true)
    np.testing.assert_allclose(est.coef_, true, atol=1e-8)
    assert est.score(X, A @ true) == pytest.approx(1.0)
    # coefficient view agrees with prediction: C + C_r δ + B δ̇ + B_r δ⊗δ̇
    c = est.coefficients(X[:5, 0])
    d, a = X[:5, 1:5], X[:5, 5:7]
    manual = c["C"] + np.einsum("kor,kr->ko", c["C_r"], d) + np.einsum("koa,ka->ko", c["B"], a) \
        + np.einsum("kora,kr,ka->ko", c["B_r"], d, a)
    np.testing.assert_allclose(manual, est.predict(X[:5]), atol=1e-9)


def test_errors() -> None:
    X, y = _data(n=50)
    est = SudsRegressor(n_actuated=2)
    with pytest.raises(NotFittedError, match="not fitted"):
        est.predict(X)
    with pytest.raises(NotFittedError, match="not fitted"):
        est.coefficients(X[:, 0])
    with pytest.raises(SudsDataError, match=r"expected shape \(n, 1 \+ 2·\(nj \+ 2\)\)"):
        est.fit(X[:, :7], y)
    est.fit(X, y)
    with pytest.raises(SudsDataError, match=r"expected shape \(n, 13\)"):
        est.predict(X[:, :11])
    with pytest.raises(SudsDataError, match="expected 3 outputs"):
        est.partial_fit(X, y[:, :2])
    bad = X.copy()
    bad[3, 2] = np.nan
    with pytest.raises(SudsDataError, match="NaN"):
        est.partial_fit(bad, y)
    with pytest.raises(SudsConfigError, match="regressors"):
        SudsConfig(regressors=4)
    with pytest.raises(SudsConfigError, match="forgetting"):
        SudsConfig(forgetting=0.0)


def test_gamma() -> None:
    truth = np.array([1.0, 2.0, 3.0])
    assert gamma(truth, truth + 1, truth) == 1.0
    assert gamma(truth + 1, truth + 1, truth) == 0.0
    assert gamma(truth + 0.5, truth - 1, truth) == pytest.approx(0.5)
    with pytest.raises(SudsDataError, match="undefined"):
        gamma(truth, truth, truth)


def test_large_fits_and_predictions_build_the_design_in_blocks(monkeypatch) -> None:
    """Memory is bounded by a block of rows; the fit and the predictions are those of one block."""
    import scipy.sparse

    from suds_ros.core.ident import sysid
    from suds_ros.core.ident.sysid import AveragedTargets

    X, y = _data(n=900)
    q = 300  # averaged targets: each the mean of three consecutive rows' first two outputs
    W = scipy.sparse.csr_matrix((np.full(900, 1 / 3), (np.repeat(np.arange(q), 3), np.arange(900))), shape=(q, 900))
    avg = AveragedTargets(X=X, weights=W, y=np.asarray(W @ y[:, :2]), columns=(0, 1))
    cfg = SudsConfig(regressors=2)
    whole = SudsRegressor(cfg, n_actuated=2).fit(X, y[:, 2:], avg)
    seen = []
    design = sysid.regressor_design
    monkeypatch.setattr(sysid, "regressor_design", lambda c, Xb, *a: seen.append(len(Xb)) or design(c, Xb, *a))
    monkeypatch.setattr(sysid, "BLOCK_ELEMENTS", 64 * feature_layout(cfg, 4, 2).n_columns)
    blocks = SudsRegressor(cfg, n_actuated=2).fit(X, y[:, 2:], avg)
    assert max(seen) <= 3 * 64 and len(seen) > 900 // 64  # an averaged row spans 3 rows
    np.testing.assert_allclose(blocks.coef_, whole.coef_, rtol=0, atol=1e-9 * np.abs(whole.coef_).max())
    np.testing.assert_allclose(blocks.predict(X), whole.predict(X), rtol=0, atol=1e-9)
    with pytest.raises(SudsDataError, match="NaN or Inf"):  # a bad row anywhere: nothing is added
        bad = X.copy()
        bad[-1, 1] = np.nan
        blocks.partial_fit(bad, y[:, 2:])
    assert blocks.n_samples_seen_ == 900
