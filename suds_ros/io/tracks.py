"""Tracker files of filmed animals → per-frame points (``suds import``).

Five formats, each read into one :class:`Tracks` (points per frame, head first;
times or frame numbers; the file's length unit when it states one):

``csv``
    The project's plain layout: a header row, then one row per frame.  One time
    column, ``t`` (seconds) or ``frame`` (an integer frame number; give ``--fps``),
    then ``x0,y0,x1,y1,…`` head to tail.  An empty cell or ``nan`` is a lost point;
    lines starting with ``#`` are comments.  Any other column is an error.
``wcon``
    The Worm tracker Commons Object Notation (openworm/tracker-commons), read with
    :mod:`json` as its specification says: ``units`` (``t``, ``x``, ``y``) and
    ``data``, one record or a list of records with ``id``, ``t``, ``x``, ``y`` and
    optionally ``ox``, ``oy`` offsets.  One animal (one ``id``) per file; records of
    that id are joined in file order; ``null`` or empty coordinates are lost.
``dlc``
    DeepLabCut's ``.h5`` or ``.csv`` (header rows scorer / bodyparts / coords
    x, y, likelihood).  Read through the ``movement`` package when it is installed; a
    single-animal ``.csv`` is also read without it (the :mod:`csv` module).  Body parts
    in the file's order are taken as head to tail.
``sleap``
    SLEAP ``.slp`` or analysis ``.h5``, through ``movement`` only.
``lightningpose``
    LightningPose's predictions ``.csv`` (DeepLabCut's csv layout, one animal), through
    ``movement``'s LightningPose reader when it is installed, else the same :mod:`csv` reader
    as a DeepLabCut ``.csv``.  Only ``--format`` selects it: by its name and first cell the
    file is a DeepLabCut csv, which reads it the same way.

``movement`` (and with it pandas, xarray, h5py) is an optional dependency: it is
imported only when a DeepLabCut ``.h5`` or a SLEAP file is read, and its absence
is one error telling the user to install it.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from suds_ros.core.errors import SudsConfigError, SudsDataError

FORMATS = ("csv", "wcon", "dlc", "sleap", "lightningpose")

#: error codes of this module
BAD_TRACK_FILE = "bad_track_file"
MISSING_DEPENDENCY = "missing_dependency"
NON_MONOTONIC_TIME = "non_monotonic_time"

_MOVEMENT_HINT = ("pip install movement (or install suds_ros with the `tracking` extra: "
                  "pip install 'suds_ros[tracking]')")


@dataclass(frozen=True)
class Tracks:
    """Tracked points of one animal, one row per frame, as the file holds them.

    Attributes
    ----------
    points : (n, P, 2) float
        x, y per point, head first, in the file's length unit; NaN where the tracker lost it.
    t : (n,) float or None
        Frame times, s (None when the file has frame numbers only).
    frame : (n,) int or None
        Frame numbers, when the file has them.
    units : str or None
        The file's length unit (``mm`` …), None when the file does not say (pixels, usually).
    format : str
        One of :data:`FORMATS`.
    point_names : tuple of str
        Names of the P points (keypoints), or ``p0`` … for a midline.
    counts : (n,) int or None
        Points the file gives for each frame when it varies (WCON); shorter frames are padded
        with their last point.
    """

    points: np.ndarray
    t: np.ndarray | None
    frame: np.ndarray | None
    units: str | None
    format: str
    point_names: tuple[str, ...]
    counts: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        """Frames (rows) in the file."""
        return int(self.points.shape[0])

    @property
    def n_points(self) -> int:
        """Points per frame P."""
        return int(self.points.shape[1])


def _fail(path: Path, what: str) -> SudsDataError:
    return SudsDataError(f"{path}: {what}", code=BAD_TRACK_FILE)


def detect_format(path: str | Path) -> str:
    """The format of ``path`` from its name (and, for ``.csv``, its first cell).

    Raises
    ------
    SudsConfigError
        An extension no reader knows, or an ``.h5`` (DeepLabCut or SLEAP: ``--format`` says which).
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext in (".wcon", ".json"):
        return "wcon"
    if ext == ".slp":
        return "sleap"
    if ext == ".csv":
        with p.open(newline="", encoding="utf-8-sig") as f:
            first = next(csv.reader(f), [""])
        return "dlc" if first and first[0].strip().lower() == "scorer" else "csv"
    if ext in (".h5", ".hdf5"):
        raise SudsConfigError(f"{p}: an .h5 file may be DeepLabCut or SLEAP: pass --format dlc or "
                              "--format sleap")
    raise SudsConfigError(f"{p}: cannot tell the format from the extension {ext or '(none)'!r}: "
                          f"pass --format ({', '.join(FORMATS)})")


