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
    return subprocess.run([sys.executable, "-m", "suds_ros.cli.main", *args],
                          capture_output=True, text=True, timeout=300)


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
    from suds_ros.core.ident.model import SudsModel

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


@pytest.mark.parametrize("args", [
    ["identify", "{bag}", "--model-o", "x"],     # not --model-out (--model is a model file)
    ["identify", "{bag}", "--stream"],           # not --streaming
    ["info", "{bag}", "--js"],                   # not --json
    ["simulate", "purcell3", "--out", "{d}/z.mcap"],
    ["score", "{bag}", "--train", "3"],
])
def test_options_are_never_abbreviated(p3_bag: Path, tmp_path: Path, args, capsys) -> None:
    argv = [a.format(bag=p3_bag, d=tmp_path) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("ERROR: suds"), err
    assert "unrecognized arguments" in lines[0] or "required: -o/--output" in lines[0], err
    assert not (tmp_path / "z.mcap").exists() and not (tmp_path / "x").exists()


def test_usage_errors_are_one_line(capsys) -> None:
    for argv in ([], ["nosuchcommand"], ["identify"], ["identify", "b.mcap", "--regressors", "7"]):
        assert main(argv) == 2, argv
        lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("ERROR: suds"), (argv, lines)


def test_missing_metadata_gets_the_command_line_hint(tmp_path: Path, capsys) -> None:
    from suds_ros.io.mcap import BagWriter
    from suds_ros.io.recording_bag import read_recording, write_recording

    src = tmp_path / "src.mcap"
    assert main(["simulate", "purcell3", "-o", str(src), "--cycles", "8"]) == 0
    capsys.readouterr()
    rec = read_recording(src)
    bare = tmp_path / "bare.mcap"
    with BagWriter(bare) as w:  # same data, no `suds` metadata record
        from suds_ros.io.mcap import iter_raw_messages

        for m in iter_raw_messages(src):
            w.add_topic(m.topic, m.type_name)
            w.write_raw(m.topic, m.data, m.log_time_ns)
    assert main(["identify", str(bare)]) == 2
    assert capsys.readouterr().err.strip().endswith("has no 'suds' metadata record; pass --system")
    assert main(["identify", str(bare), "--system", "purcell3"]) == 2
    err = capsys.readouterr().err.strip()
    assert "no 'actuated' joints" in err and err.endswith("; pass --actuated (or --passive)"), err
    # the common recording options work the same for every command that reads a recording
    assert main(["identify", str(bare), "--system", "purcell3", "--actuated", "joint_1",
                 "--train-cycles", "5", "--test-cycles", "2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["system"] == "purcell3"
    assert main(["score", str(bare), "--system", "purcell3", "--passive", "joint_2"]) == 2
    assert "no live predictions recorded" in capsys.readouterr().err
    write_recording(tmp_path / "meta.mcap", rec)
    assert main(["score", str(tmp_path / "meta.mcap")]) == 2
    assert "no live predictions recorded" in capsys.readouterr().err


@pytest.mark.parametrize("lab", [[], ["--pose-rate", "120", "--jitter-ms", "0.4", "--drop", "0.01"],
                                 ["--pose-rate", "120", "--jitter-ms", "2", "--drop", "0.01", "--stamped-late",
                                  "--latency-ms", "3"]],
                         ids=["aligned", "lab", "stamped-late"])
def test_simulate_streams_the_bag_the_whole_run_gives(tmp_path: Path, lab: list[str]) -> None:
    """Written block by block (10 cycles each), the bag is that of the whole recording written at once."""
    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import make_system
    from suds_ros.io.recording_bag import write_recording

    out, whole = tmp_path / "streamed.mcap", tmp_path / "whole.mcap"
    assert main(["simulate", "purcell3", "-o", str(out), "--cycles", "12", "--seed", "3", *lab]) == 0
    cfg, p3 = SimConfig(cycles=12, seed=3), make_system("purcell3")
    conditions = (LabConditions(pose_hz=120.0, pose_phase=0.0, jitter=4e-4, drop=0.01) if "--latency-ms" not in lab
                  else LabConditions(pose_hz=120.0, pose_phase=0.0, jitter=2e-3, drop=0.01, stamping="arrival",
                                     latency=3e-3))
    rec = simulate(p3, cfg) if not lab else simulate_lab(p3, cfg, conditions)
    write_recording(whole, rec)
    assert out.read_bytes() == whole.read_bytes()


def test_a_run_that_fails_midway_leaves_no_file(tmp_path: Path, monkeypatch, capsys) -> None:
    from suds_ros.core.errors import SudsDataError
    from suds_ros.core.physics import sim

    def failing(*args, **kwargs):  # type: ignore[no-untyped-def]
        blocks = real(*args, **kwargs)
        yield next(blocks)
        raise SudsDataError("integration diverged")

    real = sim.simulate_blocks
    monkeypatch.setattr(sim, "simulate_blocks", failing)
    out = tmp_path / "half.mcap"
    assert main(["simulate", "purcell3", "-o", str(out), "--cycles", "12"]) == 2
    assert "ERROR: integration diverged" in capsys.readouterr().err
    assert not out.exists()
