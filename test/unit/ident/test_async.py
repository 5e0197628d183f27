"""Asynchronous streams: pose-interval weights, identification on lab-style recordings, splits by time."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, split_cycles
from suds_ros.core.ident.intervals import overlap_weights, pose_intervals
from suds_ros.core.ident.online import OnlineConfig, fit_streaming
from suds_ros.core.ident.predictor import evaluate_model
from suds_ros.core.ident.scoring import score_prediction
from suds_ros.core.physics.lab import LabConditions, simulate_lab
from suds_ros.core.physics.sim import SimConfig
from suds_ros.core.physics.systems import make_system


@pytest.fixture(scope="module")
def lab_run():  # type: ignore[no-untyped-def]
    return simulate_lab(make_system("purcell3"), SimConfig(cycles=20, seed=3), LabConditions())


def test_overlap_weights_rows_sum_to_one_and_average_piecewise_constants() -> None:
    rng = np.random.default_rng(0)
    a = np.cumsum(rng.uniform(0.5, 1.5, 40))
    b = np.sort(rng.uniform(a[0], a[-1], 30))
    W = overlap_weights(a[:-1], a[1:], b[:-1], b[1:])
    np.testing.assert_allclose(np.asarray(W.sum(axis=1)).ravel(), 1.0, rtol=1e-12)
    v = rng.normal(size=a.size - 1)  # value on each a-interval
    # exact time average of the piecewise-constant signal over each b-interval
    grid = np.linspace(a[0], a[-1], 400001)
    sig = v[np.clip(np.searchsorted(a, grid, side="right") - 1, 0, v.size - 1)]
    avg = [sig[(grid >= lo) & (grid < hi)].mean() for lo, hi in zip(b[:-1], b[1:])]
    np.testing.assert_allclose(W @ v, avg, atol=2e-3)


def test_aligned_streams_give_the_identity(purcell3_run) -> None:
    rec = purcell3_run
    pv = pose_intervals(rec, rec.t[:-1], rec.t[1:])
    assert pv.is_identity(0.5 * (rec.t[:-1] + rec.t[1:]))
    W = overlap_weights(rec.t[:-1], rec.t[1:], rec.t[:-1], rec.t[1:])
    assert (W != __import__("scipy.sparse").sparse.identity(rec.t.size - 1)).nnz == 0


def test_a_pose_interval_spanning_a_dropped_shape_sample() -> None:
    shape = np.array([0.0, 1.0, 3.0, 4.0])  # the sample at 2.0 is missing
    W = overlap_weights(shape[:-1], shape[1:], np.array([0.5, 1.5]), np.array([1.5, 3.5])).toarray()
    np.testing.assert_allclose(W, [[0.5, 0.5, 0.0], [0.0, 1.5 / 2, 0.5 / 2]])


def test_split_cycles_counts_cycles_in_time_with_drops() -> None:
    rec = simulate_lab(make_system("purcell3"), SimConfig(cycles=30, seed=1), LabConditions())
    assert rec.n_samples < 3000  # messages were dropped
    train, test = split_cycles(rec, 15)
    edge = rec.t[0] + 15 - 0.5 * rec.dt  # half a period of tolerance for jittered stamps
    assert train.t[0] == rec.t[0] and train.t[-1] < edge <= test.t[0] and test.t[0] - train.t[-1] < 2 * rec.dt
    assert test.t[-1] == rec.t[-1]
    with pytest.raises(Exception, match="holds 30 cycles"):
        split_cycles(rec, 30)


def _interpolated(rec):  # type: ignore[no-untyped-def]
    """The recording with its pose interpolated at the shape stamps (the old way of pairing).

    Shape samples outside the pose stream's span have no pose and are cut.
    """
    inside = np.flatnonzero((rec.t >= rec.pose_t[0]) & (rec.t <= rec.pose_t[-1]))
    pose = rec.pose_at(rec.t[inside])
    rec = rec.slice(int(inside[0]), int(inside[-1]) + 1)
    return replace(rec, pose_t=rec.t, pose=pose)


def test_identify_on_a_lab_recording_beats_interpolation(lab_run) -> None:
    train, test = split_cycles(lab_run, 12, 8)
    new = SudsIdentifier(IdentifyConfig()).fit(train).scores(test)
    old = SudsIdentifier(IdentifyConfig()).fit(_interpolated(train)).scores(test)
    assert new.gamma_body > 0.7 and new.gamma_passive > 0.9
    assert new.gamma_body > old.gamma_body + 0.08  # both judged on the measured pose displacements


def test_streaming_matches_batch_on_async_data(lab_run) -> None:
    train, test = split_cycles(lab_run, 12, 8)
    est = fit_streaming(train, OnlineConfig(chunk=100))
    a = est.model()
    b = fit_streaming(train, OnlineConfig(chunk=7)).model()
    np.testing.assert_allclose(b.coef, a.coef, atol=1e-9 * np.abs(a.coef).max())
    assert est.regressor.avg_columns_ == (0, 1, 2)
    assert est.regressor.normal_avg_.n > 1.1 * est.regressor.normal_.n  # 120 Hz pose vs 100 Hz shape
    sc = score_prediction(evaluate_model(a, test))
    batch = SudsIdentifier(IdentifyConfig(order_grid=(), suds=OnlineConfig().suds)).fit(train).scores(test)
    assert sc.gamma_body > batch.gamma_body - 0.05
    assert sc.gamma_passive > batch.gamma_passive - 0.05
