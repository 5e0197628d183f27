"""The one module that reads and writes ROS message fields.

Pure ``*_to_msg`` / ``*_from_msg`` pairs, in the style of
``sensor_msgs_py.point_cloud2``.  Fields are accessed by name, so the
``*_from_msg`` functions accept rclpy messages and rosbags typestore messages
alike; the ``*_to_msg`` functions build rclpy messages, or typestore messages
when given ``typestore=`` (a :class:`rosbags.typesys.store.Typestore`).

Stamps are float seconds (absolute, e.g. epoch); the float ↔
``builtin_interfaces/msg/Time`` conversion goes through integer nanoseconds
with the package's one rounding rule (:mod:`suds_ros.io.stamps`), and the
planar yaw of a quaternion is :func:`suds_ros.io.stamps.quaternion_yaw`, so
nodes and the bag reader agree to the bit.

Malformed messages (length mismatches, NaN/Inf, bad stamps, a zero quaternion)
raise :class:`~suds_ros.core.errors.SudsDataError`.
"""

from __future__ import annotations

import array
import functools
import importlib
import json
import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import (
    BAD_STAMP,
    NAN_OR_INF,
    WRONG_JOINT_COUNT,
    WRONG_JOINT_NAMES,
    SudsConfigError,
    SudsDataError,
)
from suds_ros.core.ident.model import SudsModel, joint_order
from suds_ros.core.json_text import dumps
from suds_ros.core.physics.gait import Gait, dump_gait, loads_gait
from suds_ros.io.recording_bag import GAIT_TOPIC, MODEL_TOPIC, SYSTEM_TOPIC, WORLD_FRAME, parse_system_info
from suds_ros.io.stamps import float_to_ns, join_ns, ns_to_float, quaternion_yaw, split_ns, yaw_quaternion

_INT32 = (-(2**31), 2**31 - 1)
LEVELS = {"OK": 0, "WARN": 1, "ERROR": 2, "STALE": 3}


class JointSample(NamedTuple):
    """One ``sensor_msgs/msg/JointState``: stamp (s), joint names, values (rad or m, rad/s, N·m).

    ``position`` has shape (n,) (or (0,) for a velocity-only message); ``velocity``
    and ``effort`` are (n,) arrays or None when the message leaves them empty.
    """

    stamp: float
    names: tuple[str, ...]
    position: FloatArray
    velocity: FloatArray | None
    effort: FloatArray | None


class PlanarPose(NamedTuple):
    """Planar pose of a ``geometry_msgs/msg/PoseStamped``: stamp (s), x, y (m), yaw (rad)."""

    stamp: float
    x: float
    y: float
    yaw: float


class BodyTwist(NamedTuple):
    """Planar body-frame velocity of a ``TwistStamped``: stamp (s), vx, vy (m/s), wz (rad/s)."""

    stamp: float
    vx: float
    vy: float
    wz: float


class DiagnosticReport(NamedTuple):
    """One ``diagnostic_msgs/msg/DiagnosticStatus`` with the array's stamp (s)."""

    stamp: float
    name: str
    level: int
    message: str
    hardware_id: str
    values: dict[str, str]


# ------------------------------------------------------------------ backends
def _msg_class(type_name: str, typestore: Any) -> Any:
    if typestore is not None:
        try:
            return typestore.types[type_name]
        except KeyError:
            raise SudsDataError(f"typestore has no message type {type_name!r}") from None
    return _rclpy_class(type_name)


@functools.lru_cache(maxsize=None)
def _rclpy_class(type_name: str) -> Any:
    # cached: the predictor builds three messages per sample at 1 kHz, and an import per
    # message class cost a tenth of its time
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def message_class(type_name: str) -> Any:
    """The rclpy message class of ``type_name`` (``pkg/msg/Type``), imported from ``pkg.msg``.

    Raises
    ------
    SudsDataError
        If the name is malformed or the package/type is not installed.
    """
    parts = type_name.split("/")
    if len(parts) != 3 or parts[1] != "msg" or not all(parts):
        raise SudsDataError(f"message type: expected 'pkg/msg/Type', got {type_name!r}")
    try:
        return _msg_class(type_name, None)
    except (ImportError, AttributeError):
        msg = f"message type {type_name!r} is not installed (no {parts[0]}.msg.{parts[2]})"
        raise SudsDataError(msg) from None


def _floats(values: FloatArray, typestore: Any) -> Any:
    a = np.ascontiguousarray(values, dtype=np.float64)
    if typestore is not None:
        return a.copy()
    out = array.array("d")
    out.frombytes(a.tobytes())
    return out