def read_tracks(path: str | Path, fmt: str | None = None) -> Tracks:
    """Read a tracker file.

    Parameters
    ----------
    path : str or Path
        The file.
    fmt : str, optional
        One of :data:`FORMATS`; default from the file name (:func:`detect_format`).

    Raises
    ------
    SudsConfigError
        Unknown format, or ``movement`` missing for a file that needs it (code
        ``missing_dependency``).
    SudsDataError
        (code ``bad_track_file``) A file that does not follow its format.
    """
    p = Path(path)
    fmt = fmt or detect_format(p)
    if fmt not in FORMATS:
        raise SudsConfigError(f"--format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
    try:
        if fmt == "csv":
            return read_midline_csv(p)
        if fmt == "wcon":
            return read_wcon(p)
        if fmt in ("dlc", "lightningpose") and p.suffix.lower() == ".csv" and not movement_available():
            return read_dlc_csv(p, fmt)
        return read_with_movement(p, fmt)
    except UnicodeDecodeError:
        raise _fail(p, f"not a {fmt} file (not text)") from None


# ------------------------------------------------------------------ csv
def _cell(text: str) -> float:
    text = text.strip()
    if not text or text.lower() in ("nan", "na", "null", "none"):
        return math.nan
    return float(text)


def read_midline_csv(path: Path) -> Tracks:
    """The project's midline CSV (module docstring): ``t`` or ``frame``, then ``x0,y0,x1,y1,…``."""
    with path.open(newline="", encoding="utf-8-sig") as f:
        rows = [row for row in csv.reader(f) if row and not row[0].lstrip().startswith("#")]
    if not rows:
        raise _fail(path, "no header row (expected t or frame, then x0,y0,x1,y1,...)")
    header = [h.strip() for h in rows[0]]
    time_col = header[0] if header else ""
    if time_col not in ("t", "frame"):
        raise _fail(path, f"first column: expected `t` (s) or `frame`, got {time_col!r}")
    coords = header[1:]
    n_pts = len(coords) // 2
    expected = [f"{c}{k}" for k in range(n_pts) for c in ("x", "y")]
    if len(coords) % 2 or coords != expected:
        bad = next((h for h, e in zip(coords, expected + [""] * len(coords)) if h != e), coords[-1:])
        raise _fail(path, f"header: expected {time_col}, then x0,y0,x1,y1,... in order, got column "
                          f"{bad!r} in {','.join(header)}")
    if n_pts == 0:
        raise _fail(path, "header: no x0,y0 columns: the file holds no midline")
    data = np.full((len(rows) - 1, 1 + 2 * n_pts), math.nan)
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise _fail(path, f"row {i + 1}: expected {len(header)} cells, got {len(row)}")
        try:
            data[i] = [_cell(c) for c in row]
        except ValueError:
            raise _fail(path, f"row {i + 1}: expected numbers, got {row!r}") from None
    pts = data[:, 1:].reshape(-1, n_pts, 2)
    names = tuple(f"p{k}" for k in range(n_pts))
    if time_col == "t":
        return Tracks(pts, data[:, 0], None, None, "csv", names)
    frame = data[:, 0]
    if not np.all(np.isfinite(frame)) or np.any(frame != np.round(frame)):
        k = int(np.flatnonzero(~np.isfinite(frame) | (frame != np.round(frame)))[0])
        raise _fail(path, f"row {k + 1}: `frame` expected an integer, got {frame[k]!r}")
    return Tracks(pts, None, frame.astype(np.int64), None, "csv", names)


# ------------------------------------------------------------------ wcon
#: WCON unit grammar (tracker-commons ``WCON_format.md``, "Units"): SI prefixes, full or abbreviated
_PREFIX_WORDS = {"centi": 1e-2, "milli": 1e-3, "micro": 1e-6, "nano": 1e-9, "kilo": 1e3, "mega": 1e6, "giga": 1e9}
_PREFIX_ABBREVIATIONS = {"c": 1e-2, "m": 1e-3, "u": 1e-6, "\u00b5": 1e-6, "\u03bc": 1e-6, "n": 1e-9, "k": 1e3,
                         "M": 1e6, "G": 1e9}
#: units of length (L, metres) and time (T, seconds): full words (plural allowed) and abbreviations
_UNIT_WORDS = {"metre": (1.0, "L"), "meter": (1.0, "L"), "inch": (0.0254, "L"), "micron": (1e-6, "L"),
               "second": (1.0, "T"), "minute": (60.0, "T"), "hour": (3600.0, "T"), "day": (86400.0, "T")}
_UNIT_ABBREVIATIONS = {"m": (1.0, "L"), "in": (0.0254, "L"), "s": (1.0, "T"), "sec": (1.0, "T"),
                       "min": (60.0, "T"), "h": (3600.0, "T"), "hr": (3600.0, "T"), "d": (86400.0, "T")}


def _unit_word(word: str) -> tuple[float, str] | None:
    """One unit symbol or word, with an optional SI prefix (never a full prefix on an abbreviation)."""
    if word in _UNIT_ABBREVIATIONS:  # "min" is a minute, "m" a metre: no prefix read first
        return _UNIT_ABBREVIATIONS[word]
    singular = [word] + ([word[:-2]] if word.endswith("es") else []) + ([word[:-1]] if word.endswith("s") else [])
    for w in singular:
        if w in _UNIT_WORDS:
            return _UNIT_WORDS[w]
        for prefix, factor in _PREFIX_WORDS.items():
            if w.startswith(prefix) and w[len(prefix):] in _UNIT_WORDS:
                scale, dim = _UNIT_WORDS[w[len(prefix):]]
                return factor * scale, dim
    for prefix, factor in _PREFIX_ABBREVIATIONS.items():
        if word.startswith(prefix) and word[len(prefix):] in _UNIT_ABBREVIATIONS:
            scale, dim = _UNIT_ABBREVIATIONS[word[len(prefix):]]
            return factor * scale, dim
    return None


def wcon_unit(expr: str) -> tuple[float, dict[str, int]]:
    """A WCON unit expression → (SI factor, dimension exponents ``{"L": …, "T": …}``).

    Follows the tracker-commons specification: SI prefixes (``milli``/``m``, ``micro``/``u``/``µ``
    …) on metres, inches, microns, seconds, minutes, hours and days, full words (singular or
    plural; metre or meter) or abbreviations, never mixed; ``*``, ``/`` and integer ``^`` powers;
    numeric factors (``"0.04*s"``: frame numbers at 25 fps).  ``""`` and ``"1"`` are dimensionless.

    Raises
    ------
    ValueError
        The expression does not follow that grammar (the message names the part).
    """
    text = expr.strip()
    scale, dims = 1.0, {"L": 0, "T": 0}
    if text in ("", "1"):
        return scale, dims
    tokens = text.replace("/", " / ").replace("*", " * ").split()
    sign = 1
    expect_term = True
    for tok in tokens:
        if tok in ("*", "/"):
            if expect_term:
                raise ValueError(f"an operator where a unit or number was expected in {expr!r}")
            sign = 1 if tok == "*" else -1
            expect_term = True
            continue
        if not expect_term:
            raise ValueError(f"{tok!r} follows a unit without * or / in {expr!r}")
        base, _, power_text = tok.partition("^")
        try:
            power = int(power_text) if power_text else 1
        except ValueError:
            raise ValueError(f"power {power_text!r}: expected an integer in {expr!r}") from None
        try:
            factor = float(base)
        except ValueError:
            unit = _unit_word(base)
            if unit is None:
                raise ValueError(f"unknown unit {base!r} in {expr!r}") from None
            factor, dim = unit
            dims[dim] += sign * power
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"factor {base!r}: expected a positive number in {expr!r}")
        scale *= factor ** (sign * power)
        expect_term = False
    if expect_term:
        raise ValueError(f"{expr!r} ends with an operator")
    return scale, dims


