"""The estimator contract of the package, without scikit-learn.

Every class that learns from data with ``fit`` (and ``partial_fit``) subclasses
:class:`BaseEstimator` and follows scikit-learn's rules, so ``sklearn.base.clone`` and grid
search work on it when scikit-learn happens to be installed (it is not a dependency):

- ``__init__`` only stores its hyperparameters, under the names of its arguments; nothing is
  checked or computed there (``fit`` validates, so a value given to :meth:`~BaseEstimator.set_params`
  is checked exactly like one given to the constructor);
- learned attributes end in ``_`` and only ``fit``/``partial_fit`` set them; fitting never
  changes a hyperparameter;
- methods that need a fit start with :func:`check_is_fitted`, which raises
  :class:`~suds_ros.core.errors.NotFittedError`.

Hyperparameters that are frozen configuration dataclasses (``SudsConfig``, ``PhaserConfig``, …)
take part in :meth:`~BaseEstimator.get_params` ``(deep=True)`` and
:meth:`~BaseEstimator.set_params` field by field, as ``config__ridge``; a new value builds a
new dataclass (``dataclasses.replace``), whose own checks run.
"""

from __future__ import annotations

import copy
import dataclasses
import inspect
from collections.abc import Iterable
from typing import Any, TypeVar

from suds_ros.core.errors import NotFittedError, SudsConfigError

E = TypeVar("E", bound="BaseEstimator")


def _learned(obj: object) -> list[str]:
    """Names of the instance attributes that end in ``_`` (learned), private dunders excluded."""
    return [k for k in vars(obj) if k.endswith("_") and not k.startswith("__")]


