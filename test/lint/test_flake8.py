"""flake8 over the package, configured by the ``[flake8]`` section of setup.cfg (the ament_flake8 promise).

Skipped, with the reason, where flake8 is not installed.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.linter
def test_flake8():
    pytest.importorskip("flake8", reason="flake8 is not installed (pip install flake8)")
    proc = subprocess.run([sys.executable, "-m", "flake8", "--config", "setup.cfg", "."], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"flake8 found problems:\n{proc.stdout}{proc.stderr}"
