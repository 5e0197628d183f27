"""How many threads BLAS/LAPACK may use: one by default (``SUDS_BLAS_THREADS``).

A multi-threaded OpenBLAS on a small, loaded machine spins its worker threads against the
other processes: on a 2-core machine shared with other work, LAPACK least squares of our sizes
ran ~70× slower than with one thread.  Our matrices are small (thousands of rows, ≤ a few
hundred columns), so one thread per process is also the fast choice on an idle machine, and
the nodes of a pipeline run side by side anyway.  Every entry point (the ``suds`` command,
every node, the benchmarks) calls :func:`pin_blas_threads` first.

``SUDS_BLAS_THREADS``: a positive integer (default 1), or ``0`` to leave BLAS alone (then the
usual ``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS`` govern).

How (in order): threadpoolctl, when installed, limits every BLAS/OpenMP pool it knows;
otherwise the OpenBLAS libraries already loaded into the process (found in
``/proc/self/maps``: numpy's and scipy's own copies) are set through their
``*openblas_set_num_threads*`` entry points; and the environment variables above are set for
libraries loaded later.  Limits without threadpoolctl: an MKL or OpenMP runtime already loaded
is not changed (only libraries loaded after the call see the variables), and outside Linux only
the variables are set.
"""

from __future__ import annotations

import ctypes
import os
from dataclasses import dataclass
from pathlib import Path

from suds_ros.core.errors import SudsConfigError

#: the environment variable that sets the thread count
ENV_VAR = "SUDS_BLAS_THREADS"
#: the variables BLAS and OpenMP runtimes read when they are loaded
_RUNTIME_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: the setter / getter names of the OpenBLAS builds we meet (plain, numpy's 64-bit and scipy's)
_SETTERS = ("openblas_set_num_threads", "scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads")
_GETTERS = ("openblas_get_num_threads", "scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads")


@dataclass(frozen=True)
class BlasPinning:
    """What :func:`pin_blas_threads` did.

    ``threads``: the limit (None: left alone); ``method``: ``threadpoolctl``, ``openblas``
    (loaded libraries set directly) or ``environment`` (variables only); ``libraries``: the
    loaded libraries set directly.
    """

    threads: int | None
    method: str
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


def _loaded_openblas() -> list[str]:
    """Paths of the OpenBLAS libraries mapped into this process (Linux; [] elsewhere)."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return []
    paths = {line.split(None, 5)[-1] for line in maps.splitlines() if "openblas" in line.lower()}
    return sorted(p for p in paths if p.startswith("/") and ".so" in p)


def _call(path: str, names: tuple[str, ...], *args: int) -> int | None:
    """Call the first of ``names`` that the loaded library ``path`` exports; None if none does."""
    try:
        # RTLD_NOLOAD: only a library already mapped; RTLD_LOCAL: never promote its symbols to the
        # global scope (libraries loaded later, e.g. scipy's LAPACK wrappers, would bind to them,
        # across OpenBLAS builds with different integer sizes, and compute wrong numbers)
        lib = ctypes.CDLL(path, mode=getattr(os, "RTLD_NOLOAD", 0) | ctypes.RTLD_LOCAL)
    except OSError:
        return None
    for name in names:
        fn = getattr(lib, name, None)
        if fn is not None:
            fn.argtypes = [ctypes.c_int] * len(args)
            fn.restype = ctypes.c_int if not args else None
            out = fn(*args)
            return int(out) if out is not None else 0
    return None


def blas_thread_counts() -> dict[str, int]:
    """Current thread count of each OpenBLAS library loaded into this process (name → threads)."""
    out = {}
    for path in _loaded_openblas():
        n = _call(path, _GETTERS)
        if n is not None:
            out[Path(path).name] = n
    return out


def pin_blas_threads(threads: int | None = None) -> BlasPinning:
    """Limit BLAS/LAPACK to ``threads`` threads (default: :func:`threads_from_env`).

    Safe to call more than once and after numpy is imported.  Raises
    :class:`~suds_ros.core.errors.SudsConfigError` for a bad ``SUDS_BLAS_THREADS``.
    """
    n = threads_from_env() if threads is None else threads
    if n is None:
        return BlasPinning(None, "none")
    if n < 1:
        raise SudsConfigError(f"`threads`: expected ≥ 1, got {n}")
    for var in _RUNTIME_VARS:
        os.environ[var] = str(n)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        done = tuple(Path(p).name for p in _loaded_openblas() if _call(p, _SETTERS, n) is not None)
        return BlasPinning(n, "openblas" if done else "environment", done)
    threadpool_limits(limits=n)
    return BlasPinning(n, "threadpoolctl")
