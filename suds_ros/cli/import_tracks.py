"""``suds import``: a tracked animal (midlines or keypoints per video frame) → a recording and a model file.

The tracker file is read (:mod:`suds_ros.io.tracks`), lengths and times are put in SI units, the
frames the tracker lost are dropped and reported, an N-link chain is fitted to every other frame
(:mod:`suds_ros.core.midline`), and two files are written: the recording (``-o``, the joint angles
on ``/suds/shape`` and the body link's centre frame on ``/suds/body_pose``, stamped with the
file's own frame times) and beside it a ``suds-robot/1`` model file (mean link lengths, joint
roles, the gait frequency and drive seen in the data), ready for ``suds identify --model``.
"""

from __future__ import annotations

import argparse
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from suds_ros.core.errors import EXISTS, TOO_LITTLE_DATA, SudsConfigError, SudsDataError
from suds_ros.core.json_text import dumps

EPILOG = """\
examples:
  suds import worm.wcon -o worm.mcap --links 10                  # WCON: units and times in the file
  suds import plate.wcon.zip -o worm.mcap --links 10 --animal 7  # one worm of a multi-worm archive
  suds import midline.csv -o fish.mcap --links 6 --units px --px-size 2.5e-4
  suds import tracks.csv -o eel.mcap --links 4 --units mm --fps 50 --passive joint_3,joint_4
  suds import fish_dlc.h5 --format dlc -o fish.mcap --links 4 --units px --px-size 1e-4 --fps 100
  suds import larva.csv -o larva.mcap --links 5 --units mm --segment amplitude:0.15   # swims in bouts

Midline CSV layout: a header row, then one row per frame: `t` (s) or `frame` (with --fps), then
x0,y0,x1,y1,... head (first point) to tail.  Empty or `nan` cells mark a lost point; a frame with
a lost point is dropped (and reported), never filled in.  `#` lines are comments.

The chain: the midline is cut into N links of equal arc length (or --fractions: relative link
lengths head to tail); with exactly N+1 points per frame the points are the joints.  Joint j
joins links j and j+1, r_j = θ_{j+1} − θ_j; the pose is the body link's centre, x along the link
towards the head.  Coordinates are taken as given: image axes (y down) mirror the animal and
flip the sign of every angle.

Written: the recording (-o) and, beside it, FILE.yaml (suds-robot/1): mean link lengths,
every joint actuated except --passive (these get a placeholder stiffness: edit it), drag
c∥ = 1, c⊥ = 2 (nominal), gait_hz from the dominant frequency of the joint angles, and each
actuated joint's drive fitted at that frequency.  DeepLabCut .h5 and SLEAP files need the
optional `movement` package (pip install movement); a LightningPose .csv (--format
lightningpose) and a DeepLabCut .csv are read through it when it is installed, else directly.

Intermittent motion (--segment MEASURE:THRESH): activity is measured at every kept frame over a
centred window of one gait cycle, and a bout is a run of frames at or above THRESH lasting at
least --min-bout-cycles gait cycles (default 2):
  speed:THRESH      body speed, body lengths per second (the body link's centre, displacement
                    across the window / its duration / the chain's length)
  amplitude:THRESH  joint-angle amplitude, rad (largest over joints of √2 × the windowed SD)
The bouts are reported (count, times, cycles each) and listed in the recording's metadata
(key `bouts`); `suds identify` then trains and tests on whole bouts.
"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``import`` on the ``suds`` subcommand parser."""
    p = subparsers.add_parser("import", help="tracked midlines/keypoints of an animal → recording + model file",
                              description=__doc__.splitlines()[0], epilog=EPILOG,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", metavar="FILE",
                   help="tracker file: .csv (midline, DeepLabCut or LightningPose), .wcon, .h5 (DeepLabCut or SLEAP), "
                        ".slp")
    p.add_argument("-o", "--output", required=True, metavar="REC.mcap",
                   help="output recording; the model file is written beside it as REC.yaml "
                        "(neither is overwritten without --overwrite)")
    p.add_argument("--links", type=int, required=True, metavar="N", help="links of the fitted chain (≥ 2)")
    p.add_argument("--body-link", type=int, metavar="K",
                   help="link (1-based, head first) carrying the recorded pose (default the middle, ⌈N/2⌉)")
    p.add_argument("--format", choices=("wcon", "csv", "dlc", "sleap", "lightningpose"),
                   help="file format (default from the file name)")
    p.add_argument("--units", choices=("m", "mm", "um", "px"),
                   help="length unit of the coordinates (required unless the file states it, as WCON does)")
    p.add_argument("--px-size", type=float, metavar="M", help="metres per pixel (with --units px)")
    p.add_argument("--fps", type=float, metavar="F",
                   help="frames per second, for files with frame numbers instead of times")
    p.add_argument("--keep-head-tail", action="store_true",
                   help="take each frame's head as the tracker gave it (default: frames whose head and tail the "
                        "tracker swapped, against the frames next to them, are reversed and reported)")
    p.add_argument("--animal", metavar="ID",
                   help="the animal to import from a file of several: a WCON id, or a DeepLabCut / SLEAP / "
                        "LightningPose individual (a file of several without it is refused, with their names)")
    p.add_argument("--passive", metavar="J,...",
                   help="passive joints: names (joint_3) or numbers (3), comma-separated; the rest are actuated")
    p.add_argument("--fractions", metavar="a,b,...",
                   help="relative link lengths head to tail, N numbers (default equal)")
    p.add_argument("--gait-hz", type=float, metavar="HZ",
                   help="gait frequency, Hz (default: the dominant frequency of the joint angles)")
    p.add_argument("--segment", metavar="MEASURE:THRESH",
                   help="find bouts of steady motion: speed:THRESH (body lengths/s) or amplitude:THRESH "
                        "(rad); listed in the recording for `suds identify` (see below)")
    p.add_argument("--min-bout-cycles", type=float, default=2.0, metavar="C",
                   help="with --segment: shortest bout kept, gait cycles (default 2)")
    p.add_argument("--name", help="system id in the recording and the model file (default from -o)")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.add_argument("--json", action="store_true", help="machine-readable summary")
    p.set_defaults(func=run)


