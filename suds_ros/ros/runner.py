"""The shared ``main`` of every suds node: help, init, run, report a bad start, shut down."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any, TypeVar

import rclpy
from rclpy.executors import ExternalShutdownException

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
    run: Callable[[N], Any] = rclpy.spin,
    close: Callable[[N], None] | None = None,
) -> int:
    """Start the node ``make()`` and ``run`` it until it returns, SIGINT/SIGTERM or shutdown.

    ``--help`` (or ``-h``) in ``args`` prints the node's parameters (from ``config_cls``
    and the first line of ``doc``) and returns 0.  A :class:`SudsError` while starting or
    running (a refused parameter, an unreadable checkpoint or bag) prints one
    ``ERROR: <name>: <reason>`` line and returns 1.  ``close`` (then ``destroy_node``)
    always runs on the node once it exists, so bags and checkpoints are finalised.
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
    rclpy.init(args=args)
    node = None
    try:
        node = make()
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
            node.destroy_node()  # type: ignore[attr-defined]
        try:
            rclpy.try_shutdown()
        except Exception:  # noqa: BLE001 - rclpy's SIGINT handler may shut the context down meanwhile
            pass
    return 0
