"""SudsModel: JSON round trip, predictions consistent with the estimator, sample checks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from suds_ros.core.errors import DUPLICATE_STAMP, OUT_OF_ORDER_STAMP, WRONG_JOINT_NAMES, SudsDataError
from suds_ros.core.ident.model import SudsModel, check_shape_sample, check_stamp, model_template
from suds_ros.core.ident.online import fit_streaming
from suds_ros.core.ident.sysid import design_matrix


@pytest.fixture(scope="module")
def model(purcell3_run) -> SudsModel:
    return fit_streaming(purcell3_run.slice(0, 1000)).model()


def test_model_json_roundtrip(model) -> None:
    back = SudsModel.from_dict(json.loads(json.dumps(model.to_dict())))
    np.testing.assert_array_equal(back.coef, model.coef)
    np.testing.assert_array_equal(back.template_coef, model.template_coef)
    assert back.suds == model.suds and back.channels == model.channels


def test_prediction_takes_the_template_and_the_regressors_from_one_basis(model) -> None:
    # predict() evaluates the harmonics once, at the highest order it needs, and slices the
    # template's and each regressor group's columns from it: the same as evaluating each apart
    tmpl = model_template(model)
    phase = np.linspace(0.0, 7.0, 9)
    theta, dtheta = tmpl.predict(phase), tmpl.derivative(phase)
    rng = np.random.default_rng(3)
    r = theta + 0.05 * rng.standard_normal(theta.shape)
    rdot = dtheta * model.omega + 0.1 * rng.standard_normal(theta.shape)
    act = [model.joint_names.index(j) for j in model.actuated]
    X = design_matrix(model.suds, phase, r - theta, (rdot - dtheta * model.omega)[:, act], r, rdot[:, act],
                      model.kernel_scale)
    out = model.predict(phase, r, rdot)
    assert out.shape == (9, len(model.channels))
    np.testing.assert_allclose(out, X @ model.coef, rtol=1e-10, atol=1e-12)
    assert model.template(phase).shape == (9, len(model.channels))
    with pytest.raises(SudsDataError, match="`basis`"):
        design_matrix(model.suds, phase, r - theta, rdot[:, act], basis=np.ones((9, 3)))


def test_sample_checks() -> None:
    check_stamp("shape", 1.0, 0.5)
    for t, code in ((0.5, DUPLICATE_STAMP), (0.4, OUT_OF_ORDER_STAMP)):
        with pytest.raises(SudsDataError, match="pose stamp") as info:
            check_stamp("pose", t, 0.5)
        assert info.value.code == code
    with pytest.raises(SudsDataError, match="expected \\['a'\\]") as info:
        check_shape_sample(0.0, ("b",), [1.0], ("a",))
    assert info.value.code == WRONG_JOINT_NAMES
    assert check_shape_sample(0.0, ("a",), [1], ("a",)).dtype == float
