"""Fixtures for tests that run ROS 2 processes.

Each test gets its own DDS world: a ``ROS_DOMAIN_ID`` derived from the pid and
a counter, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a private
``ROS_LOG_DIR``.  Processes started through :func:`start_process` are stopped
(SIGINT, then SIGTERM, then SIGKILL of their process group) at teardown.
Tests marked ``ros`` are skipped when rclpy cannot be imported.
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
_COUNTER = itertools.count()

try:
    import rclpy  # noqa: F401

    RCLPY_ERROR = ""
except ImportError as exc:  # pragma: no cover - depends on the environment
    RCLPY_ERROR = f"rclpy cannot be imported ({exc})"


def pytest_runtest_setup(item: pytest.Item) -> None:
    if item.get_closest_marker("ros") and RCLPY_ERROR:
        pytest.skip(RCLPY_ERROR)


def unique_domain_id() -> int:
    """A ROS domain id in 1..100 unlikely to collide with concurrent test runs."""
    return 1 + (os.getpid() * 37 + next(_COUNTER)) % 100


@pytest.fixture
def ros_env(tmp_path: Path) -> dict[str, str]:
    """Environment for ROS child processes, isolated from other tests and users."""
    env = dict(os.environ)
    log_dir = tmp_path / "ros_log"
    log_dir.mkdir()
    prefixes = [p for p in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    if sys.prefix not in prefixes:
        prefixes.insert(0, sys.prefix)
    env.update(
        ROS_DOMAIN_ID=str(unique_domain_id()),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        ROS_LOG_DIR=str(log_dir),
        AMENT_PREFIX_PATH=os.pathsep.join(prefixes),
        PYTHONPATH=os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])]),
        PYTHONUNBUFFERED="1",
    )
    env.pop("ROS_STATIC_PEERS", None)
    env.pop("ROS_LOCALHOST_ONLY", None)
    return env


def stop_process(proc: subprocess.Popen, timeouts: tuple[float, float] = (5.0, 3.0)) -> int:
    """Stop ``proc`` (SIGINT, SIGTERM, then SIGKILL of its group) and return its exit code."""
    for sig, timeout in ((signal.SIGINT, timeouts[0]), (signal.SIGTERM, timeouts[1])):
        if proc.poll() is not None:
            return proc.returncode
        proc.send_signal(sig)
        try:
            return proc.wait(timeout)
        except subprocess.TimeoutExpired:
            pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    return proc.wait()


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
    """Factory ``start_process(args, name=...)``: start a child with :func:`ros_env`.

    The child runs in its own session (process group); its stdout and stderr go
    to ``tmp_path/<name>.log`` (``proc.output()``).  Every child still running at
    teardown is stopped, SIGKILL as last resort.
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
        stop_process(proc, timeouts=(3.0, 2.0))


def _node_command(module: str, *params: str) -> list[str]:
    cmd = [sys.executable, "-m", f"suds_ros.ros.{module}"]
    if params:
        cmd.append("--ros-args")
        for p in params:
            cmd += ["-p", p]
    return cmd


@pytest.fixture
def node_command() -> Callable[..., list[str]]:
    """``node_command(module, "name:=value", ...)``: ``python -m suds_ros.ros.<module> --ros-args -p ...``."""
    return _node_command
