"""A robot known only by its model file, end to end through the `suds` command (issue 9).

For each robot: `suds simulate --model F` (60 cycles) → `suds identify --model F` (30/30 cycles,
Γ ≥ 0.85 body and passive) → `suds simulate --model F --effect …` → `suds diagnose --model F`
names the effect on its joint with its parameter within 25 %.  The robots differ in link count
and body frame (snake5: 5 links, body on link 2; eel4: 4 links, body on the tail link, turned
and shifted, 0.5 Hz gait); one chain runs on lab-style recordings (pose at 120 Hz from 3.7 ms
later, 0.4 ms jitter, 1 % drops, lz4).  Every step is a separate process of the real entry point.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SNAKE5 = ROOT.parent / "shared" / "robots" / "snake5.yaml"
EEL4 = ROOT / "test" / "data" / "robots" / "eel4.yaml"
LAB = ["--pose-rate", "120", "--jitter-ms", "0.4", "--drop", "0.01", "--pose-phase-ms", "3.7",
       "--compression", "lz4"]

CASES = {
    # id: (model file, effect, joint, parameter, true value, lab recording options)
    "snake5": (SNAKE5, "joint_viscous_damping", "joint_4", "d", 0.6, []),
    "eel4": (EEL4, "spring_rest_offset", "tail", "offset", 0.25, []),
    "snake5-lab": (SNAKE5, "joint_viscous_damping", "joint_4", "d", 0.6, LAB),
}


def suds(*args: str) -> str:
    """Run `python -m suds_ros.cli.main ARGS`; its stdout (fails the test with stderr on an error)."""
    proc = subprocess.run([sys.executable, "-m", "suds_ros.cli.main", *args], capture_output=True,
                          text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, f"suds {' '.join(args)} exited {proc.returncode}:\n{proc.stderr}"
    assert "Traceback" not in proc.stderr
    return proc.stdout


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_model_file_robot_simulate_identify_diagnose(case: str, tmp_path: Path) -> None:
    model, effect, joint, param, value, lab = CASES[case]
    if not model.exists():
        pytest.skip(f"{model} not available")
    nominal, damaged = tmp_path / "nominal.mcap", tmp_path / "effect.mcap"

    suds("simulate", "--model", str(model), "-o", str(nominal), "--cycles", "60", "--seed", "1", *lab)
    res = json.loads(suds("identify", "--model", str(model), str(nominal), "--train-cycles", "30",
                          "--test-cycles", "30", "--json"))
    assert res["system"] == model.stem and (res["train_cycles"], res["test_cycles"]) == (30, 30)
    assert res["gamma_body"] >= 0.85 and res["gamma_passive"] >= 0.85, res

    suds("simulate", "--model", str(model), "-o", str(damaged), "--cycles", "60", "--seed", "2",
         "--effect", f"{effect}:{joint}:{param}={value}", *lab)
    report = json.loads(suds("diagnose", "--model", str(model), str(damaged), "--json"))
    assert report["mismatch"] and not report["unexplained"], report
    named = [(e["name"], e["target"]) for e in report["effects"]]
    assert named == [(effect, joint)], named
    got = report["effects"][0]["parameters"][param]
    assert abs(got - value) <= 0.25 * abs(value), (param, got, value)
