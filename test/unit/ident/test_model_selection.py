"""Model selection on nested designs: column subsets, exact fold fits, the chosen model, the interval state."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.ident import model_selection as ms
from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, split_cycles
from suds_ros.core.ident.model import SudsModel
from suds_ros.core.ident.sysid import (
    SudsConfig,
    SudsRegressor,
    design_matrix,
    feature_layout,
    interval_state,
    regressor_design,
    regressor_input,
    segment_state,
)


def test_candidate_designs_are_column_subsets_of_the_largest() -> None:
    rng = np.random.default_rng(3)
    nj, na, n = 4, 2, 50
    phase, delta, dda = rng.uniform(0, 6.3, n), rng.normal(size=(n, nj)), rng.normal(size=(n, na))
    cands = ms.candidates(SudsConfig(), (1, 2, 3), ((1, 0), (2, 1), (4, 2)), (1e-6,))
    big = ms.largest(cands)
    assert (big.regressors, big.linear_order, big.bilinear_order) == (3, 4, 2)
    A = design_matrix(big, phase, delta, dda)
    for cfg in cands:
        cols = ms.subset_columns(feature_layout(big, nj, na), feature_layout(cfg, nj, na))
        np.testing.assert_array_equal(A[:, cols], design_matrix(cfg, phase, delta, dda))
    # set 1 ignores the bilinear order, so (1, 2, 1) and (1, 2, 0) are one candidate
    assert len({(c.regressors, c.linear_order, c.bilinear_order) for c in cands}) == len(cands)


@pytest.mark.parametrize("n", [300, 60])
def test_cv_scores_equal_refits_on_each_fold(n: int) -> None:
    """Every score comes from the fold's own least-squares fit (Gram subtraction and the dual are exact).

    With 60 rows the folds train on fewer rows than the largest design has columns (dual path).
    """
    rng = np.random.default_rng(5)
    nj, na = 3, 1
    delta, dda = rng.normal(size=(n, nj)), rng.normal(size=(n, na))
    X = regressor_input(np.linspace(0, 40, n), delta, dda, delta, dda)
    y = np.column_stack([np.sin(X[:, 0]) + X[:, 1] * X[:, 4], X[:, 2] - X[:, 3]]) + 0.1 * rng.normal(size=(n, 2))
    T = np.column_stack([np.sin(X[:, 0]), np.zeros(n)])
    cands = ms.candidates(SudsConfig(intercept_order=2), (1, 2), ((1, 0), (4, 2)), (1e-6, 1e-2))
    edges = np.linspace(0, n, 4).astype(int)
    problem = ms.CVProblem(A=regressor_design(ms.largest(cands), X, na), y=y, template=T, columns=(0, 1),
                           groups=((0,), (1,)), edges=edges)
    best, scores = ms.select(problem, cands, nj, na)
    for cfg in cands:
        total = 0.0
        for f in range(3):
            te = np.zeros(n, dtype=bool)
            te[edges[f]:edges[f + 1]] = True
            reg = SudsRegressor(cfg, n_actuated=na).fit(X[~te], y[~te])
            err = np.abs(reg.predict(X[te]) - y[te])
            ref = np.abs(T[te] - y[te])
            total += np.mean(err.sum(0) / ref.sum(0))
        assert scores[ms.key(cfg)] == pytest.approx(total / 3, rel=1e-6)
    assert scores[ms.key(best)] == min(scores.values())
    if n == 300:
        assert best.regressors == 2  # the product X₁·X₄ is only in set 2


def test_the_model_follows_the_amount_of_data(swimmer9_run) -> None:
    """Few cycles: the choice made for them beats the large-data choice fitted on the same few cycles."""
    small, test = split_cycles(swimmer9_run, 4, 10)
    large, _ = split_cycles(swimmer9_run, 16)
    p_small = SudsIdentifier().fit(small)
    p_large = SudsIdentifier().fit(large)
    chosen = p_large.regressor_.config
    assert p_large.cv_scores_[ms.key(chosen)] == min(p_large.cv_scores_.values())
    assert chosen != p_small.regressor_.config
    fixed = SudsIdentifier(IdentifyConfig(suds=chosen, order_grid=())).fit(small).scores(test)
    own = p_small.scores(test)
    print(p_small.regressor_.config, own.gamma_body, own.gamma_passive, "vs", fixed.gamma_body, fixed.gamma_passive)
    assert own.gamma_body + own.gamma_passive > fixed.gamma_body + fixed.gamma_passive + 0.02


def test_start_state_beats_midpoint_on_swimmer9_passive(swimmer9_run) -> None:
    """swimmer9's stiff passive modes relax within an interval: the start state predicts ṙ_p better."""
    train, test = split_cycles(swimmer9_run, 16)
    g = {}
    for state in ("start", "midpoint"):
        cfg = IdentifyConfig(suds=SudsConfig(linear_order=6, bilinear_order=3, state=state), order_grid=())
        g[state] = SudsIdentifier(cfg).fit(train).scores(test).gamma_passive
    print(g)
    assert g["start"] > g["midpoint"] + 0.005


