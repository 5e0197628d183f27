"""Robot model files (``suds-robot/1``, ``shared/spec/robot_model.md``): load, validate, export.

A model file describes a user's planar chain robot — link lengths and drag,
joints with their roles, springs, damping and friction, the drive, the frame
of the recorded pose — and becomes a :class:`~suds_ros.core.physics.rft.ChainModel`.
The loader accepts exactly the documented keys and refuses anything else with
a :class:`~suds_ros.core.errors.SudsConfigError` (code ``bad_model_file``) that
names the key, what was expected and what was found.  :func:`model_to_dict`
writes the file of a chain, so the built-in swimmers round-trip.
:func:`model_differences` / :func:`check_recording` compare a recording's joint
names and actuated/passive split with a model (code ``model_mismatch``).
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from suds_ros.core.errors import MODEL_MISMATCH, SudsConfigError
from suds_ros.core.physics.rft import ChainModel
from suds_ros.core.recording import Recording
from suds_ros.core.recording import joint_names as default_joint_names

FORMAT = "suds-robot/1"
BAD_MODEL_FILE = "bad_model_file"

_TOP_KEYS = {"format", "name", "gait_hz", "drag", "links", "body", "joints", "environment"}
_DRAG_KEYS = {"c_par", "c_perp"}
_LINK_KEYS = {"length", "c_par", "c_perp"}
_BODY_KEYS = {"link", "offset"}
_JOINT_KEYS = {"name", "actuated", "gait", "stiffness", "rest", "damping", "k3", "coulomb", "limit",
               "speed_limit"}
_GAIT_KEYS = {"amplitude", "phase", "offset"}
_ENV_KEYS = {"flow"}
_NAME_RE = re.compile(r"^[A-Za-z0-9_-]+$")


class _Where:
    """Builds error messages that name the file and the key path."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, expected: str, found: Any) -> SudsConfigError:
        return SudsConfigError(f"{self.source}: `{key}`: expected {expected}, got {found!r}", code=BAD_MODEL_FILE)


class _StrictLoader(yaml.SafeLoader):
    """A safe YAML loader that refuses duplicate mapping keys (a silent last-wins hides typos)."""


