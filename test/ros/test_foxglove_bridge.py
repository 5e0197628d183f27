"""The Foxglove bridge: a WebSocket client receives the predictions; the pipeline starts it.

The live test runs a publisher of predictions and the bridge as separate processes and
connects with the stdlib client of ``_foxglove_client.py`` (Foxglove WebSocket protocol);
the pipeline tests only build argument lists (no rclpy).
"""

from __future__ import annotations

import socket
import sys
from pathlib import Path

import pytest

from suds_ros.io.mcap import decode_message
from suds_ros.io.msgdefs import schema_text
from suds_ros.io.recording_bag import PREDICTED_BODY_TOPIC, TWIST_TYPE
from suds_ros.ros import pipeline

try:
    from ._foxglove_client import SUBPROTOCOLS, FoxgloveClient, parse_message_data
    from ._ros_helpers import stop, wait_for
except ImportError:
    from _foxglove_client import SUBPROTOCOLS, FoxgloveClient, parse_message_data
    from _ros_helpers import stop, wait_for

HERE = Path(__file__).resolve().parent
CONFIG = HERE.parents[1] / "config" / "foxglove_bridge.yaml"


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def bridge_command(port: int) -> list[str]:
    """The bridge with the shipped parameter file, on ``port``."""
    return [sys.executable, "-m", "suds_ros.ros.foxglove_node", "--ros-args",
            "--params-file", str(CONFIG), "-p", f"port:={port}"]


@pytest.mark.ros
def test_client_receives_the_predictions(start_process):
    pytest.importorskip("foxglove")
    port = free_port()
    pub = start_process([sys.executable, HERE / "_twist_publisher.py", "50"], "publisher")
    bridge = start_process(bridge_command(port), "bridge")
    wait_for(lambda: f"serving {PREDICTED_BODY_TOPIC}" in bridge.output() or bridge.poll() is not None,
             60, lambda: f"the bridge serving {PREDICTED_BODY_TOPIC}\n{bridge.output()}\n{pub.output()}")
    assert bridge.poll() is None, bridge.output()
    client = FoxgloveClient("127.0.0.1", port)
    try:
        assert client.subprotocol in SUBPROTOCOLS
        assert client.wait_for(lambda m: isinstance(m, dict) and m.get("op") == "serverInfo",
                               30, "serverInfo")
        advert = client.wait_for(
            lambda m: isinstance(m, dict) and m.get("op") == "advertise"
            and any(c["topic"] == PREDICTED_BODY_TOPIC for c in m["channels"]),
            30, f"an advertise of {PREDICTED_BODY_TOPIC}")
        channel = next(c for c in advert["channels"] if c["topic"] == PREDICTED_BODY_TOPIC)
        assert (channel["encoding"], channel["schemaName"], channel["schemaEncoding"]) == (
            "cdr", TWIST_TYPE, "ros2msg")
        assert channel["schema"] == schema_text(TWIST_TYPE)
        client.send_json({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channel["id"]}]})
        received = []
        for _ in range(3):
            frame = client.wait_for(lambda m: isinstance(m, bytes), 30, "a messageData frame")
            received.append(parse_message_data(frame))
    finally:
        client.close()
    for sub, log_time, payload in received:
        assert sub == 7
        assert log_time > 1_000_000_000 * 10**9  # the bridge's receive time, ns since the epoch
        msg = decode_message(TWIST_TYPE, payload)
        i = round((msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - 1.7e9) * 100)
        assert (msg.twist.linear.x, msg.twist.linear.y) == (float(i), float(-i))
        assert msg.twist.angular.z == pytest.approx(i / 10.0)
    stamps = [decode_message(TWIST_TYPE, p).header.stamp for _, _, p in received]
    assert len({(s.sec, s.nanosec) for s in stamps}) == 3  # three different predictions
    assert stop(bridge) == 0, bridge.output()


@pytest.mark.ros
def test_busy_port_is_refused_at_start(start_process):
    pytest.importorskip("foxglove")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        bridge = start_process(bridge_command(s.getsockname()[1]), "bridge")
        assert bridge.wait(60) == 1, bridge.output()
    assert "ERROR: foxglove_bridge:" in bridge.output() and "port" in bridge.output()


def test_pipeline_starts_the_bridge_with_foxglove():
    cmds = pipeline.build_commands(pipeline.parse_args(
        ["--foxglove", "9123", "--namespace", "/robot1", "--nodes", "simulator,predictor"]))
    assert list(cmds) == ["simulator", "predictor", "foxglove_bridge"]
    bridge = cmds["foxglove_bridge"]
    assert bridge[1:3] == ["-m", "suds_ros.ros.foxglove_node"]
    assert bridge[bridge.index("-p") + 1] == "port:=9123"
    assert "__ns:=/robot1" in bridge


def test_pipeline_without_foxglove_has_no_bridge():
    assert "foxglove_bridge" not in pipeline.build_commands(pipeline.parse_args([]))
    assert "foxglove_bridge" not in pipeline.build_commands(
        pipeline.parse_args(["--foxglove", "0", "--nodes", "simulator,foxglove_bridge"]))


@pytest.mark.parametrize("value", ["-1", "70000"])
def test_pipeline_rejects_a_bad_foxglove_port(value, capsys):
    with pytest.raises(SystemExit, match="2"):
        pipeline.parse_args(["--foxglove", value])
    assert "--foxglove" in capsys.readouterr().err
