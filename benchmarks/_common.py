"""Helpers shared by the benchmark scripts (not part of the package)."""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

RESULTS = ROOT / "docs" / "results"


def machine() -> str:
    """One line describing the machine the figures were measured on."""
    import os

    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"


def stamp() -> str:
    """UTC time of the run."""
    return time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())


def write(name: str, text: str) -> Path:
    """Write a results file under docs/results and echo it."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / name
    path.write_text(text)
    print(text)
    return path