def _vector(name: str, values: Any, n: int | None) -> FloatArray:
    a = np.asarray(values, dtype=float).reshape(-1) if values is not None else np.empty(0)
    if n is not None and a.size != n:
        raise SudsDataError(f"`{name}`: expected {n} values (one per joint name), got {a.size}",
                            code=WRONG_JOINT_COUNT)
    # a finite sum is the fast test; only a non-finite one (NaN, Inf or an overflow) looks closer
    if not math.isfinite(float(a.sum())) and not np.all(np.isfinite(a)):
        bad = int(np.flatnonzero(~np.isfinite(a))[0])
        raise SudsDataError(f"`{name}`: value {bad} is not finite ({a[bad]!r})", code=NAN_OR_INF)
    return a


def _finite(name: str, value: Any) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise SudsDataError(f"`{name}`: expected a finite number, got {v!r}", code=NAN_OR_INF)
    return v


# ------------------------------------------------------------------ stamps
def ns_to_time(ns: int, *, typestore: Any = None) -> Any:
    """Integer nanoseconds → ``builtin_interfaces/msg/Time`` (``sec`` floored, ``0 ≤ nanosec < 1e9``)."""
    sec, nanosec = split_ns(ns)
    if not _INT32[0] <= sec <= _INT32[1]:
        raise SudsDataError(f"`stamp`: {ns} ns is outside the int32 seconds range of a ROS Time",
                            code=BAD_STAMP)
    return _msg_class("builtin_interfaces/msg/Time", typestore)(sec=sec, nanosec=nanosec)


def time_to_ns(msg: Any) -> int:
    """``builtin_interfaces/msg/Time`` → integer nanoseconds (exact)."""
    return int(join_ns(msg.sec, msg.nanosec))


def float_to_time(stamp: float, *, typestore: Any = None) -> Any:
    """Float seconds → ``builtin_interfaces/msg/Time``."""
    return ns_to_time(float_to_ns(stamp), typestore=typestore)


def time_to_float(msg: Any) -> float:
    """``builtin_interfaces/msg/Time`` → float seconds (correctly rounded)."""
    return ns_to_float(time_to_ns(msg))


def _time(stamp: Any, typestore: Any) -> Any:
    """A ``Time`` message: float seconds converted, or a ``builtin_interfaces/msg/Time`` kept as it is.

    An output stamped with its input's Time carries it to the nanosecond; float seconds of a
    wall-clock stamp are only good to a few hundred ns.
    """
    if hasattr(stamp, "nanosec"):
        return stamp
    return float_to_time(stamp, typestore=typestore)


def _header(stamp: Any, frame_id: str, typestore: Any) -> Any:
    return _msg_class("std_msgs/msg/Header", typestore)(stamp=_time(stamp, typestore), frame_id=str(frame_id))


def _restamp(msg: Any, stamp: Any, frame_id: str) -> None:
    """Set the header of a message to be published again (the live path reuses its outputs)."""
    msg.header.stamp = _time(stamp, None)
    if msg.header.frame_id != frame_id:
        msg.header.frame_id = frame_id


# ------------------------------------------------------------------ JointState
def _names(names: Sequence[str]) -> tuple[str, ...]:
    out = tuple(names)
    if out == _last_names[0]:  # a stream repeats its joint names: check them once
        return _last_names[0]
    if not all(isinstance(n, str) for n in out):
        raise SudsDataError(f"`name`: expected joint names as strings, got {list(out)!r}",
                            code=WRONG_JOINT_NAMES)
    if len(set(out)) != len(out):
        raise SudsDataError(f"`name`: joint names are not unique: {list(out)}", code=WRONG_JOINT_NAMES)
    _last_names[0] = out
    return out


#: the last joint names that passed :func:`_names` (one entry; checks are pure, so sharing it is safe)
_last_names: list[tuple[str, ...]] = [()]


def joint_state_to_msg(
    stamp: float,
    names: Sequence[str],
    position: FloatArray,
    velocity: FloatArray | None = None,
    effort: FloatArray | None = None,
    *,
    frame_id: str = "",
    typestore: Any = None,
) -> Any:
    """Build a ``sensor_msgs/msg/JointState``; velocity/effort None → empty fields.

    Parameters
    ----------
    stamp : float
        Sample time, s.
    names : sequence of str
        Joint names, head to tail.
    position, velocity, effort : (n,) float
        Joint values (rad or m), rates (rad/s or m/s), efforts (N·m or N).
    """
    nm = _names(names)
    n = len(nm)
    pos = _vector("position", position, n)
    vel = _vector("velocity", velocity, n) if velocity is not None else np.empty(0)
    eff = _vector("effort", effort, n) if effort is not None else np.empty(0)
    return _msg_class("sensor_msgs/msg/JointState", typestore)(
        header=_header(stamp, frame_id, typestore),
        name=list(nm),
        position=_floats(pos, typestore),
        velocity=_floats(vel, typestore),
        effort=_floats(eff, typestore),
    )


