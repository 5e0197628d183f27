"""suds_ros.io.msgdefs: the ros2msg schema texts and type hashes."""

from __future__ import annotations

import pytest
from _bags import JS, shared

from suds_ros.core.errors import SudsBagError
from suds_ros.io import msgdefs


def test_msg_defs_match_shared_bags_schemas() -> None:
    from mcap.reader import make_reader

    with open(shared("swimmer9_nominal"), "rb") as f:
        schemas = make_reader(f).get_summary().schemas.values()
    for s in schemas:
        assert msgdefs.schema_text(s.name).encode() == s.data
    assert msgdefs.type_hash(JS).startswith("RIHS01_")
    assert len(msgdefs.known_types()) == 6


def test_msg_defs_unknown_type() -> None:
    with pytest.raises(SudsBagError, match=r"'nav_msgs/msg/Odometry' has no schema"):
        msgdefs.schema_text("nav_msgs/msg/Odometry")
