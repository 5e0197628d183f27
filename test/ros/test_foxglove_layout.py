"""The shipped Foxglove layout references only topics the suds nodes publish (no ROS needed)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from suds_ros.ros import topics

LAYOUT = Path(__file__).resolve().parents[2] / "foxglove" / "suds_layout.json"
#: the topic of a Foxglove message path: everything before the first field access or filter
_TOPIC = re.compile(r"^(/[A-Za-z0-9_/]+?)(?=\.|\[|\{|$)")


def message_paths(node) -> list[str]:
    """Every message path of the layout: ``topicPath`` of raw-message panels, ``paths[].value`` of plots."""
    out: list[str] = []
    if isinstance(node, dict):
        for key, value in node.items():
            if key in ("topicPath", "value") and isinstance(value, str) and value:
                out.append(value)
            else:
                out += message_paths(value)
    elif isinstance(node, list):
        for item in node:
            out += message_paths(item)
    return out


def test_layout_references_only_published_topics():
    doc = json.loads(LAYOUT.read_text(encoding="utf-8"))
    published = {topics.resolve(t, "/") for t in topics.PUBLISHED}
    paths = message_paths(doc["configById"])
    assert paths, "the layout shows no topic"
    used = set()
    for path in paths:
        m = _TOPIC.match(path)
        assert m, f"{path!r} does not start with a topic"
        used.add(m.group(1))
    assert used <= published, f"not published by suds: {sorted(used - published)}"
    # what the issue asks to see: predicted vs measured, status, the diagnosis report
    for wanted in (topics.PREDICTED_BODY, topics.MEASURED_BODY, topics.PREDICTED_PASSIVE,
                   topics.MEASURED_PASSIVE, topics.STATUS, topics.DIAGNOSIS):
        assert "/" + wanted in used, wanted


def test_layout_panels_all_placed():
    doc = json.loads(LAYOUT.read_text(encoding="utf-8"))

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(doc["layout"])) == sorted(doc["configById"])


def test_a_topic_outside_suds_is_caught():
    assert _TOPIC.match("/joint_states.position[0]").group(1) == "/joint_states"
    assert _TOPIC.match('/suds/status.status[0].values[:]{key=="phase"}.value').group(1) == "/suds/status"
