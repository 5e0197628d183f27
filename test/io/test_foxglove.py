"""Our bags open in Foxglove's readers (@mcap/core + @foxglove/rosmsg2-serialization) where Node is present."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from suds_ros.io import cdr
from suds_ros.io.mcap import BagWriter
from suds_ros.io.recording_bag import write_recording

JS = Path(__file__).resolve().parents[1] / "js"


def _node_reader() -> list[str]:
    node = shutil.which("node")
    if node is None:
        pytest.skip("Node.js is not installed: Foxglove reader check skipped")
    if not (JS / "node_modules" / "@mcap" / "core").exists():
        pytest.skip(f"Foxglove packages not installed: run `npm ci` in {JS} (scripts/setup_env.sh does)")
    return [node, str(JS / "read_bag.mjs")]


def _read(path: Path) -> dict:
    proc = subprocess.run([*_node_reader(), str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_recording_reads_in_foxglove(tmp_path: Path, purcell3_run) -> None:
    path = tmp_path / "p3.mcap"
    rec = purcell3_run.slice(0, 300)
    write_recording(path, rec)
    out = _read(path)
    assert out["topics"]["/suds/shape"] == {"type": "sensor_msgs/msg/JointState", "count": 300}
    assert out["topics"]["/suds/body_pose"]["count"] == 300
    first = out["first"]["/suds/shape"]
    assert first["name"] == ["joint_1", "joint_2"]
    np.testing.assert_allclose(first["position"], rec.r[0])
    assert first["velocity"] == [] and first["effort"] == []  # empty trailing arrays, no padding
    assert out["metadata"]["suds"]["actuated"] == "joint_1"


def test_every_schema_we_write_reads_in_foxglove(tmp_path: Path) -> None:
    path = tmp_path / "all.mcap"
    msgs = {
        "/suds/predicted/body_velocity": ("geometry_msgs/msg/TwistStamped", {
            "header": {"stamp": {"sec": 5, "nanosec": 7}, "frame_id": "body"},
            "twist": {"linear": {"x": 0.1, "y": -0.2, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.3}}}),
        "/suds/status": ("diagnostic_msgs/msg/DiagnosticArray", {
            "header": {"stamp": {"sec": 5, "nanosec": 0}, "frame_id": ""},
            "status": [{"level": b"\x00", "name": "suds_estimator", "message": "ok", "hardware_id": "",
                        "values": [{"key": "phase", "value": "1.25"}]}]}),
        "/suds/model": ("std_msgs/msg/String", {"data": '{"coef": [1, 2]}'}),
        "/clock": ("rosgraph_msgs/msg/Clock", {"clock": {"sec": 5, "nanosec": 1}}),
    }
    with BagWriter(path) as w:
        for i, (topic, (type_name, msg)) in enumerate(msgs.items()):
            w.add_topic(topic, type_name)
            w.write_raw(topic, cdr.encode(type_name, msg), log_time_ns=1000 + i)
    out = _read(path)
    assert set(out["topics"]) == set(msgs)
    assert out["first"]["/suds/predicted/body_velocity"]["twist"]["angular"]["z"] == pytest.approx(0.3)
    assert out["first"]["/suds/status"]["status"][0]["values"][0] == {"key": "phase", "value": "1.25"}
    assert out["first"]["/suds/model"]["data"] == '{"coef": [1, 2]}'
