"""What the ``suds`` subcommands share: the recording options, the one recording loader, progress.

Every command that reads a recording (identify, score, diagnose) takes the same
options (:func:`add_recording_options`) and loads through :func:`load_recording`,
so the metadata overrides mean the same everywhere; ``info`` shares the bag
argument and its check (:func:`add_bag_argument`, :func:`existing_bag`).
``--model FILE`` (or ``--system`` given a path) names a robot model file: its
name is the system id, and the recording's joints and roles are checked against
it (:func:`load_recording_and_model` also returns the model).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from typing import TYPE_CHECKING

from suds_ros.core.errors import MISSING_JOINT_ROLES, SudsBagError, SudsConfigError
from suds_ros.core.recording import Recording

if TYPE_CHECKING:
    from suds_ros.core.physics.rft import ChainModel


def add_bag_argument(p: argparse.ArgumentParser, **kwargs: str) -> None:
    """The positional ``bag`` (an ``.mcap`` file or a rosbag2 directory holding one)."""
    kwargs.setdefault("help", "the recording: an .mcap file (or a rosbag2 directory holding one)")
    p.add_argument("bag", **kwargs)  # type: ignore[arg-type]


def add_recording_options(p: argparse.ArgumentParser) -> None:
    """Add the recording options to ``p``.

    ``--system``, ``--model``, ``--actuated``, ``--passive``, ``--gait-hz``: overrides of the bag's
    metadata; ``--namespace``: which robot's topics to read.
    """
    p.add_argument("--system", help="system id (overrides the bag's metadata); a path means --model")
    p.add_argument("--model", metavar="FILE",
                   help="robot model file (suds-robot/1): its name is the system id; the recording's "
                        "joint names and actuated/passive split must match it")
    p.add_argument("--actuated", help="comma-separated actuated joint names (overrides metadata)")
    p.add_argument("--passive", help="comma-separated passive joint names (overrides metadata)")
    p.add_argument("--gait-hz", type=float, help="nominal gait frequency, Hz (overrides metadata)")
    p.add_argument("--namespace", default="", metavar="NS",
                   help="the robot's ROS namespace in a bag of several robots (e.g. /robot1: topics "
                        "/robot1/suds/shape, ...; its system from /robot1/suds/system if recorded)")


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


def model_path(args: argparse.Namespace) -> str | None:
    """Return the robot model file named by ``--model`` (or by ``--system`` given a path), or None.

    Raises
    ------
    SudsConfigError
        When both ``--model`` and ``--system`` are given.
    """
    from suds_ros.core.physics.systems import is_model_file

    path, system = getattr(args, "model", None), getattr(args, "system", None)
    if path and system:
        raise SudsConfigError(f"--model {path!r} and --system {system!r}: give one of them "
                              "(the model file's name is the system id)")
    if system and is_model_file(system):
        return str(system)
    return str(path) if path else None


def load_model_argument(args: argparse.Namespace) -> ChainModel | None:
    """Load the :class:`ChainModel` of :func:`model_path`'s file; None when no model file is named."""
    from suds_ros.core.physics.robot_model import load_model

    path = model_path(args)
    return None if path is None else load_model(path)


def load_recording_and_model(path_text: str, args: argparse.Namespace
                             ) -> tuple[Recording, ChainModel | None]:
    """Read the recording with the overrides of :func:`add_recording_options`, and the model file if any.

    With a model file: the system id is the model's name; the joint roles come from the bag's
    metadata (or ``--actuated``/``--passive``), else from the model; ``gait_hz`` from
    ``--gait-hz``, else the metadata, else the model's; and the recording's joint names, order
    and roles must match the model's.

    Raises
    ------
    SudsConfigError
        (code ``model_mismatch``) listing how the recording's joints differ from the model's;
        (code ``bad_model_file``) for a model file that does not follow ``suds-robot/1``.
    """
    from suds_ros.core.physics.robot_model import check_recording

    model = load_model_argument(args)  # a bad model file is reported before the bag is read
    path = existing_bag(path_text)
    system = model.name if model is not None else args.system
    actuated, passive = split_names(args.actuated), split_names(args.passive)
    ns = getattr(args, "namespace", "")
    try:
        rec = _read(path, system=system, actuated=actuated, passive=passive, namespace=ns)
    except SudsBagError as exc:
        if model is None or exc.code != MISSING_JOINT_ROLES:
            raise
        rec = _with_model_roles(_read(path, system=system, passive=(), namespace=ns), model, model_path(args))
    gait_hz = args.gait_hz or rec.gait_hz or (model.gait_hz if model is not None else None)
    if gait_hz != rec.gait_hz:
        rec = replace(rec, gait_hz=gait_hz)
    if model is not None:
        check_recording(rec, model, source=model_path(args))
    return rec, model


def _with_model_roles(rec: Recording, model: ChainModel, source: str | None) -> Recording:
    """``rec`` (read without roles) with the model's actuated/passive split.

    Raises
    ------
    SudsConfigError
        (code ``model_mismatch``) when the joint names or their order differ from the model's.
    """
    from suds_ros.core.physics.robot_model import check_joints

    names = model.joint_names
    actuated = tuple(names[i] for i in model.actuated if names[i] in rec.joint_names)
    check_joints(model, rec.joint_names, actuated, source=source)
    return replace(rec, actuated=actuated, passive=tuple(n for n in rec.joint_names if n not in actuated))


def load_recording(path_text: str, args: argparse.Namespace) -> Recording:
    """Read the recording at ``path_text`` with the overrides of :func:`add_recording_options`."""
    return load_recording_and_model(path_text, args)[0]


def _read(path: Path, **overrides: object) -> Recording:
    """Read a recording; damage that was skipped is reported as one ``WARNING:`` line on stderr."""
    from suds_ros.io.recording_bag import read_recording_report

    read = read_recording_report(path, **overrides)  # type: ignore[arg-type]
    if read.warning():
        print(f"WARNING: {read.warning()}", file=sys.stderr)
    return read.recording


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
