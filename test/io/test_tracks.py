"""io.tracks: the tracker file readers (midline CSV, WCON, DeepLabCut csv; movement for DLC .h5 / SLEAP)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from suds_ros.core.errors import SudsConfigError, SudsDataError
from suds_ros.io import tracks as tr
from suds_ros.io.tracks import BAD_TRACK_FILE, MISSING_DEPENDENCY, detect_format, read_tracks


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_midline_csv_with_times_frames_comments_and_lost_cells(tmp_path: Path) -> None:
    f = write(tmp_path / "m.csv", "# from my tracker\nt,x0,y0,x1,y1\n0.0,1,2,3,4\n0.5,,2,3,4\n1.0,nan,NaN,5,6\n")
    got = read_tracks(f)
    assert got.format == "csv" and got.t.tolist() == [0.0, 0.5, 1.0] and got.frame is None
    assert got.points.shape == (3, 2, 2) and got.units is None
    np.testing.assert_array_equal(got.points[0], [[1, 2], [3, 4]])
    assert np.isnan(got.points[1, 0, 0]) and np.isnan(got.points[2, 0]).all()
    g = read_tracks(write(tmp_path / "f.csv", "frame,x0,y0,x1,y1\n10,1,2,3,4\n12,1,2,3,4\n"))
    assert g.t is None and g.frame.tolist() == [10, 12]


@pytest.mark.parametrize("text, match", [
    ("", "no header row"),
    ("time,x0,y0\n0,1,2\n", "first column: expected `t` .* got 'time'"),
    ("t,x0,y0,y1,x1\n0,1,2,3,4\n", "got column 'y1'"),
    ("t,x0,y0,x1,y1,likelihood\n0,1,2,3,4,1\n", "got column 'likelihood'"),
    ("t\n0\n", "no x0,y0 columns"),
    ("t,x0,y0\n0,1\n", "row 1: expected 3 cells, got 2"),
    ("t,x0,y0\n0,a,2\n", "row 1: expected numbers"),
    ("frame,x0,y0\n1.5,1,2\n", "`frame` expected an integer"),
])
def test_midline_csv_errors_name_the_problem(tmp_path: Path, text: str, match: str) -> None:
    with pytest.raises(SudsDataError, match=match) as exc:
        read_tracks(write(tmp_path / "bad.csv", text))
    assert exc.value.code == BAD_TRACK_FILE


def wcon(data: object, units: object = None) -> str:
    return json.dumps({"units": units or {"t": "ms", "x": "mm", "y": "mm"}, "data": data})


def test_wcon_records_offsets_nulls_units(tmp_path: Path) -> None:
    data = [
        {"id": "w1", "t": [0, 20], "x": [[1, 2, 3], [1, 2, 3]], "y": [[0, 0, 0], [0, 1, None]],
         "ox": [10, 20], "oy": 5},
        {"id": "w1", "t": 40, "x": [], "y": []},  # a time without points: lost
        {"id": "w1", "t": [60], "x": [[4, 5, 6]], "y": [[1, 1, 1]], "@custom": {"ignored": True}},
    ]
    got = read_tracks(write(tmp_path / "w.wcon", wcon(data)))
    assert got.format == "wcon" and got.units == "mm"
    np.testing.assert_allclose(got.t, [0.0, 0.02, 0.04, 0.06])
    np.testing.assert_array_equal(got.points[0], [[11, 5], [12, 5], [13, 5]])
    assert np.isnan(got.points[1, 2, 1]) and np.isnan(got.points[2]).all()
    np.testing.assert_array_equal(got.points[3], [[4, 1], [5, 1], [6, 1]])
    assert got.counts is None  # every frame with points has all of them
    one = read_tracks(write(tmp_path / "one.json", wcon({"id": 1, "t": 0.5, "x": [1, 2], "y": [3, 4]},
                                                        {"t": "s", "x": "um", "y": "um"})))
    assert one.units == "um" and one.t.tolist() == [0.5] and one.points.shape == (1, 2, 2)


def test_wcon_varying_point_counts_pad_with_the_tail(tmp_path: Path) -> None:
    data = {"id": 1, "t": [0, 1], "x": [[0, 1, 2], [0, 1]], "y": [[0, 0, 0], [0, 0]]}
    got = read_tracks(write(tmp_path / "v.wcon", wcon(data, {"t": "s", "x": "mm", "y": "mm"})))
    assert got.counts.tolist() == [3, 2]
    np.testing.assert_array_equal(got.points[1], [[0, 0], [1, 0], [1, 0]])


@pytest.mark.parametrize("expr, scale, dims", [
    ("mm", 1e-3, (1, 0)), ("um", 1e-6, (1, 0)), ("\u00b5m", 1e-6, (1, 0)), ("\u03bcm", 1e-6, (1, 0)),
    ("micrometers", 1e-6, (1, 0)),  # as Tierpsy writes it
    ("millimetre", 1e-3, (1, 0)), ("microns", 1e-6, (1, 0)), ("Mm", 1e6, (1, 0)), ("inches", 0.0254, (1, 0)),
    ("12*in", 0.3048, (1, 0)), ("in/72", 0.0254 / 72, (1, 0)), ("0.04*s", 0.04, (0, 1)), ("ms", 1e-3, (0, 1)),
    ("min", 60.0, (0, 1)), ("minutes", 60.0, (0, 1)), ("mm^2/s", 1e-6, (2, -1)), ("1", 1.0, (0, 0)),
])
def test_wcon_unit_grammar(expr: str, scale: float, dims: tuple[int, int]) -> None:
    """The tracker-commons unit grammar: SI prefixes, words or abbreviations, *, /, ^ and factors."""
    got, d = tr.wcon_unit(expr)
    assert got == pytest.approx(scale, rel=1e-12) and (d["L"], d["T"]) == dims


@pytest.mark.parametrize("expr", ["msecond", "millis", "fortnight", "mm mm", "m/", "*s", "mm^1.5", "0*s"])
def test_wcon_unit_grammar_refuses_what_it_does_not_define(expr: str) -> None:
    """Mixed abbreviation and word, unknown words, missing operators, fractional powers, zero factors."""
    with pytest.raises(ValueError):
        tr.wcon_unit(expr)


def test_wcon_in_micrometers_and_inches_reads_in_si(tmp_path: Path) -> None:
    """A Tierpsy export's \"micrometers\" and a frame clock \"0.04*s\"; inches come back in metres."""
    rec = {"id": 1, "t": [0, 1], "x": [[1, 2], [1, 2]], "y": [[0, 0], [0, 1]]}
    um = read_tracks(write(tmp_path / "um.wcon", wcon(rec, {"t": "0.04*s", "x": "micrometers", "y": "microns"})))
    assert um.units == "um" and um.t.tolist() == [0.0, 0.04]
    np.testing.assert_array_equal(um.points[1], [[1, 0], [2, 1]])
    inch = read_tracks(write(tmp_path / "in.wcon", wcon(rec, {"t": "s", "x": "in", "y": "inches"})))
    assert inch.units == "m"
    np.testing.assert_allclose(inch.points[1], [[0.0254, 0], [0.0508, 0.0254]])


