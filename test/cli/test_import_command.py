"""`suds import`: a simulated worm8 run written as tracker files and imported back exactly.

The recording simulated from ``test/data/robots/worm8.yaml`` (8 links, all joints actuated) is
turned into midline points by the forward kinematics (:func:`~suds_ros.core.midline.chain_points`),
written in each format, imported, and compared with the simulated joint angles and body pose.
DeepLabCut .h5 and SLEAP files are made with ``movement`` (their kept library) and skipped when it
is not installed.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from suds_ros.cli.main import main
from suds_ros.core.midline import chain_points, wrap
from suds_ros.core.physics.robot_model import load_model
from suds_ros.core.recording import Recording
from suds_ros.io.recording_bag import read_recording
from suds_ros.io.tracks import movement_available

ROOT = Path(__file__).resolve().parents[2]
WORM8 = ROOT / "test" / "data" / "robots" / "worm8.yaml"
LOST = [(40, 44), (300, 300), (1000, 1011)]  # rows the "tracker" loses (inclusive)
TOL = 1e-6  # rad and m


def error_line(capsys: pytest.CaptureFixture[str]) -> str:
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("ERROR: "), lines
    return lines[0]


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Recording, np.ndarray]:
    """The simulated recording and its midline: (n, 9, 2) joint points, metres, head first."""
    out = tmp_path_factory.mktemp("sim") / "worm8.mcap"
    assert main(["simulate", "--model", str(WORM8), "-o", str(out), "--cycles", "16", "--seed", "5"]) == 0
    rec = read_recording(out)
    model = load_model(WORM8)
    assert rec.pose_t.tolist() == rec.t.tolist()
    q = chain_points(rec.r, rec.pose, model.link_length, model.body_link)
    return rec, q


def lost_mask(n: int) -> np.ndarray:
    mask = np.zeros(n, bool)
    for a, b in LOST:
        mask[a:b + 1] = True
    return mask


def write_csv(path: Path, t: np.ndarray, q: np.ndarray, scale: float, time_col: str = "t") -> Path:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([time_col] + [f"{c}{k}" for k in range(q.shape[1]) for c in "xy"])
        for i in range(t.size):
            row = q[i].ravel() / scale
            w.writerow([repr(float(t[i])) if time_col == "t" else int(t[i])]
                       + ["" if np.isnan(v) else repr(float(v)) for v in row])
    return path


def write_wcon(path: Path, t: np.ndarray, q: np.ndarray) -> Path:
    """WCON in mm and ms, the head as the (ox, oy) offset of each frame, lost frames null."""
    mm = q * 1e3
    head = np.nan_to_num(mm[:, :1], nan=0.0)
    rel = mm - head
    lost = np.isnan(mm).any(axis=(1, 2))
    xs = [None if lost[i] else rel[i, :, 0].tolist() for i in range(t.size)]
    ys = [None if lost[i] else rel[i, :, 1].tolist() for i in range(t.size)]
    half = t.size // 2  # two records of the same animal
    recs = [{"id": "worm", "t": (t[s] * 1e3).tolist(), "x": xs[s], "y": ys[s],
             "ox": head[s, 0, 0].tolist(), "oy": head[s, 0, 1].tolist()}
            for s in (slice(0, half), slice(half, None))]
    path.write_text(json.dumps({"units": {"t": "ms", "x": "mm", "y": "mm"},
                                "metadata": {"software": {"name": "test"}}, "data": recs}))
    return path


def check_import(rec: Recording, out: Path, keep: np.ndarray, *, tol: float = TOL,
                 same_stamps: bool = True) -> Recording:
    got = read_recording(out)
    assert got.n_samples == int(keep.sum())
    if same_stamps:
        np.testing.assert_allclose(got.t, rec.t[keep], atol=2e-6, rtol=0)  # ms in WCON: 1 µs steps of 1.7e12
    np.testing.assert_allclose(got.r, rec.r[keep], atol=tol, rtol=0)
    np.testing.assert_allclose(got.pose[:, :2], rec.pose[keep, :2], atol=tol, rtol=0)
    np.testing.assert_allclose(wrap(got.pose[:, 2] - rec.pose[keep, 2]), 0.0, atol=tol)
    assert got.system == "worm8" and got.actuated == tuple(f"joint_{j}" for j in range(1, 8))
    return got


def test_csv_round_trip_exact_with_lost_frames_dropped(run, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    rec, q = run
    q = q.copy()
    mask = lost_mask(rec.n_samples)
    q[mask, 3, 0] = np.nan  # one lost coordinate loses the frame
    src = write_csv(tmp_path / "worm.csv", rec.t, q, 1e-3)
    out = tmp_path / "worm8.mcap"
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--units", "mm", "--body-link", "4",
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    check_import(rec, out, ~mask)
    assert summary["lost"]["frames"] == int(mask.sum()) == 18
    assert [(r["first_frame"], r["last_frame"]) for r in summary["lost"]["runs"]] == LOST
    assert summary["lost"]["runs"][0]["t_first"] == pytest.approx(rec.t[40])
    assert summary["missing"] == [] and summary["points"] == 9 and summary["max_links"] == 8
    # the model file beside it: measured lengths, all actuated, gait frequency from the data
    model = load_model(tmp_path / "worm8.yaml")
    np.testing.assert_allclose(model.link_length, load_model(WORM8).link_length, atol=1e-9)
    assert model.actuated == tuple(range(7)) and model.body_link == 3 and model.name == "worm8"
    assert model.gait_hz == pytest.approx(1.0, rel=0.02)
    assert read_recording(out).gait_hz == pytest.approx(model.gait_hz)
    assert main(["model", "check", str(tmp_path / "worm8.yaml")]) == 0
    capsys.readouterr()
    # then the imported recording identifies
    assert main(["identify", str(out), "--model", str(tmp_path / "worm8.yaml"), "--train-cycles", "8",
                 "--test-cycles", "7"]) == 0
    assert "body" in capsys.readouterr().out


def test_wcon_round_trip_exact(run, tmp_path) -> None:  # type: ignore[no-untyped-def]
    rec, q = run
    q = q.copy()
    mask = lost_mask(rec.n_samples)
    q[mask] = np.nan
    src = write_wcon(tmp_path / "worm.wcon", rec.t, q)
    out = tmp_path / "worm8.mcap"
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--body-link", "4"]) == 0
    check_import(rec, out, ~mask)


def test_wcon_archive_of_a_multi_worm_tracker_chunked_tail_first_round_trip_exact(  # type: ignore[no-untyped-def]
        run, tmp_path, capsys) -> None:
    """A real tracker's export: zipped chunks, two worms, tail-first points, centroid origins, shuffled records.

    The worm of interest is split over two chunks (``files``) in one ``.wcon.zip``; its points are
    stored tail first (``head`` "R") relative to its centroid (``cx``, ``cy`` in µm, x and y in mm);
    its records come newest first; a second worm shares the plate; two times are ``null``.  With
    ``--animal`` it imports as exactly as the plain file; without, the error names both worms.
    """
    import zipfile

    rec, q = run
    q = q.copy()
    mask = lost_mask(rec.n_samples)
    q[mask] = np.nan
    mm = q * 1e3
    centroid = np.zeros((rec.t.size, 2))
    centroid[~mask] = np.mean(mm[~mask], axis=1)
    rel = (mm - centroid[:, None])[:, ::-1]  # tail first
    n = rec.t.size
    parts = [slice(0, n // 3), slice(n // 3, 2 * n // 3), slice(2 * n // 3, n)]

    def worm_record(s: slice) -> dict:
        lost = np.isnan(rel[s]).any(axis=(1, 2))
        return {"id": 7, "t": rec.t[s].tolist(), "head": "R", "ventral": "CW",
                "x": [None if lost[i] else rel[s][i, :, 0].tolist() for i in range(lost.size)],
                "y": [None if lost[i] else rel[s][i, :, 1].tolist() for i in range(lost.size)],
                "cx": (centroid[s, 0] * 1e3).tolist(), "cy": (centroid[s, 1] * 1e3).tolist(),
                "@OMG": {"feature_values": [1.0]}}
    other = {"id": 8, "t": [0.0, 0.1], "x": [[1, 2, 3], [1, 2, 3]], "y": [[0, 0, 0], [0, 1, 0]]}
    ghost = {"id": 7, "t": [None, None], "x": [[0, 1], [0, 1]], "y": [[0, 0], [0, 0]]}
    units = {"t": "s", "x": "mm", "y": "mm", "cx": "um", "cy": "um"}
    chunks = {
        "plate_0.wcon": {"files": {"this": "_0", "prev": None, "next": ["_1"]}, "units": units,
                         "data": [worm_record(parts[1]), other, worm_record(parts[0])]},
        "plate_1.wcon": {"files": {"this": "_1", "prev": ["_0"], "next": []}, "units": units,
                         "data": [ghost, worm_record(parts[2])]},
    }
    src = tmp_path / "plate.wcon.zip"
    with zipfile.ZipFile(src, "w", compression=zipfile.ZIP_DEFLATED) as z:
        for name in ("plate_1.wcon", "plate_0.wcon"):
            z.writestr(name, json.dumps(chunks[name]))
    out = tmp_path / "worm8.mcap"
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--body-link", "4"]) == 2
    err = error_line(capsys)
    assert "2 animals (ids 7 (" in err and "8 (2 times, 0–0.1 s)" in err and "pass --animal ID" in err
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--body-link", "4", "--animal", "9"]) == 2
    assert "--animal '9': no such id" in error_line(capsys)
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--body-link", "4", "--animal", "7",
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    check_import(rec, out, ~mask)
    notes = " | ".join(summary["notes"])
    assert f'head "R" (the head is the last point) in {n} frames' in notes
    assert "2 frames with a null time dropped" in notes and "relative to the centroid" in notes
    assert "2 chunks joined" in notes and summary["animal"] == "7"


def test_frames_the_tracker_gave_tail_first_are_turned_round_and_reported(  # type: ignore[no-untyped-def]
        run, tmp_path, capsys) -> None:
    """A midline tracker's head–tail swaps (runs of frames, one across a lost run) import exactly, and are listed."""
    rec, q = run
    q = q.copy()
    mask = lost_mask(rec.n_samples)
    q[mask] = np.nan
    swapped = np.zeros(rec.n_samples, dtype=bool)
    swapped[[7, 45, 46]] = True  # 45, 46: right after the lost run 40–44
    swapped[500:620] = True
    given = np.where(swapped[:, None, None], q[:, ::-1], q)
    src = write_csv(tmp_path / "worm.csv", rec.t, given, 1e-3)
    out = tmp_path / "worm8.mcap"
    base = ["import", str(src), "-o", str(out), "--links", "8", "--units", "mm", "--body-link", "4"]
    assert main(base + ["--json"]) == 0
    h = json.loads(capsys.readouterr().out)["head_tail"]
    check_import(rec, out, ~mask)
    assert h["swapped"] == 123 and h["reversed"] and h["unlinked"] == 0
    assert [(x["first_frame"], x["last_frame"]) for x in h["runs"]] == [(7, 7), (45, 46), (500, 619)]
    assert main(base + ["--overwrite"]) == 0
    text = capsys.readouterr().out
    assert "head–tail: 123 frames in 3 runs given tail first against the frames next to them; reversed" in text
    assert "tail first: frames 500–619" in text
    assert main(base + ["--overwrite", "--keep-head-tail", "--json"]) == 0
    h = json.loads(capsys.readouterr().out)["head_tail"]
    assert h["swapped"] == 123 and not h["reversed"]
    got = read_recording(out)
    kept = np.flatnonzero(~mask)
    wrong = np.any(np.abs(got.r - rec.r[kept]) > 1e-6, axis=1)
    np.testing.assert_array_equal(wrong, swapped[kept])  # as given: exactly those frames wrong


