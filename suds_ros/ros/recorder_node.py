"""``recorder``: record suds topics, serialized as received, into an MCAP bag like rosbag2.

Topics (parameter ``topics``, shell-style patterns) are discovered from the
graph as their publishers appear.  A relative pattern (the default ones,
``suds/shape``, ``suds/predicted/*``, …: :data:`suds_ros.ros.topics.RECORDED`)
is resolved in the recorder's namespace (``suds/*`` of a recorder started with
``-r __ns:=/robot1`` records ``/robot1/suds/*``); an absolute one is taken as is
(``/robot*/suds/*`` records several robots into one bag).  Every topic is
recorded under its resolved name, so a bag of a namespaced robot holds
``/robot1/suds/shape``; the player's ``strip_prefix`` replays it elsewhere.
Each topic is each is subscribed with ``raw=True`` and a
QoS matching its publishers, and its CDR bytes are written unchanged
(log time = receive time on the node clock, channel metadata
``offered_qos_profiles`` from the publishers).  The open chunk is written
and the file flushed (and, with ``fsync``, synced to the disk) every
``flush_period`` s of log time and on a wall-clock timer of the same period,
so a recorder killed or a machine losing power leaves a file readable up to
the last flush: with the defaults at most the last 0.5 s of data are lost
(``docs/recording_safety.md``).  SIGINT/SIGTERM close the bag with its
summary, after writing what the subscriptions still held of the messages received before
the signal (each topic's history keeps all by default, so a recorder that falls behind under
load is behind, not lossy; ``drain_timeout`` bounds that last catch-up).  An existing output
is never overwritten unless ``overwrite`` is true.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import Any

from rclpy.node import Node

from suds_ros.core.config import check_settings
from suds_ros.core.errors import SudsConfigError, SudsError
from suds_ros.io.mcap import BagWriter
from suds_ros.io.recording_bag import (
    META_ACTUATED,
    META_GAIT_HZ,
    META_PASSIVE,
    META_SYSTEM,
    METADATA_NAME,
)
from suds_ros.ros.conversions import message_class
from suds_ros.ros.params import config_from_parameters
from suds_ros.ros.qos import qos_to_yaml, subscription_qos_for
from suds_ros.ros.discovery import TopicFinder
from suds_ros.ros.runner import run_node
from suds_ros.ros.topics import RECORDED, resolve

DEFAULT_TOPICS = RECORDED


@dataclass(frozen=True)
class RecorderConfig:
    """Recorder parameters (all read-only)."""

    output: str = field(default="", metadata={"description": "output .mcap file (required)"})
    topics: tuple[str, ...] = field(default=DEFAULT_TOPICS, metadata={
        "description": "topics to record; shell-style patterns such as suds/predicted/* "
                       "(relative: in the recorder's namespace) or /robot*/suds/*"})
    overwrite: bool = field(default=False, metadata={
        "description": "replace an existing output file"})
    compression: str = field(default="zstd", metadata={
        "description": "chunk compression: zstd, lz4 or none"})
    flush_period: float = field(default=0.5, metadata={
        "description": "s between flushes: the open chunk is written and the file flushed "
                       "at least this often (log time and wall clock), so a crash or power "
                       "loss loses at most this much data",
        "range": (0.01, 3600.0)})
    fsync: bool = field(default=True, metadata={
        "description": "fsync the file at each flush, so flushed data survive a power loss "
                       "too (false: only a crash of the recorder process)"})
    queue_depth: int = field(default=0, metadata={
        "description": "subscription history per topic: 0 keeps all (messages wait in DDS while the "
                       "recorder is busy, none is dropped); N > 0 keeps the last N (a burst of 5000 "
                       "messages at once lost 70 % of them with 1000)",
        "range": (0, 1_000_000)})
    drain_timeout: float = field(default=3.0, metadata={
        "description": "s at most spent after SIGINT/SIGTERM writing the messages received before "
                       "the signal that are still queued in the subscriptions (0: none)",
        "range": (0.0, 3600.0)})
    discovery_period: float = field(default=0.25, metadata={
        "description": "s between looks for new topics", "range": (0.01, 60.0)})
    system: str = field(default="", metadata={"description": "suds metadata: system id"})
    actuated: str = field(default="", metadata={
        "description": "suds metadata: comma-separated actuated joints"})
    passive: str = field(default="", metadata={
        "description": "suds metadata: comma-separated passive joints"})
    gait_hz: float = field(default=0.0, metadata={
        "description": "suds metadata: nominal gait frequency, Hz (0: unknown)",
        "range": (0.0, 1000.0)})

    def __post_init__(self) -> None:
        check_settings(self)  # the ranges in the field metadata
        if not self.output:
            raise SudsConfigError("`output`: expected the path of the .mcap file to write, got ''")
        if not self.topics:
            raise SudsConfigError("`topics`: expected at least one topic or pattern, got []")
        private = [t for t in self.topics if not t or t.startswith("~")]
        if private:
            raise SudsConfigError(f"`topics`: expected absolute or relative patterns, got {private}")

    def suds_metadata(self) -> dict[str, str]:
        """The ``suds`` metadata record (empty when no system/joint roles are given)."""
        meta = {META_SYSTEM: self.system, META_ACTUATED: self.actuated,
                META_PASSIVE: self.passive}
        meta = {k: v for k, v in meta.items() if v}
        if meta and self.gait_hz > 0:
            meta[META_GAIT_HZ] = repr(self.gait_hz)
        return meta


class RecorderNode(Node):
    """Write every matching topic's serialized messages to ``output``."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("recorder", **kwargs)
        self.config = config_from_parameters(self, RecorderConfig)
        cfg = self.config
        self.patterns = tuple(resolve(t, self.get_namespace()) for t in cfg.topics)
        self._writer = BagWriter(cfg.output, overwrite=cfg.overwrite, compression=cfg.compression,
                                 chunk_interval=cfg.flush_period, fsync=cfg.fsync)
        if cfg.suds_metadata():
            self._writer.write_metadata(METADATA_NAME, cfg.suds_metadata())
        self._subs: dict[str, Any] = {}
        self._written = 0
        self._stop_ns = 0  # wall-clock time of the stop request; 0 while recording
        self._finder = TopicFinder(self, self.patterns, "recording")
        self._discovery = self.create_timer(cfg.discovery_period, self._discover)
        self.create_timer(cfg.flush_period, self._writer.flush)
        self.get_logger().info(f"recording {list(self.patterns)} to {cfg.output}")
        self._discover()

    def _discover(self) -> None:
        for topic, type_name, infos in self._finder.new():
            offered = [i.qos_profile for i in infos]
            try:
                cls = message_class(type_name)
                self._writer.add_topic(topic, type_name, qos_yaml=qos_to_yaml(offered))
            except SudsError as exc:
                self._finder.skip(topic, str(exc))
                continue
            self._subs[topic] = self.create_subscription(
                cls, topic, self._callback(topic), subscription_qos_for(offered, depth=self.config.queue_depth),
                raw=True)
            self._finder.take(topic)
            self.get_logger().info(f"recording {topic} ({type_name})")

    def _callback(self, topic: str) -> Any:
        def on_message(data: bytes, info: dict[str, int]) -> None:
            if self._stop_ns and info.get("received_timestamp", 0) > self._stop_ns:
                return  # arrived after the stop request
            now = self.get_clock().now().nanoseconds
            self._writer.write_raw(topic, data, now, info.get("source_timestamp") or now)
            self._written += 1
        return on_message

    def drain(self, quiet: float = 0.2) -> None:
        """Write the messages received before now that the subscriptions still hold.

        Spins the node's executor (the runner's, still alive at shutdown) until ``quiet`` s pass
        without one (messages arriving after now are not written) or ``drain_timeout`` s have
        passed; does nothing a second time, or without an executor or a live context.
        """
        executor = self.executor
        if executor is None or self._stop_ns or not self.context.ok():
            return
        self._stop_ns = time.time_ns()
        self._discovery.cancel()
        start = written = self._written
        now = time.monotonic()
        deadline, last = now + self.config.drain_timeout, now
        while now < deadline and now - last < quiet:
            executor.spin_once(timeout_sec=quiet / 4)
            now = time.monotonic()
            if self._written != written:
                written, last = self._written, now
        if now >= deadline:
            self.get_logger().warning(f"stopped writing queued messages after drain_timeout "
                                      f"{self.config.drain_timeout} s ({written - start} written)")
        elif written > start:
            self.get_logger().info(f"wrote {written - start} queued messages after the stop request")

    def close(self) -> None:
        """Write what is still queued (:meth:`drain`), then the summary, and close the bag (idempotent)."""
        try:
            self.drain()
        finally:
            self._writer.close()


def main(args: list[str] | None = None) -> int:
    """Run the recorder until SIGINT/SIGTERM; 1 with the reason if it cannot start."""
    return run_node(args, name="recorder", doc=__doc__, config_cls=RecorderConfig,
                    make=RecorderNode, close=RecorderNode.close)


if __name__ == "__main__":
    sys.exit(main())
