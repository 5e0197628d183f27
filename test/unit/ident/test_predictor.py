"""StreamingPredictor, the carry-over policy of a new model, and evaluate_model."""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
import pytest

from suds_ros.core.errors import DUPLICATE_STAMP, SudsDataError
from suds_ros.core.ident.identify import split_cycles
from suds_ros.core.ident.online import fit_streaming
from suds_ros.core.ident.predictor import StreamingPredictor, carry_over, evaluate_model, nearest_phase
from suds_ros.core.ident.scoring import score_prediction


class Sample(NamedTuple):
    stamp: float
    names: tuple[str, ...]
    position: np.ndarray


@pytest.fixture(scope="module")
def fitted(purcell3_run):
    train, test = split_cycles(purcell3_run, 10)
    return fit_streaming(train).model(), test


def test_first_sample_starts_then_every_sample_predicts(fitted) -> None:
    model, test = fitted
    pred = StreamingPredictor(model)
    assert pred.update(float(test.t[0]), test.joint_names, test.r[0]) is None
    xi, rdot = pred.update(float(test.t[1]), test.joint_names, test.r[1])
    assert xi.shape == (3,) and rdot.shape == (len(model.passive),)
    with pytest.raises(SudsDataError, match="duplicate shape stamp") as info:
        pred.update(float(test.t[1]), test.joint_names, test.r[1])
    assert info.value.code == DUPLICATE_STAMP


def test_nearest_phase_is_on_the_template(fitted) -> None:
    model, _ = fitted
    pred = StreamingPredictor(model)
    theta = pred.template.predict(np.array([1.0]))[0]
    assert abs(nearest_phase(pred.template, theta) - 1.0) < 2 * np.pi / 720 + 1e-9


def test_carry_over_policy(fitted) -> None:
    model, test = fitted
    names = test.joint_names
    new, how = carry_over(None, model, None)
    assert how == "fresh" and new.last_stamp == -np.inf
    new, how = carry_over(None, model, Sample(float(test.t[0]), names, test.r[0]))
    assert how == "primed" and new.last_stamp == test.t[0]
    assert new.update(float(test.t[1]), names, test.r[1]) is not None  # predicts at once
    again, how = carry_over(new, model, None)
    assert how == "tracker" and again.last_stamp == new.last_stamp
    other = replace(model, omega=1.01 * model.omega)
    moved, how = carry_over(new, other, Sample(float(test.t[1]), names, test.r[1]))
    assert how == "primed" and moved.model is other
    bad, how = carry_over(None, model, Sample(float(test.t[0]), ("x", "y"), test.r[0]))
    assert how == "fresh"


def test_evaluate_model_scores_a_recording(fitted, swimmer9_run) -> None:
    model, test = fitted
    sc = score_prediction(evaluate_model(model, test))
    assert sc.gamma_body > 0.5 and sc.gamma_passive > 0.5
    with pytest.raises(SudsDataError, match="differ from the model's"):
        evaluate_model(model, swimmer9_run)