@pytest.mark.parametrize("text, match", [
    ("{not json", "invalid JSON"),
    (json.dumps({"data": []}), "expected a JSON object with `units` and `data`"),
    (wcon({"id": 1, "t": 0, "x": [1], "y": [1]}, {"t": "fortnight", "x": "mm", "y": "mm"}), "units.t"),
    (wcon({"id": 1, "t": 0, "x": [1], "y": [1]}, {"t": "s", "x": "px", "y": "px"}), "units.x"),
    (wcon({"id": 1, "t": 0, "x": [1], "y": [1]}, {"t": "mm", "x": "mm", "y": "mm"}), "units.t: expected a time"),
    (wcon({"id": 1, "t": 0, "x": [1], "y": [1]}, {"t": "s", "x": "mm/s", "y": "mm"}), "units.x: expected a length"),
    (wcon({"id": 1, "t": 0, "x": [1], "y": [1]}, {"t": "s", "x": "mm", "y": "um"}), "x in 'mm' but y in 'um'"),
    (wcon([{"id": 1, "t": 0, "x": [1], "y": [1]}, {"id": 2, "t": 0, "x": [1], "y": [1]}]), "2 animals"),
    (wcon({"id": 1, "t": [0, 1], "x": [[1]], "y": [[1], [2]]}), r"data\[0\].x: expected 2 entries"),
    (wcon({"id": 1, "t": [0, 1], "x": [[], []], "y": [[], []]}), "no midline"),
    (wcon([{"t": 0}]), r"data\[0\]: expected a record with id, t, x, y"),
])
def test_wcon_errors_name_the_problem(tmp_path: Path, text: str, match: str) -> None:
    with pytest.raises(SudsDataError, match=match) as exc:
        read_tracks(write(tmp_path / "bad.wcon", text))
    assert exc.value.code == BAD_TRACK_FILE


