"""Intermittent motion: `suds import --segment` finds bouts, `suds identify` holds out whole bouts.

A simulated worm8 run (16 cycles at 1 Hz) is frozen four times: the midline stays still for
1.5 s after every 4 cycles and then carries on where it stopped, so the file holds four bouts of
4 cycles at known times, separated by still stretches.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from suds_ros.cli.main import main
from suds_ros.core.ident.identify import split_bouts
from suds_ros.core.midline import chain_points
from suds_ros.core.physics.robot_model import load_model
from suds_ros.io.recording_bag import read_recording, write_recording

ROOT = Path(__file__).resolve().parents[2]
WORM8 = ROOT / "test" / "data" / "robots" / "worm8.yaml"


def error_line(capsys: pytest.CaptureFixture[str]) -> str:
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("ERROR: "), lines
    return lines[0]


def write_csv(path: Path, t: np.ndarray, q: np.ndarray) -> Path:
    """A midline CSV in mm: t, x0, y0, … head first."""
    rows = np.column_stack([t, q.reshape(t.size, -1) * 1e3])
    head = "t," + ",".join(f"{c}{k}" for k in range(q.shape[1]) for c in "xy")
    np.savetxt(path, rows, delimiter=",", header=head, comments="", fmt="%.17g")
    return path


PAUSE = 150  # frames still between bouts (1.5 s at 100 fps)
CHUNK = 400  # frames per bout (4 cycles)


@pytest.fixture(scope="module")
def bout_file(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[tuple[float, float]]]:
    """A midline CSV with 4 bouts and the true (first, last) frame time of each."""
    tmp = tmp_path_factory.mktemp("bouts")
    sim = tmp / "worm8.mcap"
    assert main(["simulate", "--model", str(WORM8), "-o", str(sim), "--cycles", "16", "--seed", "3"]) == 0
    rec = read_recording(sim)
    q = chain_points(rec.r, rec.pose, load_model(WORM8).link_length, load_model(WORM8).body_link)
    frames, truth = [], []
    n = 0
    for k in range(4):
        chunk = q[k * CHUNK:(k + 1) * CHUNK]
        truth.append((n, n + chunk.shape[0] - 1))
        frames.append(chunk)
        n += chunk.shape[0]
        if k < 3:
            frames.append(np.repeat(chunk[-1:], PAUSE, axis=0))
            n += PAUSE
    pts = np.concatenate(frames)
    t = 0.01 * np.arange(pts.shape[0])
    src = write_csv(tmp / "larva.csv", t, pts)
    return src, [(t[a], t[b]) for a, b in truth]


@pytest.fixture(scope="module")
def imported(bout_file, tmp_path_factory) -> tuple[Path, dict]:  # type: ignore[no-untyped-def]
    src, _ = bout_file
    out = tmp_path_factory.mktemp("imp") / "larva.mcap"
    rc = main(["import", str(src), "-o", str(out), "--links", "8", "--units", "mm", "--body-link", "4",
               "--gait-hz", "1", "--segment", "amplitude:0.25", "--json"])
    assert rc == 0
    return out, {}


@pytest.mark.parametrize("segment", ["amplitude:0.25", "speed:0.02"])
def test_bouts_found_at_the_right_times(bout_file, tmp_path, capsys, segment) -> None:  # type: ignore[no-untyped-def]
    src, truth = bout_file
    out = tmp_path / "larva.mcap"
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--units", "mm", "--body-link", "4",
                 "--gait-hz", "1", "--segment", segment, "--json"]) == 0
    seg = json.loads(capsys.readouterr().out)["segment"]
    assert len(seg["bouts"]) == 4
    for b, (a0, b0) in zip(seg["bouts"], truth):
        assert b["t_first"] == pytest.approx(a0, abs=0.5) and b["t_last"] == pytest.approx(b0, abs=0.5)
        assert b["cycles"] == pytest.approx(4.0, abs=1.0)
    rec = read_recording(out)
    assert rec.bouts == tuple((b["t_first"], b["t_last"]) for b in seg["bouts"])  # listed in the metadata


def test_import_text_reports_bouts(bout_file, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    src, _ = bout_file
    assert main(["import", str(src), "-o", str(tmp_path / "a.mcap"), "--links", "8", "--units", "mm",
                 "--gait-hz", "1", "--segment", "amplitude:0.25"]) == 0
    text = capsys.readouterr().out
    assert "bouts (amplitude ≥ 0.25 rad, ≥ 2 cycles): 4," in text and "bout 4:" in text


def test_no_bout_is_an_error_naming_the_activity(bout_file, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    src, _ = bout_file
    out = tmp_path / "a.mcap"
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--units", "mm", "--gait-hz", "1",
                 "--segment", "amplitude:5"]) != 0
    line = error_line(capsys)
    assert "no bout of at least 2 gait cycles" in line and "the amplitude ranges" in line
    assert not out.exists()
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--units", "mm",
                 "--segment", "pace:1"]) != 0
    assert "--segment: expected speed:THRESH or amplitude:THRESH, got 'pace:1'" in error_line(capsys)


def test_identify_holds_out_whole_bouts(imported, capsys) -> None:  # type: ignore[no-untyped-def]
    out, _ = imported
    rec = read_recording(out)
    assert len(rec.bouts) == 4
    assert main(["identify", str(out), "--train-cycles", "7", "--test-cycles", "8", "--regressors", "1",
                 "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    # 7 cycles need two whole bouts (about 8 cycles); the other two are held out whole
    assert np.allclose(res["bouts"]["train"], rec.bouts[:2], atol=1e-6)  # stamps read back (ns)
    assert np.allclose(res["bouts"]["test"], rec.bouts[2:], atol=1e-6)
    # each found bout reaches up to half a window into the still stretches around it
    assert res["train_cycles"] == pytest.approx(8.0, abs=1.2) and res["test_cycles"] == pytest.approx(8.0, abs=1.2)
    assert res["gamma_body"] > 0.5  # a noise-free simulation: the model beats the template
    train, test = split_bouts(rec, 7, 8)
    assert np.allclose([b.t[0] for b in test], [b[0] for b in rec.bouts[2:]], atol=1e-6)
    # no interval spans a pause: one interval fewer than samples per held-out bout
    from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier
    from suds_ros.core.ident.sysid import SudsConfig

    ident = SudsIdentifier(IdentifyConfig(suds=SudsConfig(regressors=1), order_grid=())).fit(train)
    pred = ident.predict(test)
    assert pred.t.size == sum(b.n_samples - 1 for b in test)
    assert np.all(np.diff(pred.t) < 1.6)  # gaps only between bouts (1.5 s pause + a frame)
    assert main(["identify", str(out), "--train-cycles", "7", "--ignore-bouts", "--json"]) == 0
    assert "bouts" not in json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("train, match", [
    ("16", "cannot train on 16 cycles of whole bouts and hold out a whole bout: the recording's 4 bouts hold "),
    ("15", "cycles can train (pass --train-cycles 13 or fewer)"),
])
def test_too_few_cycles_is_an_error_naming_the_numbers(imported, capsys, train,  # type: ignore[no-untyped-def]
                                                       match) -> None:
    out, _ = imported
    assert main(["identify", str(out), "--train-cycles", train]) != 0
    line = error_line(capsys)
    assert match in line and "cycles of 1 s" in line


def test_one_bout_is_too_few(imported, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    from dataclasses import replace

    out, _ = imported
    rec = read_recording(out)
    one = tmp_path / "one.mcap"
    write_recording(one, replace(rec, bouts=rec.bouts[:1]))
    assert main(["identify", str(one), "--train-cycles", "2"]) != 0
    line = error_line(capsys)
    assert "cannot hold out whole bouts: the recording's 1 bouts hold" in line and "need at least 2 bouts" in line
    assert main(["identify", str(one), "--streaming"]) != 0
    assert "--streaming: the recording lists bouts" in error_line(capsys)