def model_path_for(output: Path) -> Path:
    """The model file written beside the recording ``output``: same stem, ``.yaml``."""
    return output.with_suffix(".yaml")


def _system_name(args: argparse.Namespace, out: Path) -> str:
    if args.name is not None:
        if not re.fullmatch(r"[A-Za-z0-9_-]+", args.name):
            raise SudsConfigError(f"--name: expected letters, digits, `_` and `-`, got {args.name!r}")
        return str(args.name)
    return re.sub(r"[^A-Za-z0-9_-]", "_", out.stem) or "animal"


def _numbers(option: str, text: str) -> list[float]:
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise SudsConfigError(f"{option}: expected comma-separated numbers, got {text!r}") from None


def _passive(text: str | None, names: tuple[str, ...]) -> list[str]:
    """Joint names of ``--passive`` (names or 1-based numbers)."""
    if not text:
        return []
    out = []
    for item in (x.strip() for x in text.split(",") if x.strip()):
        name = f"joint_{item}" if item.isdigit() else item
        if name not in names:
            raise SudsConfigError(f"--passive: {item!r} is not a joint; expected names among "
                                  f"{', '.join(names)} (or numbers 1..{len(names)})")
        out.append(name)
    if len(set(out)) == len(names):
        raise SudsConfigError("--passive: every joint named; at least one joint must be actuated")
    return [n for n in names if n in out]  # head to tail


def _metres_per_unit(args: argparse.Namespace, file_units: str | None, source: str) -> float:
    """Metres per coordinate unit from the file's unit and ``--units`` / ``--px-size``."""
    if args.px_size is not None and args.units != "px":
        raise SudsConfigError(f"--px-size: only with --units px (got --units {args.units})")
    if file_units is not None:
        if args.units is not None and args.units != file_units:
            raise SudsConfigError(f"--units {args.units}: the {source} file states its unit, {file_units!r}")
        from suds_ros.io.tracks import wcon_unit

        return wcon_unit(file_units)[0]
    if args.units is None:
        raise SudsConfigError(f"--units: the {source} file does not state its length unit; pass "
                              "--units m|mm|um, or --units px --px-size M")
    if args.units == "px":
        if args.px_size is None or not (math.isfinite(args.px_size) and args.px_size > 0):
            raise SudsConfigError(f"--px-size: expected metres per pixel > 0 with --units px, got {args.px_size}")
        return float(args.px_size)
    from suds_ros.io.tracks import wcon_unit

    return wcon_unit(args.units)[0]


