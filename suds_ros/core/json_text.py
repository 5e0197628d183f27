"""Strict JSON text: every non-finite number becomes ``null``, never ``NaN`` or ``Infinity``.

Python's :func:`json.dumps` writes ``NaN``, ``Infinity`` and ``-Infinity`` by default, which is not
JSON (RFC 8259): ``jq``, JavaScript's ``JSON.parse`` and most other readers refuse the whole
document.  Every JSON document the package writes for others goes through :func:`dumps`, which
converts first (:func:`finite_or_null`, the one place that decides what is non-finite) and then
serialises with ``allow_nan=False``, so a value the conversion missed raises instead of being
written.  A quantity that does not apply (Γ of the passive joints of a fully actuated chain) is
``None`` at its source and ``null`` in the text.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np


def finite_or_null(obj: Any) -> Any:
    """``obj`` with every non-finite float replaced by None, ready for strict JSON.

    Recurses through mappings (keys kept), lists, tuples and numpy arrays (→ lists); numpy
    scalars become Python ``float``/``int``/``bool``.  Other objects are returned unchanged
    (``json`` then serialises them or calls its ``default``).

    Examples
    --------
    >>> finite_or_null({"gamma": float("nan"), "rms": [1.0, np.inf], "n": np.int64(3)})
    {'gamma': None, 'rms': [1.0, None], 'n': 3}
    """
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.ndarray):
        return finite_or_null(obj.tolist())
    if isinstance(obj, Mapping):
        return {k: finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_null(v) for v in obj]
    return obj


def dumps(obj: Any, **kwargs: Any) -> str:
    """Strict JSON text of ``obj``: :func:`finite_or_null`, then :func:`json.dumps` with ``allow_nan=False``.

    ``kwargs`` go to :func:`json.dumps` (``indent``, ``sort_keys``, ``default``, …); passing
    ``allow_nan`` is a :class:`TypeError`.
    """
    if "allow_nan" in kwargs:
        raise TypeError("dumps(): `allow_nan` is fixed to False (non-finite numbers are written as null)")
    return json.dumps(finite_or_null(obj), allow_nan=False, **kwargs)
