"""Helpers of the io tests: the public recordings, small recordings, hand-made (foreign) bags."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mcap.writer import CompressionType, IndexType, Writer

from suds_ros.core.recording import Recording
from suds_ros.io import cdr, msgdefs

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "bags"
BAGS = ("purcell3_nominal", "swimmer9_nominal", "purcell3_real_friction",
        "swimmer9_real_rest_offset")
JS, PS = "sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseStamped"


def shared(name: str) -> Path:
    path = SHARED / f"{name}.mcap"
    if not path.is_file():
        pytest.skip(f"shared recording {path} is absent (the public test bags are not mounted)")
    return path


def make_rec(n: int = 50, t0: float = 1.7e9, effort: bool = False, **kw: object) -> Recording:
    rng = np.random.default_rng(0)
    t = t0 + 0.01 * np.arange(n)
    r = rng.normal(size=(n, 3))
    pose = np.column_stack([rng.normal(size=n), rng.normal(size=n),
                            np.linspace(-3.0, 3.0, n)])
    args = dict(t=t, r=r, joint_names=("joint_1", "joint_2", "joint_3"), actuated=("joint_1",),
                passive=("joint_2", "joint_3"), pose_t=t, pose=pose, system="swimmer4",
                gait_hz=1.5, effort=rng.normal(size=(n, 3)) if effort else None)
    args.update(kw)
    return Recording(**args)  # type: ignore[arg-type]


def assert_rec_equal(a: Recording, b: Recording) -> None:
    for name in ("t", "r", "pose_t"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    np.testing.assert_allclose(a.pose, b.pose, rtol=0, atol=1e-12)  # yaw via quaternion
    for name in ("joint_names", "actuated", "passive", "system", "gait_hz"):
        assert getattr(a, name) == getattr(b, name), name
    if a.effort is None or b.effort is None:
        assert a.effort is None and b.effort is None
    else:
        np.testing.assert_array_equal(a.effort, b.effort)


def raw_bag(path: Path, shape_msgs: list[bytes], stamps_ns: list[int], *,
            compression: CompressionType = CompressionType.ZSTD, summary: bool = True,
            meta: dict[str, str] | None = None, chunked: bool = True,
            pose_msgs: list[bytes] | None = None) -> None:
    """Write a bag with the mcap Writer directly (ids and layout unlike ours)."""
    with open(path, "wb") as f:
        w = Writer(f, compression=compression, use_chunking=chunked, chunk_size=4096,
                   repeat_channels=summary, repeat_schemas=summary, use_statistics=summary,
                   use_summary_offsets=summary,
                   index_types=IndexType.ALL if summary else IndexType(0))
        w.start(profile="ros2", library="test")
        w.register_schema("std_msgs/msg/String", "ros2msg", b"string data\n")  # id 1, unused
        sid_p = w.register_schema(PS, "ros2msg", msgdefs.schema_text(PS).encode())
        sid_j = w.register_schema(JS, "ros2msg", msgdefs.schema_text(JS).encode())
        w.register_channel("/other", "cdr", 1)
        cp = w.register_channel("/suds/body_pose", "cdr", sid_p)
        cj = w.register_channel("/suds/shape", "cdr", sid_j)
        if meta is not None:
            w.add_metadata("suds", meta)
        if pose_msgs is None:
            pose_msgs = [cdr.pose_stamped(ns, (0.1 * k, 0.0, 0.0), (0, 0, 0, 1))
                         for k, ns in enumerate(stamps_ns)]
        for k, (ns, data) in enumerate(zip(stamps_ns, shape_msgs)):
            w.add_message(cj, ns, data, ns, k)
            w.add_message(cp, ns, pose_msgs[k], ns, k)
        if summary:
            w.finish()
        else:
            w.flush()


def js(ns: int, names=("joint_1", "joint_2"), pos=(0.1, 0.2), vel=(), eff=()) -> bytes:
    return cdr.joint_state(ns, names, pos, vel, eff)


STAMPS = [1_700_000_000_000_000_000 + k * 10_000_000 for k in range(20)]
META = {"system": "purcell3", "actuated": "joint_1", "passive": "joint_2", "gait_hz": "1"}