def test_wcon_records_in_any_order_are_put_in_time_order_and_a_repeated_time_is_refused(tmp_path: Path) -> None:
    data = [{"id": 1, "t": [2, 3], "x": [[2, 2], [3, 3]], "y": [[0, 1], [0, 1]]},
            {"id": 1, "t": 0, "x": [0, 0], "y": [0, 1]},
            {"id": 1, "t": [1, None], "x": [[1, 1], [9, 9]], "y": [[0, 1], [0, 1]]}]
    got = read_tracks(write(tmp_path / "o.wcon", wcon(data, {"t": "s", "x": "mm", "y": "mm"})))
    assert got.t.tolist() == [0, 1, 2, 3] and got.points[:, 0, 0].tolist() == [0, 1, 2, 3]
    assert got.notes == ("1 frames with a null time dropped (cannot be placed)",)
    data[1]["t"] = 3
    with pytest.raises(SudsDataError, match=r"two frames of the animal at t = 3 s \(.*data\[0\] and .*data\[1\]\)"):
        read_tracks(write(tmp_path / "d.wcon", wcon(data, {"t": "s", "x": "mm", "y": "mm"})))
    only_null = [{"id": 1, "t": [None], "x": [[0, 0]], "y": [[0, 1]]}]
    with pytest.raises(SudsDataError, match="no frame with a time"):
        read_tracks(write(tmp_path / "n.wcon", wcon(only_null)))


def test_wcon_head_order(tmp_path: Path) -> None:
    """``head`` "R": the head is the last point, so the frame is reversed; "?" is kept and noted."""
    rec = {"id": 1, "t": [0, 1, 2], "x": [[0, 1, 2]] * 3, "y": [[0, 0, 0]] * 3, "head": ["L", "R", "?"]}
    got = read_tracks(write(tmp_path / "h.wcon", wcon(rec)))
    assert got.points[:, 0, 0].tolist() == [0, 2, 0] and got.points[:, 2, 0].tolist() == [2, 0, 2]
    assert got.notes == ('head "R" (the head is the last point) in 1 frames: their points reversed',
                         'head "?" (not known) in 1 frames: the first point is taken as the head')
    for head, match in (("up", r'data\[0\].head: expected "L", "R" or "\?", got \'up\''),
                        (["R"], r"data\[0\].head: expected one value or 3 \(one per time\), got 1")):
        with pytest.raises(SudsDataError, match=match):
            read_tracks(write(tmp_path / "bad.wcon", wcon(dict(rec, head=head))))


def test_wcon_origins_in_their_own_units_and_the_centroid_read_either_way(tmp_path: Path) -> None:
    """ox/oy in µm under x in mm; cx/cy alone: the origin (tracker-commons), unless the points lie around them."""
    units = {"t": "s", "x": "mm", "y": "mm", "ox": "um", "oy": "um", "cx": "mm", "cy": "mm"}
    rel = {"id": 1, "t": [0, 1], "x": [[-1, 1], [-1, 1]], "y": [[0, 0], [0, 0]]}
    got = read_tracks(write(tmp_path / "o.wcon", wcon(dict(rel, ox=[1000, 2000], oy=500), units)))
    np.testing.assert_allclose(got.points[:, :, 0], [[0, 2], [1, 3]])
    np.testing.assert_allclose(got.points[:, :, 1], 0.5)
    assert got.notes == ()
    got = read_tracks(write(tmp_path / "c.wcon", wcon(dict(rel, cx=[10, 20], cy=[5, 5]), units)))
    np.testing.assert_allclose(got.points[:, :, 0], [[9, 11], [19, 21]])
    assert "relative to the centroid" in got.notes[0]
    absolute = {"id": 1, "t": [0, 1], "x": [[9, 11], [19, 21]], "y": [[5, 5], [5, 5]], "cx": [10, 20], "cy": [5, 5]}
    got = read_tracks(write(tmp_path / "a.wcon", wcon(absolute, units)))
    np.testing.assert_allclose(got.points[:, :, 0], [[9, 11], [19, 21]])
    assert "taken as absolute" in got.notes[0]
    with pytest.raises(SudsDataError, match=r"data\[0\]: `ox` and `oy` go in pairs; got only `ox`"):
        read_tracks(write(tmp_path / "p.wcon", wcon(dict(rel, ox=1), units)))
    with pytest.raises(SudsDataError, match=r"units.ox: expected a length"):
        read_tracks(write(tmp_path / "u.wcon", wcon(dict(rel, ox=1, oy=1), dict(units, ox="s"))))


