"""fork_map (:mod:`suds_ros.core.parallel`): the serial loop's results, in order, in forked workers."""

from __future__ import annotations

import os

import numpy as np
import pytest

from suds_ros.core import parallel
from suds_ros.core.parallel import fork_map


def _pid_and_square(x: int) -> tuple[int, int]:
    return os.getpid(), x * x


def test_results_come_back_in_order_from_other_processes() -> None:
    big = np.arange(1_000_000, dtype=float)  # shared state the workers inherit, never pickled

    def f(i: int) -> tuple[int, float]:
        return os.getpid(), float(big[i * 1000])

    got = fork_map(f, range(40), 2)
    assert [v for _, v in got] == [float(i * 1000) for i in range(40)]
    assert os.getpid() not in {p for p, _ in got}


def test_one_job_or_one_item_runs_here() -> None:
    assert fork_map(_pid_and_square, [3, 4], 1) == [(os.getpid(), 9), (os.getpid(), 16)]
    assert fork_map(_pid_and_square, [5], 4) == [(os.getpid(), 25)]
    assert fork_map(_pid_and_square, [], 4) == []


def test_a_map_inside_a_worker_runs_serially_there() -> None:
    def outer(x: int) -> list[tuple[int, int]]:
        return fork_map(_pid_and_square, [x, x + 1], 2)

    for inner in fork_map(outer, [1, 10], 2):
        assert len({p for p, _ in inner}) == 1  # both inner calls in the worker itself
    assert parallel._CALL is None


def test_an_error_in_a_call_is_the_serial_loop_error() -> None:
    def f(x: int) -> int:
        if x == 3:
            raise ValueError("three")
        return x

    with pytest.raises(ValueError, match="three"):
        fork_map(f, range(6), 2)
    assert parallel._CALL is None


def test_a_killed_worker_falls_back_to_the_serial_loop() -> None:
    def f(x: int) -> int:
        if os.getpid() != parent:
            os._exit(1)  # the worker dies: BrokenProcessPool
        return x + 1

    parent = os.getpid()
    assert fork_map(f, range(5), 2) == [1, 2, 3, 4, 5]
    assert parallel._CALL is None
