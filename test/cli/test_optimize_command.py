"""`suds optimize --physics` and `suds optimize BAG`: a gait within the bounds that loads back; JSON; one ERROR line."""

from __future__ import annotations

import json
import re
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
    lo, hi = doc["speed_over_time_origins"]  # the speed counted from other points of the cycle
    assert lo <= doc["values"]["speed"] <= hi
    system = make_system("purcell3")
    gait = load_gait(out, system)
    assert constraint_violations(gait, gait_limits(system)) == []
    # and it drives the simulator
    assert main(["simulate", "purcell3", "--gait", str(out), "-o", str(tmp_path / "run.mcap"), "--cycles", "1"]) == 0
    # and it is a start of another optimisation (after the nominal gait)
    capsys.readouterr()
    assert main(["optimize", "--physics", "--system", "purcell3", "--order", "2", "--starts", "1", "--screened", "0",
                 "--start", str(out),
                 "-o", str(tmp_path / "again.yaml"), "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert [s["kind"] for s in again["starts"]] == ["nominal", "given"]
    assert again["value"] >= doc["value"] * (1 - 1e-3)


@pytest.mark.parametrize("argv, message", [
    (["optimize", "--system", "purcell3", "-o", "{tmp}/g.yaml"], "nothing to optimise on: give --physics"),
    (["optimize", "{tmp}/none.mcap", "--physics", "--system", "purcell3", "-o", "{tmp}/g.yaml"],
     "--physics and BAG"),
    (["optimize", "{tmp}/none.mcap", "-o", "{tmp}/g.yaml"], "no such file"),
    (["optimize", "--physics", "-o", "{tmp}/g.yaml"], "no robot: give --model FILE or --system ID"),
    (["optimize", "--physics", "--model", "{tmp}/none.yaml", "-o", "{tmp}/g.yaml"], "--model: no such file"),
    (["optimize", "--physics", "--system", "purcell3", "--order", "0", "-o", "{tmp}/g.yaml"],
     "--order: `order`: expected 1..8, got 0"),
    (["optimize", "--physics", "--system", "purcell3", "--screen", "-1", "-o", "{tmp}/g.yaml"],
     "--screen: `screen`: expected ≥ 0, got -1"),
    (["optimize", "--physics", "--system", "nosuch", "-o", "{tmp}/g.yaml"], "unknown system 'nosuch'"),
    (["optimize", "--physics", "--system", "purcell3", "--start", "{tmp}/none.yaml", "-o", "{tmp}/g.yaml"],
     "--start: no such file"),
])
def test_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
                             message: str) -> None:
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ERROR: ") and message in err[0]


@pytest.fixture(scope="module")
def p3_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = tmp_path_factory.mktemp("dataopt") / "p3.mcap"
    assert main(["simulate", "purcell3", "-o", str(bag), "--cycles", "10", "--seed", "1"]) == 0
    return bag


def test_optimize_from_a_recording(p3_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    out = tmp_path / "step.yaml"
    assert main(["optimize", str(p3_bag), "--system", "purcell3", "--draws", "4", "-o", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["start"] == "the robot's nominal gait" and doc["cycles_used"] == pytest.approx(10.0)
    pred, sim = doc["predicted"], doc["simulated"]
    assert pred["proposed"] >= pred["recorded"] and pred["proposed_std"] > 0 and pred["gain_std"] >= 0
    assert doc["step_taken"] or pred["proposed"] == pred["recorded"]  # a gain under 1 σ of the draws: no step
    assert sim["recorded"] == pytest.approx(0.08665, rel=1e-3)  # the nominal gait on the physics
    assert sim["proposed"] >= 0.99 * sim["recorded"] and doc["trust_used"] <= doc["trust_radius"] * 1.01
    system = make_system("purcell3")
    assert constraint_violations(load_gait(out, system), gait_limits(system)) == []
    # without a robot: the recording's own range and speed bound the gait; text output
    assert main(["optimize", str(p3_bag), "--draws", "0", "-o", str(tmp_path / "t.yaml")]) == 0
    text = capsys.readouterr().out
    assert "recorded gait: the recording's gait template" in text and "simulated" not in text


def test_a_half_wave_step_from_a_recording(p3_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    out = tmp_path / "odd.yaml"
    assert main(["optimize", str(p3_bag), "--system", "purcell3", "--draws", "0", "--half-wave", "yes",
                 "-o", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    gait = load_gait(out, make_system("purcell3"))
    assert doc["step_taken"] and gait.order == 3 and gait.is_half_wave(atol=0.0)
    assert abs(doc["simulated"]["proposed"]) > 0 and doc["trust_used"] <= doc["trust_radius"] * 1.01
    assert main(["optimize", str(p3_bag), "--system", "purcell3", "--half-wave", "yes", "--objective", "turn",
                 "-o", str(tmp_path / "turn.yaml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ERROR: --half-wave: `half_wave`: expected False for the turn")


def test_efficiency_needs_a_torque_model(p3_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["optimize", str(p3_bag), "--objective", "efficiency", "-o", str(tmp_path / "e.yaml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no learned torque model" in err[0] and "efficiency is unavailable" in err[0]


def test_optimize_loop_on_a_simulated_robot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "loop.yaml"
    assert main(["optimize", "--simulate", "purcell3", "--budget-cycles", "12", "--seed", "1", "--limit", "no",
                 "-o", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["cycles_used"] == 10 and doc["budget_cycles"] == 12 and "budget spent" in doc["stopped"]
    its = doc["iterations"]
    assert [it["cycles_used"] for it in its] == [5, 10] and its[0]["accepted"] and its[0]["note"] == "start gait"
    assert all(it["predicted"] > 0 and it["measured"] > 0 for it in its)
    best = max((it for it in its if it["accepted"]), key=lambda it: it["index"])
    assert doc["measured"] == best["measured"] and doc["predicted"] == best["predicted"]
    assert doc["predicted_std"] > 0  # the prediction's spread over the model's coefficient draws
    assert doc["motion_warning"] is None and doc["measured_detail"]["translation_p"] < 0.05  # it swims
    # the rotation the straight-course bound was judged on: the model of the gait's own cycles (purcell3 runs straight)
    assert all(abs(it["measured_detail"]["model_rotation"]) < 0.05 for it in its)
    assert doc["limit"] is None and doc["limit_note"] == "skipped: --limit no"
    assert doc["simulated"]["returned"] > 0.5 * doc["simulated"]["start"]
    system = make_system("purcell3")
    assert constraint_violations(load_gait(out, system), gait_limits(system)) == []
    # text output: one line per gait run on stderr, the summary on stdout
    assert main(["optimize", "--simulate", "purcell3", "--budget-cycles", "6", "--limit", "no",
                 "-o", str(tmp_path / "t.yaml")]) == 0
    cap = capsys.readouterr()
    assert re.search(r"predicted \d\.\d+ ± \d\.\d+ m/s", cap.out)  # the start's prediction and its spread
    assert "[0] cycles   5" in cap.err and "after 5 of 6 cycles" in cap.out and "physics limit skipped" in cap.out


FLAP2 = """\
format: suds-robot/1
name: flap2
gait_hz: 1.0
drag: {c_par: 1.0, c_perp: 2.0}
links: [{length: 1.0}, {length: 1.0}]
joints: [{name: hinge, actuated: true, gait: {amplitude: 1.0, phase: 0.0}}]
"""


def test_loop_warns_when_the_robot_does_not_move(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two links and one hinge cannot swim (the scallop theorem): the noise's translation is flagged."""
    robot = tmp_path / "flap2.yaml"
    robot.write_text(FLAP2)
    argv = ["optimize", "--simulate", str(robot), "--budget-cycles", "6", "--seed", "0", "--limit", "no",
            "-o", str(tmp_path / "f.yaml"), "--overwrite"]
    assert main([*argv, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert abs(doc["simulated"]["returned"]) < 1e-9 < doc["measured"]  # the physics: none; measured: noise
    assert doc["measured_detail"]["translation_p"] > 0.05 and "cannot be told from none" in doc["motion_warning"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "warning: the measured translation per cycle" in out and "over 4 cycles" in out


def test_loop_reads_the_rotation_from_the_mean_of_the_cycles_on_request(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--no-rotation-from-model``: no run carries the model's rotation; the bound reads the cycles' mean."""
    assert main(["optimize", "--simulate", "purcell3", "--budget-cycles", "10", "--seed", "1", "--limit", "no",
                 "--no-rotation-from-model", "-o", str(tmp_path / "m.yaml"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [it["cycles_used"] for it in doc["iterations"]] == [5, 10]
    assert all("model_rotation" not in it["measured_detail"] for it in doc["iterations"])


def test_loop_takes_the_rotation_margin(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """``--rotation-margin F`` reaches the loop's settings; without it the loop's default stands."""
    import suds_ros.core.optimize.loop as loop

    seen, real = [], loop.optimize_loop

    def spy(system, config, **kwargs):
        seen.append(config.rotation_margin)
        return real(system, config, **kwargs)

    monkeypatch.setattr(loop, "optimize_loop", spy)
    for extra in ([], ["--rotation-margin", "0.5"]):
        assert main(["optimize", "--simulate", "purcell3", "--budget-cycles", "5", "--limit", "no", *extra,
                     "-o", str(tmp_path / f"g{len(extra)}.yaml")]) == 0
    assert seen == [loop.LoopConfig(budget_cycles=5).rotation_margin, 0.5]
    capsys.readouterr()


def test_loop_with_a_reverse_trial(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The reverse trial (default): the second run is the start backwards in time; on neck4 it is kept (it swims
    faster).  --no-reverse-trial: the second run is a trust-region step."""
    neck4 = Path(__file__).resolve().parents[1] / "data" / "robots" / "neck4.yaml"
    for flag in ([], ["--no-reverse-trial"]):
        assert main(["optimize", "--simulate", str(neck4), "--budget-cycles", "10", "--seed", "0", "--limit", "no",
                     *flag, "-o", str(tmp_path / "r.yaml"), "--overwrite", "--json"]) == 0
        doc = json.loads(capsys.readouterr().out)
        its = doc["iterations"]
        assert len(its) == 2 and ("backwards in time" in its[1]["note"]) == (not flag)
        assert (doc["simulated"]["returned"] > 3 * doc["simulated"]["start"]) == (not flag)


def test_loop_on_a_robot_that_changes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    change = '30:[{"name": "stiffness_to_drag_error", "scale": 3.0}]'
    assert main(["optimize", "--simulate", "purcell3", "--budget-cycles", "45", "--seed", "0", "--watch",
                 "--change", change, "--limit", "no", "-o", str(tmp_path / "c.yaml"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["changes"] == [{"cycle": 30, "effects": [{"name": "stiffness_to_drag_error", "scale": 3.0}]}]
    assert doc["changes_taken"] and all(30 < c <= 45 for c in doc["changes_taken"])
    # judged on the robot as it is at the end: about half as fast as the nominal purcell3 (limit 0.043 m/s)
    assert doc["simulated"]["returned"] < 0.05


def test_loop_on_efficiency_measures_the_work(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["optimize", "--simulate", "purcell3", "--budget-cycles", "11", "--seed", "0", "--objective",
                 "efficiency", "--limit", "no", "-o", str(tmp_path / "e.yaml"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["objective"] == "efficiency" and doc["cycles_used"] == 10 and len(doc["iterations"]) == 2
    for it in doc["iterations"]:
        d = it["measured_detail"]
        assert d["work"] > 0 and it["measured"] == d["efficiency"] == pytest.approx(d["speed"] / d["work"])
    assert doc["simulated"]["start"] > 0 and doc["predicted"] > 0


@pytest.mark.parametrize("argv, message", [
    (["optimize", "--simulate", "purcell3", "-o", "{tmp}/g.yaml"], "--budget-cycles: required with --simulate"),
    (["optimize", "--simulate", "purcell3", "--system", "purcell3", "--budget-cycles", "9", "-o", "{tmp}/g.yaml"],
     "--model/--system are not taken with it"),
    (["optimize", "--simulate", "purcell3", "--physics", "--budget-cycles", "9", "-o", "{tmp}/g.yaml"],
     "--simulate and --physics"),
    (["optimize", "--simulate", "purcell3", "--budget-cycles", "4", "-o", "{tmp}/g.yaml"],
     "--budget-cycles: `budget_cycles`: expected at least settle_cycles + first_cycles = 5"),
    (["optimize", "--physics", "--system", "purcell3", "--budget-cycles", "9", "-o", "{tmp}/g.yaml"],
     "--budget-cycles: only with --simulate"),
    (["optimize", "--simulate", "nosuch", "--budget-cycles", "9", "-o", "{tmp}/g.yaml"], "unknown system 'nosuch'"),
    (["optimize", "--simulate", "purcell3", "--budget-cycles", "9", "--change", "x:[]", "-o", "{tmp}/g.yaml"],
     "--change: expected CYCLE:[{effect}, ...]"),
    (["optimize", "--simulate", "purcell3", "--budget-cycles", "9", "--change", '3:[{"name": "nope"}]',
      "-o", "{tmp}/g.yaml"], "--change: "),
    (["optimize", "--simulate", "purcell3", "--budget-cycles", "9", "--change",
      '3:[{"name": "joint_viscous_damping", "joint": "joint_1", "d": 1}]', "-o", "{tmp}/g.yaml"], "--change: "),
    (["optimize", "--simulate", "purcell3", "--budget-cycles", "9", "--pool-incumbents", "-1", "-o", "{tmp}/g.yaml"],
     "--pool-incumbents: `pool_incumbents`: expected ≥ 0, got -1"),
    (["optimize", "--simulate", "purcell3", "--budget-cycles", "9", "--rotation-margin", "1.5", "-o", "{tmp}/g.yaml"],
     "--rotation-margin: `rotation_margin`: expected in (0, 1], got 1.5"),
])
def test_loop_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
                                  message: str) -> None:
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ERROR: ") and message in err[0]


def test_optimize_a_fully_actuated_chain_from_data_and_on_its_physics(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No passive joint (a crawler, a snake robot, an imported animal): no steady state to shoot for,
    every cycle is periodic; a gait within the bounds, null for the passive excursion in JSON."""
    robot = str(Path(__file__).resolve().parents[1] / "data" / "robots" / "crawler5.yaml")
    bag = tmp_path / "crawl.mcap"
    assert main(["simulate", robot, "-o", str(bag), "--cycles", "8", "--seed", "3"]) == 0
    capsys.readouterr()
    out = tmp_path / "step.yaml"
    assert main(["optimize", str(bag), "--model", robot, "--draws", "4", "-o", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["passive_excursion"] is None and doc["simulated"]["recorded"] > 0
    assert doc["predicted"]["proposed"] >= doc["predicted"]["recorded"]
    from suds_ros.core.physics.systems import load_system

    system = load_system(robot)
    assert constraint_violations(load_gait(out, system), gait_limits(system)) == []
    assert main(["optimize", str(bag), "--model", robot, "--draws", "0", "-o", str(tmp_path / "t.yaml")]) == 0
    assert "no passive joint (fully actuated)" in capsys.readouterr().out
    phys = tmp_path / "phys.yaml"
    assert main(["optimize", "--physics", "--model", robot, "--order", "1", "--starts", "1", "-o", str(phys),
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["value"] >= doc["nominal_value"] * (1 - 1e-9)