def test_wcon_several_animals_need_one_named(tmp_path: Path) -> None:
    data = [{"id": 1, "t": [0, 1], "x": [[0, 1]] * 2, "y": [[0, 0]] * 2},
            {"id": "b", "t": 0.5, "x": [5, 6], "y": [0, 0]}]
    f = write(tmp_path / "m.wcon", wcon(data, {"t": "s", "x": "mm", "y": "mm"}))
    with pytest.raises(SudsDataError, match=r"2 animals \(ids 1 \(2 times, 0–1 s\), b \(1 times, 0.5–0.5 s\)\); "
                                            r".*pass --animal ID"):
        read_tracks(f)
    assert read_tracks(f, animal="b").points[0, :, 0].tolist() == [5, 6]
    assert read_tracks(f, animal="1").t.tolist() == [0, 1]
    with pytest.raises(SudsConfigError, match="--animal '2': no such id .* its ids: 1, b"):
        read_tracks(f, animal="2")
    plate = [{"id": k, "t": list(range(k)), "x": [[0, 1]] * k, "y": [[0, 0]] * k} for k in range(1, 16)]
    with pytest.raises(SudsDataError, match=r"15 animals \(ids 15 \(15 times, 0–14 s\), 14 .* 6 \(6 times, 0–5 s\), "
                                            r"and 5 more\)"):
        read_tracks(write(tmp_path / "plate.wcon", wcon(plate, {"t": "s", "x": "mm", "y": "mm"})))
    with pytest.raises(SudsConfigError, match="--animal 'x': a midline csv holds one animal"):
        read_tracks(write(tmp_path / "m.csv", "t,x0,y0\n0,1,2\n"), animal="x")


def test_wcon_archives_and_chunks(tmp_path: Path) -> None:
    """A .wcon.zip of one file is that file; chunks (``files``) are joined from a directory or an archive."""
    import zipfile

    units = {"t": "s", "x": "mm", "y": "mm"}
    one = wcon({"id": 1, "t": [0, 1], "x": [[0, 1]] * 2, "y": [[0, 0]] * 2}, units)
    z = tmp_path / "one.wcon.zip"
    with zipfile.ZipFile(z, "w") as f:
        f.writestr("inside/anything.json", one)
    assert detect_format(z) == "wcon"
    got = read_tracks(z)
    assert got.t.tolist() == [0, 1] and got.units == "mm" and got.notes == ()

    def chunk(k: int, prev: object, nxt: object, unit: str = "mm") -> str:
        return json.dumps({"files": {"this": f"_{k}", "prev": prev, "next": nxt}, "units": dict(units, x=unit, y=unit),
                           "data": {"id": 1, "t": [2 * k, 2 * k + 1], "x": [[k, 1]] * 2, "y": [[0, 0]] * 2}})
    d = tmp_path / "run"
    d.mkdir()
    write(d / "w_0.wcon", chunk(0, None, ["_1", "_2"]))
    write(d / "w_1.wcon", chunk(1, ["_0"], ["_2"]))
    write(d / "w_2.wcon", chunk(2, ["_1", "_0"], [], unit="um"))
    got = read_tracks(d / "w_1.wcon")  # any chunk names them all
    assert got.t.tolist() == [0, 1, 2, 3, 4, 5] and got.units == "m"  # mm and µm chunks: metres
    np.testing.assert_allclose(got.points[:, 0, 0], [0, 0, 1e-3, 1e-3, 2e-6, 2e-6])
    assert got.notes[-1].startswith("3 chunks joined: ")
    (d / "w_2.wcon").unlink()
    with pytest.raises(SudsDataError, match="files: the chunk 'w_2.wcon' it names is not there"):
        read_tracks(d / "w_0.wcon")
    z = tmp_path / "chunks.wcon.zip"
    with zipfile.ZipFile(z, "w") as f:
        f.writestr("w_1.wcon", chunk(1, "_0", None))
        f.writestr("w_0.wcon", chunk(0, [], "_1"))
    assert read_tracks(z).t.tolist() == [0, 1, 2, 3]
    with zipfile.ZipFile(z, "w") as f:
        f.writestr("a.wcon", one)
        f.writestr("b.wcon", one)
    with pytest.raises(SudsDataError, match=r"zip archive of 2 files \(a.wcon, b.wcon\) with no first chunk"):
        read_tracks(z)
    with zipfile.ZipFile(z, "w"):
        pass
    with pytest.raises(SudsDataError, match="zip archive without a file in it"):
        read_tracks(z)
    with zipfile.ZipFile(z, "w") as f:
        f.writestr("a.wcon", one * 50)
    raw = bytearray(z.read_bytes())
    raw[60:90] = b"x" * 30  # inside the compressed member
    z.write_bytes(bytes(raw))
    with pytest.raises(SudsDataError, match="chunks.wcon.zip: damaged zip archive: Bad CRC-32 for file 'a.wcon'"):
        read_tracks(z)
    z.write_bytes(bytes(raw[:40]))
    with pytest.raises(SudsDataError, match="chunks.wcon.zip: damaged zip archive: no zip directory"):
        read_tracks(z)
    bad = write(tmp_path / "this.wcon", json.dumps({"files": {"this": "_9"}, "units": units, "data": []}))
    with pytest.raises(SudsDataError, match="files.this: '_9' is not part of the file name 'this.wcon'"):
        read_tracks(bad)


