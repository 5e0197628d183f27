"""`suds simulate --gait FILE`: the gait drives the run and is recorded; a gait of another robot is one ERROR line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from suds_ros.cli.main import main
from suds_ros.core.physics.gait import loads_gait, nominal_gait, save_gait
from suds_ros.core.physics.systems import make_system
from suds_ros.io.mcap import bag_info
from suds_ros.io.recording_bag import read_recording


def test_simulate_with_a_gait_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    g = nominal_gait(make_system("purcell3")).from_vector(np.array([0.1, 0.2, 0.0, 0.9, 0.0]), 2)
    gpath = tmp_path / "g.yaml"
    save_gait(g, gpath)
    out = tmp_path / "run.mcap"
    assert main(["simulate", "purcell3", "-o", str(out), "--cycles", "2", "--gait", str(gpath),
                 "--ou-std", "0", "--noise", "0"]) == 0
    assert f"gait {gpath}" in capsys.readouterr().out
    rec = read_recording(out)
    t = np.arange(rec.t.size) / 100.0
    np.testing.assert_allclose(rec.r[:, 0], g.r(t)[:, 0], atol=1e-9)
    meta = bag_info(out).metadata
    assert loads_gait(meta["suds_gait"]["yaml"]) == g
    assert meta["suds"]["system"] == "purcell3"  # the contract's record unchanged


def test_simulate_refuses_a_gait_of_another_robot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gpath = tmp_path / "s9.yaml"
    save_gait(nominal_gait(make_system("swimmer9")), gpath)
    out = tmp_path / "run.mcap"
    assert main(["simulate", "purcell3", "-o", str(out), "--cycles", "1", "--gait", str(gpath)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ERROR: ") and "the gait is for 'swimmer9'" in err[0]
    assert not out.exists()
    assert main(["simulate", "purcell3", "-o", str(out), "--gait", str(tmp_path / "none.yaml")]) == 2
    assert "--gait: no such file" in capsys.readouterr().err
    save_gait(nominal_gait(make_system("purcell3")), gpath)
    assert main(["simulate", "purcell3", "-o", str(out), "--gait", str(gpath), "--gait-hz", "2"]) == 2
    assert "--gait-hz 2: the gait file" in capsys.readouterr().err