def joint_state_from_msg(msg: Any, *, require_position: bool = True) -> JointSample:
    """Read a ``JointState``: every non-empty value field must have one value per name."""
    nm = _names(msg.name)
    n = len(nm)
    fields = {}
    for key in ("position", "velocity", "effort"):
        raw = np.asarray(getattr(msg, key), dtype=float).reshape(-1)
        fields[key] = None if raw.size == 0 else _vector(key, raw, n)
    if fields["position"] is None:
        if require_position and n:
            raise SudsDataError(f"`position`: expected {n} values (one per joint name), got 0",
                                code=WRONG_JOINT_COUNT)
        fields["position"] = np.empty(0)
    return JointSample(
        time_to_float(msg.header.stamp), nm, fields["position"], fields["velocity"], fields["effort"]
    )


def select_joints(sample: JointSample, names: Sequence[str]) -> JointSample:
    """The joints ``names`` of ``sample``, in that order; other joints of the message are ignored.

    A robot's ``/joint_states`` (ros2_control's joint_state_broadcaster) lists every joint,
    in its own order, possibly with joints the model does not know (a gripper, a camera
    mount): this keeps the model's joints, ordered as the model lists them.  A sample that
    already has exactly ``names`` is returned unchanged.

    Raises
    ------
    SudsDataError
        ``WRONG_JOINT_NAMES`` when a joint of ``names`` is not in the message.
    """
    want = tuple(names)
    order = joint_order(sample.names, want)
    if order is None:
        return sample

    def pick(a: FloatArray | None) -> FloatArray | None:
        return None if a is None or a.size == 0 else a[order]

    position = sample.position[order] if sample.position.size else sample.position
    return JointSample(sample.stamp, want, position, pick(sample.velocity), pick(sample.effort))


def joint_velocity_to_msg(
    stamp: Any, names: Sequence[str], velocity: FloatArray, *, typestore: Any = None, out: Any = None
) -> Any:
    """Velocity-only ``JointState`` (empty position and effort), e.g. the passive joint rates (rad/s).

    ``stamp``: float seconds, or a ``builtin_interfaces/msg/Time`` to copy exactly.  ``out``: a
    message this function made before, filled in again and returned instead of a new one (a
    live node at 1 kHz; rclpy serialises on publish, so the message can be reused at once).
    """
    nm = _names(names)
    vel = _vector("velocity", velocity, len(nm))
    if out is not None:
        _restamp(out, stamp, "")
        if tuple(out.name) != nm:
            out.name = list(nm)
        out.velocity = _floats(vel, None)
        return out
    return _msg_class("sensor_msgs/msg/JointState", typestore)(
        header=_header(stamp, "", typestore),
        name=list(nm),
        position=_floats(np.empty(0), typestore),
        velocity=_floats(vel, typestore),
        effort=_floats(np.empty(0), typestore),
    )


def joint_velocity_from_msg(msg: Any) -> tuple[float, tuple[str, ...], FloatArray]:
    """Read a velocity-only ``JointState``: (stamp s, names, velocity (n,))."""
    sample = joint_state_from_msg(msg, require_position=False)
    if sample.velocity is None and sample.names:
        raise SudsDataError(
            f"`velocity`: expected {len(sample.names)} values (one per joint name), got 0",
            code=WRONG_JOINT_COUNT)
    vel = sample.velocity if sample.velocity is not None else np.empty(0)
    return sample.stamp, sample.names, vel


# ------------------------------------------------------------------ PoseStamped
def pose_to_msg(
    stamp: float, x: float, y: float, yaw: float, *, frame_id: str = WORLD_FRAME,
    typestore: Any = None
) -> Any:
    """Planar ``geometry_msgs/msg/PoseStamped``: position (x, y, 0) m, yaw-only quaternion."""
    x, y, yaw = _finite("x", x), _finite("y", y), _finite("yaw", yaw)
    point = _msg_class("geometry_msgs/msg/Point", typestore)(x=x, y=y, z=0.0)
    qx, qy, qz, qw = yaw_quaternion(yaw)
    quat = _msg_class("geometry_msgs/msg/Quaternion", typestore)(x=qx, y=qy, z=qz, w=qw)
    pose = _msg_class("geometry_msgs/msg/Pose", typestore)(position=point, orientation=quat)
    return _msg_class("geometry_msgs/msg/PoseStamped", typestore)(
        header=_header(stamp, frame_id, typestore), pose=pose
    )


