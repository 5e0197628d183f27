"""How many threads BLAS/LAPACK may use: one by default (``SUDS_BLAS_THREADS``).

A multi-threaded OpenBLAS on a small, loaded machine spins its worker threads against the
other processes: on a 2-core machine shared with other work, LAPACK least squares of our sizes
ran ~70× slower than with one thread.  Our matrices are small (thousands of rows, ≤ a few
hundred columns), so one thread per process is also the fast choice on an idle machine, and
the nodes of a pipeline run side by side anyway.  Every entry point (the ``suds`` command,
every node through ``ros/runner.py``, the benchmarks) calls :func:`pin_blas_threads` first.

``SUDS_BLAS_THREADS``: a positive integer (default 1), or ``0`` to leave BLAS alone (then the
usual ``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS`` govern).

How: threadpoolctl (a dependency of the package) limits every BLAS and OpenMP pool already
loaded into the process (numpy's and scipy's own OpenBLAS copies, an MKL or OpenMP runtime),
and the three variables above are set for libraries loaded later (scipy loads its OpenBLAS on
the first use of ``scipy.linalg``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from threadpoolctl import threadpool_info, threadpool_limits

from suds_ros.core.errors import SudsConfigError

#: the environment variable that sets the thread count
ENV_VAR = "SUDS_BLAS_THREADS"
#: the variables BLAS and OpenMP runtimes read when they are loaded
_RUNTIME_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@dataclass(frozen=True)
class BlasPinning:
    """What :func:`pin_blas_threads` did.

    ``threads``: the limit (None: left alone); ``libraries``: file names of the BLAS/OpenMP
    libraries loaded at the time, each limited by threadpoolctl.
    """

    threads: int | None
    libraries: tuple[str, ...] = ()


def threads_from_env(environ: dict[str, str] | None = None) -> int | None:
    """The thread count ``SUDS_BLAS_THREADS`` asks for: default 1, None for ``0`` (leave alone)."""
    env = os.environ if environ is None else environ
    raw = env.get(ENV_VAR, "").strip()
    if not raw:
        return 1
    try:
        n = int(raw)
    except ValueError:
        n = -1
    if n < 0:
        raise SudsConfigError(f"`{ENV_VAR}`: expected a whole number ≥ 0 (0: leave BLAS alone), got {raw!r}")
    return n or None


def blas_thread_counts() -> dict[str, int]:
    """Thread count of each BLAS library loaded into this process (file name → threads)."""
    return {Path(lib["filepath"]).name: int(lib["num_threads"])
            for lib in threadpool_info() if lib.get("user_api") == "blas"}


def pin_blas_threads(threads: int | None = None) -> BlasPinning:
    """Limit BLAS/LAPACK to ``threads`` threads (default: :func:`threads_from_env`).

    Safe to call more than once and after numpy is imported; the limit stays until changed
    (it is not a context manager here).

    Raises
    ------
    SudsConfigError
        A bad ``SUDS_BLAS_THREADS`` (the message names the variable) or ``threads`` < 1.
    """
    n = threads_from_env() if threads is None else threads
    if n is None:
        return BlasPinning(None)
    if n < 1:
        raise SudsConfigError(f"`threads`: expected ≥ 1, got {n}")
    for var in _RUNTIME_VARS:
        os.environ[var] = str(n)
    threadpool_limits(limits=n)
    return BlasPinning(n, tuple(sorted(Path(lib["filepath"]).name for lib in threadpool_info())))