def _unit(path: Path, units: dict[str, Any], key: str, dim: str) -> float:
    """SI factor of ``units[key]``, which must be a length (``dim`` "L") or a time ("T")."""
    u = units.get(key)
    kind = {"L": "a length (m, mm, um, micrometers, ...)", "T": "a time (s, ms, seconds, 0.04*s, ...)"}[dim]
    if not isinstance(u, str):
        raise _fail(path, f"units.{key}: expected {kind}, got {u!r}")
    try:
        scale, dims = wcon_unit(u)
    except ValueError as exc:
        raise _fail(path, f"units.{key}: expected {kind}, got {u!r}: {exc}") from None
    if dims != {"L": int(dim == "L"), "T": int(dim == "T")}:
        raise _fail(path, f"units.{key}: expected {kind}, got {u!r}")
    return scale


def _series(path: Path, where: str, value: Any, n: int) -> list[Any]:
    """A per-time list of length n (a scalar or flat list for one time is wrapped)."""
    if n == 1 and not (isinstance(value, list) and value and isinstance(value[0], list)):
        return [value]
    if not isinstance(value, list) or len(value) != n:
        raise _fail(path, f"{where}: expected {n} entries (one per time), got "
                          f"{len(value) if isinstance(value, list) else value!r}")
    return value


