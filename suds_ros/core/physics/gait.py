"""Gaits as data: the ``suds-gait/1`` file (``shared/spec/gait.md``), its evaluation and its constraints.

A gait is the periodic trajectory of a robot's actuated joints, a Fourier series in the gait
phase per joint::

    r_j(t) = offset_j + Σ_{k=1..K} ( cos_j[k−1] · cos(2πk·f·t) + sin_j[k−1] · sin(2πk·f·t) )

with f = ``gait_hz`` and t from the start of a cycle.  :class:`Gait` holds it (frozen, hashable:
coefficients are tuples; :meth:`Gait.arrays` gives arrays), evaluates r(t) and ṙ(t) vectorised,
and converts from and to the optimisers' flat parameter vector.  :func:`load_gait` /
:func:`dump_gait` read and write the file strictly: unknown keys, a missing actuated joint, a
passive joint, a non-finite number or K > 8 are :class:`~suds_ros.core.errors.SudsConfigError`
(code ``bad_gait_file``) naming the key.  :func:`gait_from_sinusoid` is a model file's nominal
drive as a K = 1 gait; :func:`nominal_gait` / :func:`gait_limits` read a system's nominal gait and
the joint range and speed bounds (defaults from the nominal gait, overridden by a model file's
``joints[j].limit`` / ``speed_limit``); :func:`constraint_violations` checks a gait against them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from suds_ros.core._typing import FloatArray
from suds_ros.core.errors import MODEL_MISMATCH, SudsConfigError, SudsDataError
from suds_ros.core.fourier import fourier_basis
from suds_ros.core.physics.robot_model import load_strict_yaml, read_text
from suds_ros.core.physics.system import SudsSystem

FORMAT = "suds-gait/1"
BAD_GAIT_FILE = "bad_gait_file"
GAIT_CONSTRAINT = "gait_constraint"
#: highest order a gait file may carry
MAX_ORDER = 8
#: order the optimisers use unless asked for more
DEFAULT_MAX_ORDER = 3
OBJECTIVES = ("speed", "turn", "efficiency")
_TOP_KEYS = ("format", "system", "gait_hz", "joints", "objective", "predicted")
_JOINT_KEYS = ("offset", "cos", "sin")
#: relative slack of the constraint checks (a bound met to rounding is met)
_SLACK = 1e-9


def _fail(source: str, key: str, expected: str, found: Any) -> SudsConfigError:
    return SudsConfigError(f"{source}: `{key}`: expected {expected}, got {found!r}", code=BAD_GAIT_FILE)


def _finite(source: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _fail(source, key, "a finite number", value)
    return float(value)


@dataclass(frozen=True)
class Gait:
    """A periodic drive of the actuated joints (``suds-gait/1``).

    Parameters
    ----------
    system : str
        The robot it was made for (model ``name`` or built-in id).
    gait_hz : float
        Cycle frequency f, Hz (> 0).
    joints : tuple of na str
        Actuated joint names, in the system's actuated order.
    offset : tuple of na float
        Constant term per joint, rad.
    cos, sin : tuple of na tuples of K float
        Fourier coefficients per joint and harmonic k = 1..K, rad (shorter rows are padded with
        zeros to the longest; 1 ≤ K ≤ 8).
    objective : str or None
        What it was optimised for (``speed``, ``turn``, ``efficiency``), if anything.
    predicted : tuple of (str, float)
        What its maker expects, e.g. ``(("speed", 0.45),)`` (units of gait.md).
    """

    system: str
    gait_hz: float
    joints: tuple[str, ...]
    offset: tuple[float, ...]
    cos: tuple[tuple[float, ...], ...]
    sin: tuple[tuple[float, ...], ...]
    objective: str | None = None
    predicted: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        na = len(self.joints)
        if na == 0 or len(set(self.joints)) != na or not all(isinstance(j, str) and j for j in self.joints):
            raise SudsConfigError(f"`joints`: expected distinct non-empty joint names, got {self.joints!r}",
                                  code=BAD_GAIT_FILE)
        if not (isinstance(self.gait_hz, (int, float)) and math.isfinite(self.gait_hz) and self.gait_hz > 0):
            raise SudsConfigError(f"`gait_hz`: expected a frequency > 0 Hz, got {self.gait_hz!r}",
                                  code=BAD_GAIT_FILE)
        for name in ("offset", "cos", "sin"):
            if len(getattr(self, name)) != na:
                raise SudsConfigError(f"`{name}`: expected {na} entries (one per joint), got "
                                      f"{len(getattr(self, name))}", code=BAD_GAIT_FILE)
        order = max(max(len(c) for c in self.cos), max(len(s) for s in self.sin), 1)
        if order > MAX_ORDER:
            raise SudsConfigError(f"`cos`/`sin`: expected at most {MAX_ORDER} harmonics, got {order}",
                                  code=BAD_GAIT_FILE)

        def pad(rows: Sequence[Sequence[float]]) -> tuple[tuple[float, ...], ...]:
            return tuple(tuple(float(v) for v in row) + (0.0,) * (order - len(row)) for row in rows)

        object.__setattr__(self, "gait_hz", float(self.gait_hz))
        object.__setattr__(self, "joints", tuple(self.joints))
        object.__setattr__(self, "offset", tuple(float(v) for v in self.offset))
        object.__setattr__(self, "cos", pad(self.cos))
        object.__setattr__(self, "sin", pad(self.sin))
        object.__setattr__(self, "predicted", tuple((str(k), float(v)) for k, v in self.predicted))
        values = [*self.offset, *np.ravel(self.cos), *np.ravel(self.sin), *(v for _, v in self.predicted)]
        if not all(math.isfinite(v) for v in values):
            raise SudsConfigError("`joints`: coefficients must be finite", code=BAD_GAIT_FILE)
        if self.objective is not None and self.objective not in OBJECTIVES:
            raise SudsConfigError(f"`objective`: expected one of {list(OBJECTIVES)}, got {self.objective!r}",
                                  code=BAD_GAIT_FILE)

    # ------------------------------------------------------------------ arrays
    @property
    def order(self) -> int:
        """K, the number of harmonics."""
        return len(self.cos[0])

    def arrays(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``offset`` (na,), ``cos`` (na, K), ``sin`` (na, K) as arrays."""
        return np.array(self.offset), np.array(self.cos), np.array(self.sin)

    def is_half_wave(self, atol: float = 1e-9) -> bool:
        """Whether r(t + T/2) = −r(t): no offset and no even harmonic (within ``atol``, rad; :func:`half_wave_free`)."""
        x = self.to_vector()
        held = np.ones(x.size, dtype=bool)
        held[half_wave_free(len(self.joints), self.order)] = False
        return bool(np.all(np.abs(x[held]) <= atol))

    def at_phase(self, s: FloatArray) -> FloatArray:
        """Joint angles at gait time ``s`` in cycles (phase 2π·s), shape (len(s), na), rad."""
        off, c, sn = self.arrays()
        theta = 2 * np.pi * np.outer(np.asarray(s, dtype=float).ravel(), np.arange(1, self.order + 1))
        return off + np.cos(theta) @ c.T + np.sin(theta) @ sn.T

    def r(self, t: FloatArray) -> FloatArray:
        """Joint angles at times ``t`` (s from the start of a cycle), shape (len(t), na), rad."""
        return self.at_phase(np.asarray(t, dtype=float) * self.gait_hz)

    def rdot(self, t: FloatArray) -> FloatArray:
        """Joint rates ṙ(t), shape (len(t), na), rad/s."""
        _, c, sn = self.arrays()
        k = np.arange(1, self.order + 1)
        w = 2 * np.pi * self.gait_hz * k
        theta = np.outer(np.asarray(t, dtype=float).ravel(), w)
        return (np.cos(theta) * w) @ sn.T - (np.sin(theta) * w) @ c.T

    # ------------------------------------------------------------- parameters
    def to_vector(self, order: int | None = None) -> FloatArray:
        """Flat parameters, per joint ``[offset, cos_1..cos_K, sin_1..sin_K]`` (zero-padded to ``order``)."""
        order = self.order if order is None else int(order)
        if order < self.order:
            raise SudsConfigError(f"`order`: the gait has {self.order} harmonics, cannot flatten to {order}")
        off, c, sn = self.arrays()
        pad = np.zeros((len(self.joints), order - self.order))
        return np.concatenate([off[:, None], c, pad, sn, pad], axis=1).ravel()

    def from_vector(self, x: FloatArray, order: int, **changes: Any) -> Gait:
        """A gait of the same system, frequency and joints with the flat parameters ``x`` (:meth:`to_vector`)."""
        na = len(self.joints)
        m = np.asarray(x, dtype=float).reshape(na, 2 * order + 1)
        return replace(self, offset=tuple(m[:, 0]), cos=tuple(map(tuple, m[:, 1:order + 1])),
                       sin=tuple(map(tuple, m[:, order + 1:])), **changes)