def pose_from_msg(msg: Any) -> PlanarPose:
    """Read a ``PoseStamped`` as a planar pose; yaw is the Z angle of the quaternion."""
    p, q = msg.pose.position, msg.pose.orientation
    x, y = _finite("pose.position.x", p.x), _finite("pose.position.y", p.y)
    quat = tuple(_finite(f"pose.orientation.{k}", getattr(q, k)) for k in "xyzw")
    yaw = quaternion_yaw(quat)
    return PlanarPose(time_to_float(msg.header.stamp), x, y, yaw)


# ------------------------------------------------------------------ TwistStamped
def twist_to_msg(
    stamp: Any, vx: float, vy: float, wz: float, *, frame_id: str = "body", typestore: Any = None,
    out: Any = None,
) -> Any:
    """Planar body-frame ``geometry_msgs/msg/TwistStamped``: linear (vx, vy, 0), angular (0, 0, wz).

    ``stamp`` and ``out`` as in :func:`joint_velocity_to_msg`.
    """
    vx, vy, wz = _finite("vx", vx), _finite("vy", vy), _finite("wz", wz)
    if out is not None:
        _restamp(out, stamp, str(frame_id))
        lin, ang = out.twist.linear, out.twist.angular
        lin.x, lin.y, lin.z, ang.x, ang.y, ang.z = vx, vy, 0.0, 0.0, 0.0, wz
        return out
    vec = _msg_class("geometry_msgs/msg/Vector3", typestore)
    twist = _msg_class("geometry_msgs/msg/Twist", typestore)(
        linear=vec(x=vx, y=vy, z=0.0), angular=vec(x=0.0, y=0.0, z=wz))
    return _msg_class("geometry_msgs/msg/TwistStamped", typestore)(
        header=_header(stamp, frame_id, typestore), twist=twist
    )


def twist_from_msg(msg: Any) -> BodyTwist:
    """Read the planar part of a ``TwistStamped`` (vx, vy m/s, wz rad/s)."""
    lin, ang = msg.twist.linear, msg.twist.angular
    return BodyTwist(
        time_to_float(msg.header.stamp),
        _finite("twist.linear.x", lin.x),
        _finite("twist.linear.y", lin.y),
        _finite("twist.angular.z", ang.z),
    )


# ------------------------------------------------------------------ diagnostics
def _level(level: int | str) -> int:
    if isinstance(level, str):
        if level.upper() not in LEVELS:
            raise SudsDataError(f"`level`: expected one of {sorted(LEVELS)}, got {level!r}")
        return LEVELS[level.upper()]
    if isinstance(level, (bytes, bytearray)):
        level = level[0] if len(level) == 1 else -1
    if int(level) not in LEVELS.values():
        raise SudsDataError(f"`level`: expected 0 (OK) … 3 (STALE), got {level!r}")
    return int(level)


def diagnostics_to_msg(
    stamp: float,
    name: str,
    values: Mapping[str, str],
    *,
    level: int | str = "OK",
    message: str = "",
    hardware_id: str = "",
    typestore: Any = None,
) -> Any:
    """``diagnostic_msgs/msg/DiagnosticArray`` with one status holding ``values`` as key/value pairs."""
    lvl = _level(level)
    kv = _msg_class("diagnostic_msgs/msg/KeyValue", typestore)
    pairs = []
    for key, value in values.items():
        if not isinstance(key, str) or not isinstance(value, str):
            raise SudsDataError(
                f"`values`: expected str keys and values, got {key!r}: {type(value).__name__}"
            )
        pairs.append(kv(key=key, value=value))
    status = _msg_class("diagnostic_msgs/msg/DiagnosticStatus", typestore)(
        level=lvl if typestore is not None else bytes([lvl]),
        name=str(name),
        message=str(message),
        hardware_id=str(hardware_id),
        values=pairs,
    )
    return _msg_class("diagnostic_msgs/msg/DiagnosticArray", typestore)(
        header=_header(stamp, "", typestore), status=[status]
    )


