"""The estimator contract: get_params/set_params/clone, check_is_fitted, partial_fit rules."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from suds_ros.core.errors import NotFittedError, SudsConfigError, SudsDataError, SudsError
from suds_ros.core.estimator import BaseEstimator, check_is_fitted, clone, is_fitted
from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier
from suds_ros.core.ident.shape_kernel import KernelScale
from suds_ros.core.ident.sysid import SudsConfig, SudsRegressor, regressor_input
from suds_ros.core.phase.phaser import Phaser, PhaserConfig
from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig

NJ, NA = 3, 1


def _rows(n: int = 400, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    phase = np.linspace(0.0, 8 * np.pi, n)
    delta, dda = rng.normal(scale=0.2, size=(n, NJ)), rng.normal(size=(n, NA))
    X = regressor_input(phase, delta, dda, delta + 0.5, dda + 1.0)
    y = np.column_stack([np.sin(phase) + delta[:, 0] * dda[:, 0], delta[:, 1]]) + 0.01 * rng.normal(size=(n, 2))
    return X, y


def _scale() -> KernelScale:
    return KernelScale(np.full(NJ, 0.5), np.ones(NJ), np.ones(NA), np.ones(NA))


def _estimators() -> list[BaseEstimator]:
    return [
        SudsRegressor(SudsConfig(regressors=1, ridge=1e-4), n_actuated=NA),
        SudsRegressor(SudsConfig(kernel_features=5), n_actuated=NA, kernel_scale=_scale()),
        FourierTemplate(FourierTemplateConfig(order=3)),
        Phaser(PhaserConfig(order=5)),
        SudsIdentifier(IdentifyConfig(order_grid=()), torque=True),
    ]


# ------------------------------------------------------------------ errors
def test_not_fitted_error_is_a_suds_value_and_attribute_error() -> None:
    assert issubclass(NotFittedError, SudsError)
    assert issubclass(NotFittedError, ValueError)
    assert issubclass(NotFittedError, AttributeError)
    err = pickle.loads(pickle.dumps(NotFittedError("x")))
    assert isinstance(err, NotFittedError) and err.code == "not_fitted"


@pytest.mark.parametrize("est", _estimators(), ids=lambda e: type(e).__name__)
def test_check_is_fitted_raises_before_fit(est: BaseEstimator) -> None:
    name = type(est).__name__
    with pytest.raises(NotFittedError, match=f"this {name} is not fitted yet; call fit"):
        check_is_fitted(est)
    assert not is_fitted(est)


def test_methods_that_need_a_fit_raise_not_fitted() -> None:
    X, y = _rows()
    reg = SudsRegressor(n_actuated=NA)
    for call in (lambda: reg.predict(X), lambda: reg.score(X, y), lambda: reg.coefficients(X[:, 0]),
                 lambda: reg.n_parameters):
        with pytest.raises(NotFittedError, match="this SudsRegressor is not fitted yet; call fit or partial_fit"):
            call()
    assert not hasattr(reg, "n_parameters")  # an AttributeError: hasattr is False
    with pytest.raises(NotFittedError, match="this FourierTemplate is not fitted yet; call fit or partial_fit"):
        FourierTemplate().predict(np.zeros(3))
    with pytest.raises(NotFittedError, match="this Phaser is not fitted yet; call fit first"):
        Phaser().transform(np.zeros((50, 2)))
    with pytest.raises(NotFittedError, match="this SudsIdentifier is not fitted yet; call fit first"):
        _ = SudsIdentifier().n_parameters


def test_check_is_fitted_arguments() -> None:
    X, y = _rows()
    reg = SudsRegressor(n_actuated=NA).fit(X, y)
    check_is_fitted(reg)
    check_is_fitted(reg, "coef_")
    check_is_fitted(reg, ["coef_", "layout_"])
    with pytest.raises(NotFittedError, match="this SudsRegressor is not fitted"):
        check_is_fitted(reg, ["coef_", "no_such_"])
    with pytest.raises(NotFittedError, match="^`est`: expected a fitted SudsRegressor$"):
        check_is_fitted(SudsRegressor(n_actuated=NA), msg="`est`: expected a fitted %(name)s")
    with pytest.raises(TypeError, match="expected an estimator instance"):
        check_is_fitted(SudsRegressor)
    with pytest.raises(TypeError, match="expected an estimator instance"):
        check_is_fitted(object())


def test_template_with_too_few_samples_is_not_fitted() -> None:
    tmpl = FourierTemplate(FourierTemplateConfig(order=3)).partial_fit(np.arange(4.0), np.ones(4))
    assert tmpl.n_samples_seen_ == 4 and not is_fitted(tmpl)
    with pytest.raises(NotFittedError, match="call fit or partial_fit first"):
        tmpl.predict(0.0)


# -------------------------------------------------------------- parameters
def test_init_only_stores_hyperparameters() -> None:
    reg = SudsRegressor(SudsConfig(ridge=1.0), n_actuated=-3, kernel_scale="nonsense")  # type: ignore[arg-type]
    assert reg.get_params(deep=False) == {"config": SudsConfig(ridge=1.0), "n_actuated": -3,
                                          "kernel_scale": "nonsense"}
    assert not [k for k in vars(reg) if k.endswith("_")]  # nothing learned in __init__
    X, y = _rows()
    with pytest.raises(SudsConfigError, match="`n_actuated`: expected an integer ≥ 0, got -3"):
        reg.fit(X, y)
    reg.set_params(n_actuated=NA, config=SudsConfig(kernel_features=4))
    with pytest.raises(SudsConfigError, match="`kernel_scale`: random shape features .* got 'nonsense'"):
        reg.fit(X, y)
    with pytest.raises(SudsConfigError, match=r"`kernel_scale`: expected scales of shapes \(3,\), \(3,\), \(1,\)"):
        reg.set_params(kernel_scale=KernelScale(np.zeros(2), np.ones(2), np.zeros(1), np.ones(1))).fit(X, y)
    with pytest.raises(SudsConfigError, match="`config`: expected a SudsConfig, got 3"):
        SudsRegressor(3, n_actuated=NA).fit(X, y)  # type: ignore[arg-type]
    with pytest.raises(SudsConfigError, match="`config`: expected an IdentifyConfig, got None"):
        SudsIdentifier(None).fit(None)  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        SudsRegressor(NJ, NA, SudsConfig())  # type: ignore[misc]  # the old signature fails loudly


def test_get_params_deep_and_nested_set_params() -> None:
    reg = SudsRegressor(SudsConfig(ridge=1e-3), n_actuated=NA)
    deep = reg.get_params()
    assert deep["config__ridge"] == 1e-3 and deep["n_actuated"] == NA and deep["kernel_scale"] is None
    assert reg.set_params(config__ridge=1e-5, config__regressors=3) is reg
    assert reg.config == SudsConfig(ridge=1e-5, regressors=3)
    with pytest.raises(SudsConfigError, match=r"`regressors`: expected an integer in \[1, 3\], got 4"):
        reg.set_params(config__regressors=4)  # the config's own checks run
    with pytest.raises(SudsConfigError, match="`config__nope`: not a field of SudsConfig"):
        reg.set_params(config__nope=1)
    with pytest.raises(SudsConfigError, match="`alpha`: not a parameter of SudsRegressor; expected one of"):
        reg.set_params(alpha=1.0)
    with pytest.raises(SudsConfigError, match="`n_actuated`: int has no parameters to set"):
        reg.set_params(n_actuated__x=1)


@pytest.mark.parametrize("est", _estimators(), ids=lambda e: type(e).__name__)
def test_clone_round_trip(est: BaseEstimator) -> None:
    twin = clone(est)
    assert type(twin) is type(est) and twin is not est
    p, q = est.get_params(deep=False), twin.get_params(deep=False)
    assert p.keys() == q.keys()
    for k in p:
        assert repr(p[k]) == repr(q[k])
    assert repr(twin) == repr(est)
    assert type(est)(**est.get_params(deep=False)).get_params(deep=False).keys() == p.keys()


def test_clone_is_unfitted_and_fits_the_same() -> None:
    X, y = _rows()
    reg = SudsRegressor(SudsConfig(kernel_features=5), n_actuated=NA, kernel_scale=_scale()).fit(X, y)
    twin = clone(reg)
    assert not is_fitted(twin) and twin.kernel_scale is not reg.kernel_scale  # a deep copy
    np.testing.assert_array_equal(twin.fit(X, y).coef_, reg.coef_)
    assert [clone(e) for e in (reg,)][0].get_params(deep=False).keys() == reg.get_params(deep=False).keys()
    with pytest.raises(TypeError, match="expected an estimator with get_params"):
        clone(3)
    assert clone([reg, 3], safe=False)[1] == 3


def test_repr_shows_changed_parameters() -> None:
    assert repr(FourierTemplate()) == "FourierTemplate()"
    assert repr(SudsRegressor(n_actuated=2)) == "SudsRegressor(n_actuated=2)"
    assert "ridge=0.5" in repr(SudsRegressor(SudsConfig(ridge=0.5), n_actuated=2))


def test_clone_refuses_an_init_that_changes_its_arguments() -> None:
    class Bad(BaseEstimator):
        def __init__(self, a: list[int] | None = None) -> None:
            self.a = list(a or [])

        def fit(self) -> "Bad":
            return self

    with pytest.raises(RuntimeError, match="does not store `a` unchanged"):
        clone(Bad([1]))


# ------------------------------------------------------------- partial_fit
def test_partial_fit_learns_shapes_on_the_first_call_and_keeps_them() -> None:
    X, y = _rows()
    reg = SudsRegressor(n_actuated=NA).partial_fit(X[:100], y[:100])
    assert reg.n_features_in_ == X.shape[1] == 1 + 2 * (NJ + NA)
    assert reg.n_joints_ == NJ and reg.n_outputs_ == 2 and reg.n_samples_seen_ == 100
    reg.partial_fit(X[100:250], y[100:250])
    assert reg.n_samples_seen_ == 250
    wider = np.column_stack([X[:, :1], X[:, 1:], X[:, 1:3]])  # as if nj were 4
    with pytest.raises(SudsDataError, match=r"X: expected shape \(n, 9\) .* as in the first fit, got \(400, 11\)"):
        reg.partial_fit(wider, y)
    with pytest.raises(SudsDataError, match="y: expected 2 outputs as before, got 1"):
        reg.partial_fit(X, y[:, :1])
    with pytest.raises(SudsDataError, match=r"X: expected shape \(n, 9\)"):
        reg.predict(wider)
    reg.set_params(config__regressors=3)
    with pytest.raises(SudsConfigError, match="after the first fit laid out .*; call fit to start again"):
        reg.partial_fit(X, y)
    with pytest.raises(SudsConfigError, match="call fit to start again"):
        reg.predict(X)
    # fit forgets the shapes: the wider rows are fine after a fresh fit
    reg.fit(wider, y)
    assert reg.n_joints_ == 4 and reg.n_samples_seen_ == 400


def test_fit_resets_and_equals_chunked_partial_fit() -> None:
    X, y = _rows()
    full = SudsRegressor(n_actuated=NA).fit(X, y)
    inc = SudsRegressor(n_actuated=NA)
    for a, b in ((0, 150), (150, 151), (151, 400)):
        inc.partial_fit(X[a:b], y[a:b])
    np.testing.assert_allclose(inc.coef_, full.coef_, rtol=0, atol=1e-9 * np.abs(full.coef_).max())
    full.fit(X[:200], y[:200])
    assert full.n_samples_seen_ == 200
    assert isinstance(full.score(X, y), float)


def test_template_partial_fit_rejects_a_channel_change() -> None:
    ph = np.linspace(0, 6 * np.pi, 90)
    tmpl = FourierTemplate(FourierTemplateConfig(order=2)).partial_fit(ph, np.c_[np.sin(ph), np.cos(ph)])
    with pytest.raises(SudsDataError, match="`Y`: expected 2 channels as in earlier calls, got 1"):
        tmpl.partial_fit(ph, np.sin(ph))


def test_hyperparameters_do_not_change_in_fit() -> None:
    X, y = _rows()
    for est, args in ((SudsRegressor(SudsConfig(ridge=1e-3), n_actuated=NA), (X, y)),
                      (FourierTemplate(FourierTemplateConfig(order=2)), (X[:, 0], y))):
        before = est.get_params(deep=False)
        est.fit(*args)
        assert est.get_params(deep=False) == before


def test_regressor_pickled_before_the_contract_loads() -> None:
    """Checkpoints (version 5) hold regressors whose constructor stored ``n_joints``."""
    X, y = _rows()
    reg = SudsRegressor(n_actuated=NA).fit(X, y)
    old = dict(vars(reg))
    del old["n_joints_"], old["n_features_in_"]
    old["n_joints"] = NJ
    legacy = SudsRegressor.__new__(SudsRegressor)
    legacy.__setstate__(old)
    np.testing.assert_array_equal(legacy.predict(X), reg.predict(X))
    legacy.partial_fit(X[:10], y[:10])
    assert legacy.n_samples_seen_ == 410 and legacy.get_params(deep=False) == reg.get_params(deep=False)


# ----------------------------------------------------- scikit-learn, if any
# (scikit-learn's own check_is_fitted also needs its estimator tags, which only its BaseEstimator has)
@pytest.mark.parametrize("est", _estimators(), ids=lambda e: type(e).__name__)
def test_sklearn_clone(est: BaseEstimator) -> None:
    base = pytest.importorskip("sklearn.base")
    twin = base.clone(est)
    assert type(twin) is type(est) and twin is not est and repr(twin) == repr(est)
    assert not is_fitted(twin)


def test_sklearn_parameter_grid_through_nested_config_fields() -> None:
    base = pytest.importorskip("sklearn.base")
    model_selection = pytest.importorskip("sklearn.model_selection")
    X, y = _rows()
    proto = SudsRegressor(n_actuated=NA)
    grid = model_selection.ParameterGrid({"config__ridge": [1e-6, 1e-2], "config__regressors": [1, 2]})
    scores = {}
    for params in grid:
        est = base.clone(proto).set_params(**params).fit(X[:300], y[:300])
        scores[(params["config__regressors"], params["config__ridge"])] = est.score(X[300:], y[300:])
    assert proto.config == SudsConfig() and not is_fitted(proto)
    assert max(scores, key=scores.__getitem__)[0] == 2  # the product δ₀·δ̇ is only in set 2
