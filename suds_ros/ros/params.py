"""Declare ROS parameters from a frozen config dataclass and build the config from them.

Each dataclass field becomes one parameter ``<namespace>.<field>`` (or
``<field>`` with an empty namespace).  Per-field options go in the field's
``metadata``::

    @dataclass(frozen=True)
    class RecorderConfig:
        flush_period: float = field(default=1.0, metadata={
            "description": "seconds between flushes", "range": (0.01, 3600.0),
            "read_only": False})

* ``description`` (str): shown by ``ros2 param describe``; defaults to the field name;
* ``range`` ((lo, hi) or (lo, hi, step)): a ``floating_point_range`` or ``integer_range``;
* ``read_only`` (bool, default True): structural parameters cannot change at runtime.

Field types map to parameter types: bool, int, float, str, and ``tuple``/``list``
of str, int or float (arrays).  ``X | None`` fields are declared with dynamic
typing and default "not set" (None).  :func:`config_from_parameters` declares
and builds in one go; any failure (a wrong type, an out-of-range value, the
dataclass's own ``__post_init__`` check) raises
:class:`~suds_ros.core.errors.SudsConfigError` naming the parameter, so the
node stops at startup with that reason.
"""

from __future__ import annotations

import dataclasses
import sys
import types
import typing
from collections.abc import Callable
from typing import Any, TypeVar

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

from suds_ros.core.errors import SudsConfigError, SudsError

C = TypeVar("C")

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


def _param_name(namespace: str, name: str) -> str:
    return f"{namespace}.{name}" if namespace else name


def _unwrap_optional(tp: Any) -> tuple[Any, bool]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0], True
    return tp, False


def _param_type(cls_name: str, name: str, tp: Any) -> tuple[int, bool, bool]:
    """(ParameterType, is_array, optional) of a field annotation."""
    tp, optional = _unwrap_optional(tp)
    if tp in _SCALAR:
        return _SCALAR[tp], False, optional
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (tuple, list) and args and args[0] in _ARRAY:
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            raise TypeError(f"{cls_name}.{name}: use tuple[T, ...] for an array parameter, got {tp}")
        return _ARRAY[args[0]], True, optional
    raise TypeError(f"{cls_name}.{name}: field type {tp} has no ROS parameter type")


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None  # required: must come from an override


def descriptors(cls: type, namespace: str = "") -> list[tuple[str, Any, ParameterDescriptor]]:
    """``(name, default, descriptor)`` for every field of the dataclass ``cls``."""
    if not (dataclasses.is_dataclass(cls) and isinstance(cls, type)):
        raise TypeError(f"`cls`: expected a dataclass type, got {cls!r}")
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        ptype, is_array, optional = _param_type(cls.__name__, f.name, hints[f.name])
        meta = f.metadata
        default = _default(f)
        d = ParameterDescriptor(
            name=_param_name(namespace, f.name),
            type=ptype,
            description=str(meta.get("description", f.name)),
            read_only=bool(meta.get("read_only", True)),
            dynamic_typing=optional,
        )
        if "range" in meta:
            lo, hi, *step = meta["range"]
            if ptype == ParameterType.PARAMETER_DOUBLE:
                d.floating_point_range = [
                    FloatingPointRange(from_value=float(lo), to_value=float(hi),
                                       step=float(step[0]) if step else 0.0)
                ]
            elif ptype == ParameterType.PARAMETER_INTEGER:
                d.integer_range = [
                    IntegerRange(from_value=int(lo), to_value=int(hi), step=int(step[0]) if step else 1)
                ]
        if is_array and default is not None:
            default = list(default)
        out.append((f.name, default, d))
    return out


def declare_from_dataclass(node: Node, cls: type, namespace: str = "") -> None:
    """Declare one parameter per field of ``cls`` on ``node`` (defaults from the dataclass).

    Raises
    ------
    SudsConfigError
        If an override has the wrong type or is outside the declared range.
    """
    for name, default, desc in descriptors(cls, namespace):
        full = _param_name(namespace, name)
        value: Any = default
        if default is None or (isinstance(default, list) and not default):
            # no typed default: declare by type, so only an override of that type is accepted
            value = None if desc.dynamic_typing else Parameter.Type(desc.type)
        try:
            node.declare_parameter(full, value, desc)
        except Exception as exc:  # rclpy raises several unrelated exception types here
            msg = f"parameter `{full}`: {exc}"
            raise SudsConfigError(msg) from None


