"""A fully actuated robot (every joint driven) through every command, and strict JSON from each.

``suds identify`` once printed ``passive nan`` and wrote ``"gamma_passive": NaN`` (not JSON: jq and
JavaScript's JSON.parse refuse it); ``suds diagnose`` ended in an IndexError.  Every ``--json``
output is parsed here with a parser that fails on NaN/Infinity.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from suds_ros.cli.main import main
from suds_ros.core.diagnosis.report import BODY
from suds_ros.io.recording_bag import read_recording

ROOT = Path(__file__).resolve().parents[2]
WORM8 = ROOT / "test" / "data" / "robots" / "worm8.yaml"  # 8 links, all 7 joints actuated


def strict_json(text: str) -> Any:
    """Parse ``text`` as RFC 8259 JSON: NaN, Infinity and -Infinity fail the test."""
    return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c} in output"))


def out_of(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 0
    return capsys.readouterr().out


@pytest.fixture(scope="module")
def worm_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("worm") / "worm8.mcap"
    assert main(["simulate", "--model", str(WORM8), "-o", str(out), "--cycles", "16", "--seed", "3"]) == 0
    return out


def test_simulate_writes_a_fully_actuated_recording(worm_bag: Path) -> None:
    rec = read_recording(worm_bag)
    assert rec.system == "worm8" and rec.passive == ()
    assert rec.actuated == tuple(f"j{k}" for k in range(1, 8))
    assert rec.n_samples == 1600 and math.isfinite(float(abs(rec.pose).max()))


def test_identify_text_says_the_passive_score_does_not_apply(  # type: ignore[no-untyped-def]
        worm_bag: Path, capsys) -> None:
    text = out_of(capsys, ["identify", str(worm_bag), "--model", str(WORM8), "--train-cycles", "8",
                           "--test-cycles", "8"])
    assert "nan" not in text.lower(), text
    passive = [ln for ln in text.splitlines() if ln.strip().startswith("passive")]
    assert passive and "none (fully actuated" in passive[0], text
    body = [ln for ln in text.splitlines() if ln.strip().startswith("body")]
    assert float(body[0].split()[-1]) > 0.7, text  # held-out Γ_body, finite and sensible


def test_identify_json_is_strict(worm_bag: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    d = strict_json(out_of(capsys, ["identify", str(worm_bag), "--model", str(WORM8), "--train-cycles", "8",
                                    "--test-cycles", "8", "--json"]))
    assert d["gamma_passive"] is None and d["gamma_torque"] is None
    assert 0.7 < d["gamma_body"] <= 1.0 and set(d["rms_model"]) == set(BODY)


def test_streaming_identify_json_is_strict(  # type: ignore[no-untyped-def]
        worm_bag: Path, tmp_path: Path, capsys) -> None:
    model = tmp_path / "model.json"
    d = strict_json(out_of(capsys, ["identify", str(worm_bag), "--model", str(WORM8), "--train-cycles", "8",
                                    "--test-cycles", "8", "--streaming", "--json", "--model-out", str(model)]))
    assert d["running_gamma"]["passive"] is None and d["gamma_passive"] is None
    assert strict_json(model.read_text())["passive"] == []
    text = out_of(capsys, ["identify", str(worm_bag), "--model", str(WORM8), "--train-cycles", "8",
                           "--test-cycles", "8", "--streaming"])
    assert "nan" not in text.lower() and "passive: none" in text, text


def test_diagnose_json_and_text(worm_bag: Path, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    rep = tmp_path / "rep"
    d = strict_json(out_of(capsys, ["diagnose", str(worm_bag), "--model", str(WORM8), "--json", "-o", str(rep)]))
    assert d["mismatch"] is False and set(d["fit"]["heldout_rms_before"]) == set(BODY)
    text = (rep / "summary.txt").read_text()  # the text report, as printed without --json
    assert "fully actuated" in text and "no significant mismatch" in text and "nan" not in text.lower()
    assert strict_json((rep / "report.json").read_text()) == d


def test_model_check_and_info_json_are_strict(worm_bag: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    d = strict_json(out_of(capsys, ["model", "check", str(WORM8), "--json"]))
    assert d["cycle"]["passive_amplitude"] == {} and d["cycle"]["forward"] > 0
    assert "passive joint amplitudes: none (fully actuated)" in out_of(capsys, ["model", "check", str(WORM8)])
    info = strict_json(out_of(capsys, ["info", str(worm_bag), "--json"]))
    assert info["message_count"] > 0


def test_an_effect_through_passive_joints_is_refused(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "x.mcap"
    assert main(["simulate", "--model", str(WORM8), "-o", str(out), "--cycles", "4",
                 "--effect", "stiffness_to_drag_error:scale=2"]) != 0
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("ERROR: ") and "stiffness_to_drag_error" in err[0], err
    assert "no passive joint" in err[0] or "has none" in err[0], err
    assert not out.exists()
