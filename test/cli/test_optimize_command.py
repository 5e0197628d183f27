"""`suds optimize --physics`: writes a gait within the bounds that loads back; one JSON object; one ERROR line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from suds_ros.cli.main import main
from suds_ros.core.physics.gait import constraint_violations, gait_limits, load_gait
from suds_ros.core.physics.systems import make_system


def test_optimize_writes_a_gait_and_prints_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "fast.yaml"
    assert main(["optimize", "--physics", "--system", "purcell3", "--order", "2", "--starts", "2",
                 "-o", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["objective"] == "speed" and doc["gait"] == str(out)
    assert doc["value"] >= doc["nominal_value"] * (1 - 1e-9) and doc["time"] > 0
    system = make_system("purcell3")
    gait = load_gait(out, system)
    assert constraint_violations(gait, gait_limits(system)) == []
    # and it drives the simulator
    assert main(["simulate", "purcell3", "--gait", str(out), "-o", str(tmp_path / "run.mcap"), "--cycles", "1"]) == 0


@pytest.mark.parametrize("argv, message", [
    (["optimize", "--system", "purcell3", "-o", "{tmp}/g.yaml"], "--physics: required"),
    (["optimize", "--physics", "-o", "{tmp}/g.yaml"], "no robot: give --model FILE or --system ID"),
    (["optimize", "--physics", "--model", "{tmp}/none.yaml", "-o", "{tmp}/g.yaml"], "--model: no such file"),
    (["optimize", "--physics", "--system", "purcell3", "--order", "0", "-o", "{tmp}/g.yaml"],
     "--order: `order`: expected 1..8, got 0"),
    (["optimize", "--physics", "--system", "nosuch", "-o", "{tmp}/g.yaml"], "unknown system 'nosuch'"),
])
def test_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
                             message: str) -> None:
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ERROR: ") and message in err[0]
