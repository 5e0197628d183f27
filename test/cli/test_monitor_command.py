"""`suds monitor`: the live monitor replayed over a bag, as text and as JSON; one-line errors for bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from suds_ros.cli.main import main

ROBOTS = Path(__file__).resolve().parents[1] / "data" / "robots"


def error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("ERROR: ") and "Traceback" not in err, err
    return lines[0]


def no_nan(text: str) -> object:
    def refuse(name: str) -> None:
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("monitor")
    out = {"nominal": d / "nominal.mcap", "current": d / "current.mcap", "short": d / "short.mcap",
           "late": d / "late.mcap"}
    assert main(["simulate", "purcell3", "-o", str(out["nominal"]), "--cycles", "6", "--seed", "2"]) == 0
    # a current from the first sample, recorded the lab way (pose 50 Hz from another start, jitter, drops)
    assert main(["simulate", "purcell3", "-o", str(out["current"]), "--cycles", "6", "--seed", "3",
                 "--effect", "background_flow:vx=0.15,vy=0", "--pose-rate", "50", "--pose-phase-ms", "3.7",
                 "--jitter-ms", "0.4", "--drop", "0.01"]) == 0
    assert main(["simulate", "purcell3", "-o", str(out["short"]), "--cycles", "2", "--seed", "4"]) == 0
    assert main(["simulate", "swimmer9", "-o", str(out["late"]), "--cycles", "7", "--seed", "5",
                 "--effect", "sensor_time_offset:dt=0.01"]) == 0
    return out


def test_text_output_per_channel(bags: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["monitor", str(bags["nominal"])]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "system purcell3" in out[0] and "first report at 3.0" in out[0]
    rows = {ln.split()[0]: ln.split() for ln in out[2:-1]}
    assert list(rows) == ["joint_2", "xi_x", "xi_y", "xi_theta"]
    assert all(r[1] == "OK" and r[2] == "-" and r[3] == "-" for r in rows.values()), out
    assert all(0.0 < float(r[4]) < 4.0 for r in rows.values())
    assert out[-1] == "worst: OK"


def test_json_output(bags: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["monitor", str(bags["nominal"]), "--json"]) == 0
    nominal = no_nan(capsys.readouterr().out)
    clean = {"worst": "OK", "first_warn_s": None, "first_error_s": None, "stale_reports": 0}
    assert nominal == {"worst": "OK", "channels": {c: clean for c in ("joint_2", "xi_x", "xi_y", "xi_theta")}}
    assert main(["monitor", str(bags["current"]), "--json", "--system", "purcell3"]) == 0
    current = no_nan(capsys.readouterr().out)
    assert set(current) == {"worst", "channels"} and current["worst"] == "ERROR"
    xi_x = current["channels"]["xi_x"]
    assert xi_x["worst"] == "ERROR"
    # reached from the first report on (after the floor's 3 cycles), measured from the recording's first stamp
    assert 3.0 <= xi_x["first_warn_s"] <= xi_x["first_error_s"] <= 6.0, xi_x


def test_text_names_the_first_error(bags: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["monitor", str(bags["current"])]) == 0
    out = capsys.readouterr().out.splitlines()
    xi_x = next(ln.split() for ln in out if ln.strip().startswith("xi_x"))
    assert xi_x[1] == "ERROR" and xi_x[3] == xi_x[5] == "s" and 3.0 <= float(xi_x[2]) <= float(xi_x[4]) <= 6.0
    assert out[-1] == "worst: ERROR"
    assert not any("ms late" in ln for ln in out)  # a current is not a lag, even where it leans like one


def test_text_says_the_lag_of_a_late_pose_stream(bags: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["monitor", str(bags["late"])]) == 0
    out = capsys.readouterr().out.splitlines()
    body = {ln.split()[0]: ln.split()[1] for ln in out if ln.strip().startswith("xi_")}
    assert body == {"xi_x": "ERROR", "xi_y": "ERROR", "xi_theta": "ERROR"}, out
    lag = [ln for ln in out if "ms late" in ln]
    assert len(lag) == 1 and abs(float(lag[0].split("pose stream ")[1].split()[0]) - 10.0) < 1.5, lag
    assert main(["monitor", str(bags["nominal"])]) == 0
    assert "ms late" not in capsys.readouterr().out


def test_model_file_names_the_robot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "eel.mcap"
    model = str(ROBOTS / "eel4.yaml")
    assert main(["simulate", "--model", model, "-o", str(bag), "--cycles", "4", "--seed", "5"]) == 0
    capsys.readouterr()
    assert main(["monitor", str(bag), "--model", model, "--json"]) == 0
    res = no_nan(capsys.readouterr().out)
    assert list(res["channels"]) == ["tail", "xi_x", "xi_y", "xi_theta"] and res["worst"] != "ERROR"


@pytest.mark.parametrize("args, message", [
    (["monitor", "{d}/missing.mcap"], "no such file"),
    (["monitor", "{short}"], "the monitor reports after 300 (3 cycles)"),
    (["monitor", "{nominal}", "--system", "swimmer9"], "lack ['joint_3'"),
    (["monitor", "{nominal}", "--system", "fish"], "unknown system 'fish'"),
    (["monitor", "{nominal}", "--system", "purcell3", "--model", "{eel4}"], "give one of them"),
    (["monitor", "{nominal}", "--model", "{eel4}"], "do not match the model 'eel4'"),
    (["monitor", "{nominal}", "--jsn"], "unrecognized arguments: --jsn"),
])
def test_bad_input_gives_one_line_error(bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                        args: list[str], message: str) -> None:
    argv = [a.format(d=tmp_path, short=bags["short"], nominal=bags["nominal"], eel4=ROBOTS / "eel4.yaml")
            for a in args]
    assert main(argv) == 2
    line = error_line(capsys)
    assert message in line, line


def test_text_says_when_the_shape_stamps_look_stamped_late(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A host stamping messages as they arrive (values on the device's clock, 2 ms of jitter in the stamps):
    the text says so, and not for the same run recorded with its values read at jittered stamps."""
    from dataclasses import replace

    import numpy as np

    from suds_ros.core.physics.lab import LabConditions, simulate_lab
    from suds_ros.core.physics.sim import SimConfig
    from suds_ros.core.physics.systems import make_system
    from suds_ros.io.recording_bag import write_recording

    system = make_system("purcell3")
    rec = simulate_lab(system, SimConfig(cycles=8, seed=6), LabConditions(jitter=0.0))
    rng = np.random.default_rng(6)
    late = replace(rec, t=rec.t + np.clip(rng.normal(0.0, 0.002, rec.t.size), -0.004, 0.004), truth={})
    read = simulate_lab(system, SimConfig(cycles=8, seed=6), LabConditions(jitter=0.002))
    for name, r, says in (("late.mcap", late, True), ("read.mcap", read, False)):
        write_recording(tmp_path / name, r)
        assert main(["monitor", str(tmp_path / name)]) == 0
        out = capsys.readouterr().out
        assert ("look stamped late" in out) == says, out
