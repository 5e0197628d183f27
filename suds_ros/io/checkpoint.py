"""Estimator checkpoints as data: numpy arrays and a versioned JSON header, never code.

A checkpoint is one ``.npz`` file (a zip of ``.npy`` arrays, read with
``allow_pickle=False``).  Its member ``header`` is a JSON text: the format name, the format
version, the suds_ros version that wrote it and the estimator's state as a tree of plain
values.  Arrays with more than :data:`INLINE_MAX` elements are members of their own,
referenced from the tree by name; smaller ones are written inline.  Floats are written in
full precision, so a saved and re-read estimator continues exactly as the original would.

Objects in the tree are named by class name, and only the classes in :data:`STATE_CLASSES`
can be rebuilt: an instance is made without running any constructor and its attributes are
set from the tree.  Nothing in the file can run code, and a class that moves between modules
does not break a checkpoint.  A class whose attributes change bumps :data:`FORMAT_VERSION`;
a file of another version, a damaged file or a foreign one is refused with
:class:`~suds_ros.core.errors.SudsDataError` (codes ``checkpoint_version`` and
``checkpoint_damaged``), and the caller starts afresh.

Writes are atomic (temporary file in the same folder, fsync, rename), so a crash mid-write
leaves the previous checkpoint in place.
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import tempfile
import zipfile
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from suds_ros.core.errors import CHECKPOINT_DAMAGED, CHECKPOINT_VERSION, SudsDataError
from suds_ros.core.fourier import NormalEquations
from suds_ros.core.ident.featurise import StreamFeaturiser
from suds_ros.core.ident.online import OnlineConfig, OnlineSudsEstimator
from suds_ros.core.ident.pairing import FrameJoiner, StampPairer
from suds_ros.core.ident.phase_init import GaitInitialiser
from suds_ros.core.ident.prequential import PrequentialSelector
from suds_ros.core.ident.shape_kernel import KernelScale
from suds_ros.core.ident.sysid import FeatureLayout, SudsConfig, SudsRegressor
from suds_ros.core.phase.phase_tracker import PhaseTracker
from suds_ros.core.phase.template import FourierTemplate, FourierTemplateConfig
from suds_ros.core.resample import LiveGrid

#: the ``format`` field of the header
FORMAT = "suds_ros.estimator_checkpoint"
#: bumped whenever the state of a class below changes shape
FORMAT_VERSION = 14
#: arrays up to this many elements are written inside the JSON header
INLINE_MAX = 64

#: the classes a checkpoint may hold, by name
STATE_CLASSES: dict[str, type] = {c.__name__: c for c in (
    OnlineSudsEstimator, OnlineConfig, SudsConfig, StampPairer, GaitInitialiser, FourierTemplate,
    FourierTemplateConfig, PhaseTracker, StreamFeaturiser, PrequentialSelector, SudsRegressor,
    NormalEquations, KernelScale, FeatureLayout, LiveGrid, FrameJoiner)}

_NUMERIC = "fiub"  # float, signed and unsigned integer, bool: what np.load takes without pickle


def _package_version() -> str:
    try:
        from importlib.metadata import version

        return version("suds_ros")
    except Exception:  # noqa: BLE001 - not installed (a checkout): the header still says the format
        return "unknown"


class _Encoder:
    def __init__(self) -> None:
        self.arrays: dict[str, np.ndarray] = {}

    def __call__(self, v: Any) -> Any:  # noqa: C901 - one branch per kind of value
        if v is None or isinstance(v, (bool, int, str)):
            return v
        if isinstance(v, float):
            return v if np.isfinite(v) else {"$float": repr(v)}
        if isinstance(v, np.generic):
            return {"$scalar": v.dtype.str, "v": self(v.item())}
        if isinstance(v, np.ndarray):
            if v.dtype.kind not in _NUMERIC and v.dtype.kind != "c":
                raise SudsDataError(f"checkpoint: cannot store an array of dtype {v.dtype}")
            if v.size <= INLINE_MAX and v.dtype.kind != "c":
                return {"$array": v.dtype.str, "shape": list(v.shape), "v": [self(x) for x in v.ravel().tolist()]}
            name = f"a{len(self.arrays)}"
            self.arrays[name] = np.ascontiguousarray(v)
            return {"$ref": name}
        if isinstance(v, complex):
            return {"$complex": [self(v.real), self(v.imag)]}
        if isinstance(v, tuple):
            return {"$tuple": [self(x) for x in v]}
        if isinstance(v, list):
            return [self(x) for x in v]
        if isinstance(v, deque):
            return {"$deque": [self(x) for x in v], "maxlen": v.maxlen}
        if isinstance(v, dict):
            if not all(isinstance(k, str) for k in v):
                raise SudsDataError("checkpoint: cannot store a dict with non-string keys")
            return {"$dict": {k: self(x) for k, x in v.items()}}
        name = type(v).__name__
        if STATE_CLASSES.get(name) is not type(v):
            raise SudsDataError(f"checkpoint: cannot store a {type(v).__module__}.{name} "
                                f"(not among {sorted(STATE_CLASSES)})")
        attrs = vars(v) if not dataclasses.is_dataclass(v) else {
            f.name: getattr(v, f.name) for f in dataclasses.fields(v)}
        return {"$obj": name, "attrs": {k: self(x) for k, x in attrs.items()}}


class _Decoder:
    def __init__(self, arrays: Any) -> None:
        self.arrays = arrays

    def __call__(self, v: Any) -> Any:  # noqa: C901 - one branch per kind of value
        if v is None or isinstance(v, (bool, int, float, str)):
            return v
        if isinstance(v, list):
            return [self(x) for x in v]
        if not isinstance(v, dict) or len(v) == 0:
            raise SudsDataError(f"unexpected value {v!r} in the state", code=CHECKPOINT_DAMAGED)
        if "$float" in v:
            return float(v["$float"])
        if "$scalar" in v:
            return np.dtype(_numeric_dtype(v["$scalar"])).type(self(v["v"]))
        if "$array" in v:
            return np.array([self(x) for x in v["v"]], dtype=_numeric_dtype(v["$array"])).reshape(v["shape"])
        if "$ref" in v:
            name = v["$ref"]
            if name not in self.arrays:
                raise SudsDataError(f"array {name!r} of the state is missing", code=CHECKPOINT_DAMAGED)
            return np.array(self.arrays[name])
        if "$complex" in v:
            re, im = (self(x) for x in v["$complex"])
            return complex(re, im)
        if "$tuple" in v:
            return tuple(self(x) for x in v["$tuple"])
        if "$deque" in v:
            return deque((self(x) for x in v["$deque"]), maxlen=v["maxlen"])
        if "$dict" in v:
            return {k: self(x) for k, x in v["$dict"].items()}
        if "$obj" in v:
            cls = STATE_CLASSES.get(v["$obj"])
            if cls is None:
                raise SudsDataError(f"unknown class {v['$obj']!r} in the state", code=CHECKPOINT_VERSION)
            obj = object.__new__(cls)
            for k, x in v["attrs"].items():
                object.__setattr__(obj, k, self(x))  # frozen dataclasses too: no constructor runs
            return obj
        raise SudsDataError(f"unexpected value {sorted(v)!r} in the state", code=CHECKPOINT_DAMAGED)


def _numeric_dtype(text: str) -> np.dtype:
    dt = np.dtype(text)
    if dt.kind not in _NUMERIC and dt.kind != "c":
        raise SudsDataError(f"dtype {text!r} in the state is not numeric", code=CHECKPOINT_DAMAGED)
    return dt


def state_to_bytes(obj: Any) -> bytes:
    """The checkpoint file contents of ``obj`` (an estimator, or any value of allowed classes)."""
    enc = _Encoder()
    tree = enc(obj)
    header = {"format": FORMAT, "version": FORMAT_VERSION, "suds_ros": _package_version(), "state": tree}
    buf = io.BytesIO()
    arrays = dict(enc.arrays)
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    np.savez(buf, **arrays)
    return buf.getvalue()


def state_from_bytes(data: bytes, what: str = "checkpoint") -> Any:
    """Inverse of :func:`state_to_bytes`.

    Raises
    ------
    SudsDataError
        ``checkpoint_damaged``: not a readable checkpoint; ``checkpoint_version``: written in
        another format version (or by another program).
    """
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise SudsDataError(f"{what} is not a readable checkpoint (.npz): {exc}", code=CHECKPOINT_DAMAGED) from None
    if "header" not in arrays:
        raise SudsDataError(f"{what} has no checkpoint header", code=CHECKPOINT_DAMAGED)
    try:
        header = json.loads(arrays.pop("header").tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SudsDataError(f"{what}: the checkpoint header is not JSON: {exc}", code=CHECKPOINT_DAMAGED) from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise SudsDataError(f"{what} is not a suds_ros estimator checkpoint (format "
                            f"{header.get('format') if isinstance(header, dict) else None!r}, expected {FORMAT!r})",
                            code=CHECKPOINT_VERSION)
    if header.get("version") != FORMAT_VERSION:
        raise SudsDataError(f"{what} is checkpoint format version {header.get('version')!r} (written by suds_ros "
                            f"{header.get('suds_ros')}); this version reads {FORMAT_VERSION}",
                            code=CHECKPOINT_VERSION)
    try:
        return _Decoder(arrays)(header["state"])
    except SudsDataError as exc:
        raise SudsDataError(f"{what}: {exc}", code=exc.code) from None
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise SudsDataError(f"{what}: damaged checkpoint state ({type(exc).__name__}: {exc})",
                            code=CHECKPOINT_DAMAGED) from None


def save_estimator(path: str | Path, est: OnlineSudsEstimator) -> None:
    """Atomically write a checkpoint of ``est`` (temporary file, fsync, rename)."""
    path = Path(path)
    data = state_to_bytes(est)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load_estimator(path: str | Path) -> OnlineSudsEstimator:
    """Read a checkpoint written by :func:`save_estimator`.

    Raises
    ------
    SudsDataError
        The file cannot be read, is damaged, foreign or of another version (codes
        ``checkpoint_damaged``, ``checkpoint_version``).
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SudsDataError(f"checkpoint {str(path)!r} is unreadable: {exc}", code=CHECKPOINT_DAMAGED) from None
    est = state_from_bytes(data, f"checkpoint {str(path)!r}")
    if not isinstance(est, OnlineSudsEstimator):
        raise SudsDataError(f"checkpoint {str(path)!r} holds a {type(est).__name__}, not an estimator",
                            code=CHECKPOINT_DAMAGED)
    return est
