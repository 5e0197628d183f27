"""Docstring conventions (PEP 257) checked by pydocstyle with the ``[pydocstyle]`` section of setup.cfg.

This is the ament_pep257 check run with the PyPI tool; skipped, with the
reason, where pydocstyle is not installed.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.linter
def test_pep257():
    pytest.importorskip("pydocstyle", reason="pydocstyle is not installed (pip install pydocstyle)")
    proc = subprocess.run([sys.executable, "-m", "pydocstyle", "--config", "setup.cfg", "."],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"pydocstyle found problems:\n{proc.stdout}{proc.stderr}"
