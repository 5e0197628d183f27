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

from suds_ros.core.blas import pin_blas_threads  # noqa: E402 - needs ROOT on sys.path

#: BLAS limited to SUDS_BLAS_THREADS threads (default 1) before any benchmark computes
BLAS = pin_blas_threads()


def machine() -> str:
    """One line describing the machine the figures were measured on."""
    import os

    cpu = platform.processor() or platform.machine()
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"BLAS threads {BLAS.threads or 'unpinned'}")


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
