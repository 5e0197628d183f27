"""The launch file parses and takes the pipeline supervisor's arguments (``launch`` is not installed here).

The launch file is read with :mod:`ast` only: its ``ARGUMENTS`` table is compared
with the supervisor's command-line options, one row per option.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from suds_ros.ros.pipeline import parse_args

LAUNCH = Path(__file__).resolve().parents[2] / "launch" / "suds_pipeline.launch.py"

#: supervisor option (argparse dest) -> launch argument, or None with the reason it has none
SUPERVISOR_TO_LAUNCH = {
    "namespace": "namespace",
    "system": "system",
    "model": "model",
    "cycles": "cycles",
    "rate": "rate",
    "seed": "seed",
    "realtime_factor": "realtime_factor",
    "output": "output",
    "overwrite": "overwrite",
    "foxglove": "foxglove",
    "optimize": "optimize",
    "optimize_budget": "optimize_budget",
    "nodes": None,          # launch: comment nodes out / use conditions
    "drain": None,          # launch stops with Ctrl-C, no supervisor timing
    "score": None,          # scoring is `suds score BAG` after a launch
    "stop_timeout": None,   # launch's own shutdown handling
    "ros_args": None,       # launch: `ros2 launch ... --ros-args` / per-node arguments
}
#: launch arguments the supervisor derives itself (from the system or model file)
LAUNCH_ONLY = {"actuated", "passive"}


def launch_arguments() -> dict[str, tuple[str, str]]:
    """The ``ARGUMENTS`` table of the launch file, read with ast."""
    tree = ast.parse(LAUNCH.read_text(encoding="utf-8"), filename=str(LAUNCH))
    for node in tree.body:
        if isinstance(node, ast.Assign) and [t.id for t in node.targets if isinstance(t, ast.Name)] == ["ARGUMENTS"]:
            return ast.literal_eval(node.value)
    raise AssertionError(f"{LAUNCH}: no ARGUMENTS table")


def test_launch_file_compiles():
    compile(LAUNCH.read_text(encoding="utf-8"), str(LAUNCH), "exec")
    tree = ast.parse(LAUNCH.read_text(encoding="utf-8"))
    names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert "generate_launch_description" in names


def test_every_supervisor_option_is_in_the_table():
    dests = set(vars(parse_args([])))
    assert dests == set(SUPERVISOR_TO_LAUNCH), "update SUPERVISOR_TO_LAUNCH for the supervisor's options"


@pytest.mark.parametrize(("option", "launch_name"), sorted(SUPERVISOR_TO_LAUNCH.items()))
def test_option_matches_a_launch_argument(option, launch_name):
    args = launch_arguments()
    if launch_name is None:
        assert option not in args
        return
    assert launch_name in args, f"supervisor --{option.replace('_', '-')} has no launch argument"
    default = getattr(parse_args([]), option)
    launch_default = args[launch_name][0]
    if default not in (None, False):  # the supervisor's unset options take the node defaults
        assert str(default) == launch_default, (option, default, launch_default)


def test_no_unknown_launch_argument():
    extra = set(launch_arguments()) - {v for v in SUPERVISOR_TO_LAUNCH.values() if v} - LAUNCH_ONLY
    assert not extra, f"launch arguments without a supervisor option: {sorted(extra)}"


def test_namespace_reaches_every_node():
    argv = parse_args(["--namespace", "/robot1", "--output", "x.mcap"])
    from suds_ros.ros.pipeline import build_commands

    for name, cmd in build_commands(argv).items():
        assert "__ns:=/robot1" in cmd, (name, cmd)


@pytest.mark.parametrize("bad", ["robot1", "/robot 1", "/1robot", "/robot1/"])
def test_bad_namespace_is_refused(bad, capsys):
    with pytest.raises(SystemExit):
        parse_args(["--namespace", bad])
    assert "--namespace" in capsys.readouterr().err
