"""The core and the bag I/O must work without ROS: importing them never imports rclpy."""

from __future__ import annotations

import pkgutil
import subprocess
import sys
from pathlib import Path

import suds_ros

ROOT = Path(__file__).resolve().parents[1]


def _modules(package: str) -> list[str]:
    pkg = __import__(package, fromlist=["_"])
    return [package] + [f"{package}.{m.name}" for m in pkgutil.iter_modules(pkg.__path__)]


def test_core_and_io_do_not_import_rclpy():
    mods = _modules("suds_ros.core") + _modules("suds_ros.io")
    assert "suds_ros.core.recording" in mods and "suds_ros.io.recording_bag" in mods
    code = (
        "import importlib, sys\n"
        f"for m in {mods!r}:\n"
        "    importlib.import_module(m)\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rosidl_runtime_py'))\n"
        "print(bad)\n"
        "sys.exit(1 if bad else 0)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, f"rclpy imported by the core: {proc.stdout}{proc.stderr}"
    assert suds_ros.__version__
