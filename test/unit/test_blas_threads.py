"""BLAS thread pinning (`SUDS_BLAS_THREADS`, default 1, through threadpoolctl) in the entry points."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from suds_ros.core.blas import ENV_VAR, threads_from_env
from suds_ros.core.errors import SudsConfigError

ROOT = Path(__file__).resolve().parents[2]

#: run an entry point in a fresh process, with numpy and scipy's BLAS loaded before it, and
#: print the OpenBLAS thread counts before and after as JSON
PROBE = """
import json, sys
import numpy, scipy.linalg
from suds_ros.core.blas import blas_thread_counts
before = blas_thread_counts()
{call}
print(json.dumps({{"before": before, "after": blas_thread_counts(), "code": code}}))
"""
CLI = "from suds_ros.cli.main import main\ncode = main(['model', 'export', 'purcell3', '-o', sys.argv[1]])"
NODE = ("from suds_ros.ros.runner import run_node\n"
        "code = run_node(['probe', '--help'], name='probe', doc='A probe.', config_cls=(), make=lambda: None)")


def probe(call: str, tmp_path: Path, **env: str) -> dict:
    clean = {k: v for k, v in os.environ.items()
             if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", ENV_VAR)}
    proc = subprocess.run([sys.executable, "-c", PROBE.format(call=call), str(tmp_path / "p3.yaml")],
                          capture_output=True, text=True, timeout=120, cwd=ROOT, env={**clean, **env})
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_the_cli_runs_on_one_blas_thread_by_default(tmp_path: Path) -> None:
    out = probe(CLI, tmp_path)
    assert out["code"] == 0 and len(out["after"]) == 2  # numpy's and scipy's OpenBLAS
    assert set(out["after"].values()) == {1}
    if (os.cpu_count() or 1) > 1:  # unpinned, OpenBLAS starts one thread per core
        assert set(out["before"].values()) == {os.cpu_count()}


def test_suds_blas_threads_sets_the_count(tmp_path: Path) -> None:
    out = probe(CLI, tmp_path, **{ENV_VAR: "3"})
    assert set(out["after"].values()) == {3}
    out = probe(CLI, tmp_path, **{ENV_VAR: "0"})  # left alone
    assert out["after"] == out["before"]


def test_a_bad_value_is_one_error_line(tmp_path: Path) -> None:
    env = {**os.environ, ENV_VAR: "many"}
    proc = subprocess.run([sys.executable, "-m", "suds_ros.cli.main", "model", "export", "purcell3"],
                          capture_output=True, text=True, timeout=120, cwd=ROOT, env=env)
    assert proc.returncode == 2
    assert proc.stderr.strip() == ("ERROR: `SUDS_BLAS_THREADS`: expected a whole number ≥ 0 "
                                   "(0: leave BLAS alone), got 'many'")


@pytest.mark.ros
def test_the_node_runner_pins_before_anything_else(tmp_path: Path) -> None:
    out = probe(NODE, tmp_path)
    assert out["code"] == 0 and set(out["after"].values()) == {1}
    out = probe(NODE, tmp_path, **{ENV_VAR: "2"})
    assert set(out["after"].values()) == {2}


#: pin in a fresh process after numpy is loaded; print what was pinned and the environment
PIN = """
import json, os
import numpy
from suds_ros.core.blas import blas_thread_counts, pin_blas_threads
p = pin_blas_threads(2)
print(json.dumps({"threads": p.threads, "libraries": p.libraries, "counts": blas_thread_counts(),
                  "env": [os.environ[v] for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")]}))
"""


def test_pin_limits_the_loaded_libraries_and_sets_the_variables_for_later_ones() -> None:
    proc = subprocess.run([sys.executable, "-c", PIN], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["threads"] == 2 and out["env"] == ["2", "2", "2"]
    assert set(out["counts"].values()) == {2} and set(out["counts"]) <= set(out["libraries"])


def test_pin_refuses_a_count_below_one() -> None:
    from suds_ros.core.blas import pin_blas_threads

    with pytest.raises(SudsConfigError, match="`threads`: expected ≥ 1, got 0"):
        pin_blas_threads(0)


@pytest.mark.parametrize(("raw", "threads"), [("", 1), ("1", 1), (" 4 ", 4), ("0", None)])
def test_threads_from_env(raw: str, threads: int | None) -> None:
    assert threads_from_env({ENV_VAR: raw}) == threads
    assert threads_from_env({}) == 1


@pytest.mark.parametrize("raw", ["-1", "1.5", "all"])
def test_threads_from_env_refuses(raw: str) -> None:
    with pytest.raises(SudsConfigError, match=f"got '{raw}'") as exc:
        threads_from_env({ENV_VAR: raw})
    assert exc.value.code == "bad_config"


#: pin first, then let scipy load its LAPACK wrappers and solve with them (SVD-based least squares)
LAPACK_AFTER_PIN = """
import numpy as np
from suds_ros.core.blas import pin_blas_threads
pin_blas_threads(1)
import scipy.linalg, scipy.optimize
rng = np.random.default_rng(0)
A, b = rng.normal(size=(200, 30)), rng.normal(size=200)
x = scipy.optimize.least_squares(lambda p: A @ p - b, np.zeros(30)).x
print(repr(float(np.abs(x - np.linalg.lstsq(A, b, rcond=None)[0]).max())))
"""


def test_pinning_never_rebinds_lapack_for_libraries_loaded_later() -> None:
    """Pinning must not make a loaded library's symbols global.

    Promoted, numpy's 64-bit-integer OpenBLAS would capture the LAPACK calls of scipy modules
    loaded afterwards (32-bit integers): wrong results or "Too large work array" errors.
    """
    proc = subprocess.run([sys.executable, "-c", LAPACK_AFTER_PIN], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert float(proc.stdout.strip()) < 1e-6
