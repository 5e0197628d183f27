"""Node parameters generated from (nested) frozen config dataclasses.

A node's config is a frozen dataclass whose fields are declared with
:func:`~suds_ros.core.config.setting` (or a ``field`` with the same metadata): the
metadata's description, range and ``read_only`` become the parameter's
``ParameterDescriptor``; the default is the config's own default.  A field whose type
is itself a config dataclass (a node config holding the core config) is walked into:

* its parameters are named ``<field>.<name>``, or just ``<name>`` when the field's
  metadata has ``parameters={"flatten": True}`` (the whole subtree is then flat: the
  estimator's ``chunk`` and ``linear_order`` live in ``session.online`` and
  ``session.online.suds``);
* ``parameters={"exclude": ("gait_hz", ...)}`` leaves fields of the nested config out
  (they keep their default, or the node sets them another way);
* ``parameters={"unset": {"gait_hz": "the model's gait_hz"}}`` declares such a
  parameter "not set" by default; the node gives its value at start-up
  (``fill`` of :func:`build_config`).

Defaults come from the default instance of the enclosing config, so a nested default
(``OnlineConfig().suds.linear_order``) is the one declared.  Two parameters with the
same name are refused when the node is built (a :class:`TypeError`: a programming error).

Field types map to parameter types: bool, int, float, str, and ``tuple[T, ...]``/``list``
of str, int, float or bool (arrays).  ``X | None`` fields are declared with dynamic
typing and default "not set" (None).

Checking is the dataclasses' own: a config is valid when it can be built (its
``__post_init__`` checks ranges through :func:`~suds_ros.core.config.check_settings`
and whatever depends on several fields).  So

* at start-up :func:`config_from_parameters` builds the config from the declared
  values; any failure raises :class:`~suds_ros.core.errors.SudsConfigError` with the
  config's reason (the node stops with it);
* at runtime :func:`watch_parameters` registers an on-set callback that only builds the
  candidate config (refusing the set with the config's reason) and a post-set callback
  that builds it again from the parameters actually set and hands it to the node.

The descriptor ranges (for ``ros2 param describe``) are the metadata's, so rclpy itself
refuses a value outside them before either callback runs; a bound the descriptor cannot
express (an open end) is left to the config.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import sys
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple, TypeVar

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from suds_ros.core.config import bounds, expected_text
from suds_ros.core.errors import SudsConfigError, SudsError

C = TypeVar("C")
Path = tuple[str, ...]

_SCALAR = {
    bool: ParameterType.PARAMETER_BOOL,
    int: ParameterType.PARAMETER_INTEGER,
    float: ParameterType.PARAMETER_DOUBLE,
    str: ParameterType.PARAMETER_STRING,
}
_ARRAY = {
    bool: ParameterType.PARAMETER_BOOL_ARRAY,
    int: ParameterType.PARAMETER_INTEGER_ARRAY,
    float: ParameterType.PARAMETER_DOUBLE_ARRAY,
    str: ParameterType.PARAMETER_STRING_ARRAY,
}
_INT64 = 2**63 - 1


class ParamSpec(NamedTuple):
    """One parameter: its public name, where it lives in the config, its type and descriptor."""

    name: str
    path: Path  # attribute path from the node config to the field
    is_array: bool
    optional: bool  # may stay unset (None): an ``X | None`` field or an ``unset`` one
    default: Any
    descriptor: ParameterDescriptor


class _Layout(NamedTuple):
    specs: tuple[ParamSpec, ...]
    nested: frozenset[Path]  # paths of the nested config dataclasses


def _unwrap_optional(tp: Any) -> tuple[Any, bool]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0], True
    return tp, False


def _param_type(where: str, tp: Any) -> tuple[int, bool, bool]:
    """(ParameterType, is_array, optional) of a field annotation."""
    tp, optional = _unwrap_optional(tp)
    if tp in _SCALAR:
        return _SCALAR[tp], False, optional
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (tuple, list) and args and args[0] in _ARRAY:
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            raise TypeError(f"{where}: use tuple[T, ...] for an array parameter, got {tp}")
        return _ARRAY[args[0]], True, optional
    raise TypeError(f"{where}: field type {tp} has no ROS parameter type (exclude it or nest a dataclass)")


def _field_default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None  # required: must come from an override


def _default_instance(cls: type) -> Any:
    try:
        return cls()
    except (TypeError, ValueError):  # required fields, or defaults that only make sense with overrides
        return None


def _descriptor(name: str, ptype: int, optional: bool, meta: Mapping[str, Any], unset: str | None,
                integer: bool) -> ParameterDescriptor:
    description = str(meta.get("description") or name.rsplit(".", 1)[-1])
    if unset is not None:
        description += f" (unset: {unset})"
    d = ParameterDescriptor(name=name, type=ptype, description=description,
                            read_only=bool(meta.get("read_only", True)), dynamic_typing=optional)
    if "range" in meta or "choices" in meta:
        d.additional_constraints = expected_text(meta, integer)
    lo, hi, _ = bounds(meta)
    if lo is None and hi is None:
        return d
    if ptype == ParameterType.PARAMETER_DOUBLE:
        d.floating_point_range = [FloatingPointRange(
            from_value=-math.inf if lo is None else float(lo), to_value=math.inf if hi is None else float(hi),
            step=0.0)]
    elif ptype == ParameterType.PARAMETER_INTEGER:
        d.integer_range = [IntegerRange(from_value=-_INT64 if lo is None else math.ceil(lo),
                                        to_value=_INT64 if hi is None else math.floor(hi), step=1)]
    return d


@functools.lru_cache(maxsize=None)
def layout(cls: type) -> _Layout:
    """Every parameter of the config dataclass ``cls`` (walking nested configs; see the module doc)."""
    if not (dataclasses.is_dataclass(cls) and isinstance(cls, type)):
        raise TypeError(f"`cls`: expected a dataclass type, got {cls!r}")
    specs: list[ParamSpec] = []
    nested: set[Path] = set()

    def walk(c: type, inst: Any, path: Path, prefix: str, flat: bool, exclude: frozenset[Path],
             unset: Mapping[Path, str]) -> None:
        hints = typing.get_type_hints(c)
        for f in dataclasses.fields(c):
            p = path + (f.name,)
            if not f.init or p in exclude:
                continue
            default = getattr(inst, f.name) if inst is not None else _field_default(f)
            tp = hints[f.name]
            if dataclasses.is_dataclass(tp) and isinstance(tp, type):
                opts = f.metadata.get("parameters", {})
                nested.add(p)
                walk(tp, default if default is not None else _default_instance(tp), p,
                     prefix if flat or opts.get("flatten") else f"{prefix}{f.name}.",
                     flat or bool(opts.get("flatten")),
                     exclude | {p + tuple(e.split(".")) for e in opts.get("exclude", ())},
                     {**unset, **{p + tuple(k.split(".")): v for k, v in opts.get("unset", {}).items()}})
                continue
            name = f"{prefix}{f.name}"
            ptype, is_array, optional = _param_type(f"{c.__name__}.{f.name}", tp)
            why_unset = unset.get(p)
            if why_unset is not None:
                optional, default = True, None
            if is_array and default is not None:
                default = list(default)
            desc = _descriptor(name, ptype, optional, f.metadata, why_unset, _unwrap_optional(tp)[0] is int)
            specs.append(ParamSpec(name, p, is_array, optional, default, desc))

    walk(cls, _default_instance(cls), (), "", False, frozenset(), {})
    seen: dict[str, Path] = {}
    for s in specs:
        if s.name in seen:
            raise TypeError(f"{cls.__name__}: parameter `{s.name}` would name both "
                            f"{'.'.join(seen[s.name])} and {'.'.join(s.path)} (exclude one)")
        seen[s.name] = s.path
    return _Layout(tuple(specs), frozenset(nested))


def descriptors(cls: type) -> list[tuple[str, Any, ParameterDescriptor]]:
    """``(name, default, descriptor)`` of every parameter of the config dataclass ``cls``."""
    return [(s.name, s.default, s.descriptor) for s in layout(cls).specs]


def declare_parameters(node: Node, cls: type) -> None:
    """Declare every parameter of ``cls`` on ``node`` (defaults and descriptors from the dataclass).

    Raises
    ------
    SudsConfigError
        If an override has the wrong type or is outside the declared range.
    """
    for s in layout(cls).specs:
        value: Any = s.default
        desc = copy.deepcopy(s.descriptor)  # rclpy writes into the descriptor it is given
        if s.default is None or (isinstance(s.default, list) and not s.default):
            # no typed default: declare by type, so only an override of that type is accepted
            value = None if desc.dynamic_typing else Parameter.Type(desc.type)
        try:
            node.declare_parameter(s.name, value, desc)
        except Exception as exc:  # rclpy raises several unrelated exception types here
            msg = f"parameter `{s.name}`: {exc}"
            raise SudsConfigError(msg) from None


def _value(node: Node, spec: ParamSpec) -> Any:
    try:
        v = node.get_parameter(spec.name).value
    except ParameterUninitializedException:
        return None
    if v is None:
        return None
    return tuple(v) if spec.is_array else v


def _construct(cls: type, inst: Any, path: Path, values: Mapping[Path, Any], nested: frozenset[Path],
               extra: Mapping[str, Any]) -> Any:
    """``cls`` built from ``inst`` (its default, or the current config) with the values under ``path``."""
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        p = path + (f.name,)
        if not f.init:
            continue
        if p in nested:
            sub = getattr(inst, f.name) if inst is not None else _field_default(f)
            if any(q[:len(p)] == p for q in values):
                kwargs[f.name] = _construct(type(sub), sub, p, values, nested, {})
            elif inst is None:
                kwargs[f.name] = sub
        elif p in values:
            kwargs[f.name] = values[p]
    kwargs.update(extra)
    return dataclasses.replace(inst, **kwargs) if inst is not None else cls(**kwargs)


def _refusal(exc: Exception) -> SudsConfigError:
    return SudsConfigError(f"node parameters: {exc}", code=getattr(exc, "code", None))


def build_config(node: Node, cls: type[C], fill: Mapping[str, Callable[[dict[str, Any]], Any]] | None = None,
                 **extra: Any) -> C:
    """Build ``cls`` from the declared parameters (and ``extra`` top-level fields).

    ``fill[name](values)`` gives the value of the parameter ``name`` when it is not set
    (``values``: every parameter's value by name).

    Raises
    ------
    SudsConfigError
        The config's reason when it refuses a value, or a required parameter is unset.
    """
    lay = layout(cls)
    named = {s.name: _value(node, s) for s in lay.specs}
    for s in lay.specs:
        if named[s.name] is None and not s.optional:
            named[s.name] = tuple(s.default) if s.is_array and s.default is not None else s.default
    for s in lay.specs:
        if named[s.name] is None and fill and s.name in fill:
            named[s.name] = fill[s.name](dict(named))
    values: dict[Path, Any] = {}
    for s in lay.specs:
        v = named[s.name]
        if v is None and not _none_allowed(cls, s):
            raise SudsConfigError(f"parameter `{s.name}` is required but was not set")
        if s.path[-1] not in extra or len(s.path) > 1:
            values[s.path] = v
    try:
        return typing.cast(C, _construct(cls, _default_instance(cls), (), values, lay.nested, extra))
    except (SudsError, ValueError, TypeError) as exc:
        raise _refusal(exc) from None


def _none_allowed(cls: type, spec: ParamSpec) -> bool:
    """True when the field itself is ``X | None`` (not just left unset for the node to fill)."""
    c: Any = cls
    for attr in spec.path[:-1]:
        c = typing.get_type_hints(c)[attr]
    return _unwrap_optional(typing.get_type_hints(c)[spec.path[-1]])[1]


def config_from_parameters(node: Node, cls: type[C],
                           fill: Mapping[str, Callable[[dict[str, Any]], Any]] | None = None, **extra: Any) -> C:
    """Declare the parameters of ``cls`` on ``node`` and build the config (see :func:`build_config`)."""
    declare_parameters(node, cls)
    return build_config(node, cls, fill, **extra)


def candidate(config: C, params: list[Parameter]) -> C | None:
    """``config`` with the parameters ``params`` (those of its class) changed; None if none is its.

    Raises
    ------
    SudsError, ValueError, TypeError
        What the config's ``__post_init__`` raises for the changed values.
    """
    lay = layout(type(config))
    by_name = {s.name: s for s in lay.specs}
    values: dict[Path, Any] = {}
    for p in params:
        s = by_name.get(p.name)
        if s is not None:
            v = p.value
            values[s.path] = tuple(v) if isinstance(v, list) else v
    if not values:
        return None
    return typing.cast(C, _construct(type(config), config, (), values, lay.nested, {}))


def watch_parameters(node: Node, get_config: Callable[[], C], apply: Callable[[C], None]) -> None:
    """Let the runtime-changeable parameters of ``get_config()``'s class change the node's config.

    On set, the candidate config is built (:func:`candidate`): a config that refuses it
    refuses the whole set, with its reason (naming the field, what was expected and what
    was received).  Nothing is applied then: only once every on-set callback of the node
    has accepted and the values are stored, the post-set callback builds the config from
    them again and calls ``apply(new_config)``.
    """

    def validate(params: list[Parameter]) -> SetParametersResult:
        try:
            candidate(get_config(), params)
        except (SudsError, ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def commit(params: list[Parameter]) -> None:
        try:
            new = candidate(get_config(), params)
        except (SudsError, ValueError, TypeError) as exc:  # accepted a moment ago: cannot happen
            node.get_logger().error(f"parameters were set but the config refused them: {exc}")
            return
        if new is not None:
            apply(new)

    node.add_on_set_parameters_callback(validate)
    node.add_post_set_parameters_callback(commit)


def parameters_help(prog: str, summary: str, cls: type | tuple[type, ...]) -> str:
    """Usage text of a node: ``summary`` and one line per parameter (type, default, description).

    ``cls`` is the node's config dataclass, or a tuple of them when it declares several.
    """
    lines = [f"usage: {prog} [--ros-args -p NAME:=VALUE ... | --params-file FILE]", "", summary, "",
             "parameters:"]
    classes = cls if isinstance(cls, tuple) else (cls,)
    for name, default, d in (row for c in classes for row in descriptors(c)):
        kind = Parameter.Type(d.type).name.lower()
        ro = ", read-only" if d.read_only else ""
        allowed = f"; {d.additional_constraints}" if d.additional_constraints else ""
        lines.append(f"  {name} ({kind}{ro}, default {default!r}): {d.description}{allowed}")
    return "\n".join(lines)


def wants_help(args: list[str] | None) -> bool:
    """True when the non-ROS command-line arguments ask for ``-h``/``--help``."""
    from rclpy.utilities import remove_ros_args

    argv = remove_ros_args(args=sys.argv if args is None else args)
    return any(a in ("-h", "--help") for a in argv[1:])
