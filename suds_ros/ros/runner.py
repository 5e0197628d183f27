"""The shared ``main`` of every suds node: help, init, run, report a bad start, shut down."""

from __future__ import annotations

import gc
import signal
import sys
import threading
from collections.abc import Callable
from typing import Any, TypeVar

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from suds_ros.core.blas import pin_blas_threads
from suds_ros.core.errors import SudsError
from suds_ros.ros.params import parameters_help, wants_help

N = TypeVar("N")


def run_node(
    args: list[str] | None,
    *,
    name: str,
    doc: str,
    config_cls: type | tuple[type, ...],
    make: Callable[[], N],
    run: Callable[[N], Any] | None = None,
    close: Callable[[N], None] | None = None,
    executor: Callable[[N], Any] | None = None,
) -> int:
    """Start the node ``make()`` and ``run`` it until it returns, SIGINT/SIGTERM or shutdown.

    ``--help`` (or ``-h``) in ``args`` prints the node's parameters (from ``config_cls``
    and the first line of ``doc``) and returns 0.  A :class:`SudsError` while starting or
    running (a refused parameter, an unreadable checkpoint or bag) prints one
    ``ERROR: <name>: <reason>`` line and returns 1.  ``close`` (then ``destroy_node``)
    always runs on the node once it exists, so bags and checkpoints are finalised.
    Without ``run`` the node is spun by an executor of its own until SIGINT/SIGTERM, which only
    set a flag: rclpy's own signal handlers, which shut the ROS context down from another thread
    at once, are not installed, and no exception interrupts a callback midway.  ``close`` then
    runs in the main thread while the context is still alive and the node still on that executor
    (the estimator publishes its final model, the recorder spins to take what its subscriptions
    still hold; it must bound its own time: further signals are ignored), the executor is shut
    down, and only then is the node destroyed.  (With rclpy's handlers and ``rclpy.spin``, the handler
    thread's shutdown of the global executor raced ``destroy_node``'s wake-up of it: one
    pipeline run in about 15 left the estimator hanging in ``destroy_node`` after Ctrl-C.)
    ``executor(node)`` makes that executor (default: a ``SingleThreadedExecutor``); it is spun
    with ``spin_once`` and, after ``close``, the node is taken off it and it is shut down before
    the node is destroyed.  (The predictor's EventsExecutor, spun by a loop of the node's own under
    rclpy's signal handlers and dropped with the node still on it, aborted the process now and
    then at shutdown: "Destroying callback manager with callbacks remaining".)
    A ``run`` of the node's own keeps rclpy's signal handlers (it must return once the context
    is shut down).
    Once the node is made, the garbage collector stops scanning every object made so far (``gc.freeze``).
    BLAS is first limited to ``SUDS_BLAS_THREADS`` threads (default 1, :mod:`suds_ros.core.blas`).
    """
    try:
        pin_blas_threads()
    except SudsError as exc:
        print(f"ERROR: {name}: {exc}", file=sys.stderr)
        return 1
    if wants_help(args):
        print(parameters_help(name, doc.strip().splitlines()[0], config_cls))
        return 0
    spinner = None
    if run is not None:
        if executor is not None:
            raise ValueError("run_node: `run` and `executor` exclude each other")
        rclpy.init(args=args)
    else:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        stop = threading.Event()
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())
        make_executor = executor if executor is not None else (lambda _node: SingleThreadedExecutor())

        def run(n: Any) -> None:
            nonlocal spinner
            spinner = make_executor(n)
            _spin_until(n, spinner, stop)
    node = None
    try:
        node = make()
        # the objects made while starting (modules, the node) are never scanned by the cyclic
        # collector again: its full collections otherwise walked ~200 000 of them, pausing a
        # callback for tens of ms now and then (a 1 kHz stream's worst latencies)
        gc.freeze()
        run(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except SudsError as exc:
        print(f"ERROR: {name}: {exc}", file=sys.stderr)
        return 1
    except Exception:
        # SIGINT/SIGTERM shut the context down while a callback was publishing ("publisher's
        # context is invalid"): that is the requested shutdown, not a failure
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            if close is not None:
                close(node)
            if spinner is not None:
                spinner.remove_node(node)
                spinner.shutdown(timeout_sec=1.0)  # destroy_node's wake-up of it is then a no-op
            node.destroy_node()  # type: ignore[attr-defined]
        try:
            rclpy.try_shutdown()
        except Exception:  # noqa: BLE001 - rclpy's SIGINT handler may shut the context down meanwhile
            pass
    return 0


def _spin_until(node: Any, executor: Any, stop: threading.Event) -> None:
    """Spin ``node`` on ``executor`` until ``stop`` is set or the context is shut down."""
    executor.add_node(node)
    while not stop.is_set() and rclpy.ok():
        executor.spin_once(timeout_sec=0.1)
