"""The `suds` command: real subcommands on real files, and one-line errors for bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from suds_ros.cli.main import main


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "suds_ros.cli.main", *args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def p3_bag(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cli") / "p3.mcap"
    assert main(["simulate", "purcell3", "-o", str(out), "--cycles", "20", "--seed", "3", "--effort"]) == 0
    return out


def test_simulate_info_identify(p3_bag: Path, tmp_path: Path, capsys) -> None:
    assert main(["info", str(p3_bag), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["topics"]["/suds/shape"]["count"] == 2000
    assert info["metadata"]["suds"]["actuated"] == "joint_1"
    fig = tmp_path / "fig.png"
    assert main(["identify", str(p3_bag), "--train-cycles", "12", "--test-cycles", "8", "--json",
                 "--figure", str(fig), "--torque"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["gamma_body"] > 0.8 and res["gamma_passive"] > 0.9 and res["gamma_torque"] > 0.85
    assert fig.stat().st_size > 10_000


def test_identify_streaming_writes_model(p3_bag: Path, tmp_path: Path, capsys) -> None:
    model = tmp_path / "model.json"
    assert main(["identify", str(p3_bag), "--streaming", "--train-cycles", "12", "--test-cycles", "8",
                 "--model-out", str(model), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["gamma_body"] > 0.8
    from suds_ros.core.ident.online import SudsModel

    m = SudsModel.from_dict(json.loads(model.read_text()))
    assert m.coef.shape[1] == 4 and np.all(np.isfinite(m.coef))


def test_help_teaches() -> None:
    out = run("identify", "--help").stdout
    assert "Γ = 1 − Σ|model − truth|" in out and "--regressors" in out
    assert "Ornstein" in run("simulate", "--help").stdout


@pytest.mark.parametrize(
    "make, args, message",
    [
        (None, ["identify", "{d}/missing.mcap"], "no such file"),
        ("text", ["identify", "{d}/x.mcap"], "not an MCAP"),
        ("empty", ["info", "{d}/x.mcap"], "empty"),
        ("short", ["identify", "{d}/x.mcap"], "cannot train on 30 cycles"),
        ("short", ["identify", "{d}/x.mcap", "--train-cycles", "1", "--test-cycles", "1"], "too little data"),
        ("short", ["simulate", "purcell3", "-o", "{d}/x.mcap"], "exists"),
        (None, ["simulate", "fish", "-o", "{d}/y.mcap"], "unknown system 'fish'"),
    ],
)
def test_bad_input_gives_one_line_error(tmp_path: Path, make, args, message) -> None:
    path = tmp_path / "x.mcap"
    if make == "text":
        path.write_text("hello, not a bag\n" * 20)
    elif make == "empty":
        path.write_bytes(b"")
    elif make == "short":
        assert main(["simulate", "purcell3", "-o", str(path), "--cycles", "2"]) == 0
    proc = run(*[a.format(d=tmp_path) for a in args])
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("ERROR: ")
    assert message.lower() in lines[0].lower(), lines[0]
