"""Finding topics to subscribe to by name pattern (the recorder and the Foxglove bridge)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from fnmatch import fnmatchcase
from typing import Any


class TopicFinder:
    """New topics whose names match ``patterns``, with exactly one type and at least one publisher.

    ``verb`` words the warning for a topic that cannot be taken ("not recording /x: …").
    """

    def __init__(self, node: Any, patterns: Iterable[str], verb: str) -> None:
        self.node = node
        self.patterns = tuple(patterns)
        self.verb = verb
        self.taken: set[str] = set()
        self.skipped: set[str] = set()

    def new(self) -> Iterator[tuple[str, str, list[Any]]]:
        """(topic, type name, publisher infos) of every matching topic not yet taken or skipped."""
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.taken or topic in self.skipped:
                continue
            if not any(fnmatchcase(topic, p) for p in self.patterns):
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            if not infos:
                continue  # only subscribers so far
            if len(types) != 1:
                self.skip(topic, f"it has several types {types}")
                continue
            yield topic, types[0], infos

    def take(self, topic: str) -> None:
        """Mark ``topic`` as subscribed."""
        self.taken.add(topic)

    def skip(self, topic: str, why: str) -> None:
        """Never look at ``topic`` again, with a warning that says why."""
        self.skipped.add(topic)
        self.node.get_logger().warning(f"not {self.verb} {topic}: {why}")