def _construct_mapping(loader: _StrictLoader, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def read_text(path: str | Path, what: str, code: str) -> str:
    """The text of the file ``path``; an unreadable file is a :class:`SudsConfigError` (``code``) naming ``what``."""
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SudsConfigError(f"{p}: cannot read the {what} ({exc.__class__.__name__}: {exc})", code=code) from None


def load_strict_yaml(text: str, source: str, code: str) -> Any:
    """``text`` parsed as YAML with duplicate keys refused.

    A parse error is a :class:`SudsConfigError` (``code``) naming ``source`` and the line.
    """
    try:
        return yaml.load(text, Loader=_StrictLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        line = f" (line {where.line + 1})" if where is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise SudsConfigError(f"{source}: not valid YAML{line}: {problem}", code=code) from None


def _mapping(w: _Where, key: str, value: Any, allowed: set[str]) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise w.fail(key, "a mapping", value)
    unknown = sorted(str(k) for k in value if k not in allowed)
    if unknown:
        raise w.fail(f"{key}.{unknown[0]}" if key else unknown[0],
                     f"one of the keys {sorted(allowed)} (unknown key)", unknown[0])
    return value


def _number(w: _Where, key: str, value: Any, *, minimum: float | None = None, strict: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise w.fail(key, "a finite number", value)
    if minimum is not None and (value <= minimum if strict else value < minimum):
        raise w.fail(key, f"a number {'>' if strict else '≥'} {minimum:g}", value)
    return float(value)


def _vector(w: _Where, key: str, value: Any, n: int) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise w.fail(key, f"a list of {n} numbers", value)
    return tuple(_number(w, f"{key}[{i}]", v) for i, v in enumerate(value))


def _parse_links(w: _Where, raw: Any, drag: dict[str, float]) -> tuple[list[float], list[float], list[float]]:
    if not isinstance(raw, list) or len(raw) < 2:
        raise w.fail("links", "a list of at least 2 links (head to tail)", raw)
    lengths, c_par, c_perp = [], [], []
    for i, link in enumerate(raw):
        key = f"links[{i}]"
        link = _mapping(w, key, link, _LINK_KEYS)
        if "length" not in link:
            raise w.fail(f"{key}.length", "a link length > 0 m (required)", None)
        lengths.append(_number(w, f"{key}.length", link["length"], minimum=0.0, strict=True))
        c_par.append(_number(w, f"{key}.c_par", link.get("c_par", drag["c_par"]), minimum=0.0, strict=True))
        c_perp.append(_number(w, f"{key}.c_perp", link.get("c_perp", drag["c_perp"]), minimum=0.0, strict=True))
    return lengths, c_par, c_perp


def _parse_joints(w: _Where, raw: Any, n_joints: int) -> dict[str, list[Any]]:
    if not isinstance(raw, list) or len(raw) != n_joints:
        found = len(raw) if isinstance(raw, list) else raw
        raise w.fail("joints", f"a list of {n_joints} joints (one fewer than the links)", found)
    out: dict[str, list[Any]] = {k: [] for k in ("name", "actuated", "gait", "stiffness", "rest",
                                                 "damping", "k3", "coulomb", "limit", "speed_limit")}
    defaults = default_joint_names(n_joints)
    for j, joint in enumerate(raw):
        key = f"joints[{j}]"
        joint = _mapping(w, key, joint, _JOINT_KEYS)
        name = joint.get("name", defaults[j])
        if not isinstance(name, str) or not name.strip():
            raise w.fail(f"{key}.name", "a non-empty string", name)
        actuated = joint.get("actuated", False)
        if not isinstance(actuated, bool):
            raise w.fail(f"{key}.actuated", "true or false", actuated)
        gait = _mapping(w, f"{key}.gait", joint.get("gait", {}), _GAIT_KEYS)
        out["gait"].append(tuple(_number(w, f"{key}.gait.{k}", gait.get(k, 0.0))
                                 for k in ("amplitude", "phase", "offset")))
        out["name"].append(name)
        out["actuated"].append(actuated)
        out["stiffness"].append(_number(w, f"{key}.stiffness", joint.get("stiffness", 0.0), minimum=0.0))
        out["rest"].append(_number(w, f"{key}.rest", joint.get("rest", 0.0)))
        out["damping"].append(_number(w, f"{key}.damping", joint.get("damping", 0.0), minimum=0.0))
        out["k3"].append(_number(w, f"{key}.k3", joint.get("k3", 0.0)))
        out["coulomb"].append(_number(w, f"{key}.coulomb", joint.get("coulomb", 0.0), minimum=0.0))
        for lim in ("limit", "speed_limit"):  # optional bounds a gait optimiser honours (gait.md)
            out[lim].append(None if joint.get(lim) is None
                            else _number(w, f"{key}.{lim}", joint[lim], minimum=0.0, strict=True))
        if not actuated and not (out["stiffness"][-1] > 0 or out["damping"][-1] > 0 or out["coulomb"][-1] > 0):
            raise w.fail(key, "an actuated joint, or a passive one held by stiffness, damping or "
                              "coulomb > 0", {k: joint.get(k, 0) for k in ("stiffness", "damping", "coulomb")})
    dup = [n for n, c in Counter(out["name"]).items() if c > 1]
    if dup:
        raise w.fail("joints[].name", "distinct joint names", dup[0])
    if not any(out["actuated"]):
        raise w.fail("joints[].actuated", "at least one actuated joint", "none")
    return out


def model_from_dict(doc: Any, source: str = "<model>") -> ChainModel:
    """Validate a parsed ``suds-robot/1`` document and build its :class:`ChainModel`.

    Raises
    ------
    SudsConfigError
        (code ``bad_model_file``) naming the key, the expected and the found value.
    """
    w = _Where(source)
    doc = _mapping(w, "", doc, _TOP_KEYS)
    if doc.get("format") != FORMAT:
        raise w.fail("format", repr(FORMAT), doc.get("format"))
    name = doc.get("name")
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise w.fail("name", "a system id of letters, digits, `_` and `-`", name)
    gait_hz = _number(w, "gait_hz", doc.get("gait_hz", 1.0), minimum=0.0, strict=True)
    drag_raw = _mapping(w, "drag", doc.get("drag", {}), _DRAG_KEYS)
    drag = {k: _number(w, f"drag.{k}", drag_raw.get(k, d), minimum=0.0, strict=True)
            for k, d in (("c_par", 1.0), ("c_perp", 2.0))}
    lengths, c_par, c_perp = _parse_links(w, doc.get("links"), drag)
    n = len(lengths)
    body = _mapping(w, "body", doc.get("body", {}), _BODY_KEYS)
    link = body.get("link", (n + 1) // 2)
    if isinstance(link, bool) or not isinstance(link, int) or not 1 <= link <= n:
        raise w.fail("body.link", f"a link number 1..{n}", link)
    offset = _vector(w, "body.offset", body.get("offset", [0.0, 0.0, 0.0]), 3)
    joints = _parse_joints(w, doc.get("joints"), n - 1)
    env = _mapping(w, "environment", doc.get("environment", {}), _ENV_KEYS)
    flow = _vector(w, "environment.flow", env.get("flow", [0.0, 0.0]), 2)
    actuated = tuple(j for j, a in enumerate(joints["actuated"]) if a)
    try:
        return ChainModel(
            n_links=n, actuated=actuated, stiffness=tuple(joints["stiffness"]), rest=tuple(joints["rest"]),
            damping=tuple(joints["damping"]), k3=tuple(joints["k3"]), coulomb=tuple(joints["coulomb"]),
            link_length=tuple(lengths), c_par=tuple(c_par), c_perp=tuple(c_perp), flow=flow,
            body_link=link - 1, name=name, pose_offset=offset, joint_names=tuple(joints["name"]),
            gait=tuple((joints["gait"][j][0], 1.0, joints["gait"][j][1], joints["gait"][j][2]) for j in actuated),
            gait_hz=gait_hz, limit=tuple(joints["limit"]), speed_limit=tuple(joints["speed_limit"]),
        )
    except SudsConfigError as exc:  # a combination the key checks above did not catch
        raise SudsConfigError(f"{source}: {exc}", code=BAD_MODEL_FILE) from None


def load_model(path: str | Path) -> ChainModel:
    """Read and validate a ``suds-robot/1`` model file.

    Raises
    ------
    SudsConfigError
        (code ``bad_model_file``) for a missing or unreadable file, invalid YAML, or any
        key that does not follow the format.
    """
    p = Path(path)
    text = read_text(p, "model file", BAD_MODEL_FILE)
    return model_from_dict(load_strict_yaml(text, str(p), BAD_MODEL_FILE), str(p))


def _common(values: tuple[float, ...]) -> float:
    """The most frequent value (ties: the first), written once as the default."""
    counts = Counter(values)
    best = max(counts.values())
    return next(v for v in values if counts[v] == best)


def model_to_dict(model: ChainModel) -> dict[str, Any]:
    """The ``suds-robot/1`` document of a chain (defaults left out, springs of passive joints kept).

    Raises
    ------
    SudsConfigError
        When the chain cannot be written in the format: a drive whose frequency differs
        from once per gait cycle, or a ``stiffness_scale`` ≠ 1.
    """
    if model.stiffness_scale != 1.0:
        raise SudsConfigError(
            f"`stiffness_scale`: the file format has none; expected 1, got {model.stiffness_scale}")
    c_par, c_perp = model.c_par, model.c_perp
    assert isinstance(c_par, tuple) and isinstance(c_perp, tuple)
    drag = {"c_par": _common(c_par), "c_perp": _common(c_perp)}
    links = []
    for i, length in enumerate(model.link_length):  # type: ignore[arg-type]
        link: dict[str, Any] = {"length": float(length)}
        for key, values in (("c_par", c_par), ("c_perp", c_perp)):
            if values[i] != drag[key]:
                link[key] = float(values[i])
        links.append(link)
    gait = dict(zip(model.actuated, model.gait))
    joints = []
    for j, name in enumerate(model.joint_names):
        joint: dict[str, Any] = {"name": name}
        if j in gait:
            amplitude, freq, phase, offset = gait[j]
            if freq != 1.0:
                raise SudsConfigError(f"`gait`: joint {name!r} is driven {freq:g}× per gait cycle; "
                                      "the file format drives every joint once per cycle (expected 1)")
            joint["actuated"] = True
            joint["gait"] = {"amplitude": amplitude, "phase": phase, "offset": offset}
        else:
            joint["stiffness"] = float(model.stiffness[j])  # type: ignore[index]
        for key in ("rest", "damping", "k3", "coulomb"):
            value = float(getattr(model, key)[j])
            if value != 0.0 and j not in gait:
                joint[key] = value
        for key in ("limit", "speed_limit"):
            bound = getattr(model, key)[j]
            if bound is not None:
                joint[key] = float(bound)
        joints.append(joint)
    doc: dict[str, Any] = {
        "format": FORMAT, "name": model.name, "gait_hz": float(model.gait_hz), "drag": drag, "links": links,
        "body": {
            "link": int(model.body_link) + 1,
            "offset": [float(v) for v in model.pose_offset],  # type: ignore[arg-type]
        },
        "joints": joints,
    }
    if model.flow != (0.0, 0.0):
        doc["environment"] = {"flow": [float(v) for v in model.flow]}
    return doc


def dump_model(model: ChainModel) -> str:
    """The model file text of a chain (YAML, keys in the order of the format's documentation)."""
    header = f"# {model.name}: {model.n_links}-link chain, robot model file ({FORMAT}, shared/spec/robot_model.md)\n"
    return header + yaml.safe_dump(model_to_dict(model), sort_keys=False, default_flow_style=None, width=100)


def _role(actuated: bool) -> str:
    return "actuated" if actuated else "passive"


def model_differences(model: ChainModel, joint_names: Sequence[str], actuated: Sequence[str]) -> list[str]:
    """How a recording's joints differ from ``model``'s; empty when names, order and roles all match.

    Parameters
    ----------
    model : ChainModel
        The robot model (its ``joint_names`` and ``actuated`` indices).
    joint_names : sequence of str
        The recording's joint names, head to tail (as on ``/suds/shape``).
    actuated : sequence of str
        The recording's actuated joints; every other joint counts as passive.

    Returns
    -------
    list of str
        One phrase per kind of difference: joints of the model missing from the recording,
        joints of the recording the model does not have, joints whose role differs, order.
    """
    rec_names, mod_names = list(joint_names), list(model.joint_names)
    mod_act = {mod_names[i] for i in model.actuated}
    rec_act = set(actuated)
    out = []
    missing = [n for n in mod_names if n not in rec_names]
    extra = [n for n in rec_names if n not in mod_names]
    if missing:
        out.append(f"missing joints (in the model, not in the recording): {', '.join(missing)}")
    if extra:
        out.append(f"extra joints (in the recording, not in the model): {', '.join(extra)}")
    differ = [f"{n} (recording {_role(n in rec_act)}, model {_role(n in mod_act)})"
              for n in mod_names if n in rec_names and (n in rec_act) != (n in mod_act)]
    if differ:
        out.append(f"roles differ: {', '.join(differ)}")
    common_rec = [n for n in rec_names if n in mod_names]
    common_mod = [n for n in mod_names if n in rec_names]
    if common_rec != common_mod:
        out.append(f"joint order differs: recording {', '.join(common_rec)}; model {', '.join(common_mod)}")
    return out


def check_joints(model: ChainModel, joint_names: Sequence[str], actuated: Sequence[str], *,
                 source: str | None = None) -> None:
    """Refuse joints (names head to tail, actuated subset) that differ from ``model``'s.

    ``source`` (the model file's path) starts the message when given.

    Raises
    ------
    SudsConfigError
        (code ``model_mismatch``) one line listing every difference (:func:`model_differences`).
    """
    diffs = model_differences(model, joint_names, actuated)
    if diffs:
        where = f"{source}: " if source else ""
        raise SudsConfigError(
            f"{where}the recording's joints ({', '.join(joint_names)}) do not match the model "
            f"{model.name!r}: {'; '.join(diffs)}", code=MODEL_MISMATCH)


def check_recording(rec: Recording, model: ChainModel, source: str | None = None) -> None:
    """Refuse a recording whose joint names, order or actuated/passive split differ from ``model``.

    Raises
    ------
    SudsConfigError
        (code ``model_mismatch``) one line listing every difference (:func:`model_differences`).
    """
    check_joints(model, rec.joint_names, rec.actuated, source=source)
