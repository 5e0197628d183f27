"""Locate and load the ros2msg schema texts and RIHS01 type hashes in ``msg_defs/``.

The texts are the MCAP Schema data that rosbag2 writes for each message type
(top type, then its dependencies after ``=====`` separator lines); they are
produced by ``msg_defs/regenerate.py``.  They are searched, in order, in

1. the directory named by the environment variable ``SUDS_MSG_DEFS``;
2. ``msg_defs/`` of the source tree (``../../msg_defs`` from this module);
3. ``share/suds_ros/msg_defs/`` of an installed package (colcon / pip prefix,
   found by walking up from this module, then under ``sys.prefix``);
4. ``_msg_defs/`` next to this module (package-data copy).
"""

from __future__ import annotations

import os
import sys
from functools import lru_cache
from pathlib import Path

from suds_ros.core.errors import SudsBagError

#: File listing ``pkg/msg/Type RIHS01_...`` lines.
HASHES_FILE = "type_hashes.txt"


def _candidates() -> list[Path]:
    here = Path(__file__).resolve().parent
    out: list[Path] = []
    env = os.environ.get("SUDS_MSG_DEFS")
    if env:
        out.append(Path(env))
    out.append(here.parents[1] / "msg_defs")
    out.extend(p / "share" / "suds_ros" / "msg_defs" for p in here.parents)
    out.append(Path(sys.prefix) / "share" / "suds_ros" / "msg_defs")
    out.append(here / "_msg_defs")
    return out


@lru_cache(maxsize=1)
def msg_defs_dir() -> Path:
    """Directory holding the schema files and ``type_hashes.txt``.

    Raises
    ------
    SudsBagError
        If no candidate directory holds ``type_hashes.txt``.
    """
    tried = _candidates()
    for path in tried:
        if (path / HASHES_FILE).is_file():
            return path
    msg = "cannot find the msg_defs directory (ros2msg schemas); looked in " + ", ".join(
        str(p) for p in tried
    )
    raise SudsBagError(msg)


@lru_cache(maxsize=1)
def type_hashes() -> dict[str, str]:
    """RIHS01 type hash of every known type, keyed by ``pkg/msg/Type``."""
    out: dict[str, str] = {}
    for line in (msg_defs_dir() / HASHES_FILE).read_text(encoding="utf-8").splitlines():
        parts = line.split()
        if len(parts) == 2:
            out[parts[0]] = parts[1]
    return out


def known_types() -> tuple[str, ...]:
    """Type names (``pkg/msg/Type``) for which a schema is available."""
    return tuple(sorted(type_hashes()))


def _check(type_name: str) -> None:
    if type_name not in type_hashes():
        msg = (
            f"message type {type_name!r} has no schema in {msg_defs_dir()}; "
            f"known types: {', '.join(known_types())}"
        )
        raise SudsBagError(msg)


@lru_cache(maxsize=None)
def schema_text(type_name: str) -> str:
    """ros2msg definition text (with dependencies) of ``type_name``.

    Parameters
    ----------
    type_name : str
        Type like ``'sensor_msgs/msg/JointState'``.

    Raises
    ------
    SudsBagError
        If the type is not one of :func:`known_types`.
    """
    _check(type_name)
    path = msg_defs_dir() / (type_name.replace("/", "__") + ".msg")
    try:
        return path.read_bytes().decode("utf-8")
    except OSError as exc:
        msg = f"cannot read the schema of {type_name!r} from {path}: {exc.strerror}"
        raise SudsBagError(msg) from None


def type_hash(type_name: str) -> str:
    """RIHS01 hash string of ``type_name`` (e.g. ``'RIHS01_a13e...'``)."""
    _check(type_name)
    return type_hashes()[type_name]