class BaseEstimator:
    """Hyperparameter access (``get_params``/``set_params``), ``repr`` and learned-state reset.

    The hyperparameters are the arguments of the subclass's ``__init__`` (no ``*args`` or
    ``**kwargs``), each stored unchanged as an attribute of the same name.
    """

    @classmethod
    def _get_param_names(cls) -> list[str]:
        """The hyperparameter names: the ``__init__`` arguments, sorted."""
        init = cls.__init__
        if init is object.__init__:
            return []
        names = []
        for p in inspect.signature(init).parameters.values():
            if p.name == "self":
                continue
            if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
                raise TypeError(f"{cls.__name__}.__init__: estimators take no *args or **kwargs, got {p}")
            names.append(p.name)
        return sorted(names)

    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The hyperparameters by name.

        Parameters
        ----------
        deep : bool
            Also list the parameters of nested estimators and the fields of configuration
            dataclasses, as ``<name>__<field>``.
        """
        out: dict[str, Any] = {}
        for name in self._get_param_names():
            value = getattr(self, name)
            if deep:
                for sub, v in _nested_params(value).items():
                    out[f"{name}__{sub}"] = v
            out[name] = value
        return out

    def set_params(self: E, **params: Any) -> E:
        """Set hyperparameters by name (``name`` or nested ``name__field``); returns ``self``.

        Raises
        ------
        SudsConfigError
            A name that is not a hyperparameter (or field) of this estimator.
        """
        valid = self._get_param_names()
        nested: dict[str, dict[str, Any]] = {}
        for key, value in params.items():
            name, delim, sub = key.partition("__")
            if name not in valid:
                raise SudsConfigError(
                    f"`{key}`: not a parameter of {type(self).__name__}; expected one of {valid}")
            if delim:
                nested.setdefault(name, {})[sub] = value
            else:
                setattr(self, name, value)
        for name, sub_params in nested.items():
            setattr(self, name, _set_nested(getattr(self, name), name, sub_params))
        return self

    def _reset_learned(self) -> None:
        """Forget everything learned (every attribute ending in ``_``): the start of ``fit``."""
        for name in _learned(self):
            delattr(self, name)

    def __repr__(self) -> str:
        sig = inspect.signature(type(self).__init__).parameters
        shown = []
        for name in self._get_param_names():
            value = getattr(self, name)
            default = sig[name].default
            if default is inspect.Parameter.empty or not _same(value, default):
                shown.append(f"{name}={value!r}")
        return f"{type(self).__name__}({', '.join(shown)})"


def _same(a: object, b: object) -> bool:
    if a is b:
        return True
    if type(a) is not type(b):
        return False
    try:
        return bool(a == b)
    except (TypeError, ValueError):  # arrays and the like: shown
        return False


def _nested_params(value: object) -> dict[str, Any]:
    """Parameters of a nested estimator, or fields of a configuration dataclass (else none)."""
    if isinstance(value, type):
        return {}
    if hasattr(value, "get_params"):
        return dict(value.get_params(deep=True))
    if dataclasses.is_dataclass(value):
        return {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
    return {}


def _set_nested(value: object, name: str, params: dict[str, Any]) -> object:
    """``value`` with ``params`` set: a nested estimator in place, a dataclass by replacement."""
    if hasattr(value, "set_params") and not isinstance(value, type):
        return value.set_params(**params)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name for f in dataclasses.fields(value)}
        unknown = sorted(set(params) - fields)
        if unknown:
            raise SudsConfigError(
                f"`{name}__{unknown[0]}`: not a field of {type(value).__name__}; expected one of {sorted(fields)}")
        return dataclasses.replace(value, **params)
    raise SudsConfigError(f"`{name}`: {type(value).__name__} has no parameters to set, got {sorted(params)}")


def clone(estimator: Any, *, safe: bool = True) -> Any:
    """A new unfitted estimator with the same hyperparameters (deep copies of them).

    Lists, tuples and sets of estimators are cloned element by element.  With ``safe=False``
    anything that is not an estimator is deep-copied; otherwise it raises ``TypeError``.
    """
    if isinstance(estimator, (list, tuple, set, frozenset)):
        return type(estimator)(clone(e, safe=safe) for e in estimator)
    if isinstance(estimator, type) or not hasattr(estimator, "get_params"):
        if not safe:
            return copy.deepcopy(estimator)
        raise TypeError(f"`estimator`: expected an estimator with get_params, got {estimator!r}")
    params = estimator.get_params(deep=False)
    fresh = {name: clone(value, safe=False) for name, value in params.items()}
    new = type(estimator)(**fresh)
    stored = new.get_params(deep=False)
    for name, value in fresh.items():
        if stored[name] is not value:
            raise RuntimeError(
                f"{type(estimator).__name__}.__init__ does not store `{name}` unchanged: it must only "
                "store its hyperparameters")
    return new


def is_fitted(estimator: object, attributes: str | Iterable[str] | None = None) -> bool:
    """Whether ``estimator`` is fitted (see :func:`check_is_fitted`)."""
    if attributes is not None:
        names = [attributes] if isinstance(attributes, str) else list(attributes)
        return all(hasattr(estimator, a) for a in names)
    probe = getattr(estimator, "__sklearn_is_fitted__", None)
    if probe is not None:
        return bool(probe())
    return bool(_learned(estimator))


def check_is_fitted(estimator: object, attributes: str | Iterable[str] | None = None, *,
                    msg: str | None = None) -> None:
    """Raise :class:`~suds_ros.core.errors.NotFittedError` unless ``estimator`` is fitted.

    Parameters
    ----------
    estimator : estimator instance
    attributes : str or iterable of str, optional
        Learned attributes that must all be present.  By default the estimator's own
        ``__sklearn_is_fitted__()`` decides if it has one (an estimator whose ``partial_fit``
        can leave it unsolved), else any attribute ending in ``_``.
    msg : str, optional
        The error message; ``%(name)s`` is replaced by the estimator's class name.

    Raises
    ------
    TypeError
        ``estimator`` is a class or has no ``fit``.
    NotFittedError
        It is not fitted.
    """
    if isinstance(estimator, type) or not hasattr(estimator, "fit"):
        raise TypeError(f"`estimator`: expected an estimator instance with fit, got {estimator!r}")
    if is_fitted(estimator, attributes):
        return
    name = type(estimator).__name__
    if msg is None:
        how = "fit or partial_fit" if hasattr(estimator, "partial_fit") else "fit"
        msg = f"this %(name)s is not fitted yet; call {how} first"
    raise NotFittedError(msg % {"name": name})