def test_dense_midline_with_fractions_frame_numbers_and_pixels(  # type: ignore[no-untyped-def]
        run, tmp_path, capsys) -> None:
    rec, q = run
    L = np.asarray(load_model(WORM8).link_length)
    a = np.arange(4) / 4
    dense = np.concatenate([q[:, i:i + 1] + (q[:, i + 1:i + 2] - q[:, i:i + 1]) * a[None, :, None]
                            for i in range(8)] + [q[:, -1:]], axis=1)  # 33 points on the 8 links
    frames = np.arange(rec.n_samples)
    keep = np.ones(rec.n_samples, bool)
    keep[500:510] = False  # frames absent from the file: reported as a gap
    src = write_csv(tmp_path / "dense.csv", frames[keep], dense[keep], 2e-4, time_col="frame")
    out = tmp_path / "worm8.mcap"
    assert main(["import", str(src), "-o", str(out), "--links", "8", "--body-link", "4", "--units", "px",
                 "--px-size", "2e-4", "--fps", "100", "--fractions", ",".join(map(str, L)), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    got = check_import(rec, out, keep, same_stamps=False)
    np.testing.assert_allclose(got.t, frames[keep] / 100.0, atol=1e-9)
    assert summary["missing"] == [{"first_frame": 500, "last_frame": 509, "frames": 10}]
    assert summary["lost"]["frames"] == 0 and summary["max_links"] == 32


def test_keypoints_report_how_many_links_they_support(run, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    rec, q = run
    src = write_csv(tmp_path / "fish.csv", rec.t[:400], q[:400, ::2], 1.0)  # 5 keypoints
    assert main(["import", str(src), "-o", str(tmp_path / "fish.mcap"), "--links", "4", "--units", "m",
                 "--passive", "joint_3,2"]) == 0
    text = capsys.readouterr().out
    assert "5 points per frame (enough for up to 4 links)" in text
    model = yaml.safe_load((tmp_path / "fish.yaml").read_text())
    roles = [j.get("actuated", False) for j in model["joints"]]
    assert roles == [True, False, False]
    assert all(j["stiffness"] > 0 for j in model["joints"][1:])
    assert main(["model", "check", str(tmp_path / "fish.yaml")]) == 0
    assert read_recording(tmp_path / "fish.mcap").passive == ("joint_2", "joint_3")
    assert main(["import", str(src), "-o", str(tmp_path / "fish6.mcap"), "--links", "5", "--units", "m"]) == 2
    line = error_line(capsys)
    assert "5 links need at least 6 points per frame; the file has 5" in line and "--links 4 or fewer" in line


def bad(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD = "t,x0,y0,x1,y1,x2,y2\n" + "".join(f"{k / 10},{k},0,{k},1,{k},{2 + (k % 3)}\n" for k in range(20))


@pytest.mark.parametrize("name, text, argv, match", [
    ("back.csv", "t,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,2,0\n0.2,0,0,1,0,2,1\n0.1,0,0,1,0,2,0\n", [],
     "time goes back at row 2 (0.1 s after 0.2 s)"),
    ("dup.csv", "t,x0,y0,x1,y1,x2,y2\n0,0,0,1,0,2,0\n0,0,0,1,0,2,1\n", [], "time repeats at row 1"),
    ("nan.csv", "t,x0,y0,x1,y1,x2,y2\n0,,,,,,\n0.1,nan,nan,nan,nan,nan,nan\n", [],
     "every one of the 2 frames is lost"),
    ("few.csv", "t,x0,y0,x1,y1\n0,0,0,1,0\n", [], "2 links need at least 3 points per frame; the file has 2"),
    ("nomid.csv", "t\n0\n", [], "no x0,y0 columns: the file holds no midline"),
    ("hdr.csv", "time,x0,y0\n0,0,0\n", [], "first column: expected `t`"),
    ("w.txt", "hello", [], "cannot tell the format"),
    ("w.wcon", "{oops", [], "not WCON: invalid JSON"),
    ("w.csv", "{oops", ["--format", "wcon"], "not WCON: invalid JSON"),
    ("units.csv", GOOD, ["--units", None], "does not state its length unit; pass --units"),
    ("px.csv", GOOD, ["--units", "px"], "--px-size: expected metres per pixel > 0"),
    ("fps.csv", GOOD, ["--fps", "30"], "has its own frame times; --fps is for files with frame numbers"),
    ("frames.csv", GOOD.replace("t,", "frame,", 1).replace(".", ""), [], "--fps: the csv file has frame numbers"),
    ("links.csv", GOOD, ["--links", "1"], "--links: expected a number of links ≥ 2"),
    ("body.csv", GOOD, ["--body-link", "3"], "--body-link: expected a link 1..2, got 3"),
    ("frac.csv", GOOD, ["--fractions", "1,2,3"], "--fractions: expected 2 relative link lengths"),
    ("pas.csv", GOOD, ["--passive", "joint_1"], "every joint named"),
    ("pas2.csv", GOOD, ["--passive", "neck"], "--passive: 'neck' is not a joint"),
    ("flat.csv", "t,x0,y0,x1,y1,x2,y2\n" + "".join(f"{k},0,0,1,0,2,0\n" for k in range(10)), [],
     "the joint angles do not change"),
    ("wun.wcon", json.dumps({"units": {"t": "s", "x": "mm", "y": "mm"},
                             "data": {"id": 1, "t": [0, 1], "x": [[0, 1, 2]] * 2, "y": [[0, 0, 1]] * 2}}),
     ["--units", "um"], "--units um: the wcon file states its unit, 'mm'"),
])
def test_bad_input_is_one_error_line(tmp_path, capsys, name, text, argv, match) -> None:  # type: ignore[no-untyped-def]
    src = bad(tmp_path, name, text)
    args = ["import", str(src), "-o", str(tmp_path / "out.mcap")]
    extra = list(argv)
    if "--links" not in extra:
        args += ["--links", "2"]
    if "--units" not in extra and src.suffix != ".wcon":
        args += ["--units", "mm"]  # the unit a csv needs, unless the case is about it
    if "--units" in extra and extra[extra.index("--units") + 1] is None:
        del extra[extra.index("--units"):extra.index("--units") + 2]
    assert main(args + extra) == 2
    line = error_line(capsys)
    assert match in line, line
    assert not (tmp_path / "out.mcap").exists() and not (tmp_path / "out.yaml").exists()


def test_existing_outputs_are_not_overwritten(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    src = bad(tmp_path, "ok.csv", GOOD)
    base = ["import", str(src), "--links", "2", "--units", "mm", "--gait-hz", "2"]
    assert main(base + ["-o", str(tmp_path / "a.mcap")]) == 0
    capsys.readouterr()
    before = (tmp_path / "a.mcap").read_bytes()
    assert main(base + ["-o", str(tmp_path / "a.mcap")]) == 2
    assert "exists; pass --overwrite" in error_line(capsys)
    (tmp_path / "b.yaml").write_text("mine")
    assert main(base + ["-o", str(tmp_path / "b.mcap")]) == 2
    assert "'" + str(tmp_path / "b.yaml") + "' exists" in error_line(capsys)
    assert not (tmp_path / "b.mcap").exists() and (tmp_path / "b.yaml").read_text() == "mine"
    assert main(base + ["-o", str(tmp_path / "a.mcap"), "--overwrite"]) == 0
    assert (tmp_path / "a.mcap").read_bytes() == before  # same input, same file
    assert load_model(tmp_path / "a.yaml").gait_hz == 2.0


# ----------------------------------------------------- DeepLabCut .h5 / SLEAP through movement
needs_movement = pytest.mark.skipif(not movement_available(),
                                    reason="movement is not installed (optional: pip install movement)")


def movement_dataset(q: np.ndarray, scale: float):  # type: ignore[no-untyped-def]
    from movement.io import load_poses

    pos = (q / scale).transpose(0, 2, 1)[..., None]  # (time, space, keypoints, individuals)
    conf = np.where(np.isnan(pos[:, 0]), 0.0, 0.9)
    return load_poses.from_numpy(position_array=pos, confidence_array=conf, individual_names=["worm"],
                                 keypoint_names=[f"p{k}" for k in range(q.shape[1])])


@needs_movement
@pytest.mark.parametrize("fmt, name", [("dlc", "worm.h5"), ("dlc", "worm.csv"), ("sleap", "worm.h5"),
                                       ("lightningpose", "worm_lp.csv")])
def test_movement_formats_round_trip(run, tmp_path, fmt, name) -> None:  # type: ignore[no-untyped-def]
    from movement.io import save_poses

    rec, q = run
    n = 600
    origin = q[0, 0]
    q = q[:n] - origin  # near the origin: SLEAP stores float32
    mask = lost_mask(n)
    q = np.where(mask[:, None, None], np.nan, q)
    ds = movement_dataset(q, 1e-3)
    path = tmp_path / name
    if fmt == "dlc":
        save_poses.to_dlc_file(ds, path, split_individuals=False if name.endswith(".h5") else True)
        if name.endswith(".csv"):
            path = tmp_path / "worm_worm.csv"
    elif fmt == "lightningpose":
        save_poses.to_lp_file(ds, path)
        path = tmp_path / "worm_lp_worm.csv"  # one file per animal, its name appended
    else:
        save_poses.to_sleap_analysis_file(ds, path)
    out = tmp_path / "worm8.mcap"
    assert main(["import", str(path), "--format", fmt, "-o", str(out), "--links", "8", "--body-link", "4",
                 "--units", "px", "--px-size", "1e-3", "--fps", "100"]) == 0
    got = read_recording(out)
    keep = ~mask
    tol = TOL  # SLEAP analysis files hold float32 coordinates: near the origin its error is 6e-7 rad, 1.4e-8 m
    np.testing.assert_allclose(got.t, np.flatnonzero(keep) / 100.0, atol=1e-9)
    np.testing.assert_allclose(got.r, rec.r[:n][keep], atol=tol, rtol=0)
    np.testing.assert_allclose(got.pose[:, :2], rec.pose[:n][keep, :2] - origin, atol=tol, rtol=0)
    np.testing.assert_allclose(wrap(got.pose[:, 2] - rec.pose[:n][keep, 2]), 0.0, atol=tol)


@needs_movement
@pytest.mark.parametrize("fmt, name", [("dlc", "plate.h5"), ("sleap", "plate.h5")])
def test_movement_file_of_two_animals_imports_the_one_named(  # type: ignore[no-untyped-def]
        run, tmp_path, capsys, fmt, name) -> None:
    """Two animals tracked in one file: refused with their names and tracked frames; ``--animal`` picks one."""
    from movement.io import load_poses, save_poses

    rec, q = run
    n = 600
    origin = q[0, 0]
    q = q[:n] - origin
    mask = lost_mask(n)
    q = np.where(mask[:, None, None], np.nan, q)
    other = np.full_like(q, np.nan)
    other[100:200] = q[:100] + 0.05  # a second animal, tracked in 100 frames only
    pos = np.stack([(x / 1e-3).transpose(0, 2, 1) for x in (other, q)], axis=-1)  # (time, space, kpts, ind)
    conf = np.where(np.isnan(pos[:, 0]), 0.0, 0.9)
    ds = load_poses.from_numpy(position_array=pos, confidence_array=conf, individual_names=["stray", "worm"],
                               keypoint_names=[f"p{k}" for k in range(q.shape[1])])
    path = tmp_path / name
    (save_poses.to_dlc_file(ds, path, split_individuals=False) if fmt == "dlc"
     else save_poses.to_sleap_analysis_file(ds, path))
    out = tmp_path / "worm8.mcap"
    base = ["import", str(path), "--format", fmt, "-o", str(out), "--links", "8", "--body-link", "4",
            "--units", "px", "--px-size", "1e-3", "--fps", "100"]
    assert main(base) == 2
    err = error_line(capsys)
    tracked = [int(np.sum(~mask[:100])), int(np.sum(~mask))]  # frames with a point: 95 and 594
    assert f"2 animals (stray ({tracked[0]} frames), worm ({tracked[1]} frames))" in err
    assert "pass --animal NAME" in err
    assert main(base + ["--animal", "fish"]) == 2
    assert "--animal 'fish': no such individual" in error_line(capsys) and not out.exists()
    assert main(base + ["--animal", "worm"]) == 0
    got = read_recording(out)
    keep = ~mask
    np.testing.assert_allclose(got.r, rec.r[:n][keep], atol=TOL, rtol=0)
    np.testing.assert_allclose(got.pose[:, :2], rec.pose[:n][keep, :2] - origin, atol=TOL, rtol=0)