def half_wave_free(na: int, order: int) -> FloatArray:
    """Indices of the odd harmonics' coefficients in a gait vector (:meth:`Gait.to_vector`).

    A gait of odd harmonics only is half-wave symmetric: r(t + T/2) = −r(t).  On a robot that is
    its own mirror image (body, springs and medium), the passive periodic steady state of such a
    drive is half-wave symmetric too, so the second half cycle undoes the first half's rotation:
    its net rotation per cycle is zero whatever the odd coefficients are.
    """
    per = 2 * order + 1
    k = np.arange(1, order + 1)
    odd = np.concatenate([k[k % 2 == 1], order + k[k % 2 == 1]])
    return (np.arange(na)[:, None] * per + odd[None]).ravel()


def time_shifted(gait: Gait, s0: float) -> Gait:
    """The same drive started ``s0`` cycles later: r'(s) = r(s + s0).

    The motion is the same, and so are the bounds, the net rotation and the work per cycle.  The
    speed |translation of g(t₀)⁻¹ g(t₀ + 1/f)| is the same only for a gait that runs straight: a
    net rotation makes the chord depend on where the cycle is counted from (snake5's order-3 speed
    optimum, turning at the 0.05 rad bound, reads 0.488–0.538 m/s over its time origins).
    """
    off, c, sn = gait.arrays()
    c, sn = shifted_harmonics(c, sn, 2 * np.pi * np.arange(1, gait.order + 1) * s0)
    return Gait(system=gait.system, gait_hz=gait.gait_hz, joints=gait.joints, offset=tuple(off),
                cos=tuple(map(tuple, c)), sin=tuple(map(tuple, sn)), objective=gait.objective,
                predicted=gait.predicted)