def diagnostics_from_msg(msg: Any) -> list[DiagnosticReport]:
    """Read every status of a ``DiagnosticArray``; level as int 0..3."""
    stamp = time_to_float(msg.header.stamp)
    return [
        DiagnosticReport(
            stamp,
            str(s.name),
            _level(s.level),
            str(s.message),
            str(s.hardware_id),
            {str(kv.key): str(kv.value) for kv in s.values},
        )
        for s in msg.status
    ]


# --- JSON payloads in std_msgs/String: the identified model and the system description ---


def model_to_msg(model: SudsModel) -> Any:
    """``std_msgs/String`` with the model's JSON (:meth:`SudsModel.to_dict`)."""
    from std_msgs.msg import String

    return String(data=dumps(model.to_dict()))


def model_from_msg(msg: Any) -> SudsModel:
    """Inverse of :func:`model_to_msg`; raises SudsConfigError for a malformed model."""
    try:
        return SudsModel.from_dict(json.loads(msg.data))
    except (ValueError, KeyError, TypeError) as exc:
        raise SudsConfigError(f"{MODEL_TOPIC}: not a SudsModel JSON ({type(exc).__name__}: {exc})") from None


def system_info_to_msg(info: dict[str, Any]) -> Any:
    """``std_msgs/String`` holding the JSON system description."""
    from std_msgs.msg import String

    return String(data=dumps(info, sort_keys=True))


def system_info_from_msg(msg: Any) -> dict[str, Any]:
    """Parse a ``/suds/system`` message; raises SudsConfigError when it is not a valid description."""
    try:
        return parse_system_info(msg.data)
    except SudsDataError as exc:
        raise SudsConfigError(f"{SYSTEM_TOPIC}: {exc}") from None


def gait_to_msg(gait: Gait) -> Any:
    """``std_msgs/String`` holding the gait file text (``suds-gait/1`` YAML) of the gait in force."""
    from std_msgs.msg import String

    return String(data=dump_gait(gait))


def gait_from_msg(msg: Any) -> Gait:
    """Parse a ``suds/gait`` message; raises SudsConfigError (code ``bad_gait_file``) naming the key."""
    return loads_gait(msg.data, source=GAIT_TOPIC)


def gait_switch_to_msg(stamp: float, gait: Gait) -> Any:
    """``std_msgs/String`` JSON ``{"stamp", "stamp_ns", "gait"}``: ``gait`` runs from the sample stamped ``stamp``."""
    from std_msgs.msg import String

    return String(data=dumps({"stamp": float(stamp), "stamp_ns": float_to_ns(stamp), "gait": dump_gait(gait)},
                             sort_keys=True))


def gait_switch_from_msg(msg: Any) -> tuple[float, Gait]:
    """Parse a ``suds/gait_switch`` message: (stamp of the first sample of the new gait, s; the gait).

    Raises
    ------
    SudsConfigError
        Not the JSON object with a numeric ``stamp_ns`` and a valid ``gait`` (code ``bad_gait_switch``).
    """
    try:
        doc = json.loads(msg.data)
        ns, text = doc["stamp_ns"], doc["gait"]
        if not isinstance(ns, int) or isinstance(ns, bool) or not isinstance(text, str):
            raise TypeError
    except (ValueError, KeyError, TypeError):
        raise SudsConfigError("`suds/gait_switch`: expected JSON {\"stamp_ns\": int, \"gait\": text}, got "
                              f"{str(msg.data)[:80]!r}", code="bad_gait_switch") from None
    return ns_to_float(ns), loads_gait(text, source="suds/gait_switch")


def gait_trajectory_msg(gait: Gait, stamp: float, points_per_cycle: int) -> Any:
    """One cycle of ``gait`` as a ``trajectory_msgs/JointTrajectory`` (a ros2_control trajectory controller's input).

    ``points_per_cycle`` + 1 points at t = k/(N·f), k = 0..N (the last closes the cycle), with
    positions (rad) and velocities (rad/s) of the actuated joints; ``time_from_start`` = t;
    ``header.stamp`` = ``stamp`` (s).
    """
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    n = int(points_per_cycle)
    t = np.arange(n + 1) / (n * gait.gait_hz)
    r, rd = gait.r(t), gait.rdot(t)
    msg = JointTrajectory()
    msg.header.stamp = float_to_time(stamp)
    msg.joint_names = list(gait.joints)
    for k in range(n + 1):
        ns = int(round(t[k] * 1e9))
        msg.points.append(JointTrajectoryPoint(positions=[float(v) for v in r[k]],
                                               velocities=[float(v) for v in rd[k]],
                                               time_from_start=Duration(sec=ns // 1_000_000_000,
                                                                        nanosec=ns % 1_000_000_000)))
    return msg
