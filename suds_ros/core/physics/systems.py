"""Registry of the named systems: the paper's swimmers, general N-link chains and model files.

``make_system(name, **overrides)`` returns a :class:`~suds_ros.core.physics.system.SudsSystem`;
``load_system(spec)`` also takes the path of a robot model file (``suds-robot/1``).
The N-link swimmers follow ``shared/spec/recording.md`` (nominal physics).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from suds_ros.core.errors import SudsConfigError
from suds_ros.core.physics.rft import ChainModel, RFTChain
from suds_ros.core.physics.system import SudsSystem


def purcell3_model() -> ChainModel:
    """Three-link Purcell swimmer: joint_1 driven 1.4·sin(2πt), joint_2 passive, k = 2, rest 0."""
    return ChainModel(
        n_links=3,
        actuated=(0,),
        stiffness=(0.0, 2.0),
        name="purcell3",
        gait=((1.4, 1.0, 0.0, 0.0),),
    )


def swimmer9_model() -> ChainModel:
    """Nine-link swimmer: joints 1–4 travelling wave 1.4·sin(2πt − iπ/4), joints 5–8 springs (20, 15, 10, 5)."""
    phi = np.pi / 4
    return ChainModel(
        n_links=9,
        actuated=(0, 1, 2, 3),
        stiffness=(0.0, 0.0, 0.0, 0.0, 20.0, 15.0, 10.0, 5.0),
        name="swimmer9",
        gait=tuple((1.4, 1.0, i * phi, 0.0) for i in range(1, 5)),
    )


def nlink_model(
    n_links: int,
    n_actuated: int | None = None,
    *,
    stiffness: float | tuple[float, ...] | None = None,
    amplitude: float = 1.4,
    wave_phase: float = np.pi / 4,
    damping: float = 0.0,
) -> ChainModel:
    """A general chain: the first ``n_actuated`` joints carry a travelling wave, the rest are springs.

    Default stiffness decreases linearly toward the tail (from 20 to 5 N·m/rad), as in swimmer9.
    """
    nj = n_links - 1
    na = max(1, nj // 2) if n_actuated is None else int(n_actuated)
    if not 1 <= na <= nj:
        raise SudsConfigError(f"`n_actuated`: expected 1..{nj}, got {n_actuated}")
    npas = nj - na
    if stiffness is None:
        k_p = np.linspace(20.0, 5.0, npas) if npas > 1 else np.full(npas, 2.0)
        stiffness = tuple([0.0] * na + list(k_p))
    return ChainModel(
        n_links=n_links,
        actuated=tuple(range(na)),
        stiffness=stiffness,
        damping=damping,
        name=f"nlink{n_links}",
        gait=tuple((amplitude, 1.0, i * wave_phase, 0.0) for i in range(1, na + 1)),
    )


def _chain(factory: Callable[[], ChainModel]) -> Callable[..., SudsSystem]:
    def build(**overrides: object) -> SudsSystem:
        model = factory()
        return RFTChain(model.with_(**overrides) if overrides else model)

    return build


def _lazy(module: str, attr: str) -> Callable[..., SudsSystem]:
    def build(**overrides: object) -> SudsSystem:
        import importlib

        return getattr(importlib.import_module(module), attr)(**overrides)  # type: ignore[no-any-return]

    return build


SYSTEMS: dict[str, Callable[..., SudsSystem]] = {
    "purcell3": _chain(purcell3_model),
    "swimmer9": _chain(swimmer9_model),
    "linear_passive": _lazy("suds_ros.core.physics.swimmers1d", "LinearPassiveSwimmer"),
    "pushmepullyou": _lazy("suds_ros.core.physics.swimmers1d", "PushmePullyou"),
}


def make_system(name: str, **overrides: object) -> SudsSystem:
    """Build a named system; ``nlinkN`` (e.g. ``nlink33``) gives a general N-link chain.

    Raises
    ------
    SudsConfigError
        For an unknown name, listing the known ones.
    """
    if name in SYSTEMS:
        return SYSTEMS[name](**overrides)
    if name.startswith("nlink") and name[5:].isdigit():
        return RFTChain(nlink_model(int(name[5:]), **overrides))  # type: ignore[arg-type]
    known = ", ".join(sorted(SYSTEMS)) + ", nlinkN (N ≥ 3)"
    raise SudsConfigError(f"unknown system {name!r}; known systems: {known}")


def is_model_file(spec: str) -> bool:
    """True when ``spec`` names a robot model file rather than a built-in system id."""
    return spec.endswith((".yaml", ".yml")) or "/" in spec or "\\" in spec or Path(spec).is_file()


def load_system(spec: str, **overrides: object) -> SudsSystem:
    """A built-in system id (``purcell3``, ``nlink7``, …) or the path of a robot model file.

    Raises
    ------
    SudsConfigError
        For an unknown id, or a model file that does not follow ``suds-robot/1``.
    """
    if is_model_file(spec):
        from suds_ros.core.physics.robot_model import load_model

        model = load_model(spec)
        return RFTChain(model.with_(**overrides) if overrides else model)
    return make_system(spec, **overrides)


def builtin_model(name: str) -> ChainModel:
    """The :class:`ChainModel` of a built-in chain (``purcell3``, ``swimmer9``, ``nlinkN``).

    Raises
    ------
    SudsConfigError
        For a name that is not a chain (the 1-D swimmers have no model file).
    """
    system = make_system(name)
    if not isinstance(system, RFTChain):
        raise SudsConfigError(f"`name`: expected a chain system (purcell3, swimmer9, nlinkN), got {name!r}")
    return system.model
