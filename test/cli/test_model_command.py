"""Robot model files on the command line: `suds model export/check`, `--model` everywhere, lab options."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from suds_ros.cli.main import build_parser, main
from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.robot_model import dump_model, load_model
from suds_ros.core.physics.systems import builtin_model
from suds_ros.io.mcap import bag_info
from suds_ros.io.recording_bag import read_recording, write_recording

ROOT = Path(__file__).resolve().parents[2]
EEL4 = ROOT / "test" / "data" / "robots" / "eel4.yaml"  # 4 links, body = tail link with offset, 0.5 Hz
SNAKE5 = ROOT.parent / "shared" / "robots" / "snake5.yaml"


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "suds_ros.cli.main", *args], capture_output=True,
                          text=True, timeout=300)


def error_line(capsys) -> str:
    """The single stderr line of a failed command (asserts there is exactly one)."""
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("ERROR: "), lines
    return lines[0]


def snake5() -> Path:
    if not SNAKE5.exists():
        pytest.skip(f"{SNAKE5} not available")
    return SNAKE5


@pytest.fixture(scope="module")
def eel_bag(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("model") / "eel4.mcap"
    assert main(["simulate", "--model", str(EEL4), "-o", str(out), "--cycles", "16", "--seed", "2"]) == 0
    return out


# --- suds model export --------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["purcell3", "swimmer9", "nlink5"])
def test_export_writes_the_builtin_file(name: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / f"{name}.yaml"
    assert main(["model", "export", name, "-o", str(out)]) == 0
    assert out.read_text() == dump_model(builtin_model(name))
    assert load_model(out) == builtin_model(name)
    assert main(["model", "export", name]) == 0  # no -o: printed
    assert capsys.readouterr().out.endswith(out.read_text())


def test_export_refuses_to_overwrite(tmp_path: Path, capsys) -> None:
    out = tmp_path / "p3.yaml"
    out.write_text("mine\n")
    assert main(["model", "export", "purcell3", "-o", str(out)]) == 2
    assert "exists; pass --overwrite" in error_line(capsys)
    assert out.read_text() == "mine\n"
    assert main(["model", "export", "purcell3", "-o", str(out), "--overwrite"]) == 0
    assert load_model(out).name == "purcell3"


def test_export_of_a_non_chain_is_one_error_line(capsys) -> None:
    assert main(["model", "export", "linear_passive"]) == 2
    assert "`name`: expected a chain system" in error_line(capsys)


# --- suds model check ---------------------------------------------------------------------------

def test_check_prints_what_it_understood(capsys) -> None:
    assert main(["model", "check", str(EEL4)]) == 0
    out = capsys.readouterr().out
    assert "robot 'eel4', 4 links, 3 joints (2 actuated), gait 0.5 Hz" in out
    rows = [ln.split() for ln in out.splitlines() if ln.startswith("  ") and ln.split()[0].isdigit()]
    assert rows == [["1", "0.9", "0.9", "2.2"], ["2", "1.1", "1.2", "2.2"], ["3", "1", "0.9", "2.2"],
                    ["4", "0.7", "0.9", "2.8"]]
    assert "body frame: link 4, offset x -0.05 m, y 0.02 m, yaw 0.3 rad" in out
    assert "neck         actuated  drive 0.05 + 1·sin(2π·0.5·t − 0) rad" in out
    assert ("tail         passive   stiffness 4 N·m/rad, rest 0.02 rad, damping 0.3 N·m·s/rad, "
            "coulomb 0.01 N·m") in out
    assert "mean forward speed" in out and "passive joint amplitudes: tail ±" in out


def test_check_json_summarises_one_cycle(capsys) -> None:
    path = snake5()
    assert main(["model", "check", str(path), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["model"] == yaml.safe_load(dump_model(load_model(path)))
    cycle = res["cycle"]
    assert cycle["samples"] == 100 and cycle["speed"] > 0.05  # it swims head first
    assert set(cycle["passive_amplitude"]) == {"joint_3", "joint_4"}
    assert all(0.05 < a < 2.0 for a in cycle["passive_amplitude"].values())


def test_check_a_bad_file_names_the_key(tmp_path: Path, capsys) -> None:
    doc = yaml.safe_load(EEL4.read_text())
    doc["joints"][2]["stifness"] = 4.0
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    assert main(["model", "check", str(bad)]) == 2
    line = error_line(capsys)
    assert "`joints[2].stifness`" in line and "unknown key" in line
    doc = yaml.safe_load(EEL4.read_text())
    doc["joints"].pop()
    bad.write_text(yaml.safe_dump(doc))
    proc = run("model", "check", str(bad))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"ERROR: {bad}: `joints`: expected a list of 3 joints")


# --- --model on simulate and on the commands that read recordings ---------------------------------

def test_simulate_with_a_model_file(eel_bag: Path, tmp_path: Path) -> None:
    info = bag_info(eel_bag)
    assert info.metadata["suds"]["system"] == "eel4" and info.metadata["suds"]["gait_hz"] == "0.5"
    rec = read_recording(eel_bag)
    assert rec.joint_names == ("neck", "waist", "tail")
    assert rec.actuated == ("neck", "waist") and rec.passive == ("tail",)
    assert rec.n_samples == 1600 and np.isclose(rec.t[1] - rec.t[0], 1 / 50)  # 100 samples per 2 s cycle
    alias = tmp_path / "alias.mcap"  # SYSTEM given a path is the same as --model
    assert main(["simulate", str(EEL4), "-o", str(alias), "--cycles", "16", "--seed", "2"]) == 0
    np.testing.assert_array_equal(read_recording(alias).r, rec.r)
    faster = tmp_path / "faster.mcap"
    assert main(["simulate", "--model", str(EEL4), "-o", str(faster), "--cycles", "2", "--gait-hz", "1"]) == 0
    assert bag_info(faster).metadata["suds"]["gait_hz"] == "1.0"


@pytest.mark.parametrize(("argv", "message"), [
    (["simulate", "purcell3", "--model", str(EEL4)], "give one of them"),
    (["simulate"], "no system: give SYSTEM"),
    (["simulate", "--model", "nothere.yaml"], "nothere.yaml: cannot read the model file"),
    (["simulate", "purcell3", "--drop", "0.7"], "--drop: `drop`: expected a probability"),
    (["simulate", "purcell3", "--pose-rate", "120", "--effort"], "--effort: not recorded"),
])
def test_simulate_refusals(argv: list[str], message: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "x.mcap"
    assert main([*argv, "-o", str(out)]) == 2
    assert message in error_line(capsys)
    assert not out.exists()


def test_identify_checks_the_recording_against_the_model(eel_bag: Path, capsys) -> None:
    assert main(["identify", "--model", str(EEL4), str(eel_bag), "--train-cycles", "8",
                 "--test-cycles", "8", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["system"] == "eel4" and res["gamma_passive"] > 0.5
    assert main(["identify", "--model", str(EEL4), str(eel_bag), "--actuated", "neck"]) == 2
    line = error_line(capsys)
    assert "roles differ: waist (recording passive, model actuated)" in line
    path = snake5()
    assert main(["identify", "--model", str(path), str(eel_bag)]) == 2
    line = error_line(capsys)
    assert line.startswith(f"ERROR: {path}: the recording's joints (neck, waist, tail) do not match")
    assert "missing joints (in the model, not in the recording): joint_1, joint_2, joint_3, joint_4" in line
    assert "extra joints (in the recording, not in the model): neck, waist, tail" in line


def test_joint_order_is_checked_and_roles_come_from_the_model(eel_bag: Path, tmp_path: Path, capsys) -> None:
    rec = read_recording(eel_bag)
    swapped = tmp_path / "swapped.mcap"
    write_recording(swapped, replace(rec, joint_names=("waist", "neck", "tail"), r=rec.r[:, [1, 0, 2]]))
    assert main(["score", "--model", str(EEL4), str(swapped)]) == 2
    assert "joint order differs: recording waist, neck, tail; model neck, waist, tail" in error_line(capsys)
    bare = tmp_path / "bare.mcap"  # no suds metadata: the model gives system, roles and gait
    from suds_ros.io.mcap import BagWriter, iter_raw_messages

    with BagWriter(bare) as w:
        for m in iter_raw_messages(eel_bag):
            w.add_topic(m.topic, m.type_name)
            w.write_raw(m.topic, m.data, m.log_time_ns)
    from suds_ros.cli.common import load_recording_and_model

    args = build_parser().parse_args(["diagnose", str(bare), "--model", str(EEL4)])
    got, model = load_recording_and_model(args.bag, args)
    assert model == load_model(EEL4)
    assert got.system == "eel4" and got.actuated == ("neck", "waist") and got.gait_hz == 0.5
    args = build_parser().parse_args(["identify", str(bare), "--system", "purcell3", "--model", str(EEL4)])
    with pytest.raises(SudsConfigError, match="give one of them"):
        load_recording_and_model(args.bag, args)


# --- lab recording options -----------------------------------------------------------------------

def test_lab_options_write_asynchronous_streams(tmp_path: Path, capsys) -> None:
    out = tmp_path / "lab.mcap"
    assert main(["simulate", "purcell3", "-o", str(out), "--cycles", "10", "--pose-rate", "120",
                 "--jitter-ms", "0.4", "--drop", "0.02", "--pose-phase-ms", "3.7", "--sensor-offset-ms",
                 "17", "--compression", "lz4", "--seed", "5"]) == 0
    assert "poses" in capsys.readouterr().out
    info = bag_info(out)
    assert info.compression == ("lz4",)
    rec = read_recording(out)
    ds, dp = np.diff(rec.t), np.diff(rec.pose_t)
    assert np.median(ds) == pytest.approx(0.01, abs=5e-4) and np.median(dp) == pytest.approx(1 / 120, abs=5e-4)
    assert 0 < np.std(ds[ds < 0.015]) < 1e-3  # jittered, not uniform
    assert 900 < rec.n_samples < 1000 and 1080 < rec.pose_t.size < 1200  # ~2 % dropped of 1000 / 1200
    # the pose grid starts 3.7 ms after the shape grid; poses whose true time is before the run are cut
    assert 0.017 <= rec.pose_t[0] - rec.t[0] < 0.017 + 1 / 120 + 1e-3
    plain = tmp_path / "plain.mcap"
    assert main(["simulate", "purcell3", "-o", str(plain), "--cycles", "2", "--compression", "none"]) == 0
    assert bag_info(plain).compression in (("none",), ())
    rec = read_recording(plain)
    np.testing.assert_array_equal(rec.t, rec.pose_t)  # no lab option: the aligned recording


def test_sensor_offset_alone_delays_the_pose_stream(tmp_path: Path) -> None:
    from suds_ros.core.physics.sim import SimConfig, simulate
    from suds_ros.core.physics.systems import make_system

    out = tmp_path / "late.mcap"
    assert main(["simulate", "purcell3", "-o", str(out), "--cycles", "3", "--noise", "0",
                 "--sensor-offset-ms", "17"]) == 0
    rec = read_recording(out)
    twin = simulate(make_system("purcell3"), SimConfig(cycles=3, noise_std=0.0))
    k = np.searchsorted(twin.t, rec.t)
    assert rec.n_samples > 290 and np.allclose(twin.t[k], rec.t)  # the shape grid is the twin's
    np.testing.assert_allclose(rec.r, twin.r[k], atol=1e-4)  # same drive and physics
    # the pose stamped s is the true pose at s − 17 ms (not a multiple of the 10 ms period)
    for col in range(3):
        late = np.interp(rec.pose_t - 0.017, twin.t, twin.truth["pose"][:, col])
        assert np.max(np.abs(rec.pose[:, col] - late)) < 2e-3
        on_time = np.interp(rec.pose_t, twin.t, twin.truth["pose"][:, col])
        assert np.max(np.abs(rec.pose[:, col] - on_time)) > 5 * np.max(np.abs(rec.pose[:, col] - late))