def _value(node: Node, name: str, is_array: bool) -> Any:
    try:
        v = node.get_parameter(name).value
    except ParameterUninitializedException:
        return None
    if v is None:
        return None
    return tuple(v) if is_array else v


def build_config(node: Node, cls: type[C], namespace: str = "", **extra: Any) -> C:
    """Read the declared parameters and build ``cls(**values, **extra)``.

    Raises
    ------
    SudsConfigError
        Naming the parameter when the dataclass rejects a value (or a required one is unset).
    """
    hints = typing.get_type_hints(cls)
    values: dict[str, Any] = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        if not f.init or f.name in extra:
            continue
        full = _param_name(namespace, f.name)
        _, is_array, optional = _param_type(cls.__name__, f.name, hints[f.name])
        v = _value(node, full, is_array)
        if v is None and not optional:
            if _default(f) is None:
                raise SudsConfigError(f"parameter `{full}` is required but was not set")
            v = _default(f)
        values[f.name] = v
    try:
        return cls(**values, **extra)
    except (SudsError, ValueError, TypeError) as exc:
        where = f"parameters of {namespace!r}" if namespace else "node parameters"
        raise SudsConfigError(f"{where}: {exc}") from None


def config_from_parameters(node: Node, cls: type[C], namespace: str = "", **extra: Any) -> C:
    """Declare the parameters of ``cls`` on ``node`` and build the config (see module doc)."""
    declare_from_dataclass(node, cls, namespace)
    return build_config(node, cls, namespace, **extra)


def add_validator(
    node: Node,
    get_config: Callable[[], C],
    namespace: str = "",
    on_valid: Callable[[C], None] | None = None,
) -> Callable[[list[Parameter]], SetParametersResult]:
    """Register an on-set-parameters callback that re-validates the whole config.

    A change to fields of ``get_config()``'s dataclass is accepted only if
    ``dataclasses.replace(config, **changes)`` succeeds; otherwise the set is
    refused with the error as ``reason``.  ``on_valid(new_config)`` is called
    for an accepted change (store the new config there).  Returns the callback.
    """
    prefix = f"{namespace}." if namespace else ""

    def callback(params: list[Parameter]) -> SetParametersResult:
        cfg = get_config()
        names = {f.name for f in dataclasses.fields(cfg)}  # type: ignore[arg-type]
        changes = {}
        for p in params:
            if p.name.startswith(prefix) and p.name[len(prefix):] in names:
                v = p.value
                changes[p.name[len(prefix):]] = tuple(v) if isinstance(v, list) else v
        if not changes:
            return SetParametersResult(successful=True)
        try:
            new = dataclasses.replace(cfg, **changes)  # type: ignore[type-var]
        except (SudsError, ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        if on_valid is not None:
            on_valid(new)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(callback)
    return callback


def parameters_help(prog: str, summary: str, cls: type | tuple[type, ...], namespace: str = "") -> str:
    """Usage text of a node: ``summary`` and one line per parameter (type, default, description).

    ``cls`` is the node's config dataclass, or a tuple of them when it declares several.
    """
    lines = [f"usage: {prog} [--ros-args -p NAME:=VALUE ... | --params-file FILE]", "", summary, "",
             "parameters:"]
    classes = cls if isinstance(cls, tuple) else (cls,)
    for name, default, d in (row for c in classes for row in descriptors(c, namespace)):
        kind = Parameter.Type(d.type).name.lower()
        ro = ", read-only" if d.read_only else ""
        lines.append(f"  {_param_name(namespace, name)} ({kind}{ro}, default {default!r}): "
                     f"{d.description}")
    return "\n".join(lines)


def wants_help(args: list[str] | None) -> bool:
    """True when the non-ROS command-line arguments ask for ``-h``/``--help``."""
    from rclpy.utilities import remove_ros_args

    argv = remove_ros_args(args=sys.argv if args is None else args)
    return any(a in ("-h", "--help") for a in argv[1:])
