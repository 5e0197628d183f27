"""Fixtures for tests that run ROS 2 processes.

Each test gets its own DDS world: a ``ROS_DOMAIN_ID`` that no other test on
this machine holds at the same time (a lock file per id, so concurrent test
runs from other checkouts never share a domain), ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``
and a private ``ROS_LOG_DIR``.  Processes started through :func:`start_process`
are stopped (:func:`_ros_helpers.stop`) at teardown.  ``ros_context`` and
``probe`` give the test process its own rclpy ``Context`` in the same domain.
Tests marked ``ros`` are skipped when rclpy cannot be imported (test/conftest.py).
"""

from __future__ import annotations

import fcntl
import itertools
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

try:  # pytest imports test/ros modules top-level (rootdir-relative) or as a package
    from ._ros_helpers import Probe, stop
except ImportError:
    from _ros_helpers import Probe, stop

ROOT = Path(__file__).resolve().parents[2]
_COUNTER = itertools.count()
_DOMAIN_LOCKS = Path(tempfile.gettempdir()) / f"suds_ros_test_domains-{os.getuid()}"


@pytest.fixture
def ros_domain_id() -> Iterator[int]:
    """A ROS domain id in 1..100 held (flock on a lock file) by this test until its teardown."""
    _DOMAIN_LOCKS.mkdir(exist_ok=True)
    first = (os.getpid() * 37 + next(_COUNTER)) % 100
    for k in range(100):
        domain = 1 + (first + k) % 100
        lock = open(_DOMAIN_LOCKS / f"{domain}.lock", "w")  # noqa: SIM115 - held until teardown
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.close()
            continue
        try:
            yield domain
        finally:
            lock.close()  # releases the lock
        return
    pytest.fail(f"every ROS domain id 1..100 is held by another test (locks in {_DOMAIN_LOCKS})")


@pytest.fixture
def ros_env(tmp_path: Path, ros_domain_id: int) -> dict[str, str]:
    """Environment for ROS child processes, isolated from other tests and users."""
    env = dict(os.environ)
    log_dir = tmp_path / "ros_log"
    log_dir.mkdir()
    prefixes = [p for p in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    if sys.prefix not in prefixes:
        prefixes.insert(0, sys.prefix)
    env.update(
        ROS_DOMAIN_ID=str(ros_domain_id),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        ROS_LOG_DIR=str(log_dir),
        AMENT_PREFIX_PATH=os.pathsep.join(prefixes),
        PYTHONPATH=os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])]),
        PYTHONUNBUFFERED="1",
    )
    env.pop("ROS_STATIC_PEERS", None)
    env.pop("ROS_LOCALHOST_ONLY", None)
    return env


@pytest.fixture
def ros_context(ros_env: dict[str, str], monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    """A fresh rclpy ``Context`` of the test process, in the domain of :func:`ros_env` (shut down at teardown)."""
    import rclpy
    from rclpy.context import Context

    for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOG_DIR"):
        monkeypatch.setenv(key, ros_env[key])
    for key in ("ROS_STATIC_PEERS", "ROS_LOCALHOST_ONLY"):
        monkeypatch.delenv(key, raising=False)
    ctx = Context()
    rclpy.init(context=ctx, domain_id=int(ros_env["ROS_DOMAIN_ID"]))
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture
def probe(ros_context: Any) -> Iterator[Probe]:
    """A spinning node of the test process (:class:`_ros_helpers.Probe`): graph queries, ``listen``."""
    p = Probe(ros_context)
    yield p
    p.close()


class Started(subprocess.Popen):
    """A started process with the path of its combined output log."""

    log_path: Path

    def output(self) -> str:
        """Everything the process wrote so far."""
        return self.log_path.read_text(errors="replace")


@pytest.fixture
def start_process(
    ros_env: dict[str, str], tmp_path: Path
) -> Iterator[Callable[..., Started]]:
    """Factory that starts a child with :func:`ros_env`.

    Called as ``start_process(args, name=...)``.  The child runs in its own session (process
    group); its stdout and stderr go to ``tmp_path/<name>.log`` (``proc.output()``).  Every child
    still running at teardown is stopped, SIGKILL as last resort.
    """
    procs: list[Started] = []

    def start(args: list[str], name: str = "proc", env: dict[str, str] | None = None) -> Started:
        log_path = tmp_path / f"{name}-{len(procs)}.log"
        with open(log_path, "wb") as log:
            proc = Started(
                [str(a) for a in args], env=env or ros_env, cwd=tmp_path,
                stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
            )
        proc.log_path = log_path
        procs.append(proc)
        return proc

    yield start
    for proc in procs:
        stop(proc, signal.SIGINT, timeout=3.0, escalate=2.0)


def _node_command(module: str, *params: str) -> list[str]:
    cmd = [sys.executable, "-m", f"suds_ros.ros.{module}"]
    if params:
        cmd.append("--ros-args")
        for p in params:
            cmd += ["-p", p]
    return cmd


@pytest.fixture
def node_command() -> Callable[..., list[str]]:
    """Factory of node command lines: ``python -m suds_ros.ros.<module> --ros-args -p ...``.

    Called as ``node_command(module, "name:=value", ...)``.
    """
    return _node_command
