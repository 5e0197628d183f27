"""Helpers shared by the benchmark scripts (not part of the package)."""

from __future__ import annotations

import argparse
from collections.abc import Callable

import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the shared folder beside the checkout (spec, bags, robots)
SHARED = ROOT.parent / "shared"
#: the shared snake5 robot model file
SNAKE5 = str(SHARED / "robots" / "snake5.yaml")
#: a robot model file of ours whose nominal wave runs the slow way (a passive neck)
NECK4 = str(ROOT / "test" / "data" / "robots" / "neck4.yaml")
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

RESULTS = ROOT / "docs" / "results"

from suds_ros.core.blas import pin_blas_threads  # noqa: E402 - needs ROOT on sys.path

#: BLAS limited to SUDS_BLAS_THREADS threads (default 1) before any benchmark computes
BLAS = pin_blas_threads()


def machine() -> str:
    """One line describing the machine the figures were measured on."""
    import os

    import numpy
    import scipy

    cpu = platform.processor() or platform.machine()
    try:  # the model name: BLAS picks its kernels by it
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            cpu += next((f" ({ln.split(':', 1)[1].strip()})" for ln in f if ln.startswith("model name")), "")
    except OSError:
        pass
    # the versions: a loop's accept/reject path turns on last bits (SLSQP, BLAS), so its runs differ between them
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {numpy.__version__}, "
            f"scipy {scipy.__version__}, BLAS threads {BLAS.threads or 'unpinned'}")


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


def run_report_cli(doc: str, choices: list[str], run: Callable[[str, argparse.Namespace], None],
                   report: Callable[[], None], *,
                   extra: Callable[[argparse.ArgumentParser], None] | None = None) -> None:
    """``SCRIPT run NAME… [--seeds S…]`` (then the report) or ``SCRIPT report``; ``extra`` adds run options."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("names", nargs="+", choices=choices)
    r.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    if extra is not None:
        extra(r)
    sub.add_parser("report")
    args = p.parse_args()
    if args.cmd == "run":
        for name in args.names:
            run(name, args)
    report()