def _times(args: argparse.Namespace, tracks: Any, path: Path) -> np.ndarray:
    """Frame times in s: the file's own, or frame numbers / ``--fps``; checked increasing."""
    from suds_ros.io.tracks import NON_MONOTONIC_TIME

    if tracks.t is not None:
        if args.fps is not None:
            raise SudsConfigError(f"--fps: the {tracks.format} file has its own frame times; --fps is "
                                  "for files with frame numbers")
        t = np.asarray(tracks.t, dtype=float)
        what = "time"
    else:
        if args.fps is None or not (math.isfinite(args.fps) and args.fps > 0):
            raise SudsConfigError(f"--fps: the {tracks.format} file has frame numbers, not times; pass "
                                  f"--fps F > 0 (got {args.fps})")
        t = np.asarray(tracks.frame, dtype=float) / args.fps
        what = "frame number"
    bad = ~np.isfinite(t)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise SudsDataError(f"{path}: row {k}: {what} is not a number", code=NON_MONOTONIC_TIME)
    d = np.diff(t)
    if np.any(d <= 0):
        k = int(np.flatnonzero(d <= 0)[0])
        kind = "repeats" if d[k] == 0 else "goes back"
        raise SudsDataError(f"{path}: {what} {kind} at row {k + 1} ({t[k + 1]:.6g} s after {t[k]:.6g} s): "
                            "expected strictly increasing frame times", code=NON_MONOTONIC_TIME)
    if t.size and t[0] < 0:
        raise SudsDataError(f"{path}: negative frame time {t[0]:.6g} s at row 0: expected times ≥ 0",
                            code=NON_MONOTONIC_TIME)
    return t


def _runs(mask: np.ndarray, t: np.ndarray, frame: np.ndarray | None) -> list[dict[str, Any]]:
    from suds_ros.core.midline import lost_runs

    ids = np.arange(t.size) if frame is None else frame
    return [{"first_frame": int(ids[a]), "last_frame": int(ids[b]), "frames": int(b - a + 1),
             "t_first": float(t[a]), "t_last": float(t[b])} for a, b in lost_runs(mask)]


def _gaps(t: np.ndarray, frame: np.ndarray | None) -> list[dict[str, Any]]:
    """Frames absent from the file (numbering jumps, or intervals > 1.5 × the median)."""
    from suds_ros.core.midline import frame_gaps, time_gaps

    if frame is not None:
        return [{"first_frame": a, "last_frame": b, "frames": b - a + 1} for a, b in frame_gaps(frame)]
    dt = float(np.median(np.diff(t))) if t.size > 2 else 0.0
    return [{"after_t": a, "before_t": b, "frames": max(int(round((b - a) / dt)) - 1, 1)}
            for _, a, b in time_gaps(t)]


def _head_tail(tracks: Any, keep: np.ndarray, tk: np.ndarray, t: np.ndarray, fix: bool
               ) -> tuple[np.ndarray, dict[str, Any]]:
    """The kept frames' points, those the tracker gave tail first reversed (``fix``), and what was found."""
    from suds_ros.core.midline import head_tail_swaps

    pts = np.array(tracks.points[keep], dtype=float)
    found = head_tail_swaps(pts, tk)
    if fix:
        counts = tracks.counts[keep] if tracks.counts is not None else None
        for i in np.flatnonzero(found.swapped):
            c = pts.shape[1] if counts is None else int(counts[i])  # a shorter midline: its own points only
            pts[i, :c] = pts[i, :c][::-1].copy()
            pts[i, c:] = pts[i, c - 1]
    mask = np.zeros(keep.size, dtype=bool)
    mask[np.flatnonzero(keep)[found.swapped]] = True
    return pts, {"swapped": int(found.swapped.sum()), "runs": _runs(mask, t, tracks.frame),
                 "reversed": bool(fix), "unlinked": found.unlinked, "linked_runs": int(found.runs[-1]) + 1}