def _numbers(value: Any) -> np.ndarray:
    """A list of numbers (null → NaN) as floats; a scalar → one value; None → empty."""
    if value is None:
        return np.empty(0)
    if not isinstance(value, list):
        value = [value]
    return np.array([math.nan if v is None else float(v) for v in value], dtype=float)


def read_wcon(path: Path) -> Tracks:
    """A WCON file with :mod:`json` (tracker-commons specification); times and lengths in SI later."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise _fail(path, f"not WCON: invalid JSON (line {exc.lineno}: {exc.msg})") from None
    if not isinstance(doc, dict) or "units" not in doc or "data" not in doc:
        raise _fail(path, "not WCON: expected a JSON object with `units` and `data`")
    units = doc["units"]
    if not isinstance(units, dict):
        raise _fail(path, f"units: expected an object, got {units!r}")
    t_scale = _unit(path, units, "t", "T")
    scale = _unit(path, units, "x", "L")
    if not math.isclose(_unit(path, units, "y", "L"), scale, rel_tol=1e-12):
        raise _fail(path, f"units: x in {units['x']!r} but y in {units['y']!r}; expected one length unit")
    records = doc["data"] if isinstance(doc["data"], list) else [doc["data"]]
    ids = []
    for k, rec in enumerate(records):
        if not isinstance(rec, dict) or not {"id", "t", "x", "y"} <= set(rec):
            raise _fail(path, f"data[{k}]: expected a record with id, t, x, y")
        if rec["id"] not in ids:
            ids.append(rec["id"])
    if len(ids) != 1:
        raise _fail(path, f"data: {len(ids)} animals (ids {', '.join(map(str, ids))}); "
                          "suds import takes a file of one animal")
    times: list[float] = []
    frames: list[np.ndarray] = []
    for k, rec in enumerate(records):
        t = rec["t"] if isinstance(rec["t"], list) else [rec["t"]]
        n = len(t)
        xs, ys = (_series(path, f"data[{k}].{c}", rec[c], n) for c in ("x", "y"))
        offs = [_series(path, f"data[{k}].{c}", rec.get(c, 0.0), n) if isinstance(rec.get(c, 0.0), list)
                else [rec.get(c, 0.0)] * n for c in ("ox", "oy")]
        for i in range(n):
            x, y = _numbers(xs[i]), _numbers(ys[i])
            if x.size != y.size:
                raise _fail(path, f"data[{k}] time {i}: x has {x.size} values, y {y.size}")
            ox, oy = (math.nan if o[i] is None else float(o[i]) for o in offs)
            frames.append(np.column_stack([x + ox, y + oy]))
            times.append(math.nan if t[i] is None else float(t[i]))
    counts = np.array([f.shape[0] for f in frames], dtype=np.int64)
    p = int(counts.max()) if counts.size else 0
    if p == 0:
        raise _fail(path, "data: no x, y points at any time: no midline")
    pts = np.full((len(frames), p, 2), math.nan)
    for i, f in enumerate(frames):
        if f.shape[0]:
            pts[i, :f.shape[0]] = f
            pts[i, f.shape[0]:] = f[-1]  # shorter midline: its tail repeated (no length added)
        # a time with no points stays NaN: lost
    t_s = np.asarray(times) * t_scale
    unit = next((u for u, v in (("m", 1.0), ("mm", 1e-3), ("um", 1e-6)) if math.isclose(v, scale, rel_tol=1e-12)),
                None)
    if unit is None:  # another length unit (inches, 12*in, ...): the points in metres
        pts, unit = pts * scale, "m"
    varied = counts if np.any(counts[counts > 0] != p) else None
    return Tracks(pts, t_s, None, unit, "wcon", tuple(f"p{k}" for k in range(p)), varied)


# ------------------------------------------------------------------ DeepLabCut csv
def read_dlc_csv(path: Path, fmt: str = "dlc") -> Tracks:
    """A single-animal DeepLabCut ``.csv`` with the :mod:`csv` module (no ``movement`` needed).

    Header rows ``scorer``, ``bodyparts``, ``coords`` (x, y, likelihood per body part); then one
    row per frame, its frame number first.  LightningPose writes the same layout (``fmt``
    "lightningpose" is recorded in the result).
    """
    with path.open(newline="", encoding="utf-8-sig") as f:
        rows = list(csv.reader(f))
    heads = [r[0].strip().lower() if r else "" for r in rows[:4]]
    if heads[:1] != ["scorer"]:
        raise _fail(path, "not a DeepLabCut csv: first cell is not `scorer`")
    if "individuals" in heads:
        raise SudsConfigError(f"{path}: a multi-animal DeepLabCut csv needs the `movement` package: "
                              f"{_MOVEMENT_HINT}", code=MISSING_DEPENDENCY)
    if heads[1:3] != ["bodyparts", "coords"]:
        raise _fail(path, "DeepLabCut csv: expected header rows scorer, bodyparts, coords")
    parts, coords = rows[1][1:], [c.strip() for c in rows[2][1:]]
    names: list[str] = []
    cols: dict[tuple[str, str], int] = {}
    for c, (part, coord) in enumerate(zip(parts, coords)):
        if part not in names:
            names.append(part)
        cols[(part, coord)] = c + 1
    missing = [f"{p}.{c}" for p in names for c in ("x", "y") if (p, c) not in cols]
    if missing or not names:
        raise _fail(path, f"DeepLabCut csv: no x, y columns for {', '.join(missing) or 'any body part'}")
    body = [r for r in rows[3:] if r]
    pts = np.full((len(body), len(names), 2), math.nan)
    frame = np.empty(len(body), dtype=np.int64)
    for i, row in enumerate(body):
        try:
            frame[i] = int(float(row[0]))
            for k, part in enumerate(names):
                pts[i, k] = (_cell(row[cols[(part, "x")]]), _cell(row[cols[(part, "y")]]))
        except (ValueError, IndexError):
            raise _fail(path, f"DeepLabCut csv: data row {i}: expected a frame number and numbers, "
                              f"got {row[:4]!r}...") from None
    return Tracks(pts, None, frame, None, fmt, tuple(names))


# ------------------------------------------------------------------ movement (DLC .h5, SLEAP)
def movement_available() -> bool:
    """True when the optional ``movement`` package can be imported."""
    import importlib.util

    return importlib.util.find_spec("movement") is not None


def read_with_movement(path: Path, fmt: str) -> Tracks:
    """A DeepLabCut, SLEAP or LightningPose file through ``movement.io.load_poses`` (one animal).

    Raises
    ------
    SudsConfigError
        (code ``missing_dependency``) ``movement`` is not installed.
    SudsDataError
        (code ``bad_track_file``) ``movement`` cannot read the file, or it holds several animals.
    """
    if not movement_available():
        kind = {"dlc": "DeepLabCut", "sleap": "SLEAP", "lightningpose": "LightningPose"}[fmt]
        raise SudsConfigError(f"{path}: reading {kind} files needs the `movement` package, which is not "
                              f"installed: {_MOVEMENT_HINT}", code=MISSING_DEPENDENCY)
    from movement.io import load_poses  # optional dependency, imported only here

    try:
        read = {"dlc": load_poses.from_dlc_file, "sleap": load_poses.from_sleap_file,
                "lightningpose": load_poses.from_lp_file}[fmt]
        ds = read(path)
    except Exception as exc:  # movement raises its own and pandas'/h5py's errors: name the file
        raise _fail(path, f"movement cannot read it as {fmt}: {type(exc).__name__}: {exc}") from None
    pos = ds["position"]
    individuals = [str(v) for v in pos.coords["individuals"].values]
    if len(individuals) != 1:
        raise _fail(path, f"{len(individuals)} animals ({', '.join(individuals)}); suds import takes "
                          "a file of one animal")
    arr = pos.transpose("time", "individuals", "keypoints", "space").values[:, 0]
    names = tuple(str(v) for v in pos.coords["keypoints"].values)
    time = np.asarray(pos.coords["time"].values, dtype=float)
    frame = np.round(time).astype(np.int64)  # no fps given: movement's time is the frame number
    return Tracks(np.asarray(arr[..., :2], dtype=float), None, frame, None, fmt, names)
