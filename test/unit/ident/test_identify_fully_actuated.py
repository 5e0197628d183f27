"""Identification of a fully actuated chain (every joint driven, no passive joint).

The paper's kinematic connection and most snake robots: the outputs are the body velocity alone,
and a passive score does not apply (None, never NaN).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, split_cycles
from suds_ros.core.ident.model import SudsModel
from suds_ros.core.ident.online import OnlineConfig, fit_streaming
from suds_ros.core.ident.predictor import StreamingPredictor, evaluate_model
from suds_ros.core.ident.scoring import BODY_CHANNELS, score_prediction
from suds_ros.core.json_text import dumps


def _strict(text: str) -> object:
    return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c} in {text[:200]}"))


@pytest.fixture(scope="module")
def halves(worm8_run):  # type: ignore[no-untyped-def]
    assert worm8_run.passive == () and len(worm8_run.actuated) == 7
    return split_cycles(worm8_run, 10, 10)


def test_batch_identifier_scores_the_body_and_no_passive_group(halves) -> None:  # type: ignore[no-untyped-def]
    train, test = halves
    ident = SudsIdentifier(IdentifyConfig()).fit(train)
    sc = ident.scores(test)
    assert ident.channels_ == BODY_CHANNELS
    assert sc.gamma_passive is None and sc.gamma_torque is None
    # the held-out body velocity is predicted far better than the phase-only template
    assert np.isfinite(sc.gamma_body) and sc.gamma_body > 0.7, sc
    assert set(sc.rms_model) == set(BODY_CHANNELS)
    assert ident.score(test) == pytest.approx(sc.gamma_body)
    d = _strict(dumps(sc.as_dict()))
    assert d["gamma_passive"] is None and d["gamma_body"] == pytest.approx(sc.gamma_body)  # type: ignore[index]


def test_streaming_estimator_and_predictor(halves) -> None:  # type: ignore[no-untyped-def]
    train, test = halves
    est = fit_streaming(train, OnlineConfig(gait_hz=1.0))
    g = est.running_gamma()
    assert g["passive"] is None and g["body"] is not None and np.isfinite(g["body"]), g
    model = est.model()
    assert model.passive == () and model.channels == BODY_CHANNELS
    back = SudsModel.from_dict(_strict(dumps(model.to_dict())))  # type: ignore[arg-type]
    np.testing.assert_array_equal(back.coef, model.coef)
    sc = score_prediction(evaluate_model(back, test))
    assert sc.gamma_passive is None and sc.gamma_body > 0.5, sc
    pred = StreamingPredictor(back)
    outs = [pred.update(test.t[k], test.joint_names, test.r[k]) for k in range(50)]
    outs = [o for o in outs if o is not None]
    assert outs, "the predictor never predicted"
    xi, rdot_p = outs[-1]
    assert xi.shape == (3,) and np.all(np.isfinite(xi)) and rdot_p.shape == (0,)


def test_estimator_session_status_says_none_for_the_passive_score(worm8_run) -> None:  # type: ignore[no-untyped-def]
    """The estimator node's status (DiagnosticArray values): "none", never "nan", for a group that does not apply."""
    from types import SimpleNamespace

    from suds_ros.core.ident.session import EstimatorSession, SessionConfig

    s = EstimatorSession(SessionConfig(actuated=tuple(worm8_run.actuated)))
    for k in range(800):
        s.on_shape(SimpleNamespace(stamp=float(worm8_run.t[k]), names=worm8_run.joint_names,
                                   position=worm8_run.r[k]), now=0.0)
        x, y, yaw = map(float, worm8_run.pose[k])
        s.on_pose(SimpleNamespace(stamp=float(worm8_run.pose_t[k]), x=x, y=y, yaw=yaw), now=0.0)
    v = s.status_values()
    assert s.est is not None and s.est.initialised, v
    assert v["gamma_passive"] == "none" and np.isfinite(float(v["gamma_body"])), v


def test_the_live_estimator_learns_from_thin_video_like_data(worm8_run) -> None:  # type: ignore[no-untyped-def]
    """25 frames a second with 40 % of them lost (a filmed animal): some 15 rows a cycle.

    The live estimator's rich candidates have hundreds of parameters per output; its small one
    is published when it predicts better, and the streaming model is then about as good as the
    batch identifier's, which chooses its size by cross-validation.  Without the small
    candidate the published model was set 2's (Γ body 0.28 against 0.87 here).
    """
    from dataclasses import replace

    keep = np.zeros(worm8_run.t.size, dtype=bool)
    keep[::4] = True
    keep &= np.random.default_rng(0).random(worm8_run.t.size) >= 0.4
    video = replace(worm8_run, t=worm8_run.t[keep], r=worm8_run.r[keep], pose_t=worm8_run.pose_t[keep],
                    pose=worm8_run.pose[keep], truth={})
    train, test = split_cycles(video, 10, 10)
    cfg = OnlineConfig(gait_hz=1.0)
    est = fit_streaming(train, cfg)
    assert est.chunk_rows == 25  # one gait cycle of rows (25 fps, 1 Hz): the candidates are compared cycle by cycle
    running = est.running_gamma()["body"]
    assert running is not None and 0.0 < running < 0.95  # prequential, so below the held-out Γ; not swamped
    live = score_prediction(evaluate_model(est.model(), test)).gamma_body
    batch = SudsIdentifier(IdentifyConfig()).fit(train).scores(test).gamma_body
    rich = fit_streaming(train, replace(cfg, alternatives=cfg.alternatives[:1]))
    assert est.model().coef.shape[0] < rich.model().coef.shape[0]
    assert live > batch - 0.05 and live > score_prediction(evaluate_model(rich.model(), test)).gamma_body + 0.3
