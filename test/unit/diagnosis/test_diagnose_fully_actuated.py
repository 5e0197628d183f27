"""Diagnosis of a fully actuated chain (every joint driven, no passive joint: ``worm8``).

Channels are the body velocity alone; joint effects (and ``stiffness_to_drag_error``, which scales
passive springs) do not exist there, so the suspects are the global effects and the model's own
parameters.  Regression: a fully actuated recording used to end in ``IndexError: arrays used as
indices must be of integer (or boolean) type`` (an empty passive index list became a float array).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from suds_ros.core.diagnosis import DiagnoseConfig, DiagnosisReport, catalogue_candidates, diagnose
from suds_ros.core.diagnosis.data import prepare
from suds_ros.core.diagnosis.replay import replay_recording
from suds_ros.core.diagnosis.report import BODY
from suds_ros.core.physics.effects import EFFECTS, apply_effects
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.physics.sim import SimConfig, simulate
from suds_ros.core.recording import Recording
from suds_ros.report.diagnosis import summary_text, write_figures

CYCLES = 10
FLOW = {"name": "background_flow", "vx": 0.04, "vy": -0.03}


def _strict(text: str) -> Any:
    return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))


def _record(model: ChainModel, effects: list[dict[str, Any]], seed: int) -> Recording:
    m, delay = apply_effects(model, effects)
    return simulate(RFTChain(m), SimConfig(cycles=CYCLES, seed=seed, pose_delay=delay))


@pytest.fixture(scope="module")
def nominal(worm8_model: ChainModel) -> Recording:
    return _record(worm8_model, [], 21)


@pytest.fixture(scope="module")
def flow_report(worm8_model: ChainModel) -> DiagnosisReport:
    """A current, diagnosed against the catalogue (the model's parameters too: the slow test below)."""
    return diagnose(_record(worm8_model, [FLOW], 22), worm8_model, DiagnoseConfig(model_suspects=False))


def test_prepare_indexes_with_integer_arrays(worm8_model: ChainModel, nominal: Recording) -> None:
    data = prepare(nominal, worm8_model)
    assert data.pas.dtype == np.intp and data.pas.shape == (0,)
    assert data.act.dtype == np.intp and list(data.act) == list(range(7))
    rep = replay_recording(data, worm8_model, 0.0, 10, 2, chunk=300, warm=300)
    assert rep.rp.shape == (data.n_used, 0)
    held = np.isfinite(rep.xi[data.n_train:]).all(axis=1)
    assert held.mean() > 0.9  # NaN only at the window edges of each half


def test_suspects_are_global_effects_and_model_parameters(worm8_model: ChainModel) -> None:
    labels = {c.label for c in catalogue_candidates(worm8_model, model_suspects=True)}
    assert {"background_flow", "drag_anisotropy_error", "sensor_time_offset", "pose_frame_offset"} <= labels
    assert {f"link_drag_error:link_{i}" for i in range(1, 9)} <= labels
    for c in catalogue_candidates(worm8_model, model_suspects=True):
        for name, _ in c.parts:
            assert not EFFECTS[name].needs_passive, c.label
    assert "stiffness_to_drag_error" not in labels
    assert {c.label for c in catalogue_candidates(worm8_model)} == {
        "background_flow", "drag_anisotropy_error", "sensor_time_offset"}


def test_nominal_recording_has_no_mismatch(worm8_model: ChainModel, nominal: Recording) -> None:
    rep = diagnose(nominal, worm8_model)
    assert rep.mismatch is False and rep.effects == () and rep.discovered == ()
    assert tuple(rep.heldout_rms_before) == BODY and tuple(rep.series) == BODY
    d = _strict(rep.to_json())
    assert d["mismatch"] is False and set(d["fit"]["heldout_rms_before"]) == set(BODY)
    text = summary_text(rep, "nominal.mcap")
    assert "fully actuated" in text and "nan" not in text.lower()


def test_a_current_is_located_named_and_fitted(flow_report: DiagnosisReport) -> None:
    rep = flow_report
    d = _strict(rep.to_json())
    assert d["mismatch"] is True and d["unexplained"] is False
    assert {loc["channel"] for loc in d["located"]} <= set(BODY) and d["located"]
    assert [(e["name"], e["target"]) for e in d["effects"]] == [("background_flow", None)], d["effects"]
    p = d["effects"][0]["parameters"]
    assert p["vx"] == pytest.approx(FLOW["vx"], rel=0.1) and p["vy"] == pytest.approx(FLOW["vy"], rel=0.1), p
    assert d["fit"]["improvement"] >= 0.5 and d["discovered"] == []
    assert not any(c.label.startswith("stiffness_to_drag_error") for c in rep.ranking)


def test_text_and_figures_of_a_fully_actuated_report(flow_report: DiagnosisReport, tmp_path: Path) -> None:
    text = summary_text(flow_report, "flow.mcap")
    assert "effect: background_flow" in text and "nan" not in text.lower()
    paths = write_figures(flow_report, tmp_path)
    assert {p.name for p in paths} == {"residual_vs_phase.png", "predicted_vs_recorded.png", "report.json",
                                       "summary.txt"}
    assert _strict((tmp_path / "report.json").read_text())["effects"][0]["name"] == "background_flow"


@pytest.mark.slow
@pytest.mark.parametrize("effect", [
    FLOW,
    {"name": "drag_anisotropy_error", "ratio": 2.6},  # a crawler on agar is far from a swimmer's 2
    {"name": "sensor_time_offset", "dt": 0.03},
])
def test_global_effects_are_named_among_every_suspect_slow(worm8_model: ChainModel, effect: dict[str, Any]) -> None:
    """The default suspects: the global effects and every link length, link drag and the pose frame."""
    rep = diagnose(_record(worm8_model, [effect], 23), worm8_model)
    d = _strict(rep.to_json())
    assert [e["name"] for e in d["effects"]] == [effect["name"]], d["effects"]
    for k, v in effect.items():
        if k != "name":
            assert d["effects"][0]["parameters"][k] == pytest.approx(v, rel=0.1), d["effects"]
    assert d["fit"]["improvement"] >= 0.5 and d["discovered"] == []