def _model(name: str, lengths: np.ndarray, joint_names: tuple[str, ...], passive: list[str],
           body_link: int, gait_hz: float, drive: np.ndarray) -> Any:
    """The ``ChainModel`` written beside the recording (nominal drag, placeholder springs)."""
    from suds_ros.core.physics.rft import ChainModel

    nj = len(joint_names)
    actuated = tuple(j for j in range(nj) if joint_names[j] not in passive)
    # placeholder spring of a passive joint: relaxes against one link's rotational drag
    # (c⊥ L³/12, c⊥ = 2) at the gait's angular frequency; identify or edit it
    k = 2 * math.pi * gait_hz * 2.0 * float(np.mean(lengths)) ** 3 / 12.0
    stiffness = tuple(0.0 if j in actuated else k for j in range(nj))
    gait = tuple((float(drive[j, 0]), 1.0, float(drive[j, 1]), float(drive[j, 2])) for j in actuated)
    return ChainModel(n_links=lengths.size, actuated=actuated, stiffness=stiffness,
                      link_length=tuple(float(v) for v in lengths), body_link=body_link, name=name,
                      gait=gait, joint_names=joint_names, gait_hz=gait_hz)


def _segment(rule: Any, t: np.ndarray, fit: Any, gait_hz: float, src: Path
             ) -> tuple[list[tuple[float, float]], dict[str, Any]]:
    """Bouts of ``--segment`` on the kept frames, and their summary; none found is an error."""
    from suds_ros.core.bouts import MEASURES, segment_bouts

    length = float(np.sum(fit.mean_lengths))
    bouts, activity = segment_bouts(rule, t, fit.r, fit.pose, gait_hz, length)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    unit = MEASURES[rule.measure]
    if not bouts:
        raise SudsDataError(f"{src}: --segment {rule.measure}:{rule.threshold:g}: no bout of at least "
                            f"{rule.min_cycles:g} gait cycles ({rule.min_cycles / gait_hz:.3g} s at {gait_hz:.4g} Hz) "
                            f"with {rule.measure} ≥ {rule.threshold:g} {unit}; the {rule.measure} ranges "
                            f"{float(np.min(activity)):.3g} … {float(np.max(activity)):.3g} {unit} "
                            f"(median {float(np.median(activity)):.3g})", code=TOO_LITTLE_DATA)
    rows = []
    for a, b in bouts:
        frames = int(np.count_nonzero((t >= a) & (t <= b)))
        rows.append({"t_first": a, "t_last": b, "frames": frames, "cycles": (b - a + dt) * gait_hz})
    return bouts, {"measure": rule.measure, "threshold": rule.threshold, "unit": unit,
                   "min_cycles": rule.min_cycles, "bouts": rows,
                   "steady_cycles": sum(r["cycles"] for r in rows),
                   "total_cycles": (float(t[-1] - t[0]) + dt) * gait_hz}


def run(args: argparse.Namespace) -> int:
    """Execute ``suds import``; returns the exit code."""
    import yaml

    from suds_ros.core.midline import dominant_frequency, fit_chain, fit_gait, lost_frames, max_links
    from suds_ros.core.midline import NO_MIDLINE, TOO_FEW_POINTS
    from suds_ros.core.physics.robot_model import dump_model, model_from_dict
    from suds_ros.core.recording import joint_names as default_joint_names
    from suds_ros.io.recording_bag import RecordingWriter
    from suds_ros.io.tracks import read_tracks

    src = Path(args.file)
    if not src.is_file():
        raise SudsConfigError(f"no such file: {str(src)!r}")
    out = Path(args.output)
    model_out = model_path_for(out)
    if out.suffix.lower() != ".mcap":
        raise SudsConfigError(f"-o {str(out)!r}: expected a .mcap file name")
    for path in (out, model_out):
        if path.exists() and not args.overwrite:
            raise SudsConfigError(f"output {str(path)!r} exists; pass --overwrite to replace it", code=EXISTS)
    n = args.links
    if n < 2:
        raise SudsConfigError(f"--links: expected a number of links ≥ 2, got {n}")
    body = (n + 1) // 2 if args.body_link is None else args.body_link
    if not 1 <= body <= n:
        raise SudsConfigError(f"--body-link: expected a link 1..{n}, got {body}")
    fractions = _numbers("--fractions", args.fractions) if args.fractions else None
    if fractions is not None and len(fractions) != n:
        raise SudsConfigError(f"--fractions: expected {n} relative link lengths (one per link), "
                              f"got {len(fractions)}")
    rule = None
    if args.segment is not None:
        from suds_ros.core.bouts import BoutRule

        if not (math.isfinite(args.min_bout_cycles) and args.min_bout_cycles > 0):
            raise SudsConfigError(f"--min-bout-cycles: expected a number of cycles > 0, got {args.min_bout_cycles}")
        rule = BoutRule.parse(args.segment, args.min_bout_cycles)
    names = default_joint_names(n - 1)
    passive = _passive(args.passive, names)
    name = _system_name(args, out)

    tracks = read_tracks(src, args.format, args.animal)
    scale = _metres_per_unit(args, tracks.units, tracks.format)
    t = _times(args, tracks, src)
    if tracks.n_points < n + 1:
        raise SudsDataError(f"{src}: {n} links need at least {n + 1} points per frame; the file has "
                            f"{tracks.n_points} ({', '.join(tracks.point_names)}), enough for at most "
                            f"{max_links(tracks.n_points)} links: pass --links {max_links(tracks.n_points)} "
                            "or fewer", code=TOO_FEW_POINTS)
    lost = lost_frames(tracks.points)
    if tracks.counts is not None:
        lost |= tracks.counts < n + 1
    keep = ~lost
    if not np.any(keep):
        raise SudsDataError(f"{src}: every one of the {tracks.n_frames} frames is lost (NaN or no points): "
                            "no midline to import", code=NO_MIDLINE)
    tk = t[keep]
    pts, head_tail = _head_tail(tracks, keep, tk, t, fix=not args.keep_head_tail)
    fit = fit_chain(pts * scale, n, body - 1, fractions)
    if args.gait_hz is not None:
        if not (math.isfinite(args.gait_hz) and args.gait_hz > 0):
            raise SudsConfigError(f"--gait-hz: expected a frequency > 0 Hz, got {args.gait_hz}")
        gait_hz = float(args.gait_hz)
    else:
        if tk.size < 8:
            raise SudsDataError(f"{src}: {tk.size} frames kept: too few to estimate the gait frequency; "
                                "pass --gait-hz", code=TOO_LITTLE_DATA)
        found = dominant_frequency(tk, fit.r)
        if found is None:
            raise SudsDataError(f"{src}: the joint angles do not change: no gait frequency to estimate; "
                                "pass --gait-hz", code=NO_MIDLINE)
        gait_hz = found
    drive = fit_gait(tk, fit.r, gait_hz)
    lengths = fit.mean_lengths
    model = _model(name, lengths, names, passive, body - 1, gait_hz, drive)
    text = dump_model(model)
    model_from_dict(yaml.safe_load(text), str(model_out))  # the file must load as it is written

    actuated = [j for j in names if j not in passive]
    bouts: list[tuple[float, float]] = []
    segment = None
    if rule is not None:
        bouts, segment = _segment(rule, tk, fit, gait_hz, src)
    try:
        with RecordingWriter(out, system=name, joint_names=names, actuated=actuated, passive=passive,
                             gait_hz=gait_hz, bouts=bouts, overwrite=args.overwrite) as writer:
            writer.write(tk, fit.r, tk, fit.pose)
        model_out.write_text(text, encoding="utf-8")
    except BaseException:
        out.unlink(missing_ok=True)  # no half import
        raise

    summary = {
        "input": str(src), "format": tracks.format, "frames": tracks.n_frames, "kept": int(keep.sum()),
        "lost": {"frames": int(lost.sum()), "runs": _runs(lost, t, tracks.frame)},
        "missing": _gaps(t, tracks.frame),
        "points": tracks.n_points, "max_links": max_links(tracks.n_points), "links": n, "body_link": body,
        "metres_per_unit": scale, "link_lengths_m": [float(v) for v in lengths],
        "gait_hz": gait_hz, "t_first": float(tk[0]), "t_last": float(tk[-1]),
        "system": name, "actuated": actuated, "passive": passive,
        "recording": str(out), "model": str(model_out), "notes": list(tracks.notes),
    }
    if args.animal is not None:
        summary["animal"] = args.animal
    summary["head_tail"] = head_tail
    if segment is not None:
        summary["segment"] = segment
    if args.json:
        print(dumps(summary, indent=2))
    else:
        print(_describe(summary))
    return 0


