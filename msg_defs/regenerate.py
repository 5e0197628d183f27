#!/usr/bin/env python3
"""Rebuild the ros2msg schema texts and type hashes in this directory.

Each ``<pkg>__msg__<Type>.msg`` file is the message definition exactly as
rosbag2's MCAP storage writes it into a Schema record: the top type's ``.msg``
text, then for every dependency (depth first, dependencies of each type in
sorted order, each type once) a newline, a line of 80 ``=``, a line
``MSG: <pkg>/<Type>`` and that type's text.  ``type_hashes.txt`` holds one
``<pkg>/msg/<Type> RIHS01_<hex>`` line per type, taken from the ``.json``
type descriptions that rosidl installs next to the ``.msg`` files.

Usage::

    python msg_defs/regenerate.py [SHARE_DIR]

``SHARE_DIR`` is a ROS 2 ``share`` directory holding ``<pkg>/msg/<Type>.msg``
(default: the first ``$AMENT_PREFIX_PATH`` entry that has ``std_msgs``, else
``<sys.prefix>/share``).
"""

from __future__ import annotations

import json
import os
import re
import sys
from pathlib import Path

TYPES = (
    "sensor_msgs/msg/JointState",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/TwistStamped",
    "diagnostic_msgs/msg/DiagnosticArray",
    "rosgraph_msgs/msg/Clock",
    "std_msgs/msg/String",
)
SEPARATOR = "=" * 80
PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 "
    "string wstring".split()
)
_FIELD_TYPE = re.compile(r"^([A-Za-z_][A-Za-z0-9_/]*)")


def find_share() -> Path:
    """Return a ROS 2 share directory that contains the message packages."""
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix and (Path(prefix) / "share" / "std_msgs" / "msg").is_dir():
            return Path(prefix) / "share"
    return Path(sys.prefix) / "share"


def read_msg(share: Path, dep: str) -> str:
    """Text of ``pkg/Type`` (``.msg`` file), unchanged."""
    pkg, name = dep.split("/")
    return (share / pkg / "msg" / f"{name}.msg").read_bytes().decode("utf-8")


def dependencies(pkg: str, text: str) -> list[str]:
    """Sorted ``pkg/Type`` names of the non-primitive field types in ``text``."""
    deps: set[str] = set()
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        match = _FIELD_TYPE.match(line)
        if not match:
            continue
        token = match.group(1)
        if token in PRIMITIVES:
            continue
        parts = token.split("/")
        if len(parts) == 1:
            deps.add("std_msgs/Header" if token == "Header" else f"{pkg}/{token}")
        else:
            deps.add(f"{parts[0]}/{parts[-1]}")
    return sorted(deps)


def full_text(share: Path, type_name: str) -> str:
    """rosbag2-style definition of ``pkg/msg/Type`` with all dependencies appended."""
    pkg, _, name = type_name.split("/")
    seen: set[str] = set()

    def walk(dep: str) -> str:
        text = read_msg(share, dep)
        out = text
        for sub in dependencies(dep.split("/")[0], text):
            if sub not in seen:
                seen.add(sub)
                out += f"\n{SEPARATOR}\nMSG: {sub}\n" + walk(sub)
        return out

    return walk(f"{pkg}/{name}")


def type_hash(share: Path, type_name: str) -> str:
    """RIHS01 hash of ``pkg/msg/Type`` from its installed ``.json`` description."""
    pkg, _, name = type_name.split("/")
    desc = json.loads((share / pkg / "msg" / f"{name}.json").read_text(encoding="utf-8"))
    for entry in desc["type_hashes"]:
        if entry["type_name"] == type_name:
            return str(entry["hash_string"])
    raise KeyError(f"{type_name}: no type hash in {pkg}/msg/{name}.json")


def main(argv: list[str] | None = None) -> int:
    """Write the schema files and ``type_hashes.txt`` next to this script."""
    args = sys.argv[1:] if argv is None else argv
    share = Path(args[0]) if args else find_share()
    out = Path(__file__).resolve().parent
    lines = []
    for type_name in TYPES:
        text = full_text(share, type_name)
        path = out / (type_name.replace("/", "__") + ".msg")
        path.write_bytes(text.encode("utf-8"))
        lines.append(f"{type_name} {type_hash(share, type_name)}\n")
        print(f"wrote {path.name} ({len(text)} chars)")
    (out / "type_hashes.txt").write_text("".join(lines), encoding="utf-8")
    print(f"wrote type_hashes.txt ({len(lines)} types) from {share}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
