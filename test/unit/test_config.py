"""core/config.py: a config field's metadata is its one check (name, expected, received, code)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import pytest

from suds_ros.core.config import check_settings, expected_text, setting
from suds_ros.core.diagnosis.monitor import MonitorConfig
from suds_ros.core.errors import OUT_OF_RANGE, WRONG_TYPE, SudsConfigError
from suds_ros.core.ident.online import OnlineConfig
from suds_ros.core.ident.session import SessionConfig
from suds_ros.core.ident.sysid import SudsConfig


@dataclass(frozen=True)
class Toy:
    gain: float = setting(0.5, "a gain", gt=0.0, le=1.0, read_only=False)
    order: int = setting(3, "an order", ge=0, le=64)
    lower: int = setting(4, "at least four", ge=4)
    mode: str = setting("a", "a mode", choices=("a", "b"))
    limit: float | None = setting(None, "unset or positive", gt=0.0)

    def __post_init__(self) -> None:
        check_settings(self)


def test_metadata_holds_description_range_and_mutability():
    meta = {f.name: f.metadata for f in fields(Toy)}
    assert meta["gain"]["description"] == "a gain" and not meta["gain"]["read_only"]
    assert meta["gain"]["range"] == (0.0, 1.0) and meta["gain"]["open"] == {"lo"}
    assert meta["order"]["read_only"] and meta["order"]["open"] == frozenset()
    assert expected_text(meta["gain"], integer=False) == "a number in (0, 1]"
    assert expected_text(meta["order"], integer=True) == "an integer in [0, 64]"
    assert expected_text(meta["lower"], integer=True) == "an integer ≥ 4"
    assert expected_text(meta["mode"], integer=False) == "one of 'a', 'b'"


@pytest.mark.parametrize(("changes", "match", "code"), [
    ({"gain": 0.0}, r"^`gain`: expected a number in \(0, 1\], got 0\.0$", OUT_OF_RANGE),
    ({"gain": 1.5}, r"^`gain`: expected a number in \(0, 1\], got 1\.5$", OUT_OF_RANGE),
    ({"gain": math.nan}, r"^`gain`: .* got nan$", OUT_OF_RANGE),
    ({"gain": "x"}, r"^`gain`: expected a number in \(0, 1\], got 'x'$", WRONG_TYPE),
    ({"gain": True}, r"^`gain`: .* got True$", WRONG_TYPE),
    ({"order": 2.5}, r"^`order`: expected an integer in \[0, 64\], got 2\.5$", WRONG_TYPE),
    ({"order": 65}, r"^`order`: expected an integer in \[0, 64\], got 65$", OUT_OF_RANGE),
    ({"lower": 3}, r"^`lower`: expected an integer ≥ 4, got 3$", OUT_OF_RANGE),
    ({"mode": "c"}, r"^`mode`: expected one of 'a', 'b', got 'c'$", OUT_OF_RANGE),
    ({"limit": -1.0}, r"^`limit`: expected a number > 0, got -1\.0$", OUT_OF_RANGE),
])
def test_a_value_outside_its_metadata_is_refused_naming_field_expected_and_received(changes, match, code):
    with pytest.raises(SudsConfigError, match=match) as info:
        Toy(**changes)
    assert info.value.code == code


def test_values_inside_pass_and_unset_optional_passes():
    Toy(gain=1.0, order=64, lower=10**9, mode="b", limit=None)
    Toy(gain=1e-300, order=0, limit=2.0)


@pytest.mark.parametrize(("cls", "kwargs", "match"), [
    (SudsConfig, {"forgetting": 0.0}, r"`forgetting`: expected a number in \(0, 1\], got 0\.0"),
    (SudsConfig, {"state": "end"}, r"`state`: expected one of 'start', 'midpoint', got 'end'"),
    (SudsConfig, {"linear_order": -1}, r"`linear_order`: expected an integer in \[0, 64\], got -1"),
    (OnlineConfig, {"init_cycles": 2.0}, r"`init_cycles`: expected a number in \[3, 1000\], got 2\.0"),
    (OnlineConfig, {"chunk": 0}, r"`chunk`: expected an integer in \[1, 1000000\], got 0"),
    (MonitorConfig, {"warn": 1.0}, r"`warn`: expected a number in \(1, 1e\+09\], got 1\.0"),
    (SessionConfig, {"pose_stall": 0.0}, r"`pose_stall`: expected a number in \[0\.01, 3600\], got 0\.0"),
])
def test_core_configs_check_their_ranges_through_the_metadata(cls, kwargs, match):
    with pytest.raises(SudsConfigError, match=match) as info:
        cls(**kwargs)
    assert info.value.code == OUT_OF_RANGE


def test_every_scalar_field_of_the_core_configs_has_a_description():
    for cls in (SudsConfig, OnlineConfig, MonitorConfig, SessionConfig):
        for f in fields(cls):
            assert f.metadata.get("description"), f"{cls.__name__}.{f.name}"


def test_setting_refuses_two_bounds_on_one_side():
    with pytest.raises(TypeError, match="at most one"):
        setting(1.0, "x", ge=0.0, gt=0.0)