def test_interval_state_and_config() -> None:
    a, b = np.array([0.0, 2.0]), np.array([1.0, 4.0])
    np.testing.assert_array_equal(interval_state(SudsConfig(), a, b), a)
    np.testing.assert_array_equal(interval_state(SudsConfig(state="midpoint"), a, b), [0.5, 3.0])
    with pytest.raises(SudsConfigError, match="`state`"):
        SudsConfig(state="end")


def test_segment_state() -> None:
    """A segment takes its interval's row ("start") or the state at its own midpoint ("midpoint")."""
    p0, p1 = np.array([0.0, 1.0]), np.array([0.5, 2.0])
    a, b = np.array([[0.0, 2.0], [1.0, 1.0]]), np.array([[1.0, 4.0], [3.0, 1.0]])
    frac = np.array([0.25, 1.0])
    ph, r = segment_state(SudsConfig(), p0, p1, a, b, frac)
    np.testing.assert_array_equal(ph, [0.25, 1.5])
    np.testing.assert_array_equal(r, a)
    ph, r = segment_state(SudsConfig(state="midpoint"), p0, p1, a, b, frac)
    np.testing.assert_array_equal(ph, [0.125, 2.0])
    np.testing.assert_array_equal(r, [[0.25, 2.5], [3.0, 1.0]])


def test_model_dicts_without_a_state_are_midpoint_models(purcell3_run) -> None:
    """Models saved before the state existed keep their meaning."""
    from suds_ros.core.ident.online import fit_streaming

    d = fit_streaming(purcell3_run).model().to_dict()
    assert d["suds"]["state"] == "start"
    del d["suds"]["state"]
    assert SudsModel.from_dict(d).suds.state == "midpoint"


def test_random_features_are_seeded_and_keep_the_output_affine_in_the_rate() -> None:
    from suds_ros.core.ident.shape_kernel import KernelScale, kernel_features

    rng = np.random.default_rng(2)
    nj, na, n = 4, 2, 20
    scale = KernelScale(np.zeros(nj), np.ones(nj), np.zeros(na), np.ones(na))
    r, u, ph = rng.normal(size=(n, nj)), rng.normal(size=(n, na)), rng.uniform(0, 6.3, n)
    a = kernel_features(30, 0.1, 7, scale, r, u, ph)
    np.testing.assert_array_equal(a, kernel_features(30, 0.1, 7, scale, r, u, ph))
    assert not np.allclose(a, kernel_features(30, 0.1, 8, scale, r, u, ph))
    assert a.shape == (n, 30 * (1 + na))
    # doubling the rate about its mean doubles the rate block and leaves ψ alone: affine in ṙ_a
    b = kernel_features(30, 0.1, 7, scale, r, 2 * u, ph)
    np.testing.assert_allclose(b[:, :30], a[:, :30])
    np.testing.assert_allclose(b[:, 30:], 2 * a[:, 30:])


def test_kernel_model_streams_like_batch_and_round_trips(purcell3_run) -> None:
    """Random-feature coefficients: chunked partial_fit is exact and the saved model predicts the same."""
    from suds_ros.core.ident.online import OnlineConfig, fit_streaming
    from suds_ros.core.ident.predictor import evaluate_model

    train, test = split_cycles(purcell3_run, 12, 8)
    cfg = OnlineConfig(suds=SudsConfig(regressors=1, linear_order=1, kernel_features=40, ridge=1e-3))
    a = fit_streaming(train, cfg).model()
    b = fit_streaming(train, OnlineConfig(suds=cfg.suds, chunk=7)).model()
    np.testing.assert_allclose(b.coef, a.coef, atol=1e-9 * np.abs(a.coef).max())
    assert a.kernel_scale is not None and a.n_samples > 0
    back = SudsModel.from_dict(a.to_dict())
    pa, pb = evaluate_model(a, test), evaluate_model(back, test)
    np.testing.assert_allclose(pb.model, pa.model)


@pytest.mark.parametrize("lab", [False, True])
def test_streamed_selection_equals_the_dense_one(purcell3_run, monkeypatch, lab: bool) -> None:
    """Designs too large to build whole are streamed in blocks: the same scores, the same choice.

    The block size is set to split folds and pose intervals at odd places; ``lab`` adds an
    asynchronous pose stream (averaged rows).
    """
    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.systems import make_system

    rec = (simulate_lab(make_system("purcell3"), SimConfig(cycles=12, seed=3), LabConditions()) if lab
           else purcell3_run.slice(0, 1200))
    cfg = IdentifyConfig(order_grid=((1, 0), (4, 2)), ridge_grid=(1e-7, 1e-4), kernel_grid=())
    dense = SudsIdentifier(cfg).fit(rec)
    monkeypatch.setattr(ms, "DENSE_LIMIT", 0)
    monkeypatch.setattr(ms, "BLOCK_ROWS", 97)
    calls = []
    streamed_errors = ms._streamed_errors
    monkeypatch.setattr(ms, "_streamed_errors", lambda *a: calls.append(1) or streamed_errors(*a))
    streamed = SudsIdentifier(cfg).fit(rec)
    assert calls  # the streamed path ran
    assert streamed.cv_scores_.keys() == dense.cv_scores_.keys()
    for k, v in dense.cv_scores_.items():
        assert streamed.cv_scores_[k] == pytest.approx(v, rel=1e-9), k
    assert streamed.regressor_.config == dense.regressor_.config