def time_reversed(gait: Gait) -> Gait:
    """The same drive run backwards in time: r'(s) = r(−s), its sine coefficients negated.

    The same range and joint speed (so the same bounds hold), and its travelling wave runs the
    other way.  On a robot of actuated joints only the body retraces its motion backwards; with
    passive joints, which lag their drive, the reversed drive's motion can differ in speed too.
    """
    off, c, sn = gait.arrays()
    return Gait(system=gait.system, gait_hz=gait.gait_hz, joints=gait.joints, offset=tuple(off),
                cos=tuple(map(tuple, c)), sin=tuple(map(tuple, -sn)))


def reversal_shift(gait: Gait, atol: float = 1e-9) -> float | None:
    """The shift s0 (cycles, in [0, 1)) with r(−s) = r(s + s0) for every s, or None if there is none.

    Whether running the drive backwards only starts it elsewhere in its cycle: one joint at one
    harmonic (purcell3's sinusoid), joints in phase; a travelling wave is not.

    Harmonic k = A cos(2πk·s − ψ) runs backwards as A cos(2πk·s + ψ), the shift s0 as
    A cos(2πk·(s + s0) − ψ): equal when 2πk·s0 ≡ 2ψ (mod 2π).  The candidates come from the largest
    harmonic of all joints and are checked on the whole drive (to ``atol`` rad on 64 points).
    """
    _, c, sn = gait.arrays()
    amp = np.hypot(c, sn)
    if not np.any(amp > atol):
        return 0.0  # (a constant drive)
    j, k = np.unravel_index(int(np.argmax(amp)), amp.shape)
    psi = math.atan2(sn[j, k], c[j, k])
    s = np.arange(64) / 64.0
    back = gait.at_phase(-s)
    for m in range(k + 1):  # harmonic k + 1 (0-based k): 2π(k + 1)·s0 = 2ψ + 2πm
        s0 = ((2 * psi / (2 * math.pi) + m) / (k + 1)) % 1.0
        if np.allclose(back, gait.at_phase(s + s0), rtol=0, atol=atol):
            return float(s0)
    return None


