"""Helpers shared by the tests of test/ros and their helper scripts (not a test module).

Everything here waits on an event (a condition polled until a deadline, a
process exit, a message received), never for a fixed time.  rclpy is imported
lazily, so ``conftest.py`` can import this module where rclpy is missing.
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from suds_ros.core.errors import SudsBagError
from suds_ros.io.mcap import decode_message, iter_raw_messages


def wait_for(predicate: Callable[[], Any], timeout: float, what: str | Callable[[], str],
             interval: float = 0.05) -> None:
    """Poll ``predicate`` every ``interval`` s until it is true.

    Raises AssertionError after ``timeout`` s, naming ``what`` (a text, or a
    callable evaluated then, so the message can show the state at the deadline).
    """
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            text = what() if callable(what) else what
            raise AssertionError(f"timed out after {timeout} s waiting for {text}")
        time.sleep(interval)


def stop(proc: subprocess.Popen, sig: int = signal.SIGINT, timeout: float = 20.0,
         escalate: float = 3.0) -> int:
    """Stop ``proc`` and return its exit code (the one place that stops a test's process).

    Sends ``sig`` and waits up to ``timeout`` s; if the process is still
    running, SIGTERM and ``escalate`` s more; then SIGKILL of its process group
    (the children run in their own session).  A process that had to be
    escalated returns the signal's negative code, so ``assert stop(p) == 0``
    still fails for it.
    """
    for s, wait in ((sig, timeout), (signal.SIGTERM, escalate)):
        if proc.poll() is not None:
            return proc.returncode
        proc.send_signal(s)
        try:
            return proc.wait(wait)
        except subprocess.TimeoutExpired:
            pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    return proc.wait()


# ------------------------------------------------------------------ recordings
def read_topic(bag: Path, topic: str) -> list:
    """Every message of ``topic``, decoded."""
    return [decode(m) for m in iter_raw_messages(bag, topics=[topic])]


def last_model(bag: Path):
    """The last /suds/model of the bag as a SudsModel."""
    from suds_ros.ros.conversions import model_from_msg

    msgs = read_topic(bag, "/suds/model")
    assert msgs, f"no /suds/model in {bag}"
    return model_from_msg(msgs[-1])


def recorded_so_far(bag: Path) -> tuple[Counter, dict[str, Any]]:
    """Message count and last raw message per topic of a bag a recorder may still be writing.

    Only what the recorder has flushed is seen (up to the last complete
    record); a bag not created or without any record yet is empty.
    """
    counts: Counter = Counter()
    last: dict[str, Any] = {}
    try:
        for m in iter_raw_messages(bag):
            counts[m.topic] += 1
            last[m.topic] = m
    except SudsBagError:
        return Counter(), {}
    return counts, last


def decode(raw: Any) -> Any:
    """A raw (serialized) bag message, decoded."""
    return decode_message(raw.type_name, raw.data)


def header_stamp(raw: Any) -> float:
    """``header.stamp`` of a raw (serialized) stamped message, in s."""
    stamp = decode(raw).header.stamp
    return stamp.sec + stamp.nanosec * 1e-9


# ------------------------------------------------------------------ in-process ROS
class Inbox:
    """Messages received on one topic by a :class:`Probe` (thread safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._messages: list[Any] = []
        self.subscription: Any = None

    def _add(self, msg: Any) -> None:
        with self._lock:
            self._messages.append(msg)

    def messages(self) -> list[Any]:
        """A copy of everything received so far, oldest first."""
        with self._lock:
            return list(self._messages)

    def __len__(self) -> int:
        with self._lock:
            return len(self._messages)

    def publishers(self) -> int:
        """Publishers matched with this inbox's subscription."""
        return self.subscription.get_publisher_count()


class Probe:
    """A node of the test process, in ``context``, spun by a background thread.

    ``node`` answers graph questions (``count_publishers``, ``count_subscribers``);
    :meth:`listen` collects a topic's messages in an :class:`Inbox`.
    """

    def __init__(self, context: Any, name: str = "test_probe") -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.context = context
        self.node = rclpy.create_node(name, context=context)
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self.node)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name=f"{name}-spin", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            with self._lock:  # entities are only created while the executor is not waiting
                self._executor.spin_once(timeout_sec=0.05)
            time.sleep(0)  # let listen() take the lock

    def listen(self, topic: str, msg_type: Any, qos: Any) -> Inbox:
        """Subscribe to ``topic``; returns the :class:`Inbox` its messages go to."""
        inbox = Inbox()
        with self._lock:
            inbox.subscription = self.node.create_subscription(msg_type, topic, inbox._add, qos)
        return inbox

    def publisher(self, topic: str, msg_type: Any, qos: Any) -> Any:
        """A publisher of the probe's node on ``topic``."""
        with self._lock:
            return self.node.create_publisher(msg_type, topic, qos)

    def close(self) -> None:
        """Stop spinning and destroy the node (the context is the caller's)."""
        self._stop.set()
        self._thread.join(10.0)
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()


def set_simulator_parameter(probe, name: str, value: str):  # type: ignore[no-untyped-def]
    """Set a string parameter of the running simulator through its parameter service.

    Returns the SetParametersResult.
    """
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    with probe._lock:  # entities are created while the probe's executor is not waiting
        client = probe.node.create_client(SetParameters, "/suds_simulator/set_parameters")
    wait_for(lambda: client.service_is_ready(), 30, "the simulator's parameter service")
    req = SetParameters.Request(parameters=[Parameter(name=name, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=value))])
    future = client.call_async(req)
    wait_for(future.done, 30, "the answer of set_parameters")
    return future.result().results[0]
