"""Config fields that carry their own description, range and check.

Every frozen config dataclass declares its fields with :func:`setting` and calls
:func:`check_settings` first thing in its ``__post_init__`` (cross-field checks follow)::

    @dataclass(frozen=True)
    class RecorderConfig:
        flush_period: float = setting(1.0, "s between flushes", gt=0.0, le=3600.0, read_only=False)

        def __post_init__(self) -> None:
            check_settings(self)

The field's ``metadata`` is then the one source of what a value may be: the check below
reads it, and :mod:`suds_ros.ros.params` builds the node parameters (name, default,
description, ``floating_point_range``/``integer_range``, ``read_only``) from it.

Metadata keys (a plain ``field(metadata={...})`` with these keys works the same):

* ``description`` (str): one line for a person, with the unit;
* ``range`` ((lo, hi), None for an open-ended side): the allowed interval, both ends included
  unless named in ``open`` (a subset of ``{"lo", "hi"}``);
* ``choices`` (tuple): the allowed values;
* ``read_only`` (bool, default True): a node may not change it at runtime.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import types
import typing
from typing import Any

from suds_ros.core.errors import OUT_OF_RANGE, WRONG_TYPE, SudsConfigError

_MISSING: Any = dataclasses.MISSING


def setting(
    default: Any = _MISSING,
    description: str = "",
    *,
    default_factory: Any = _MISSING,
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    choices: tuple[Any, ...] | None = None,
    read_only: bool = True,
    **extra: Any,
) -> Any:
    """A dataclass ``field`` whose metadata holds the description, range and mutability.

    ``ge``/``gt`` give the lower bound (included/excluded), ``le``/``lt`` the upper.
    ``extra`` keys are kept in the metadata as they are (e.g. how a node names nested fields).
    """
    if ge is not None and gt is not None or le is not None and lt is not None:
        raise TypeError("setting: give at most one of ge/gt and one of le/lt")
    meta: dict[str, Any] = {"description": description, "read_only": read_only, **extra}
    lo, hi = (ge if gt is None else gt), (le if lt is None else lt)
    if lo is not None or hi is not None:
        meta["range"] = (lo, hi)
        meta["open"] = frozenset(s for s, b in (("lo", gt), ("hi", lt)) if b is not None)
    if choices is not None:
        meta["choices"] = tuple(choices)
    return dataclasses.field(default=default, default_factory=default_factory, metadata=meta)


def _fmt(x: float) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


def bounds(meta: typing.Mapping[str, Any]) -> tuple[float | None, float | None, frozenset[str]]:
    """``(lo, hi, open sides)`` of a field's metadata (None: no bound on that side)."""
    if "range" not in meta:
        return None, None, frozenset()
    lo, hi, *_ = meta["range"]  # a third element (a ROS step) is ignored here
    return lo, hi, frozenset(meta.get("open", ()))


def expected_text(meta: typing.Mapping[str, Any], integer: bool) -> str:
    """What a field's metadata allows, in words: ``a number in (0, 1]``, ``an integer ≥ 4``."""
    if "choices" in meta:
        return "one of " + ", ".join(repr(c) for c in meta["choices"])
    kind = "an integer" if integer else "a number"
    lo, hi, open_ = bounds(meta)
    if lo is not None and hi is not None:
        return (f"{kind} in {'(' if 'lo' in open_ else '['}{_fmt(lo)}, {_fmt(hi)}"
                f"{')' if 'hi' in open_ else ']'}")
    if lo is not None:
        return f"{kind} {'>' if 'lo' in open_ else '≥'} {_fmt(lo)}"
    if hi is not None:
        return f"{kind} {'<' if 'hi' in open_ else '≤'} {_fmt(hi)}"
    return kind


@functools.lru_cache(maxsize=None)
def _checked_fields(cls: type) -> tuple[tuple[str, typing.Mapping[str, Any], bool, bool], ...]:
    """(name, metadata, integer, optional) of the fields of ``cls`` that have a range or choices."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        if "range" not in f.metadata and "choices" not in f.metadata:
            continue
        tp, optional = hints[f.name], False
        if typing.get_origin(tp) in (typing.Union, types.UnionType) and type(None) in typing.get_args(tp):
            args = [a for a in typing.get_args(tp) if a is not type(None)]
            tp, optional = (args[0] if len(args) == 1 else tp), True
        out.append((f.name, f.metadata, tp is int, optional))
    return tuple(out)


def check_value(name: str, value: Any, meta: typing.Mapping[str, Any], integer: bool) -> None:
    """Check one value against its field metadata.

    Raises
    ------
    SudsConfigError
        ``code`` :data:`~suds_ros.core.errors.WRONG_TYPE` (not a number / not an integer) or
        :data:`~suds_ros.core.errors.OUT_OF_RANGE` (outside the range, not one of the choices);
        the message names the field, what was expected and what was received.
    """
    expected = expected_text(meta, integer)
    if "choices" in meta:
        if value not in meta["choices"]:
            raise SudsConfigError(f"`{name}`: expected {expected}, got {value!r}", code=OUT_OF_RANGE)
        return
    number = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if not number or (integer and not (math.isfinite(value) and float(value).is_integer())):
        raise SudsConfigError(f"`{name}`: expected {expected}, got {value!r}", code=WRONG_TYPE)
    lo, hi, open_ = bounds(meta)
    ok = ((lo is None or (value > lo if "lo" in open_ else value >= lo))
          and (hi is None or (value < hi if "hi" in open_ else value <= hi)))
    if not ok:  # NaN fails every bound
        raise SudsConfigError(f"`{name}`: expected {expected}, got {value!r}", code=OUT_OF_RANGE)


def check_settings(config: Any) -> None:
    """Check every field of the dataclass instance ``config`` that has a range or choices.

    ``None`` passes for an ``X | None`` field (not set).  Call it first in ``__post_init__``.

    Raises
    ------
    SudsConfigError
        The first field out of its range (see :func:`check_value`).
    """
    for name, meta, integer, optional in _checked_fields(type(config)):
        value = getattr(config, name)
        if value is None and optional:
            continue
        check_value(name, value, meta, integer)
