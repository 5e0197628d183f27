"""The import rules of docs/architecture.md: each room imports only rooms further in."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "suds_ros"

#: room → rooms of ours it must not import
FORBIDDEN = {
    "core": ("suds_ros.io", "suds_ros.report", "suds_ros.cli", "suds_ros.ros"),
    "io": ("suds_ros.report", "suds_ros.cli", "suds_ros.ros"),
    "report": ("suds_ros.cli", "suds_ros.ros"),
    "ros": ("suds_ros.cli",),
}


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append(node.module)
    return out


@pytest.mark.parametrize("room", sorted(FORBIDDEN))
def test_rooms_import_only_inward(room: str) -> None:
    bad = []
    for path in sorted((PKG / room).rglob("*.py")):
        for mod in _imports(path):
            if mod.startswith(FORBIDDEN[room]):
                bad.append(f"{path.relative_to(PKG.parent)} imports {mod}")
    assert not bad, "\n".join(bad)


def test_no_node_imports_another_node() -> None:
    bad = []
    for path in sorted((PKG / "ros").glob("*_node.py")):
        for mod in _imports(path):
            if mod.startswith("suds_ros.ros.") and mod.endswith("_node"):
                bad.append(f"{path.name} imports {mod}")
    assert not bad, "\n".join(bad)


def test_the_check_sees_a_forbidden_import(tmp_path: Path) -> None:
    f = tmp_path / "x.py"
    f.write_text("from suds_ros.ros.qos import MODEL_QOS\nimport suds_ros.io.mcap\n")
    assert _imports(f) == ["suds_ros.ros.qos", "suds_ros.io.mcap"]


#: rooms inside core → the rooms of core they may import (besides core's top-level modules)
CORE_ALLOWED = {
    "diagnosis": ("ident", "phase", "physics"),
    "ident": ("phase",),
    "phase": (),
    "physics": (),
    "optimize": ("ident", "phase", "physics"),  # data-driven steps fit the SUDS model
}


def _core_room_violations() -> list[str]:
    bad = []
    for room, allowed in CORE_ALLOWED.items():
        for path in sorted((PKG / "core" / room).rglob("*.py")):
            for mod in _imports(path):
                parts = mod.split(".")
                if parts[:2] != ["suds_ros", "core"] or len(parts) < 3 or parts[2] == room:
                    continue
                if (PKG / "core" / parts[2]).is_dir() and parts[2] not in allowed:
                    bad.append(f"{path.relative_to(PKG.parent)} imports {mod}")
    return bad


def test_rooms_inside_core_import_only_inward() -> None:
    """diagnosis → ident, phase, physics; ident → phase; phase and physics → core's top level only."""
    bad = _core_room_violations()
    assert not bad, "\n".join(bad)


def test_the_core_rooms_are_the_ones_the_rule_names() -> None:
    rooms = {p.name for p in (PKG / "core").iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert rooms == set(CORE_ALLOWED)
