"""Diagnosis configuration and report (:mod:`suds_ros.core.diagnosis.report`): validation, JSON schema."""

from __future__ import annotations

import json

import pytest

from suds_ros.core.diagnosis import DiagnoseConfig, diagnose
from suds_ros.core.physics.systems import purcell3_model


def test_json_schema_is_exact(purcell3_run) -> None:  # type: ignore[no-untyped-def]
    d = json.loads(diagnose(purcell3_run, purcell3_model()).to_json())
    assert set(d) == {"mismatch", "located", "effects", "confounded_with", "unexplained", "fit", "discovered"}
    assert set(d["fit"]) == {"heldout_rms_before", "heldout_rms_after", "improvement"}
    assert set(d["fit"]["heldout_rms_before"]) == {"joint_2", "xi_x", "xi_y", "xi_theta"}


def test_config_is_validated() -> None:
    from suds_ros.core.errors import SudsConfigError

    with pytest.raises(SudsConfigError, match="`f_threshold`"):
        DiagnoseConfig(f_threshold=0.5)
