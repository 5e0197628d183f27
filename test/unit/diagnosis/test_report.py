"""Diagnosis configuration and report (:mod:`suds_ros.core.diagnosis.report`): validation, JSON schema."""

from __future__ import annotations

import json

import pytest

from suds_ros.core.diagnosis import DiagnoseConfig, diagnose
from suds_ros.core.physics.systems import purcell3_model


def test_json_schema_is_exact(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    rep = diagnose(purcell3_run, purcell3_model())
    d = json.loads(rep.to_json())
    assert d["notes"] == list(rep.notes)  # the text report's notes, e.g. a parameter the data disagree on
    assert set(d) == {"mismatch", "located", "effects", "confounded_with", "unexplained", "fit", "discovered",
                      "notes"}
    assert set(d["fit"]) == {"heldout_rms_before", "heldout_rms_after", "improvement"}
    assert set(d["fit"]["heldout_rms_before"]) == {"joint_2", "xi_x", "xi_y", "xi_theta"}


def test_config_is_validated() -> None:
    from suds_ros.core.errors import SudsConfigError

    with pytest.raises(SudsConfigError, match="`f_threshold`"):
        DiagnoseConfig(f_threshold=0.5)


def test_a_channel_without_usable_samples_is_null_in_json_and_na_in_text() -> None:
    """A channel whose held-out samples are all left out (NaN statistics): strict JSON, no "nan" in text."""
    import math

    from suds_ros.core.diagnosis import DiagnosisReport
    from suds_ros.report.diagnosis import summary_text

    nan = float("nan")
    rms = {"xi_x": nan, "xi_y": 0.01, "xi_theta": 0.02}
    rep = DiagnosisReport(
        mismatch=False, located=(), effects=(), confounded_with=(), unexplained=False,
        heldout_rms_before=rms, heldout_rms_after=rms, improvement=0.0, system="worm8",
        noise_floor={"xi_x": 0.01, "xi_y": 0.01, "xi_theta": 0.02},
        statistics={"xi_x": nan, "xi_y": 1.0, "xi_theta": 1.0},
        notes=("not tested: xi_x (no usable held-out sample)",),
    )
    d = json.loads(rep.to_json(), parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert d["fit"]["heldout_rms_before"] == {"xi_x": None, "xi_y": 0.01, "xi_theta": 0.02}
    text = summary_text(rep)
    assert "nan" not in text.lower() and "n/a" in text and "on the channels tested" in text, text
    assert math.isnan(rep.heldout_rms_before["xi_x"])  # the report itself keeps the number


def test_untested_channels_are_the_all_nan_columns() -> None:
    import numpy as np

    from suds_ros.core.diagnosis.locate import ChannelTable

    held = np.arange(10) >= 4
    table = ChannelTable(data=None, channels=("a", "b", "c"), held=held,  # type: ignore[arg-type]
                         xi_rec=np.zeros((10, 3)))
    E = np.ones((10, 3))
    E[held, 1] = np.nan  # every held-out sample of b left out
    E[~held, 2] = np.nan  # c lost only training samples
    assert table.untested(E) == ["b"]
    rms = table.rms(E)
    assert np.isnan(rms["b"]) and rms["a"] == rms["c"] == 1.0
