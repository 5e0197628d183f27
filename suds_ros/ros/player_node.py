"""``player``: replay a bag's topics, publishing the recorded CDR bytes with the original timing.

Parameters: ``bag``, ``rate`` (> 0, playback speed factor), ``loop``,
``start_offset`` (s into the bag), ``topics`` (empty: all), ``clock``
(publish ``/clock`` with the bag log time before each message) and ``delay``
(s to wait after creating the publishers, so subscribers can match).
Exits when the bag is done unless ``loop`` is set.

Topics are published under their recorded (absolute) names; remapping applies
(``-r /suds/shape:=/robot2/suds/shape``).  With ``strip_prefix`` (e.g. ``/robot1``,
or ``/`` for every topic) a recorded name starting with it is published without
it as a relative name, resolved in the player's namespace: a bag of
``/robot1/suds/*`` replays into ``/robot2/suds/*`` with ``strip_prefix:=/robot1``
and ``-r __ns:=/robot2``.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.node import Node

from suds_ros.core.config import check_settings
from suds_ros.core.errors import MISSING_TOPIC, SudsBagError, SudsConfigError
from suds_ros.io.mcap import bag_info, iter_raw_messages
from suds_ros.io.stamps import float_to_ns, ns_to_float
from suds_ros.ros.conversions import message_class, ns_to_time
from suds_ros.ros.params import config_from_parameters
from suds_ros.ros.qos import replay_qos
from suds_ros.ros.runner import run_node
from suds_ros.ros.topics import CLOCK


@dataclass(frozen=True)
class PlayerConfig:
    """Player parameters (all read-only)."""

    bag: str = field(default="", metadata={"description": "the .mcap bag to play (required)"})
    rate: float = field(default=1.0, metadata={
        "description": "playback speed factor (> 0; 2.0 plays twice as fast)",
        "range": (1e-3, 1e3)})
    loop: bool = field(default=False, metadata={"description": "restart at the end, forever"})
    start_offset: float = field(default=0.0, metadata={
        "description": "s into the bag (log time) where playback starts", "range": (0.0, 1e9)})
    topics: tuple[str, ...] = field(default=(), metadata={
        "description": "topics to play (empty: all)"})
    clock: bool = field(default=False, metadata={
        "description": "publish /clock (bag log time) before each message"})
    delay: float = field(default=0.0, metadata={
        "description": "s to wait before the first message, for subscribers to match",
        "range": (0.0, 3600.0)})
    strip_prefix: str = field(default="", metadata={
        "description": "recorded names starting with this prefix are published without it, as "
                       "relative names in the player's namespace ('/': all; empty: as recorded)"})
    wait_subscribers: int = field(default=0, metadata={
        "description": "before playing, wait (up to 60 s) until every played topic has this many "
                       "matched subscribers", "range": (0, 1000)})

    def __post_init__(self) -> None:
        check_settings(self)  # the ranges in the field metadata
        if not self.bag:
            raise SudsConfigError("`bag`: expected the path of an .mcap bag, got ''")
        if not self.rate > 0:
            raise SudsConfigError(f"`rate`: expected a factor > 0, got {self.rate!r}")
        if self.strip_prefix and not self.strip_prefix.startswith("/"):
            raise SudsConfigError(f"`strip_prefix`: expected an absolute prefix such as '/robot1', "
                                  f"got {self.strip_prefix!r}")

    def published_name(self, topic: str) -> str:
        """The name ``topic`` (as recorded) is published under (see the module doc)."""
        prefix = self.strip_prefix.rstrip("/")
        if self.strip_prefix and (topic.startswith(prefix + "/")):
            return topic[len(prefix):].lstrip("/")
        return topic


class PlayerNode(Node):
    """Publishers for the bag's topics; :meth:`play` sends the messages."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("player", **kwargs)
        self.config = config_from_parameters(self, PlayerConfig)
        info = bag_info(self.config.bag)
        wanted = set(self.config.topics) or set(info.topics)
        missing = wanted - set(info.topics)
        if missing:
            msg = f"`topics`: {sorted(missing)} not in {self.config.bag}; it has {sorted(info.topics)}"
            raise SudsBagError(msg, code=MISSING_TOPIC)
        if info.start_ns is None:
            raise SudsBagError(f"{self.config.bag}: the bag holds no message", code=MISSING_TOPIC)
        self._start_ns = info.start_ns + float_to_ns(self.config.start_offset)
        self._pubs = {
            topic: self.create_publisher(
                message_class(info.topics[topic].type_name), self.config.published_name(topic),
                replay_qos(topic))
            for topic in sorted(wanted)
        }
        self.get_logger().info(
            f"playing {self.config.bag} at rate {self.config.rate:g}: "
            + ", ".join(f"{t} -> {p.topic_name}" for t, p in self._pubs.items()))
        self._clock_cls = message_class("rosgraph_msgs/msg/Clock")
        self._clock = self.create_publisher(self._clock_cls, CLOCK, 10) if self.config.clock else None

    def _sleep_until(self, deadline: float) -> bool:
        while rclpy.ok(context=self.context):
            left = deadline - time.monotonic()
            if left <= 0:
                return True
            time.sleep(min(left, 0.05))
        return False

    def play(self) -> int:
        """Publish the bag once (or forever with ``loop``); returns the number of messages sent."""
        cfg = self.config
        if cfg.wait_subscribers:
            deadline = time.monotonic() + 60.0
            while any(p.get_subscription_count() < cfg.wait_subscribers for p in self._pubs.values()):
                if time.monotonic() > deadline:
                    short = sorted(t for t, p in self._pubs.items()
                                   if p.get_subscription_count() < cfg.wait_subscribers)
                    raise SudsBagError(f"`wait_subscribers`: after 60 s, {short} still have fewer "
                                       f"than {cfg.wait_subscribers} subscriber(s)")
                if not self._sleep_until(time.monotonic() + 0.05):
                    return 0
        if not self._sleep_until(time.monotonic() + cfg.delay):
            return 0
        sent = 0
        while True:
            t0 = time.monotonic()
            for m in iter_raw_messages(cfg.bag, topics=list(self._pubs)):
                if m.log_time_ns < self._start_ns:
                    continue
                if not self._sleep_until(t0 + ns_to_float(m.log_time_ns - self._start_ns) / cfg.rate):
                    return sent
                if self._clock is not None:
                    self._clock.publish(self._clock_cls(clock=ns_to_time(m.log_time_ns)))
                self._pubs[m.topic].publish(m.data)
                sent += 1
            if not cfg.loop:
                for pub in self._pubs.values():  # let reliable subscribers receive the tail
                    pub.wait_for_all_acked(Duration(seconds=2.0))
                return sent


def _play(node: PlayerNode) -> None:
    sent = node.play()
    node.get_logger().info(f"played {sent} messages from {node.config.bag}")


def main(args: list[str] | None = None) -> int:
    """Play the bag; 0 when done (or interrupted), 1 with the reason if it cannot start."""
    return run_node(args, name="player", doc=__doc__, config_cls=PlayerConfig, make=PlayerNode,
                    run=_play)


if __name__ == "__main__":
    sys.exit(main())