def _describe(s: dict[str, Any]) -> str:
    """What ``suds import`` prints."""
    lines = [f"{s['input']}: {s['format']}" + (f", animal {s['animal']}" if "animal" in s else "")
             + f", {s['frames']} frames, {s['points']} points per frame (enough for up to {s['max_links']} links)",
             *(f"note: {n}" for n in s["notes"]),
             f"kept {s['kept']} frames ({s['t_first']:.6g} … {s['t_last']:.6g} s); "
             f"lost {s['lost']['frames']} (dropped, not filled in)"]
    for run in s["lost"]["runs"][:10]:
        lines.append(f"  lost frames {run['first_frame']}–{run['last_frame']} "
                     f"({run['t_first']:.6g} … {run['t_last']:.6g} s)")
    if len(s["lost"]["runs"]) > 10:
        lines.append(f"  … {len(s['lost']['runs']) - 10} more runs (see --json)")
    h = s["head_tail"]
    if h["swapped"]:
        lines.append(f"head–tail: {h['swapped']} frames in {len(h['runs'])} runs given tail first against the frames "
                     "next to them; " + ("reversed" if h["reversed"] else "kept as given (--keep-head-tail)"))
        for run in h["runs"][:10]:
            lines.append(f"  tail first: frames {run['first_frame']}–{run['last_frame']} "
                         f"({run['t_first']:.6g} … {run['t_last']:.6g} s)")
        if len(h["runs"]) > 10:
            lines.append(f"  … {len(h['runs']) - 10} more runs (see --json)")
    if h["unlinked"]:
        lines.append(f"head–tail: at {h['unlinked']} frames the midline read the same either way round (a curled "
                     f"body); the {h['linked_runs']} stretches between them keep the tracker's heads")
    if s["missing"]:
        total = sum(g["frames"] for g in s["missing"])
        lines.append(f"absent from the file: about {total} frames in {len(s['missing'])} gaps")
    lengths = ", ".join(f"{v * 1e3:.4g}" for v in s["link_lengths_m"])
    lines.append(f"chain: {s['links']} links (mm, head to tail: {lengths}), body link {s['body_link']}")
    lines.append(f"gait {s['gait_hz']:.4g} Hz; actuated {', '.join(s['actuated'])}"
                 + (f"; passive {', '.join(s['passive'])} (placeholder stiffness in the model file)"
                    if s["passive"] else ""))
    if "segment" in s:
        g = s["segment"]
        lines.append(f"bouts ({g['measure']} ≥ {g['threshold']:g} {g['unit']}, ≥ {g['min_cycles']:g} cycles): "
                     f"{len(g['bouts'])}, {g['steady_cycles']:.1f} cycles of {g['total_cycles']:.1f}")
        for k, b in enumerate(g["bouts"][:20]):
            lines.append(f"  bout {k + 1}: {b['t_first']:.6g} … {b['t_last']:.6g} s, {b['cycles']:.1f} cycles, "
                         f"{b['frames']} frames")
        if len(g["bouts"]) > 20:
            lines.append(f"  … {len(g['bouts']) - 20} more bouts (see --json)")
    lines.append(f"wrote {s['recording']} (system {s['system']!r}) and {s['model']}")
    return "\n".join(lines)
