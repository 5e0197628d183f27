"""Strict JSON (``suds_ros.core.json_text``): non-finite numbers become null, never NaN/Infinity."""

from __future__ import annotations

import ast
import json
import math
from pathlib import Path

import numpy as np
import pytest

from suds_ros.core.json_text import dumps, finite_or_null

PKG = Path(__file__).resolve().parents[2] / "suds_ros"

#: modules that may call json.dump(s) themselves, and why
OWN_JSON = {
    "core/json_text.py": "the helper itself",
    "io/checkpoint.py": "the estimator's own checkpoint header: NaN state must round-trip, read only by us",
    "ros/simulator_node.py": "a log line, not a document",
}


def strict_loads(text: str) -> object:
    return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))


def test_non_finite_numbers_become_null_everywhere() -> None:
    obj = {
        "nan": float("nan"), "inf": math.inf, "ninf": -np.inf, "np_nan": np.float32("nan"),
        "finite": 1.5, "np_finite": np.float64(2.5), "int": np.int64(3), "flag": np.bool_(True),
        "nested": {"list": [1.0, float("nan"), {"deep": (np.inf, 0.0)}]},
        "array": np.array([[1.0, np.nan], [np.inf, -2.0]]),
        "none": None, "text": "nan",
    }
    got = finite_or_null(obj)
    assert got == {
        "nan": None, "inf": None, "ninf": None, "np_nan": None,
        "finite": 1.5, "np_finite": 2.5, "int": 3, "flag": True,
        "nested": {"list": [1.0, None, {"deep": [None, 0.0]}]},
        "array": [[1.0, None], [None, -2.0]],
        "none": None, "text": "nan",
    }
    assert type(got["flag"]) is bool and type(got["int"]) is int and type(got["np_finite"]) is float
    assert strict_loads(dumps(obj, indent=2)) == got


def test_finite_values_are_written_as_json_would() -> None:
    obj = {"a": [1, 2.25, -1e-300, 1e300], "b": "x", "c": True, "d": None}
    assert dumps(obj, sort_keys=True) == json.dumps(obj, sort_keys=True)


def test_a_value_the_conversion_cannot_see_raises_instead_of_writing_nan() -> None:
    class Opaque:
        pass

    # the conversion leaves unknown objects to json's `default`; what it returns is still checked
    with pytest.raises(ValueError, match="Out of range float values are not JSON compliant"):
        dumps({"x": Opaque()}, default=lambda o: float("nan"))
    assert strict_loads(dumps({"x": Opaque()}, default=lambda o: "opaque")) == {"x": "opaque"}


def test_allow_nan_cannot_be_switched_back_on() -> None:
    with pytest.raises(TypeError, match="`allow_nan` is fixed to False"):
        dumps({"x": 1.0}, allow_nan=True)


def _json_dump_calls(path: Path) -> list[int]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [n.lineno for n in ast.walk(tree)
            if isinstance(n, ast.Attribute) and n.attr in ("dump", "dumps")
            and isinstance(n.value, ast.Name) and n.value.id == "json"]


def test_every_json_document_goes_through_the_helper() -> None:
    """No module writes JSON with json.dump(s) directly (which writes NaN), except the listed ones."""
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG).as_posix()
        lines = _json_dump_calls(path)
        if lines and rel not in OWN_JSON:
            bad.append(f"suds_ros/{rel}: json.dump(s) at line(s) {lines}; use suds_ros.core.json_text.dumps")
    assert not bad, "\n".join(bad)


def test_the_audit_sees_a_direct_call(tmp_path: Path) -> None:
    f = tmp_path / "x.py"
    f.write_text("import json\nprint(json.dumps({'a': float('nan')}))\n")
    assert _json_dump_calls(f) == [2]
