"""QoS profiles of the suds topics (STYLE.md §4) and their rosbag2 YAML form.

* high-rate state (``/suds/shape``, ``/suds/body_pose``) from the simulator →
  :func:`latched_state_qos` (reliable, transient local, keep last N, so a node
  started late still gets the start of the run); a robot driver may publish it
  with :data:`STATE_QOS` (``qos_profile_sensor_data``: best effort, keep last 5);
  subscribers adapt to whatever is offered (:func:`subscription_qos_for`);
* estimates and predictions → :data:`ESTIMATE_QOS` (reliable, depth 100: a reliable subscriber
  that falls behind for a moment — a recorder flushing to disk, a loaded machine — loses
  nothing within 100 messages; with depth 10 a 2-core machine under load lost ≈ 10 % of a
  500 Hz prediction stream);
* the identified model → :data:`MODEL_QOS` (reliable, depth 1, transient local,
  so a late subscriber still gets the last model);
* status / diagnostics → :data:`STATUS_QOS` (reliable, depth 10);
* the gait in force → :data:`GAIT_QOS` (as the model: reliable, depth 1, transient local);
* gait switches → :data:`SWITCH_QOS` (reliable, depth 10, transient local).

A RELIABLE subscriber does not match a BEST_EFFORT publisher: subscribe to
state topics with :data:`STATE_QOS` (or best effort) too.
"""

from __future__ import annotations

from collections.abc import Iterable

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from rclpy.qos_overriding_options import QoSOverridingOptions

from suds_ros.io.recording_bag import MODEL_TOPIC
from suds_ros.io.stamps import split_ns

STATE_QOS: QoSProfile = qos_profile_sensor_data
ESTIMATE_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
MODEL_QOS = QoSProfile(
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
STATUS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
#: the gait in force (``suds/gait``): latched like the model, so a late subscriber gets the current one
GAIT_QOS = MODEL_QOS
#: gait switches (``suds/gait_switch``): reliable and kept (the last 10), so a listener whose
#: subscription matched after a switch still places it by its stamp
SWITCH_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Publisher QoS of the player: reliable matches both reliable and best-effort subscribers.
REPLAY_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


def burst_qos(depth: int) -> QoSProfile:
    """:data:`ESTIMATE_QOS` with depth ``depth``, for a publisher that may send many messages at once.

    Such a burst (the estimator's measured velocities of its initial cycles) then reaches reliable
    subscribers in full.
    """
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)


def latched_state_qos(depth: int) -> QoSProfile:
    """Shape/pose publisher QoS of the simulator: reliable, transient local, keep last ``depth``."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def overriding_options() -> QoSOverridingOptions:
    """The QoS overriding options every suds publisher/subscription accepts (``qos_overrides.<topic>...``)."""
    return QoSOverridingOptions.with_default_policies()


def replay_qos(topic: str) -> QoSProfile:
    """Publisher QoS for replaying ``topic``: the model (``/suds/model`` in any namespace) stays latched."""
    if topic == MODEL_TOPIC or topic.endswith(MODEL_TOPIC):
        return MODEL_QOS
    return REPLAY_QOS


def _duration_yaml(d: Duration, indent: str) -> list[str]:
    ns = int(d.nanoseconds)
    if ns <= 0 or ns >= 2**63 - 1:  # "infinite"/default, as rosbag2 writes it
        sec, nsec = 9223372036, 854775807
    else:
        sec, nsec = split_ns(ns)
    return [f"{indent}  sec: {sec}", f"{indent}  nsec: {nsec}"]


def qos_to_yaml(profiles: Iterable[QoSProfile]) -> str:
    """``offered_qos_profiles`` text as rosbag2 (Jazzy) writes it into the MCAP channel metadata.

    Returns ``"[]"`` for no profile.
    """
    lines: list[str] = []
    for q in profiles:
        lines += [
            f"- history: {HistoryPolicy(q.history).name.lower()}",
            f"  depth: {int(q.depth)}",
            f"  reliability: {ReliabilityPolicy(q.reliability).name.lower()}",
            f"  durability: {DurabilityPolicy(q.durability).name.lower()}",
            "  deadline:",
            *_duration_yaml(q.deadline, "  "),
            "  lifespan:",
            *_duration_yaml(q.lifespan, "  "),
            f"  liveliness: {q.liveliness.name.lower()}",
            "  liveliness_lease_duration:",
            *_duration_yaml(q.liveliness_lease_duration, "  "),
            f"  avoid_ros_namespace_conventions: {str(bool(q.avoid_ros_namespace_conventions)).lower()}",
        ]
    return "\n".join(lines) + "\n" if lines else "[]"


def subscription_qos_for(offered: Iterable[QoSProfile], depth: int = 100) -> QoSProfile:
    """A subscription QoS that matches every offered publisher QoS, as ``ros2 bag record`` adapts it.

    Reliable only if all publishers are reliable; transient local only if all are.  History
    keep last ``depth``, or keep all with ``depth`` 0: then DDS queues whatever arrives while the
    subscriber is busy instead of dropping the oldest (the recorder: a burst of thousands of
    messages at once, such as the estimator's measured velocities of its initial cycles, overflows
    any fixed depth of a subscriber that writes each message to a file).
    """
    offered = list(offered)
    reliable = bool(offered) and all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = bool(offered) and all(
        q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered
    )
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST if depth > 0 else HistoryPolicy.KEEP_ALL,
        depth=max(depth, 1),
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )
