"""Every node takes ``--ros-args --params-file FILE``: the shipped config/*.yaml load, a bad value is refused.

Each node is started with its shipped example file, then a second file that changes
one parameter (a later file wins, as in ROS); the node's start-up log shows the
changed value.  A file with a bad value stops the node at start-up (exit 1) with
the parameter's name and the reason.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import stop, wait_for
    from .test_recorder_player import _make_bag
except ImportError:
    from _ros_helpers import stop, wait_for
    from test_recorder_player import _make_bag

from suds_ros.executables import EXECUTABLES

pytestmark = pytest.mark.ros

CONFIG = Path(__file__).resolve().parents[2] / "config"
NODES = ("simulator", "estimator", "predictor", "recorder", "player", "monitor", "foxglove_bridge", "optimizer")


def params_file(path: Path, values: dict[str, str]) -> Path:
    """A ROS parameter file setting ``values`` (YAML text) for every node."""
    lines = ["/**:", "  ros__parameters:", *(f"    {k}: {v}" for k, v in values.items())]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def required(node: str, tmp_path: Path) -> list[str]:
    """``-p`` arguments a node needs besides its file (the bag to write or to play)."""
    if node == "recorder":
        return ["-p", f"output:={tmp_path / 'out.mcap'}"]
    if node == "player":
        bag = tmp_path / "in.mcap"
        if not bag.exists():
            _make_bag(bag, 3)
        return ["-p", f"bag:={bag}", "-p", "loop:=true"]
    return []


def command(node: str, files: list[Path], tmp_path: Path) -> list[str]:
    args = [a for f in files for a in ("--params-file", str(f))]
    return [sys.executable, "-m", EXECUTABLES[node], "--ros-args", *args, *required(node, tmp_path)]


#: node -> (one changed parameter, text its start-up log then shows)
CHANGE = {
    "simulator": ({"rate": "200.0"}, "200 Hz (200 samples/cycle)"),
    "estimator": ({"system": "swimmer9"}, "(from swimmer9)"),
    "predictor": ({"frame_id": "base_link", "depth": "42"}, "frame_id base_link, depth 42"),
    "recorder": ({"topics": "['/robot7/suds/*']"}, "recording ['/robot7/suds/*']"),
    "player": ({"rate": "3.5"}, "at rate 3.5"),
    "monitor": ({"warn": "5.0"}, "warn F > 5,"),
    "foxglove_bridge": ({"port": "0"}, "on ws://127.0.0.1:"),
    "optimizer": ({"objective": "turn", "budget_cycles": "77"}, "optimising turn of purcell3: budget 77 cycles"),
}
#: node -> (a bad value, the parameter name and reason the node stops with)
BAD = {
    "simulator": ({"noise": "-1.0"}, ("noise", "range")),
    "estimator": ({"forgetting": "0.0"}, ("`forgetting`", "(0, 1]")),
    "predictor": ({"executor": "threads"}, ("`executor`", "'events' or 'single'")),
    "recorder": ({"compression": "gzip"}, ("compression", "gzip")),
    "player": ({"rate": "-2.0"}, ("rate", "range")),
    "monitor": ({"warn": "0.5"}, ("warn", "range")),
    "foxglove_bridge": ({"port": "70000"}, ("port", "range")),
    "optimizer": ({"objective": "fastest"}, ("objective", "efficiency")),
}


def test_every_node_has_a_shipped_file():
    assert {p.stem for p in CONFIG.glob("*.yaml")} == set(NODES)


@pytest.mark.parametrize("node", NODES)
def test_shipped_file_loads_and_a_file_value_takes_effect(node, start_process, tmp_path):
    values, shown = CHANGE[node]
    change = params_file(tmp_path / "change.yaml", values)
    proc = start_process(command(node, [CONFIG / f"{node}.yaml", change], tmp_path), node)
    wait_for(lambda: shown in proc.output() or proc.poll() is not None, 60,
             lambda: f"{shown!r} in the {node}'s log\n{proc.output()}")
    assert shown in proc.output(), proc.output()
    assert stop(proc) == 0, proc.output()


@pytest.mark.parametrize("node", NODES)
def test_bad_value_in_a_file_is_refused_at_start(node, start_process, tmp_path):
    values, expected = BAD[node]
    bad = params_file(tmp_path / "bad.yaml", values)
    proc = start_process(command(node, [CONFIG / f"{node}.yaml", bad], tmp_path), node)
    assert proc.wait(60) == 1, proc.output()
    out = proc.output()
    assert f"ERROR: {node}:" in out, out
    for text in expected:
        assert text in out, out
