"""StreamingPredictor, the carry-over policy of a new model, and evaluate_model."""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
import pytest

from suds_ros.core.errors import DUPLICATE_STAMP, SudsDataError
from suds_ros.core.ident.identify import split_cycles
from suds_ros.core.ident.online import fit_streaming
from suds_ros.core.ident.predictor import (
    GridPredictor,
    StreamingPredictor,
    carry_over,
    evaluate_model,
    nearest_phase,
)
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


def test_evaluate_model_leaves_out_what_was_bridged_across_lost_messages(fitted) -> None:
    """A shape stream with runs of lost messages: only measured intervals are compared, as in batch scores.

    Before 2026-12-06 the intervals bridged across each run were compared too, and Γ read the
    straight line drawn over the gap as the model's error.
    """
    from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier
    from suds_ros.core.resample import on_shape_grid

    model, test = fitted
    lost = np.zeros(test.t.size, dtype=bool)
    for start in range(40, test.t.size - 60, 150):  # 20 messages (0.2 s) lost every 1.5 s
        lost[start:start + 20] = True
    gappy = on_shape_grid(replace(test, t=test.t[~lost], r=test.r[~lost], truth={}))
    assert gappy.bridged is not None and gappy.bridged.sum() >= 20 * 5
    pred = evaluate_model(model, gappy)
    inside = gappy.bridged[:-1] | gappy.bridged[1:]  # intervals with a bridged end
    assert pred.t.size == (~inside).sum() and not np.isin(pred.t, 0.5 * (gappy.t[:-1] + gappy.t[1:])[inside]).any()
    whole = score_prediction(evaluate_model(model, test))
    sc = score_prediction(pred)
    assert sc.gamma_body > whole.gamma_body - 0.05 and sc.gamma_passive > whole.gamma_passive - 0.05
    batch = SudsIdentifier(IdentifyConfig()).fit(split_cycles(gappy, 5)[0])
    assert batch.predict(gappy).t.size == pred.t.size  # the batch identifier compares the same intervals


def test_grid_predictor_on_a_uniform_stream_is_the_streaming_predictor(fitted) -> None:
    """Every sample passes the grid stage at once and unchanged: the same predictions, at the same stamps."""
    model, test = fitted
    grid, plain = GridPredictor(), StreamingPredictor(model)
    names = ("extra", *reversed(test.joint_names))  # a /joint_states message: other joints, other order
    order = [test.joint_names.index(n) for n in names[1:]]
    assert grid.add(float(test.t[0]), names, np.r_[0.5, test.r[0, order]]) == []  # before the model
    assert grid.set_model(model) == "primed"
    plain.update(float(test.t[0]), test.joint_names, test.r[0])
    for k in range(1, 300):
        out = grid.add(float(test.t[k]), names, np.r_[0.5, test.r[k, order]])
        want = plain.update(float(test.t[k]), test.joint_names, test.r[k])
        assert len(out) == 1 and out[0][0] == test.t[k], (k, out)
        np.testing.assert_array_equal(np.concatenate(out[0][1:]), np.concatenate(want))
    assert grid.mode == "raw" and grid.held == 0 and grid.drain() == [] and not grid.errors


def test_grid_predictor_predicts_a_jittered_stream_on_its_grid() -> None:
    """2 ms of stamp jitter: predictions for the grid intervals, stamped on the batch grid, as good as the
    batch grid's and better than the raw intervals'; what is held comes out at the end."""
    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.systems import make_system
    from suds_ros.core.resample import on_shape_grid

    rec = simulate_lab(make_system("purcell3"), SimConfig(cycles=36, seed=5), LabConditions(jitter=0.002))
    train, test = split_cycles(rec, 24, 12)
    model = fit_streaming(train).model()
    grid = GridPredictor()
    grid.set_model(model)
    out = []
    for k in range(test.n_samples):
        out += grid.add(float(test.t[k]), test.joint_names, test.r[k])
    assert grid.mode == "grid" and grid.held > 0
    out += grid.drain()
    assert grid.held == 0 and not grid.errors
    stamps = np.array([o[0] for o in out])
    assert np.all(np.diff(stamps) > 0)
    batch = on_shape_grid(test)
    step = batch.dt
    inside = stamps <= batch.t[-1] + 0.5 * step  # the batch grid ends with the pose stream
    near = np.abs(stamps[inside, None] - batch.t[None, :]).min(axis=1)
    # the first two samples pass as they came (one interval looks uniform), the rest are grid times
    assert near[2:].max() < 0.05 * step, near[2:].max() / step
    assert stamps.size >= 0.95 * batch.n_samples  # lost messages are not released: a few fewer
    # each prediction against the model run over the batch grid (evaluate_model on on_shape_grid, as
    # `suds identify --streaming` scores), interval by interval where both ends were predicted
    ref = evaluate_model(model, batch)
    k = np.round((stamps - batch.t[0]) / step).astype(int)  # each prediction's grid point
    by_k = dict(zip(k.tolist(), range(k.size)))
    rows = [(i, by_k[i + 1]) for i in range(batch.n_samples - 1) if i in by_k and i + 1 in by_k]
    assert len(rows) >= 0.9 * batch.n_samples
    iv, pj = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    pred = np.array([np.concatenate(out[j][1:]) for j in pj])
    miss = np.sqrt(np.mean((pred - ref.model[iv]) ** 2, axis=0))
    spread = np.sqrt(np.mean((ref.model[iv] - ref.model[iv].mean(axis=0)) ** 2, axis=0))
    assert np.all(miss < 0.05 * spread), miss / spread
    # the raw intervals' predictions are not that: each cuts a bend of the drive
    raw = evaluate_model(model, test)
    near_raw = np.searchsorted(test.t[1:], batch.t[iv + 1])
    near_raw = np.clip(near_raw, 0, raw.model.shape[0] - 1)
    assert np.sqrt(np.mean((raw.model[near_raw] - ref.model[iv]) ** 2, axis=0)).max() > 2 * miss.max()


def test_grid_predictor_refuses_a_bad_sample_and_restarts_for_other_joints(fitted) -> None:
    model, test = fitted
    grid = GridPredictor()
    grid.set_model(model)
    names = test.joint_names
    grid.add(float(test.t[0]), names, test.r[0])
    for bad, code in (((float(test.t[0]), names, test.r[0]), DUPLICATE_STAMP),
                      ((float(test.t[1]), names, np.r_[test.r[1][:-1], np.nan]), "nan_or_inf"),
                      ((float(test.t[1]), names, test.r[1][:-1]), "wrong_joint_count")):
        with pytest.raises(SudsDataError) as info:
            grid.add(*bad)
        assert info.value.code == code
    assert len(grid.add(float(test.t[1]), names, test.r[1])) == 1  # the stage took none of them
    # a message without the model's joints: taken by the grid, refused by the predictor, reported
    assert grid.add(float(test.t[2]), ("x",), np.zeros(1)) == [] and grid.names == ("x",)
    assert [e.code for e in grid.errors] == ["wrong_joint_names"]
