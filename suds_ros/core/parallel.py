"""Independent calls of one function in forked worker processes, results in order.

The diagnosis fits dozens of candidate sets that share one large, read-only state (the
recording's equation-error terms, the replay pieces).  Forked workers inherit that state instead
of receiving it pickled; only each call's small argument index and result cross the pipe.  The
results are those of the serial loop, in the same order, whatever the number of workers: a call
must not depend on side effects of the calls before it.

A call made inside a worker runs serially (no pools within pools), and so does everything where
the ``fork`` start method does not exist or the pool breaks (a worker killed): never an error
that the serial loop would not raise.

How many workers: the ``jobs`` argument, or else the count set for a block of work with
:func:`workers` (1, serial, outside any such block), so that deep helpers (a refinement's
Jacobian columns) take the caller's choice without passing it down every signature.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")

#: the function and the items of the map in progress (inherited by the forked workers)
_CALL: tuple[Callable[[Any], Any], list[Any]] | None = None
#: workers of a map called without ``jobs`` (set by :func:`workers`)
_WORKERS = 1


@contextmanager
def workers(jobs: int) -> Iterator[None]:
    """Within the block, :func:`fork_map` without ``jobs`` uses ``jobs`` processes."""
    global _WORKERS
    old, _WORKERS = _WORKERS, max(1, int(jobs))
    try:
        yield
    finally:
        _WORKERS = old


def _run(i: int) -> Any:
    assert _CALL is not None
    return _CALL[0](_CALL[1][i])


def fork_map(fun: Callable[[T], R], items: Iterable[T], jobs: int | None = None) -> list[R]:
    """``[fun(x) for x in items]``, computed by up to ``jobs`` forked processes (default :func:`workers`)."""
    global _CALL
    todo = list(items)
    n = min(_WORKERS if jobs is None else int(jobs), len(todo))
    if n <= 1 or _CALL is not None or "fork" not in multiprocessing.get_all_start_methods():
        return [fun(x) for x in todo]
    _CALL = (fun, todo)
    try:
        with ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("fork")) as pool:
            return list(pool.map(_run, range(len(todo)), chunksize=max(1, len(todo) // (4 * n))))
    except BrokenProcessPool:
        _CALL = None
        return [fun(x) for x in todo]
    finally:
        _CALL = None
