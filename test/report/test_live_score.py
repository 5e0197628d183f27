"""Scoring of recorded live predictions (``suds score``, the pipeline's closing line).

The bags are written without ROS: a simulated purcell3 run, and as "live" predictions the
streaming predictor of a model fitted on the first cycles only, stamped like the predictor
node stamps them (the stamp of the sample that closes the interval).
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from suds_ros.cli.main import main as suds_main
from suds_ros.core.errors import SudsDataError
from suds_ros.core.ident.identify import split_cycles
from suds_ros.core.ident.online import fit_streaming
from suds_ros.core.ident.predictor import StreamingPredictor
from suds_ros.io import cdr
from suds_ros.io.mcap import BagWriter
from suds_ros.io.recording_bag import (
    METADATA_NAME,
    POSE_TOPIC,
    POSE_TYPE,
    PREDICTED_BODY_TOPIC,
    PREDICTED_PASSIVE_TOPIC,
    SHAPE_TOPIC,
    SHAPE_TYPE,
    STRING_TYPE,
    SYSTEM_TOPIC,
    TWIST_TYPE,
    namespaced,
)
from suds_ros.io.stamps import float_to_ns, split_ns, yaw_quaternion
from suds_ros.report.live_score import score_live_predictions

TRAIN = 10


def _header(ns: int) -> dict:
    sec, nanosec = split_ns(ns)
    return {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": "body"}


def write_bag(path, rec, preds, passive_names=None, pose_from=-np.inf, namespace="", passive_topic=True) -> None:
    """Shape, pose and predictions (stamp s → (ξ (3,), ṙ_p)) of ``rec`` into ``path``.

    ``pose_from``: no pose message before this time (s; motion capture started late).
    ``passive_topic``: False leaves the passive predictions out (a fully actuated robot's recorder
    may not record the topic of its empty messages).
    ``namespace``: every topic under it, and the system on ``<namespace>/suds/system`` (as a
    namespaced pipeline records it) instead of the metadata record.
    """
    passive_names = rec.passive if passive_names is None else passive_names
    shape, pose, body, passive = (namespaced(namespace, t) for t in (
        SHAPE_TOPIC, POSE_TOPIC, PREDICTED_BODY_TOPIC, PREDICTED_PASSIVE_TOPIC))
    with BagWriter(path) as w:
        for topic, type_name in ((shape, SHAPE_TYPE), (pose, POSE_TYPE), (body, TWIST_TYPE),
                                 (passive, SHAPE_TYPE)):
            w.add_topic(topic, type_name)
        info = {"system": rec.system, "actuated": ",".join(rec.actuated),
                "passive": ",".join(rec.passive), "gait_hz": "1.0"}
        if namespace:
            w.add_topic(namespaced(namespace, SYSTEM_TOPIC), STRING_TYPE)
            text = json.dumps({"system": rec.system, "joint_names": list(rec.joint_names),
                               "actuated": list(rec.actuated), "passive": list(rec.passive), "gait_hz": 1.0})
            t0 = float_to_ns(rec.t[0])
            w.write_raw(namespaced(namespace, SYSTEM_TOPIC), cdr.encode(STRING_TYPE, {"data": text}), t0, t0)
        else:
            w.write_metadata(METADATA_NAME, info)
        for k, t in enumerate(rec.t):
            ns = float_to_ns(t)
            w.write_raw(shape, cdr.joint_state(ns, rec.joint_names, rec.r[k], (), ()), ns, ns)
            x, y, yaw = rec.pose[k]
            if t >= pose_from:
                w.write_raw(pose, cdr.pose_stamped(ns, (x, y, 0.0), yaw_quaternion(yaw)), ns, ns)
            if t in preds:
                xi, rp = preds[t]
                twist = {"header": _header(ns), "twist": {
                    "linear": {"x": xi[0], "y": xi[1], "z": 0.0},
                    "angular": {"x": 0.0, "y": 0.0, "z": xi[2]}}}
                w.write_raw(body, cdr.encode(TWIST_TYPE, twist), ns, ns)
                if passive_topic:
                    w.write_raw(passive, cdr.joint_state(ns, passive_names, (), rp, ()), ns, ns)


@pytest.fixture(scope="module")
def live(purcell3_run):
    """Predictions of a model fitted on the first TRAIN cycles, for every later sample."""
    train, _ = split_cycles(purcell3_run, TRAIN)
    model = fit_streaming(train).model()
    pred = StreamingPredictor(model)
    preds = {}
    start = train.n_samples - 1
    for k in range(start, purcell3_run.n_samples):
        out = pred.update(purcell3_run.t[k], purcell3_run.joint_names, purcell3_run.r[k])
        if out is not None:
            preds[purcell3_run.t[k]] = out
    return purcell3_run, preds


def test_out_of_sample_predictions_beat_the_template(live, tmp_path):
    rec, preds = live
    bag = tmp_path / "live.mcap"
    write_bag(bag, rec, preds)
    s = score_live_predictions(bag, TRAIN)
    # intervals whose midpoint lies after the cut; the first prediction closes the interval
    # that straddles it
    assert s.n_intervals == rec.n_samples - 1 - TRAIN * 100
    assert s.n_scored == s.n_intervals and s.n_predictions == len(preds) == s.n_intervals + 1
    assert s.coverage == 1.0
    assert s.gamma_body > 0.8 and s.gamma_passive > 0.9, s
    assert abs(s.first_prediction_s - TRAIN) < 1e-6


def test_motion_capture_starting_late(live, tmp_path):
    """Intervals before the first pose have no measured body velocity: they are neither template
    rows nor scored, and the rest scores as with the full pose stream."""
    rec, preds = live
    write_bag(tmp_path / "full.mcap", rec, preds)
    write_bag(tmp_path / "late_pose.mcap", rec, preds, pose_from=rec.t[0] + 0.537)
    full = score_live_predictions(tmp_path / "full.mcap", TRAIN)
    late = score_live_predictions(tmp_path / "late_pose.mcap", TRAIN)
    assert np.isfinite([late.gamma_body, late.gamma_passive, late.rms_body, late.rms_passive]).all(), late
    assert late.gamma_body == pytest.approx(full.gamma_body, abs=0.01), (late, full)
    assert late.gamma_passive == pytest.approx(full.gamma_passive, abs=0.01), (late, full)


def test_a_robot_in_a_namespace(live, tmp_path, capsys):
    """A namespaced pipeline's bag (topics /robot1/suds/..., system on /robot1/suds/system) is
    scored with ``--namespace``; without it the error says which namespace holds the topics."""
    rec, preds = live
    write_bag(tmp_path / "root.mcap", rec, preds)
    write_bag(tmp_path / "ns.mcap", rec, preds, namespace="/robot1")
    ref = score_live_predictions(tmp_path / "root.mcap", TRAIN)
    got = score_live_predictions(tmp_path / "ns.mcap", TRAIN, namespace="/robot1")
    assert got == ref
    assert suds_main(["score", str(tmp_path / "ns.mcap"), "--namespace", "/robot1", "--train-cycles",
                      str(TRAIN), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["gamma_passive"] == pytest.approx(ref.gamma_passive)
    assert suds_main(["score", str(tmp_path / "ns.mcap")]) == 2
    assert "namespace /robot1" in capsys.readouterr().err


def test_worse_predictions_score_worse_and_gaps_lower_coverage(live, tmp_path):
    rec, preds = live
    stamps = sorted(preds)
    # every prediction 5 samples (50 ms) late: the right waveform at the wrong time
    late = {t: preds[stamps[max(i - 5, 0)]] for i, t in enumerate(stamps)}
    gapped = {t: v for i, (t, v) in enumerate(sorted(preds.items())) if i % 4}
    for name, p in (("late", late), ("gapped", gapped)):
        write_bag(tmp_path / f"{name}.mcap", rec, p)
    lagged = score_live_predictions(tmp_path / "late.mcap", TRAIN)
    write_bag(tmp_path / "good.mcap", rec, preds)
    ref = score_live_predictions(tmp_path / "good.mcap", TRAIN)
    assert lagged.gamma_body < ref.gamma_body - 0.1 and lagged.gamma_passive < ref.gamma_passive - 0.1
    g = score_live_predictions(tmp_path / "gapped.mcap", TRAIN)
    assert g.n_scored == len(gapped)
    assert g.coverage == pytest.approx(0.75, abs=0.01)


def test_errors_name_the_problem(live, tmp_path):
    rec, preds = live
    write_bag(tmp_path / "none.mcap", rec, {})
    with pytest.raises(SudsDataError, match="no live predictions recorded"):
        score_live_predictions(tmp_path / "none.mcap")
    write_bag(tmp_path / "names.mcap", rec, preds, passive_names=("joint_9",))
    with pytest.raises(SudsDataError, match="joint_9"):
        score_live_predictions(tmp_path / "names.mcap")
    write_bag(tmp_path / "ok.mcap", rec, preds)
    with pytest.raises(SudsDataError, match="cannot keep 19"):
        score_live_predictions(tmp_path / "ok.mcap", 19.5)
    early = {t: v for t, v in preds.items() if t < rec.t[0] + 15}
    write_bag(tmp_path / "early.mcap", rec, early)
    with pytest.raises(SudsDataError, match="no live prediction after cycle 16"):
        score_live_predictions(tmp_path / "early.mcap", 16)


def test_cli_score(live, tmp_path, capsys):
    rec, preds = live
    bag = tmp_path / "live.mcap"
    write_bag(bag, rec, preds)
    assert suds_main(["score", str(bag), "--train-cycles", str(TRAIN), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["coverage"] == 1.0 and out["gamma_passive"] > 0.9
    assert suds_main(["score", str(bag)]) == 0
    assert "Γ body" in capsys.readouterr().out
    assert suds_main(["score", str(tmp_path / "missing.mcap")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_with_model_continues_the_stream(live):
    rec, _ = live
    train, _ = split_cycles(rec, TRAIN)
    model = fit_streaming(train).model()
    a, b = StreamingPredictor(model), StreamingPredictor(model)
    for k in range(50):
        a.update(rec.t[k], rec.joint_names, rec.r[k])
        b.update(rec.t[k], rec.joint_names, rec.r[k])
    c = a.with_model(model)  # same template and phase rate: continues
    assert c.shares_phase_with(model) and c.last_stamp == a.last_stamp
    out_b = b.update(rec.t[50], rec.joint_names, rec.r[50])
    out_c = c.update(rec.t[50], rec.joint_names, rec.r[50])
    np.testing.assert_allclose(np.concatenate(out_c), np.concatenate(out_b))
    other = replace(model, omega=1.01 * model.omega)
    assert not a.shares_phase_with(other)
    d = a.with_model(other)  # a different template: starts afresh
    assert d.update(rec.t[50], rec.joint_names, rec.r[50]) is None


def test_a_fully_actuated_robot_has_no_passive_score(worm8_run, tmp_path, capsys):
    """No passive joint: Γ and RMS of the passive group are None (null in JSON, "none" in text),
    whether the predictor's empty passive messages were recorded or not."""
    train, _ = split_cycles(worm8_run, TRAIN)
    pred = StreamingPredictor(fit_streaming(train).model())
    preds = {}
    for k in range(train.n_samples - 1, worm8_run.n_samples):
        out = pred.update(worm8_run.t[k], worm8_run.joint_names, worm8_run.r[k])
        if out is not None:
            assert out[1].shape == (0,)
            preds[worm8_run.t[k]] = out
    write_bag(tmp_path / "empty.mcap", worm8_run, preds)
    write_bag(tmp_path / "absent.mcap", worm8_run, preds, passive_topic=False)
    s = score_live_predictions(tmp_path / "empty.mcap", TRAIN)
    assert s.gamma_passive is None and s.rms_passive is None
    assert np.isfinite(s.gamma_body) and s.gamma_body > 0.5 and s.coverage == 1.0, s
    assert score_live_predictions(tmp_path / "absent.mcap", TRAIN) == s
    assert suds_main(["score", str(tmp_path / "absent.mcap"), "--train-cycles", str(TRAIN), "--json"]) == 0
    d = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(c))
    assert d["gamma_passive"] is None and d["rms_passive"] is None and d["gamma_body"] == pytest.approx(s.gamma_body)
    assert suds_main(["score", str(tmp_path / "empty.mcap"), "--train-cycles", str(TRAIN)]) == 0
    text = capsys.readouterr().out
    assert "Γ passive none" in text and "passive velocity none" in text and "nan" not in text.lower(), text


