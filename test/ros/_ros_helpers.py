"""Helpers shared by the end-to-end tests of test/ros (not a test module)."""

from __future__ import annotations

import signal
import time
from pathlib import Path

from suds_ros.io.mcap import decode_message, iter_raw_messages


def wait_for(predicate, timeout: float, what: str) -> None:
    """Poll ``predicate`` every 50 ms; AssertionError after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def stop(proc, sig=signal.SIGINT, timeout: float = 20.0) -> int:
    """Send ``sig`` and wait; returns the exit code."""
    if proc.poll() is None:
        proc.send_signal(sig)
    return proc.wait(timeout)


def read_topic(bag: Path, topic: str) -> list:
    """Every message of ``topic``, decoded."""
    return [decode_message(m.type_name, m.data) for m in iter_raw_messages(bag, topics=[topic])]


def last_model(bag: Path):
    """The last /suds/model of the bag as a SudsModel."""
    from suds_ros.ros.conversions import model_from_msg

    msgs = read_topic(bag, "/suds/model")
    assert msgs, f"no /suds/model in {bag}"
    return model_from_msg(msgs[-1])
