"""The text report of a diagnosis (:func:`suds_ros.report.diagnosis.summary_text`)."""

from __future__ import annotations

import json

from suds_ros.core.diagnosis.report import NO_EFFECT, Alternative, DiagnosisReport, FittedEffect, Located
from suds_ros.report.diagnosis import summary_text


def test_the_nominal_model_as_an_alternative_is_said_in_words() -> None:
    """"Or no effect at all": the text says so instead of printing an effect called ``none``;
    the JSON keeps the alternative with a null target and no parameters."""
    none = Alternative(NO_EFFECT, None, {}, 21.0, (), ("pose_frame_offset",))
    offset = FittedEffect("pose_frame_offset", None, {"x": 0.01, "y": 0.0, "yaw": 0.02},
                          {"x": 1e-3, "y": 1e-3, "yaw": 1e-3}, 21.0, (none,))
    rep = DiagnosisReport(True, (Located("xi_y", ((0.0, 1.0),), 2.2),), (offset,), (), False,
                          {"xi_y": 0.05}, {"xi_y": 0.04}, 0.7)
    text = summary_text(rep)
    assert "no effect at all (the nominal model)" in text and "+21.0 nats" in text
    assert "none (" not in text
    alt = json.loads(rep.to_json())["effects"][0]["alternatives"][0]
    assert alt["name"] == NO_EFFECT and alt["target"] is None and alt["parameters"] == {}
    assert alt["instead_of"] == ["pose_frame_offset"]
