"""The core and the bag I/O must work without ROS: importing them never imports rclpy.

The suite's one import check of the layering (STYLE.md §1).  Every module of
``suds_ros.core`` and ``suds_ros.io``, subpackages included, is imported in a
fresh interpreter; a control run on a ROS module shows the check sees rclpy.
"""

from __future__ import annotations

import ast
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import suds_ros

ROOT = Path(__file__).resolve().parents[1]
ROS_PACKAGES = ("rclpy", "rosidl_runtime_py")


def _modules(package: str) -> list[str]:
    """``package`` and every module below it, found on disk (walking subpackages)."""
    pkg = __import__(package, fromlist=["_"])
    return [package] + sorted(m.name for m in pkgutil.walk_packages(pkg.__path__, prefix=f"{package}."))


def _ros_imported_by(modules: list[str]) -> list[str]:
    """The ROS client modules present after importing ``modules`` in a fresh interpreter."""
    code = (
        "import importlib, sys\n"
        f"for m in {modules!r}:\n"
        "    importlib.import_module(m)\n"
        f"print(sorted(m for m in sys.modules if m.split('.')[0] in {ROS_PACKAGES!r}))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, f"importing {modules} failed:\n{proc.stderr}"
    return ast.literal_eval(proc.stdout.strip().splitlines()[-1])


def test_core_and_io_do_not_import_rclpy():
    mods = _modules("suds_ros.core") + _modules("suds_ros.io")
    # subpackages are walked: a module two levels down is among them
    assert any(m.count(".") >= 3 for m in mods), mods
    assert _ros_imported_by(mods) == [], "the core or the bag I/O imports rclpy"
    assert suds_ros.__version__


@pytest.mark.ros
def test_the_check_sees_rclpy():
    assert "rclpy" in _ros_imported_by(["suds_ros.ros.qos"])