def shifted_harmonics(c: FloatArray, sn: FloatArray, angles: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Cosine and sine coefficients (na, K) of harmonics 1…K after a time shift, harmonic k by ``angles[k − 1]``.

    A shift of s0 cycles, r'(s) = r(s + s0), turns harmonic k by 2π·k·s0 (:func:`time_shifted`).
    """
    ca, sa = np.cos(angles), np.sin(angles)
    return c * ca + sn * sa, sn * ca - c * sa


def fitted_gait(template: Gait, t: FloatArray, r: FloatArray, order: int) -> Gait:
    """The K = ``order`` gait of ``template``'s joints and frequency that fits the drive ``r`` at ``t``.

    Least squares of each actuated joint's recorded angle (``r``, (n, na) rad, the template's joint
    order; rows with a NaN are left out) on [1, cos 2πkft, sin 2πkft]: the mean periodic drive of
    a recording, with time counted from its first usable stamp (a steady cycle does not depend on
    the phase there).
    """
    t = np.asarray(t, dtype=float)
    r = np.asarray(r, dtype=float)
    if r.ndim != 2 or r.shape != (t.size, len(template.joints)):
        raise SudsDataError(f"`r`: expected shape ({t.size}, {len(template.joints)}), got {r.shape}")
    ok = np.isfinite(r).all(axis=1) & np.isfinite(t)
    if ok.sum() < 2 * order + 1:
        raise SudsDataError(f"`r`: expected at least {2 * order + 1} finite samples, got {int(ok.sum())}")
    X = fourier_basis(2 * np.pi * template.gait_hz * (t[ok] - t[ok][0]), order)
    coef, *_ = np.linalg.lstsq(X, r[ok], rcond=None)  # (2K + 1, na): [1, cos 1, sin 1, cos 2, …]
    cos, sin = coef[1::2].T, coef[2::2].T
    return replace(template, offset=tuple(coef[0]), cos=tuple(map(tuple, cos)), sin=tuple(map(tuple, sin)),
                   objective=None, predicted=())


# ------------------------------------------------------------------------ file
def gait_from_dict(doc: Any, source: str = "<gait>") -> Gait:
    """Validate a parsed ``suds-gait/1`` document and build its :class:`Gait`.

    Raises
    ------
    SudsConfigError
        (code ``bad_gait_file``) naming the key, what was expected and what was found.
    """
    if not isinstance(doc, dict):
        raise _fail(source, "", "a mapping", doc)
    unknown = sorted(str(k) for k in doc if k not in _TOP_KEYS)
    if unknown:
        raise _fail(source, unknown[0], f"one of the keys {list(_TOP_KEYS)} (unknown key)", unknown[0])
    if doc.get("format") != FORMAT:
        raise _fail(source, "format", repr(FORMAT), doc.get("format"))
    system = doc.get("system")
    if not isinstance(system, str) or not system:
        raise _fail(source, "system", "the robot's name or built-in id", system)
    if "gait_hz" not in doc:
        raise _fail(source, "gait_hz", "a frequency > 0 Hz (required)", None)
    gait_hz = _finite(source, "gait_hz", doc["gait_hz"])
    if gait_hz <= 0:
        raise _fail(source, "gait_hz", "a frequency > 0 Hz", gait_hz)
    joints = doc.get("joints")
    if not isinstance(joints, dict) or not joints:
        raise _fail(source, "joints", "a mapping of actuated joint name → {offset, cos, sin}", joints)
    names, offset, cos, sin = [], [], [], []
    for name, entry in joints.items():
        key = f"joints.{name}"
        if not isinstance(entry, dict):
            raise _fail(source, key, "a mapping {offset, cos, sin}", entry)
        bad = sorted(str(k) for k in entry if k not in _JOINT_KEYS)
        if bad:
            raise _fail(source, f"{key}.{bad[0]}", f"one of the keys {list(_JOINT_KEYS)} (unknown key)", bad[0])
        rows = []
        for part in ("cos", "sin"):
            raw = entry.get(part, [])
            if not isinstance(raw, list):
                raise _fail(source, f"{key}.{part}", "a list of numbers", raw)
            if len(raw) > MAX_ORDER:
                raise _fail(source, f"{key}.{part}", f"at most {MAX_ORDER} harmonics (K ≤ {MAX_ORDER})",
                            f"{len(raw)} values")
            rows.append(tuple(_finite(source, f"{key}.{part}[{i}]", v) for i, v in enumerate(raw)))
        names.append(str(name))
        offset.append(_finite(source, f"{key}.offset", entry.get("offset", 0.0)))
        cos.append(rows[0])
        sin.append(rows[1])
    objective = doc.get("objective")
    if objective is not None and objective not in OBJECTIVES:
        raise _fail(source, "objective", f"one of {list(OBJECTIVES)}", objective)
    predicted_raw = doc.get("predicted", {})
    if not isinstance(predicted_raw, dict):
        raise _fail(source, "predicted", "a mapping of objective → value", predicted_raw)
    predicted = tuple((str(k), _finite(source, f"predicted.{k}", v)) for k, v in predicted_raw.items())
    return Gait(system=system, gait_hz=gait_hz, joints=tuple(names), offset=tuple(offset), cos=tuple(cos),
                sin=tuple(sin), objective=objective, predicted=predicted)


def same_gait(a: Gait, b: Gait) -> bool:
    """Whether two gaits are the same drive (joints, frequency and coefficients to 1e-12)."""
    if a.joints != b.joints or a.gait_hz != b.gait_hz:
        return False
    k = max(a.order, b.order)
    return bool(np.allclose(a.to_vector(k), b.to_vector(k), rtol=0, atol=1e-12))


def gait_to_dict(gait: Gait) -> dict[str, Any]:
    """The ``suds-gait/1`` document of ``gait`` (optional keys only when set)."""
    doc: dict[str, Any] = {"format": FORMAT, "system": gait.system, "gait_hz": gait.gait_hz, "joints": {
        name: {"offset": gait.offset[j], "cos": list(gait.cos[j]), "sin": list(gait.sin[j])}
        for j, name in enumerate(gait.joints)}}
    if gait.objective is not None:
        doc["objective"] = gait.objective
    if gait.predicted:
        doc["predicted"] = dict(gait.predicted)
    return doc


def dump_gait(gait: Gait) -> str:
    """The gait file text (YAML; floats written so that they load back exactly)."""
    return f"# gait of {gait.system} ({FORMAT}, shared/spec/gait.md)\n" + yaml.safe_dump(
        gait_to_dict(gait), sort_keys=False, default_flow_style=None, width=120)


def loads_gait(text: str, source: str = "<gait>") -> Gait:
    """Parse and validate gait file text (duplicate keys refused).

    Raises
    ------
    SudsConfigError
        (code ``bad_gait_file``) for invalid YAML or any key that does not follow the format.
    """
    return gait_from_dict(load_strict_yaml(text, source, BAD_GAIT_FILE), source)


def load_gait(path: str | Path, system: SudsSystem | None = None) -> Gait:
    """Read a ``suds-gait/1`` file; with ``system``, also check it is a gait of that system (:func:`check_gait`).

    Raises
    ------
    SudsConfigError
        (code ``bad_gait_file``) unreadable file or bad key; (code ``model_mismatch``) another
        system, a missing actuated or a passive joint.
    """
    p = Path(path)
    gait = loads_gait(read_text(p, "gait file", BAD_GAIT_FILE), str(p))
    if system is not None:
        gait = check_gait(gait, system, source=str(p))
    return gait


def save_gait(gait: Gait, path: str | Path) -> None:
    """Write ``gait`` to ``path`` (replacing it)."""
    Path(path).write_text(dump_gait(gait), encoding="utf-8")


def check_gait(gait: Gait, system: SudsSystem, source: str = "gait") -> Gait:
    """Refuse a gait made for another system or for other joints; return it in the system's actuated order.

    Raises
    ------
    SudsConfigError
        (code ``model_mismatch``) naming the system or the joints that differ.
    """
    if gait.system != system.name:
        raise SudsConfigError(f"{source}: `system`: the gait is for {gait.system!r}, the simulated system is "
                              f"{system.name!r}", code=MODEL_MISMATCH)
    names = system.joint_names
    act = [names[i] for i in system.actuated]
    passive = [j for j in gait.joints if j in names and j not in act]
    if passive:
        raise SudsConfigError(f"{source}: `joints.{passive[0]}`: a passive joint of {system.name!r}; a gait "
                              f"drives only the actuated joints {act}", code=MODEL_MISMATCH)
    unknown = [j for j in gait.joints if j not in names]
    if unknown:
        raise SudsConfigError(f"{source}: `joints.{unknown[0]}`: not a joint of {system.name!r} "
                              f"(joints {list(names)})", code=MODEL_MISMATCH)
    missing = [j for j in act if j not in gait.joints]
    if missing:
        raise SudsConfigError(f"{source}: `joints.{missing[0]}`: actuated joint missing; expected every "
                              f"actuated joint {act}", code=MODEL_MISMATCH)
    idx = [gait.joints.index(j) for j in act]
    return replace(gait, joints=tuple(act), offset=tuple(gait.offset[i] for i in idx),
                   cos=tuple(gait.cos[i] for i in idx), sin=tuple(gait.sin[i] for i in idx))


# --------------------------------------------------------------- nominal gait
def gait_from_sinusoid(system: str, gait_hz: float, joints: Sequence[str], amplitude: Sequence[float],
                       phase: Sequence[float], offset: Sequence[float]) -> Gait:
    """The K = 1 gait of the drive ``offset + amplitude·sin(2π·f·t − phase)`` per joint.

    cos = [−amplitude·sin(phase)], sin = [amplitude·cos(phase)] (``shared/spec/gait.md``).
    """
    return Gait(system=system, gait_hz=gait_hz, joints=tuple(joints), offset=tuple(offset),
                cos=tuple((-a * math.sin(p),) for a, p in zip(amplitude, phase)),
                sin=tuple((a * math.cos(p),) for a, p in zip(amplitude, phase)))


def nominal_gait(system: SudsSystem, gait_hz: float | None = None) -> Gait:
    """The nominal drive of a chain system (``model.gait``, once per cycle) as a :class:`Gait`.

    Raises
    ------
    SudsConfigError
        A system without a chain model or gait, or a drive not once per cycle.
    """
    model = getattr(system, "model", None)
    drive = getattr(model, "gait", None)
    if not drive:
        raise SudsConfigError(f"`system`: {system.name!r} has no nominal sinusoidal gait to convert")
    if any(g[1] != 1.0 for g in drive):
        raise SudsConfigError(f"`gait`: {system.name!r} drives a joint other than once per cycle")
    names = system.joint_names
    hz = float(getattr(model, "gait_hz", 1.0) if gait_hz is None else gait_hz)
    return gait_from_sinusoid(system.name, hz, [names[i] for i in system.actuated],
                              [g[0] for g in drive], [g[2] for g in drive], [g[3] for g in drive])


# ---------------------------------------------------------------- constraints
@dataclass(frozen=True)
class GaitLimits:
    """Bounds every optimiser honours, per actuated joint: |r_j| ≤ ``limit`` rad, |ṙ_j| ≤ ``speed_limit`` rad/s."""

    joints: tuple[str, ...]
    limit: tuple[float, ...]
    speed_limit: tuple[float, ...]

    def __post_init__(self) -> None:
        for name in ("limit", "speed_limit"):
            values = getattr(self, name)
            if len(values) != len(self.joints) or not all(math.isfinite(v) and v > 0 for v in values):
                raise SudsConfigError(f"`{name}`: expected {len(self.joints)} bounds > 0, got {values}")


def gait_extremes(gait: Gait) -> tuple[FloatArray, FloatArray]:
    """Largest |r_j| and |ṙ_j| over a cycle: exact for K = 1, a 4096-point grid otherwise.

    The one measure of how far a gait goes (the bounds' defaults, how far a gait may be scaled).
    """
    off, c, s = gait.arrays()
    if gait.order == 1 or not np.any(c[:, 1:]) and not np.any(s[:, 1:]):
        amp = np.hypot(c[:, 0], s[:, 0])
        return np.abs(off) + amp, 2 * np.pi * gait.gait_hz * amp
    t = np.arange(4096) / (4096 * gait.gait_hz)
    return np.abs(gait.r(t)).max(axis=0), np.abs(gait.rdot(t)).max(axis=0)


def gait_limits(system: SudsSystem, nominal: Gait | None = None) -> GaitLimits:
    """The joint range and speed bounds of ``system``'s actuated joints (``shared/spec/gait.md``).

    A model's ``limit`` / ``speed_limit`` where set; else the nominal gait's largest |r_j| and |ṙ_j|.
    """
    model = getattr(system, "model", None)
    names = system.joint_names
    act = list(system.actuated)
    nominal = nominal_gait(system) if nominal is None else nominal
    r_max, v_max = gait_extremes(nominal)
    lim = getattr(model, "limit", None) or (None,) * len(names)
    spd = getattr(model, "speed_limit", None) or (None,) * len(names)
    return GaitLimits(joints=tuple(names[i] for i in act),
                      limit=tuple(float(r_max[a]) if lim[j] is None else float(lim[j]) for a, j in enumerate(act)),
                      speed_limit=tuple(float(v_max[a]) if spd[j] is None else float(spd[j])
                                        for a, j in enumerate(act)))


def constraint_grid(order: int, gait_hz: float, per_harmonic: int = 64) -> FloatArray:
    """Times (s) of one cycle on which the constraints are checked: ``per_harmonic``·K points."""
    n = per_harmonic * max(int(order), 1)
    return np.arange(n) / (n * gait_hz)


def checked_extremes(gait: Gait, per_harmonic: int = 64) -> tuple[FloatArray, FloatArray]:
    """Largest |r_j| and |ṙ_j| as the constraints are checked: on :func:`constraint_grid`, exact for K = 1."""
    t = constraint_grid(gait.order, gait.gait_hz, per_harmonic)
    r_max = np.maximum(np.abs(gait.r(t)).max(axis=0), gait_extremes(gait)[0] if gait.order == 1 else 0.0)
    v_max = np.maximum(np.abs(gait.rdot(t)).max(axis=0), gait_extremes(gait)[1] if gait.order == 1 else 0.0)
    return r_max, v_max


def constraint_violations(gait: Gait, limits: GaitLimits, per_harmonic: int = 64) -> list[str]:
    """Phrases naming each joint whose range or speed bound the gait breaks (empty: it meets them).

    Checked on :func:`constraint_grid` (exactly at the extremes for K = 1), with a relative slack of 1e-9.
    """
    if tuple(limits.joints) != tuple(gait.joints):
        raise SudsConfigError(f"`limits`: joints {limits.joints} differ from the gait's {gait.joints}")
    r_max, v_max = checked_extremes(gait, per_harmonic)
    out = []
    for j, name in enumerate(gait.joints):
        if r_max[j] > limits.limit[j] * (1 + _SLACK):
            out.append(f"{name}: |r| reaches {r_max[j]:.6g} rad > limit {limits.limit[j]:.6g} rad")
        if v_max[j] > limits.speed_limit[j] * (1 + _SLACK):
            out.append(f"{name}: |ṙ| reaches {v_max[j]:.6g} rad/s > speed limit {limits.speed_limit[j]:.6g} rad/s")
    return out


def check_constraints(gait: Gait, limits: GaitLimits, per_harmonic: int = 64) -> None:
    """Refuse a gait that breaks a bound (:func:`constraint_violations`).

    Raises
    ------
    SudsConfigError
        (code ``gait_constraint``) listing the joints and bounds.
    """
    bad = constraint_violations(gait, limits, per_harmonic)
    if bad:
        raise SudsConfigError(f"gait breaks its constraints: {'; '.join(bad)}", code=GAIT_CONSTRAINT)


def predicted_value(gait: Gait, key: str) -> float | None:
    """The ``predicted`` value under ``key``, None when absent."""
    return dict(gait.predicted).get(key)


def with_predicted(gait: Gait, objective: str, values: Mapping[str, float]) -> Gait:
    """A copy carrying ``objective`` and ``predicted`` values."""
    return replace(gait, objective=objective, predicted=tuple((k, float(v)) for k, v in values.items()))