DLC_CSV = """scorer,DLC_resnet50,DLC_resnet50,DLC_resnet50,DLC_resnet50,DLC_resnet50,DLC_resnet50
bodyparts,snout,snout,snout,tail,tail,tail
coords,x,y,likelihood,x,y,likelihood
0,1.5,2.5,0.99,3.5,4.5,0.98
1,,,0.01,3.0,4.0,0.97
"""


def test_dlc_csv_without_movement(tmp_path: Path) -> None:
    f = write(tmp_path / "fish.csv", DLC_CSV)
    assert detect_format(f) == "dlc"
    got = tr.read_dlc_csv(f)
    assert got.point_names == ("snout", "tail") and got.frame.tolist() == [0, 1] and got.t is None
    np.testing.assert_array_equal(got.points[0], [[1.5, 2.5], [3.5, 4.5]])
    assert np.isnan(got.points[1, 0]).all()
    multi = write(tmp_path / "ma.csv", DLC_CSV.replace("bodyparts", "individuals,fish1\nbodyparts", 1))
    with pytest.raises(SudsConfigError, match="multi-animal DeepLabCut csv needs the `movement` package"):
        tr.read_dlc_csv(multi)


def test_lightningpose_csv_without_movement_reads_as_its_dlc_layout(tmp_path: Path, monkeypatch) -> None:
    """LightningPose writes DeepLabCut's csv layout: without ``movement`` the csv reader takes it."""
    f = write(tmp_path / "lp.csv", DLC_CSV)
    monkeypatch.setattr(tr, "movement_available", lambda: False)
    got = read_tracks(f, "lightningpose")
    assert got.format == "lightningpose" and got.point_names == ("snout", "tail")
    np.testing.assert_array_equal(got.points[0], [[1.5, 2.5], [3.5, 4.5]])


def test_formats_that_need_movement_say_how_to_get_it(  # type: ignore[no-untyped-def]
        tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(tr, "movement_available", lambda: False)
    for name, fmt in (("a.h5", "dlc"), ("a.slp", "sleap"), ("a.h5", "sleap")):
        with pytest.raises(SudsConfigError, match="needs the `movement` package.*pip install movement") as exc:
            read_tracks(write(tmp_path / name, "x"), fmt)
        assert exc.value.code == MISSING_DEPENDENCY
    got = read_tracks(write(tmp_path / "fish.csv", DLC_CSV))  # a DLC csv is read without it
    assert got.format == "dlc"


def test_detect_format(tmp_path: Path) -> None:
    assert detect_format(write(tmp_path / "a.wcon", "{}")) == "wcon"
    assert detect_format(write(tmp_path / "a.csv", "t,x0,y0\n")) == "csv"
    assert detect_format(tmp_path / "a.slp") == "sleap"
    with pytest.raises(SudsConfigError, match="pass --format dlc or --format sleap"):
        detect_format(tmp_path / "a.h5")
    with pytest.raises(SudsConfigError, match=r"extension '\.txt'"):
        detect_format(tmp_path / "a.txt")
