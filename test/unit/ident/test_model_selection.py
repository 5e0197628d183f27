"""Model selection on nested designs: column subsets, exact fold fits, the chosen model, the interval state."""

from __future__ import annotations

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.ident import model_selection as ms
from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, split_cycles
from suds_ros.core.ident.model import SudsModel
from suds_ros.core.ident.sysid import SudsConfig, SudsRegressor, design_matrix, feature_layout, interval_state


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


def test_cv_scores_equal_refits_on_each_fold() -> None:
    """Every score comes from the fold's own least-squares fit (Gram subtraction is exact)."""
    rng = np.random.default_rng(5)
    nj, na, n = 3, 1, 300
    X = np.column_stack([np.linspace(0, 40, n), rng.normal(size=(n, nj)), rng.normal(size=(n, na))])
    y = np.column_stack([np.sin(X[:, 0]) + X[:, 1] * X[:, 4], X[:, 2] - X[:, 3]]) + 0.1 * rng.normal(size=(n, 2))
    T = np.column_stack([np.sin(X[:, 0]), np.zeros(n)])
    cands = ms.candidates(SudsConfig(intercept_order=2), (1, 2), ((1, 0), (2, 1)), (1e-6, 1e-2))
    big = SudsRegressor(nj, na, ms.largest(cands))
    edges = np.linspace(0, n, 4).astype(int)
    problem = ms.CVProblem(A=big._design(X), y=y, template=T, columns=(0, 1), groups=((0,), (1,)), edges=edges)
    best, scores = ms.select(problem, cands, nj, na)
    for cfg in cands:
        total = 0.0
        for f in range(3):
            te = np.zeros(n, dtype=bool)
            te[edges[f]:edges[f + 1]] = True
            reg = SudsRegressor(nj, na, cfg).fit(X[~te], y[~te])
            err = np.abs(reg.predict(X[te]) - y[te])
            ref = np.abs(T[te] - y[te])
            total += np.mean(err.sum(0) / ref.sum(0))
        key = (cfg.regressors, cfg.linear_order, cfg.bilinear_order, cfg.ridge)
        assert scores[key] == pytest.approx(total / 3, rel=1e-7)
    assert scores[(best.regressors, best.linear_order, best.bilinear_order, best.ridge)] == min(scores.values())
    assert best.regressors == 2  # the product X₁·X₄ is only in set 2


def test_small_data_chooses_a_smaller_model_than_large_data(swimmer9_run) -> None:
    """The model's size follows the amount of data, and the fit is the chosen candidate's."""
    small, _ = split_cycles(swimmer9_run, 4)
    large, _ = split_cycles(swimmer9_run, 16)
    p_small = SudsIdentifier().fit(small)
    p_large = SudsIdentifier().fit(large)
    assert p_small.n_parameters < p_large.n_parameters
    chosen = p_large.regressor_.config
    key = (chosen.regressors, chosen.linear_order, chosen.bilinear_order, chosen.ridge)
    assert p_large.cv_scores_[key] == min(p_large.cv_scores_.values())


def test_start_state_beats_midpoint_on_swimmer9_passive(swimmer9_run) -> None:
    """swimmer9's stiff passive modes relax within an interval: the start state predicts ṙ_p better."""
    train, test = split_cycles(swimmer9_run, 16)
    g = {}
    for state in ("start", "midpoint"):
        cfg = IdentifyConfig(suds=SudsConfig(linear_order=6, bilinear_order=3, state=state), order_grid=())
        g[state] = SudsIdentifier(cfg).fit(train).score(test).gamma_passive
    print(g)
    assert g["start"] > g["midpoint"] + 0.005


def test_interval_state_and_config() -> None:
    a, b = np.array([0.0, 2.0]), np.array([1.0, 4.0])
    np.testing.assert_array_equal(interval_state(SudsConfig(), a, b), a)
    np.testing.assert_array_equal(interval_state(SudsConfig(state="midpoint"), a, b), [0.5, 3.0])
    with pytest.raises(SudsConfigError, match="`state`"):
        SudsConfig(state="end")


def test_model_dicts_without_a_state_are_midpoint_models(purcell3_run) -> None:
    """Models saved before the state existed keep their meaning."""
    from suds_ros.core.ident.online import fit_streaming

    d = fit_streaming(purcell3_run).model().to_dict()
    assert d["suds"]["state"] == "start"
    del d["suds"]["state"]
    assert SudsModel.from_dict(d).suds.state == "midpoint"
