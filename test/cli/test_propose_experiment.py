"""`suds diagnose --propose-experiment DIR`: the run that settles an ambiguous finding, end to end.

Two cases through the command line only, as a user would go: the same physics (nothing to run),
and an ambiguity that a drive separates, whose proposed gait is run with `suds simulate --gait`
and diagnosed again.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from suds_ros.cli.main import main
from suds_ros.core.physics.gait import constraint_violations, gait_limits, load_gait, nominal_gait
from suds_ros.core.physics.systems import make_system


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:  # type: ignore[type-arg]
    capsys.readouterr()
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_the_same_physics_gets_no_gait(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """purcell3 has one passive joint: its stiffness and the stiffness-to-drag scale are one
    parameter.  The finding lists both; the proposal says no drive separates them and writes nothing."""
    bag = tmp_path / "stiff.mcap"
    assert main(["simulate", "purcell3", "-o", str(bag), "--cycles", "12", "--seed", "3",
                 "--effect", "stiffness_to_drag_error:scale=1.3"]) == 0
    out = tmp_path / "exp"
    d = _json(capsys, ["diagnose", "--system", "purcell3", str(bag), "--json", "--propose-experiment", str(out)])
    first = d["effects"][0]
    assert {first["name"]} | {a["name"] for a in first["alternatives"]} == {
        "stiffness_to_drag_error", "joint_stiffness_error"}
    (e,) = d["experiments"]
    assert e["separable"] is False and e["gait_file"] is None and e["cycles"] is None
    assert not out.exists() or not any(out.iterdir())
    capsys.readouterr()
    assert main(["diagnose", "--system", "purcell3", str(bag), "--propose-experiment", str(out)]) == 0
    assert "the same physics" in capsys.readouterr().out


@pytest.mark.slow  # three diagnoses and a proposal per rival: about 4 min alone, 9 under load
def test_a_proposed_run_settles_friction_against_damping(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A weak Coulomb friction (0.04 on joint_2) in 16 noisy cycles: with a wide ambiguity band
    (200 nats) a viscous damping on the same joint is listed beside it.  The proposed gait stays
    within the joint range and speed; running it for the proposed cycles and diagnosing that
    recording as a user would (the default band) names the friction alone, within 25 %."""
    effect = "joint_coulomb_friction:joint_2:mu=0.04"
    bag = tmp_path / "weak.mcap"
    assert main(["simulate", "purcell3", "-o", str(bag), "--cycles", "16", "--seed", "11", "--noise", "5e-3",
                 "--effect", effect]) == 0
    out = tmp_path / "exp"
    d = _json(capsys, ["diagnose", "--system", "purcell3", str(bag), "--json", "--ambiguity-band", "200",
                       "--propose-experiment", str(out)])
    first = d["effects"][0]
    names = {(first["name"], first["target"])} | {(a["name"], a["target"]) for a in first["alternatives"]}
    assert {("joint_coulomb_friction", "joint_2"), ("joint_viscous_damping", "joint_2")} <= names, names
    runs = [e for e in d["experiments"] if e["separable"]]
    assert runs, d["experiments"]
    best = max(runs, key=lambda e: e["nats_per_cycle"])
    assert best["nats_per_cycle"] >= best["baseline_nats_per_cycle"] > 0
    assert best["baseline_drive"] is (best["nats_per_cycle"] == best["baseline_nats_per_cycle"])
    gait = load_gait(best["gait_file"])
    system = make_system("purcell3")
    assert constraint_violations(gait, gait_limits(system, nominal_gait(system))) == []
    run = tmp_path / "proposed.mcap"
    assert main(["simulate", "purcell3", "-o", str(run), "--cycles", str(best["cycles"]), "--seed", "12",
                 "--noise", "5e-3", "--gait", best["gait_file"], "--effect", effect]) == 0
    d2 = _json(capsys, ["diagnose", "--system", "purcell3", str(run), "--json"])
    assert [(e["name"], e["target"]) for e in d2["effects"]] == [("joint_coulomb_friction", "joint_2")], d2["notes"]
    assert d2["effects"][0]["alternatives"] == []
    assert d2["effects"][0]["parameters"]["mu"] == pytest.approx(0.04, rel=0.25)


def test_diagnose_refuses_a_nonpositive_worker_count(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["diagnose", "--system", "purcell3", str(tmp_path / "any.mcap"), "--jobs", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--jobs: expected a positive number of processes, got 0" in err[0]
