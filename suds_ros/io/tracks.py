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
    ``data``, one record or a list of records with ``id``, ``t``, ``x``, ``y``; also
    ``ox``, ``oy`` origins (or ``cx``, ``cy``), each in its own unit, and ``head`` ("R":
    the head is the last point).  A ``.zip`` archive (``.wcon.zip``) and an experiment
    split into chunks (``files``) are read whole.  One animal: the only ``id``, or the
    one ``--animal`` names; its records are joined in time order; ``null`` or empty
    coordinates are lost.
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
import zipfile
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

#: animals listed (the most often seen first) when a file of several is given without ``--animal``
LIST_ANIMALS = 10

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
    notes : tuple of str
        What the reader did that the user should know (a WCON head order reversed, frames
        without a time dropped, chunks joined ...).
    """

    points: np.ndarray
    t: np.ndarray | None
    frame: np.ndarray | None
    units: str | None
    format: str
    point_names: tuple[str, ...]
    counts: np.ndarray | None = None
    notes: tuple[str, ...] = ()

    @property
    def n_frames(self) -> int:
        """Frames (rows) in the file."""
        return int(self.points.shape[0])

    @property
    def n_points(self) -> int:
        """Points per frame P."""
        return int(self.points.shape[1])


def _fail(path: Path | str, what: str) -> SudsDataError:
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
    if ext in (".wcon", ".json") or ext == ".zip":  # tracker-commons archives: .wcon.zip
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


def read_tracks(path: str | Path, fmt: str | None = None, animal: str | None = None) -> Tracks:
    """Read a tracker file.

    Parameters
    ----------
    path : str or Path
        The file.
    fmt : str, optional
        One of :data:`FORMATS`; default from the file name (:func:`detect_format`).
    animal : str, optional
        The animal to read from a file of several (a WCON ``id``, an ``individuals`` name of
        DeepLabCut, SLEAP or LightningPose); a file of several without it is an error that
        lists them.

    Raises
    ------
    SudsConfigError
        Unknown format, ``movement`` missing for a file that needs it (code
        ``missing_dependency``), or an ``animal`` the file does not hold.
    SudsDataError
        (code ``bad_track_file``) A file that does not follow its format, or holds several
        animals and ``animal`` is not given.
    """
    p = Path(path)
    fmt = fmt or detect_format(p)
    if fmt not in FORMATS:
        raise SudsConfigError(f"--format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
    try:
        if fmt == "csv":
            if animal is not None:
                raise SudsConfigError(f"--animal {animal!r}: a midline csv holds one animal, without a name")
            return read_midline_csv(p)
        if fmt == "wcon":
            return read_wcon(p, animal)
        if fmt in ("dlc", "lightningpose") and p.suffix.lower() == ".csv" and not movement_available():
            if animal is not None:
                raise SudsConfigError(f"--animal {animal!r}: choosing an animal of a DeepLabCut csv needs the "
                                      f"`movement` package: {_MOVEMENT_HINT}", code=MISSING_DEPENDENCY)
            return read_dlc_csv(p, fmt)
        return read_with_movement(p, fmt, animal)
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


def _unit(path: Path | str, units: dict[str, Any], key: str, dim: str) -> float:
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


def _series(path: Path | str, where: str, value: Any, n: int) -> list[Any]:
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


def _links(where: str, value: Any) -> list[str]:
    """``files.prev`` / ``files.next``: null, empty, one string or a list of strings (nulls skipped)."""
    if value is None:
        return []
    items = value if isinstance(value, list) else [value]
    if not all(v is None or isinstance(v, str) for v in items):
        raise ValueError(f"{where}: expected a string, a list of strings or null, got {value!r}")
    return [v for v in items if v]


def chunk_names(name: str, files: Any) -> list[str]:
    """The file names of a chunked WCON experiment in temporal order, from one chunk's ``files``.

    tracker-commons: the last occurrence of ``files.this`` in ``name`` is replaced by each of
    ``prev`` (reverse temporal order) and ``next`` (temporal order).

    Raises
    ------
    ValueError
        ``files`` does not follow that form (the message names the key).
    """
    if not isinstance(files, dict):
        raise ValueError(f"files: expected an object with this, prev, next, got {files!r}")
    this = files.get("this")
    if not isinstance(this, str) or not this:
        raise ValueError(f"files.this: expected the variable part of the file name, got {this!r}")
    at = name.rfind(this)
    if at < 0:
        raise ValueError(f"files.this: {this!r} is not part of the file name {name!r}")
    other = [name[:at] + s + name[at + len(this):] for s in
             list(reversed(_links("files.prev", files.get("prev")))) + [this]
             + _links("files.next", files.get("next"))]
    if len(set(other)) != len(other):
        raise ValueError(f"files: a chunk is named twice ({', '.join(other)})")
    return other


def _load_json(where: str, raw: bytes) -> Any:
    try:
        return json.loads(raw.decode("utf-8-sig"))
    except UnicodeDecodeError:
        raise _fail(where, "not WCON (not UTF-8 text)") from None
    except json.JSONDecodeError as exc:
        raise _fail(where, f"not WCON: invalid JSON (line {exc.lineno}: {exc.msg})") from None


def wcon_documents(path: Path) -> list[tuple[str, Any]]:
    """The WCON objects of ``path`` in temporal order, each with the name errors give it.

    ``path`` is a WCON file or a zip archive of them (tracker-commons: ``.wcon.zip``; an archive
    of one file is that file; of several, the chunk without a ``prev`` starts).  A file with a
    ``files`` entry is one chunk of an experiment: every chunk it names is read, from the same
    directory or archive.
    """
    members: dict[str, bytes] | None = None  # an archive's files
    if path.suffix.lower() == ".zip" and not zipfile.is_zipfile(path):
        raise _fail(path, "damaged zip archive: no zip directory at its end (truncated?)")
    if zipfile.is_zipfile(path):
        try:
            with zipfile.ZipFile(path) as z:
                members = {i.filename: z.read(i) for i in z.infolist()
                           if not i.is_dir() and not i.filename.startswith("__MACOSX/")
                           and not Path(i.filename).name.startswith("._")}
        except (zipfile.BadZipFile, OSError, RuntimeError) as exc:  # damaged, or encrypted
            raise _fail(path, f"damaged zip archive: {exc}") from None
        if not members:
            raise _fail(path, "zip archive without a file in it: expected a WCON file")

    def label(name: str) -> str:
        return f"{path}!{name}" if members is not None else str(path.parent / name)

    def load(name: str) -> Any:
        if members is not None:
            raw = members.get(name)
        else:
            f = path.parent / name
            raw = f.read_bytes() if f.is_file() else None
        if raw is None:
            where = "in the archive" if members is not None else f"in {path.parent}"
            raise _fail(path, f"files: the chunk {name!r} it names is not there ({where})"
                        if name != path.name else "no such file")
        return _load_json(label(name), raw)

    docs: dict[str, Any] = {}
    if members is None:
        first = path.name
    elif len(members) == 1:
        first = next(iter(members))
    else:
        docs = {name: load(name) for name in members}
        firsts = [name for name, d in docs.items() if isinstance(d, dict) and isinstance(d.get("files"), dict)
                  and not _links("files.prev", d["files"].get("prev"))]
        if len(firsts) != 1:
            raise _fail(path, f"zip archive of {len(members)} files ({', '.join(sorted(members))}) "
                              f"{'with no' if not firsts else 'with ' + str(len(firsts))} first chunk "
                              "(a `files` entry without `prev`): expected one WCON file or the chunks of one "
                              "experiment")
        first = firsts[0]
    doc = docs[first] if first in docs else load(first)
    if not (isinstance(doc, dict) and "files" in doc):
        return [(label(first), doc)]
    try:
        names = chunk_names(first, doc["files"])
    except ValueError as exc:
        raise _fail(path, str(exc)) from None
    return [(label(name), doc if name == first else docs[name] if name in docs else load(name)) for name in names]


def _per_time(where: str, value: Any, n: int) -> list[Any]:
    """A value given once for a record or once per time (``head``, ``ox`` …): n entries."""
    if isinstance(value, list):
        if len(value) != n:
            raise _fail(where, f"expected one value or {n} (one per time), got {len(value)}")
        return value
    return [value] * n


def _origin(where: str, rec: dict[str, Any], n: int, factor: dict[str, float], x: list[np.ndarray],
            y: list[np.ndarray]) -> tuple[list[float], list[float], str | None]:
    """Per time, the origin the record's x, y are relative to (in x's unit), and how it was read.

    ``ox``/``oy`` when given; else ``cx``/``cy`` (tracker-commons: the centroid is then the origin)
    — unless the points already sit around the centroid, as absolute points do: then (0, 0).
    """
    for a, b in (("ox", "oy"), ("cx", "cy")):
        if a in rec or b in rec:
            if not (a in rec and b in rec):
                raise _fail(where, f"`{a}` and `{b}` go in pairs; got only `{a if a in rec else b}`")
            o = [[math.nan if v is None else float(v) * factor[k] for v in _per_time(f"{where}.{k}", rec[k], n)]
                 for k in (a, b)]
            if a == "ox":
                return o[0], o[1], None
            mean = np.array([[np.nanmean(xi), np.nanmean(yi)] if np.any(np.isfinite(xi)) else [math.nan] * 2
                             for xi, yi in zip(x, y)])
            c = np.array(o).T
            off, rel = np.linalg.norm(mean - c, axis=1), np.linalg.norm(mean, axis=1)
            ok = np.isfinite(off) & np.isfinite(rel)
            if ok.any() and np.median(off[ok]) < np.median(rel[ok]):
                return [0.0] * n, [0.0] * n, "absolute"  # the points are around (cx, cy) already
            return o[0], o[1], "relative"
    return [0.0] * n, [0.0] * n, None


def read_wcon(path: Path, animal: str | None = None) -> Tracks:
    """A WCON file, archive or chunked experiment (tracker-commons specification), one animal.

    Records of the animal (``animal``: its ``id``; needed when the file holds several) are joined
    and put in time order.  ``head`` "R" reverses a frame's points (the head is the last point),
    "?" keeps them as given (noted); ``ox``/``oy`` (or ``cx``/``cy``) origins are added, each in
    its own unit.  A time given as ``null`` cannot be placed: its frame is dropped (noted).
    """
    docs = wcon_documents(path)
    frames: list[tuple[float, np.ndarray, float, str]] = []  # (t in s, points, their unit in m, record label)
    seen: dict[str, list[float]] = {}
    notes: list[str] = []
    unknown_head = reversed_head = no_time = 0
    cx_read: set[str] = set()
    scales = set()
    for label, doc in docs:
        if not isinstance(doc, dict) or "units" not in doc or "data" not in doc:
            raise _fail(label, "not WCON: expected a JSON object with `units` and `data`")
        units = doc["units"]
        if not isinstance(units, dict):
            raise _fail(label, f"units: expected an object, got {units!r}")
        t_scale = _unit(label, units, "t", "T")
        scale = _unit(label, units, "x", "L")
        if not math.isclose(_unit(label, units, "y", "L"), scale, rel_tol=1e-12):
            raise _fail(label, f"units: x in {units['x']!r} but y in {units['y']!r}; expected one length unit")
        scales.add(scale)
        factor = {k: (_unit(label, units, k, "L") / scale if k in units else 1.0)
                  for k in ("ox", "oy", "cx", "cy")}
        records = doc["data"] if isinstance(doc["data"], list) else [doc["data"]]
        for k, rec in enumerate(records):
            where = f"data[{k}]"
            if not isinstance(rec, dict) or not {"id", "t", "x", "y"} <= set(rec):
                raise _fail(label, f"{where}: expected a record with id, t, x, y")
            if isinstance(rec["id"], (list, dict)) or rec["id"] is None:
                raise _fail(label, f"{where}.id: expected one number or string, got {rec['id']!r}")
            name = str(rec["id"])
            t = rec["t"] if isinstance(rec["t"], list) else [rec["t"]]
            seen.setdefault(name, []).extend(float(v) * t_scale for v in t if isinstance(v, (int, float)))
            if animal is not None and name != animal:
                continue
            n = len(t)
            xs, ys = (_series(label, f"{where}.{c}", rec[c], n) for c in ("x", "y"))
            try:
                x = [_numbers(v) for v in xs]
                y = [_numbers(v) for v in ys]
            except (TypeError, ValueError):
                raise _fail(label, f"{where}: x and y: expected numbers or null") from None
            for i in range(n):
                if x[i].size != y[i].size:
                    raise _fail(label, f"{where} time {i}: x has {x[i].size} values, y {y[i].size}")
            heads = _per_time(f"{label}: {where}.head", rec.get("head", "L"), n)
            try:
                ox, oy, how = _origin(f"{label}: {where}", rec, n, factor, x, y)
            except SudsDataError:
                raise
            except (TypeError, ValueError):
                raise _fail(label, f"{where}: ox, oy, cx, cy: expected numbers or null") from None
            if how is not None:
                cx_read.add(how)
            for i in range(n):
                if heads[i] not in ("L", "R", "?"):
                    raise _fail(label, f"{where}.head: expected \"L\", \"R\" or \"?\", got {heads[i]!r}")
                if t[i] is None:
                    no_time += 1
                    continue
                if not isinstance(t[i], (int, float)) or isinstance(t[i], bool) or not math.isfinite(t[i]):
                    raise _fail(label, f"{where}.t: expected numbers or null, got {t[i]!r}")
                pts = np.column_stack([x[i] + ox[i], y[i] + oy[i]])
                if heads[i] == "R":
                    pts = pts[::-1]
                    reversed_head += 1
                unknown_head += heads[i] == "?"
                frames.append((float(t[i]) * t_scale, pts, scale, f"{label}: {where}"))
    if animal is not None and animal not in seen:
        raise SudsConfigError(f"--animal {animal!r}: no such id in {path}; its ids: "
                              f"{', '.join(seen) or 'none'}")
    if animal is None and len(seen) > 1:
        most = sorted(seen, key=lambda a: -len(seen[a]))[:LIST_ANIMALS]  # a multi-worm plate has hundreds
        listed = ", ".join(f"{a} ({len(seen[a])} times" + (f", {min(seen[a]):.10g}–{max(seen[a]):.10g} s)"
                                                           if seen[a] else ")") for a in most)
        more = f", and {len(seen) - len(most)} more" if len(seen) > len(most) else ""
        raise _fail(path, f"data: {len(seen)} animals (ids {listed}{more}); suds import takes one: pass --animal ID")
    if not frames:
        raise _fail(path, "data: no frame with a time" if no_time else "data: no x, y points at any time: no midline")
    frames.sort(key=lambda f: f[0])  # records may come in any order (tracker-commons); stable
    for a, b in zip(frames, frames[1:]):
        if a[0] == b[0]:
            raise _fail(path, f"data: two frames of the animal at t = {a[0]:.9g} s ({a[3]} and {b[3]}): "
                              "expected one frame per time")
    counts = np.array([f[1].shape[0] for f in frames], dtype=np.int64)
    p = int(counts.max())
    if p == 0:
        raise _fail(path, "data: no x, y points at any time: no midline")
    one = len(scales) == 1  # points in the file's unit; several chunks in several units: metres
    pts = np.full((len(frames), p, 2), math.nan)
    for i, (_, f, s, _) in enumerate(frames):
        f = f if one else f * s
        if f.shape[0]:
            pts[i, :f.shape[0]] = f
            pts[i, f.shape[0]:] = f[-1]  # shorter midline: its tail repeated (no length added)
        # a time with no points stays NaN: lost
    t_s = np.array([f[0] for f in frames])
    unit = "m"
    if one:
        only = scales.pop()
        unit = next((u for u, v in (("m", 1.0), ("mm", 1e-3), ("um", 1e-6)) if math.isclose(v, only, rel_tol=1e-12)),
                    "")
        if not unit:  # another length unit (inches, 12*in, ...): the points in metres
            pts, unit = pts * only, "m"
    if reversed_head:
        notes.append(f"head \"R\" (the head is the last point) in {reversed_head} frames: their points reversed")
    if unknown_head:
        notes.append(f"head \"?\" (not known) in {unknown_head} frames: the first point is taken as the head")
    if no_time:
        notes.append(f"{no_time} frames with a null time dropped (cannot be placed)")
    if "relative" in cx_read:
        notes.append("cx, cy without ox, oy: the points taken relative to the centroid (tracker-commons)")
    if "absolute" in cx_read:
        notes.append("cx, cy without ox, oy: the points already lie around the centroid, so taken as absolute")
    if len(docs) > 1:
        notes.append(f"{len(docs)} chunks joined: {', '.join(label for label, _ in docs)}")
    varied = counts if np.any(counts[counts > 0] != p) else None
    return Tracks(pts, t_s, None, unit, "wcon", tuple(f"p{k}" for k in range(p)), varied, tuple(notes))


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


def read_with_movement(path: Path, fmt: str, animal: str | None = None) -> Tracks:
    """A DeepLabCut, SLEAP or LightningPose file through ``movement.io.load_poses`` (one animal: ``animal``).

    Raises
    ------
    SudsConfigError
        (code ``missing_dependency``) ``movement`` is not installed.
    SudsConfigError
        (code ``missing_dependency``) ``movement`` is not installed; or no individual is ``animal``.
    SudsDataError
        (code ``bad_track_file``) ``movement`` cannot read the file, or it holds several animals
        and ``animal`` is not given.
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
    arr = pos.transpose("time", "individuals", "keypoints", "space").values
    if animal is not None:
        if animal not in individuals:
            raise SudsConfigError(f"--animal {animal!r}: no such individual in {path}; its individuals: "
                                  f"{', '.join(individuals)}")
        arr = arr[:, individuals.index(animal)]
    elif len(individuals) != 1:
        tracked = np.any(np.isfinite(arr[..., :2]), axis=(2, 3)).sum(axis=0)  # frames with a point, per animal
        listed = ", ".join(f"{a} ({int(c)} frames)" for a, c in zip(individuals, tracked))
        raise _fail(path, f"{len(individuals)} animals ({listed}); suds import takes one: pass --animal NAME")
    else:
        arr = arr[:, 0]
    names = tuple(str(v) for v in pos.coords["keypoints"].values)
    time = np.asarray(pos.coords["time"].values, dtype=float)
    frame = np.round(time).astype(np.int64)  # no fps given: movement's time is the frame number
    return Tracks(np.asarray(arr[..., :2], dtype=float), None, frame, None, fmt, names)
