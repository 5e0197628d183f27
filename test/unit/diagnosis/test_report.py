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


def test_a_parameter_fitted_at_the_end_of_its_range_is_a_limit_without_stderr() -> None:
    """A real crawling worm pushed c⊥/c∥ to its upper bound (100), reported as "100 ± 260": the
    value is then a limit the data want beyond, and no stderr is given (null in JSON)."""
    import math

    import numpy as np

    from suds_ros.core.diagnosis import DiagnosisReport
    from suds_ros.core.diagnosis.naming import Candidate
    from suds_ros.core.diagnosis.refine import at_bound, fitted_effects
    from suds_ros.core.physics.effects import EFFECTS
    from suds_ros.report.diagnosis import summary_text

    (ratio,) = EFFECTS["drag_anisotropy_error"].params
    assert at_bound(ratio, ratio.upper) == "upper" and at_bound(ratio, ratio.lower) == "lower"
    assert at_bound(ratio, 0.999 * ratio.upper) is None and at_bound(ratio, 2.0) is None
    cand = Candidate((("drag_anisotropy_error", None), ("joint_viscous_damping", "joint_2")))
    fx = fitted_effects(cand, np.array([ratio.upper, 0.3]), np.array([258.0, 0.01]))
    assert fx[0].at_bound == {"ratio": "upper"} and math.isnan(fx[0].stderr["ratio"])
    assert fx[1].at_bound == {} and fx[1].stderr == {"d": 0.01}
    floor = {"joint_2": 0.001, "xi_x": 0.01, "xi_y": 0.01, "xi_theta": 0.02}
    rep = DiagnosisReport(mismatch=True, located=(), effects=tuple(fx), confounded_with=(), unexplained=False,
                          heldout_rms_before=floor, heldout_rms_after=floor, improvement=0.7, system="purcell3",
                          noise_floor=floor, statistics={c: 1.0 for c in floor})
    d = json.loads(rep.to_json())
    assert d["effects"][0]["stderr"] == {"ratio": None} and d["effects"][0]["at_bound"] == {"ratio": "upper"}
    assert d["effects"][1]["at_bound"] == {}
    text = summary_text(rep)
    assert "ratio ≥ 100 (at the upper end of its admissible range" in text and "d = 0.3 ± 0.01" in text, text
