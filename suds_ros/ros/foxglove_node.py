"""``foxglove_bridge``: serve suds topics live to the Foxglove app over a WebSocket.

For set-ups without ROS tools on the viewing side (the pip install): the node
subscribes to the suds topics as serialized messages and forwards their CDR
bytes unchanged to a Foxglove WebSocket server (the ``foxglove-sdk`` package),
one channel per topic, with the ``ros2msg`` schema text of its type
(:func:`suds_ros.io.msgdefs.schema_text`, as in our bags).  In the Foxglove
app: *Open connection* → *Foxglove WebSocket* → ``ws://HOST:PORT``; the
shipped layout (``share/suds_ros/foxglove/suds_layout.json``) then works as on
a bag, the topic names being the same.

Topics (parameter ``topics``, shell-style patterns, default every topic a suds
node publishes: :data:`suds_ros.ros.topics.PUBLISHED`) are discovered from the
graph as their publishers appear; relative patterns resolve in the node's
namespace, as the recorder's do.  Each message's log time is its receive time
on the node clock, in ns (every topic has one, ``std_msgs/String`` included;
the header stamp stays in the payload).  ``port`` 0 takes a free port (the log
line ``serving ... on ws://HOST:PORT`` names it).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from typing import Any

from rclpy.node import Node

from suds_ros.core.config import check_settings
from suds_ros.core.errors import SudsConfigError, SudsError
from suds_ros.io import msgdefs
from suds_ros.ros.conversions import message_class
from suds_ros.ros.params import config_from_parameters
from suds_ros.ros.qos import subscription_qos_for
from suds_ros.ros.discovery import TopicFinder
from suds_ros.ros.runner import run_node
from suds_ros.ros.topics import PUBLISHED, resolve

DEFAULT_TOPICS = PUBLISHED


@dataclass(frozen=True)
class FoxgloveBridgeConfig:
    """Foxglove bridge parameters (all read-only)."""

    host: str = field(default="127.0.0.1", metadata={
        "description": "address the WebSocket server listens on (0.0.0.0: every interface)"})
    port: int = field(default=8765, metadata={
        "description": "WebSocket port (0: any free port)", "range": (0, 65535)})
    topics: tuple[str, ...] = field(default=DEFAULT_TOPICS, metadata={
        "description": "topics to serve; shell-style patterns such as suds/predicted/* "
                       "(relative: in the node's namespace) or /robot*/suds/*"})
    queue_depth: int = field(default=100, metadata={
        "description": "subscription history depth per topic", "range": (1, 100_000)})
    discovery_period: float = field(default=0.25, metadata={
        "description": "s between looks for new topics", "range": (0.01, 60.0)})

    def __post_init__(self) -> None:
        check_settings(self)  # the ranges in the field metadata
        if not self.host:
            raise SudsConfigError("`host`: expected an address such as 127.0.0.1, got ''")
        if not self.topics:
            raise SudsConfigError("`topics`: expected at least one topic or pattern, got []")
        private = [t for t in self.topics if not t or t.startswith("~")]
        if private:
            raise SudsConfigError(f"`topics`: expected absolute or relative patterns, got {private}")


class FoxgloveBridgeNode(Node):
    """Forward every matching topic's serialized messages to a Foxglove WebSocket server."""

    def __init__(self, **kwargs: Any) -> None:
        import foxglove  # optional dependency: only this node needs it

        super().__init__("foxglove_bridge", **kwargs)
        self.config = config_from_parameters(self, FoxgloveBridgeConfig)
        cfg = self.config
        self.patterns = tuple(resolve(t, self.get_namespace()) for t in cfg.topics)
        self._fox = foxglove
        self._fox_context = foxglove.Context()  # not `_context`: rclpy's Node uses that name
        try:
            self._server = foxglove.start_server(name="suds_ros", host=cfg.host, port=cfg.port,
                                                 context=self._fox_context)
        except RuntimeError as exc:
            raise SudsConfigError(f"`host`/`port`: cannot serve on {cfg.host}:{cfg.port}: {exc}") from None
        self.port = self._server.port
        self._channels: dict[str, Any] = {}
        self._subs: dict[str, Any] = {}
        self._finder = TopicFinder(self, self.patterns, "serving")
        self.create_timer(cfg.discovery_period, self._discover)
        self.get_logger().info(f"serving {list(self.patterns)} on ws://{cfg.host}:{self.port}")
        self._discover()

    def _discover(self) -> None:
        for topic, type_name, infos in self._finder.new():
            try:
                cls = message_class(type_name)
                schema = msgdefs.schema_text(type_name).encode("utf-8")
            except SudsError as exc:
                self._finder.skip(topic, str(exc))
                continue
            self._channels[topic] = self._fox.Channel(
                topic, schema=self._fox.Schema(name=type_name, encoding="ros2msg", data=schema),
                message_encoding="cdr", context=self._fox_context)
            qos = subscription_qos_for([i.qos_profile for i in infos], depth=self.config.queue_depth)
            self._subs[topic] = self.create_subscription(cls, topic, self._callback(topic), qos,
                                                         raw=True)
            self._finder.take(topic)
            self.get_logger().info(f"serving {topic} ({type_name})")

    def _callback(self, topic: str) -> Any:
        channel = self._channels[topic]

        def on_message(data: bytes) -> None:
            channel.log(bytes(data), log_time=self.get_clock().now().nanoseconds)
        return on_message

    def close(self) -> None:
        """Stop the WebSocket server and close the channels (idempotent)."""
        for channel in self._channels.values():
            channel.close()
        self._channels.clear()
        self._server.stop()


def main(args: list[str] | None = None) -> int:
    """Run the bridge until SIGINT/SIGTERM; 1 with the reason if it cannot start."""
    return run_node(args, name="foxglove_bridge", doc=__doc__, config_cls=FoxgloveBridgeConfig,
                    make=FoxgloveBridgeNode, close=FoxgloveBridgeNode.close)


if __name__ == "__main__":
    sys.exit(main())