def write_lab_bag(path, rec, preds) -> None:
    """Shape and pose each on their own stamps, and predictions (stamp s → (ξ, ṙ_p)) on theirs."""
    events = [(float_to_ns(t), 0, k) for k, t in enumerate(rec.t)]
    events += [(float_to_ns(t), 1, k) for k, t in enumerate(rec.pose_t)]
    events += [(float_to_ns(t), 2, t) for t in preds]
    with BagWriter(path) as w:
        for topic, type_name in ((SHAPE_TOPIC, SHAPE_TYPE), (POSE_TOPIC, POSE_TYPE), (PREDICTED_BODY_TOPIC, TWIST_TYPE),
                                 (PREDICTED_PASSIVE_TOPIC, SHAPE_TYPE)):
            w.add_topic(topic, type_name)
        w.write_metadata(METADATA_NAME, {"system": rec.system, "actuated": ",".join(rec.actuated),
                                         "passive": ",".join(rec.passive), "gait_hz": "1.0"})
        for ns, kind, k in sorted(events, key=lambda e: e[:2]):
            if kind == 0:
                w.write_raw(SHAPE_TOPIC, cdr.joint_state(ns, rec.joint_names, rec.r[k], (), ()), ns, ns)
            elif kind == 1:
                x, y, yaw = rec.pose[k]
                w.write_raw(POSE_TOPIC, cdr.pose_stamped(ns, (x, y, 0.0), yaw_quaternion(yaw)), ns, ns)
            else:
                xi, rp = preds[k]
                twist = {"header": _header(ns), "twist": {
                    "linear": {"x": xi[0], "y": xi[1], "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": xi[2]}}}
                w.write_raw(PREDICTED_BODY_TOPIC, cdr.encode(TWIST_TYPE, twist), ns, ns)
                w.write_raw(PREDICTED_PASSIVE_TOPIC, cdr.joint_state(ns, rec.passive, (), rp, ()), ns, ns)


def test_predictions_on_the_live_grid_of_a_jittered_stream_are_scored_on_its_grid(tmp_path):
    """2 ms of stamp jitter: the predictor's grid-stamped predictions are scored on the recording's
    fitted grid (as `suds identify --streaming` scores the same model), and read better than the
    raw intervals' predictions, which are still scored on the raw stamps they carry."""
    from suds_ros.core.ident.predictor import GridPredictor, evaluate_model
    from suds_ros.core.ident.scoring import score_prediction
    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.systems import make_system
    from suds_ros.core.resample import on_shape_grid

    rec = simulate_lab(make_system("purcell3"), SimConfig(cycles=36, seed=5), LabConditions(jitter=0.002))
    train, test = split_cycles(rec, 24, 12)
    model = fit_streaming(train).model()
    on_grid, on_raw = GridPredictor(), StreamingPredictor(model)
    grid_preds, raw_preds = {}, {}
    for k in range(rec.n_samples):
        if k == train.n_samples - 1:
            on_grid.set_model(model)  # the model arrives as the training cycles end
        for t, xi, rp in on_grid.add(float(rec.t[k]), rec.joint_names, rec.r[k]):
            grid_preds[t] = (xi, rp)
        if k >= train.n_samples - 1:
            out = on_raw.update(float(rec.t[k]), rec.joint_names, rec.r[k])
            if out is not None:
                raw_preds[float(rec.t[k])] = out
    for t, xi, rp in on_grid.drain():
        grid_preds[t] = (xi, rp)
    write_lab_bag(tmp_path / "grid.mcap", rec, grid_preds)
    write_lab_bag(tmp_path / "raw.mcap", rec, raw_preds)
    s_grid = score_live_predictions(tmp_path / "grid.mcap", 24)
    s_raw = score_live_predictions(tmp_path / "raw.mcap", 24)
    offline = score_prediction(evaluate_model(model, on_shape_grid(test)))
    assert s_grid.coverage > 0.95 and s_raw.coverage > 0.98, (s_grid, s_raw)
    assert abs(s_grid.gamma_body - offline.gamma_body) < 0.02, (s_grid, offline)
    assert abs(s_grid.gamma_passive - offline.gamma_passive) < 0.02, (s_grid, offline)
    assert s_grid.gamma_body > s_raw.gamma_body + 0.03, (s_grid, s_raw)
