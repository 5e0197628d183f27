"""What the ``suds`` subcommands share: the recording options, the one recording loader, progress.

Every command that reads a recording (identify, score, diagnose) takes the same
options (:func:`add_recording_options`) and loads through :func:`load_recording`,
so the metadata overrides mean the same everywhere; ``info`` shares the bag
argument and its check (:func:`add_bag_argument`, :func:`existing_bag`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.recording import Recording


def add_bag_argument(p: argparse.ArgumentParser, **kwargs: str) -> None:
    """The positional ``bag`` (an ``.mcap`` file or a rosbag2 directory holding one)."""
    kwargs.setdefault("help", "the recording: an .mcap file (or a rosbag2 directory holding one)")
    p.add_argument("bag", **kwargs)  # type: ignore[arg-type]


def add_recording_options(p: argparse.ArgumentParser) -> None:
    """``--system``, ``--actuated``, ``--passive``, ``--gait-hz``: overrides of the bag's metadata."""
    p.add_argument("--system", help="system id (overrides the bag's metadata)")
    p.add_argument("--actuated", help="comma-separated actuated joint names (overrides metadata)")
    p.add_argument("--passive", help="comma-separated passive joint names (overrides metadata)")
    p.add_argument("--gait-hz", type=float, help="nominal gait frequency, Hz (overrides metadata)")


def split_names(text: str | None) -> list[str] | None:
    """``'a, b,'`` → ``['a', 'b']``; None or empty → None (not given)."""
    return [x.strip() for x in text.split(",") if x.strip()] if text else None


def existing_bag(path_text: str) -> Path:
    """The path of a recording argument, checked before anything is read.

    Raises
    ------
    SudsConfigError
        If nothing exists at ``path_text``.
    """
    path = Path(path_text)
    if not path.exists():
        raise SudsConfigError(f"no such file: {str(path)!r}")
    return path


def load_recording(path_text: str, args: argparse.Namespace) -> Recording:
    """Read the recording at ``path_text`` with the overrides of :func:`add_recording_options`."""
    from suds_ros.io.recording_bag import read_recording_report

    path = existing_bag(path_text)
    read = read_recording_report(path, system=args.system, actuated=split_names(args.actuated),
                                 passive=split_names(args.passive))
    if read.warning():
        print(f"WARNING: {read.warning()}", file=sys.stderr)
    rec = read.recording
    if args.gait_hz:
        rec = replace(rec, gait_hz=args.gait_hz)
    return rec


def progress_bar(label: str) -> Callable[[int, int], None] | None:
    """A ``cb(done, total)`` drawing a bar on a terminal's stderr; None when stderr is not a terminal."""
    if not sys.stderr.isatty():
        return None

    def cb(done: int, total: int) -> None:
        frac = done / max(total, 1)
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r{label} [{bar:<30}] {100 * frac:5.1f}%")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()

    return cb
