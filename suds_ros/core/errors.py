"""Package exceptions, each with a machine-readable code.

Every error the package raises on purpose derives from :class:`SudsError`, so a
command-line front end can catch exactly these and print a one-line message.
Each also subclasses the matching built-in so ordinary ``except ValueError``
code keeps working.

Code that reacts to an error (a node counting rejected samples by reason, a
test) reads ``exc.code``, never the message text: messages are for people and
may be reworded.  Each class has a default code; a raise site that callers need
to tell apart passes one of the constants below, e.g.
``raise SudsDataError("`stamp`: duplicate …", code=DUPLICATE_STAMP)``.
"""

from __future__ import annotations

# Specific codes (a raise site passes one as ``code=``).  Values are stable identifiers:
# nodes publish them as status keys and tests compare them.
NAN_OR_INF = "nan_or_inf"
DUPLICATE_STAMP = "duplicate_stamp"
OUT_OF_ORDER_STAMP = "out_of_order_stamp"
BAD_STAMP = "bad_stamp"
WRONG_JOINT_NAMES = "wrong_joint_names"
WRONG_JOINT_COUNT = "wrong_joint_count"
MODEL_MISMATCH = "model_mismatch"
BAD_QUATERNION = "bad_quaternion"
QUEUE_FULL = "queue_full"
NO_POSE = "no_pose"
TOO_LITTLE_DATA = "too_little_data"
MISSING_TOPIC = "missing_topic"
MISSING_METADATA = "missing_metadata"
MISSING_SYSTEM = "missing_system"
MISSING_JOINT_ROLES = "missing_joint_roles"
DAMAGED_BAG = "damaged_bag"
EXISTS = "exists"
UNKNOWN_SYSTEM = "unknown_system"
CHECKPOINT_VERSION = "checkpoint_version"
CHECKPOINT_DAMAGED = "checkpoint_damaged"
OUT_OF_RANGE = "out_of_range"  # a config value outside its range or choices
WRONG_TYPE = "wrong_type"  # a config value of the wrong kind (not a number, not an integer)


class SudsError(Exception):
    """Base class of every deliberate suds_ros error.

    Parameters
    ----------
    message : str
        One line for a person: the argument, what was expected, what was received.
    code : str, optional
        Machine-readable reason; defaults to the class's ``code``.
    """

    code: str = "error"

    def __init__(self, message: str = "", *, code: str | None = None) -> None:
        super().__init__(message)
        if code is not None:
            self.code = code

    def __reduce__(self):  # type: ignore[no-untyped-def]
        # keep the code across pickling (worker processes, checkpoints)
        return (_rebuild, (type(self), str(self), self.code))


def _rebuild(cls: type[SudsError], message: str, code: str) -> SudsError:
    return cls(message, code=code)


class SudsConfigError(SudsError, ValueError):
    """A configuration value or argument is out of its allowed range."""

    code = "bad_config"


class SudsDataError(SudsError, ValueError):
    """Input data are malformed: NaN, unsorted or duplicate stamps, wrong shapes."""

    code = "bad_data"


class SudsBagError(SudsError, OSError):
    """A recording cannot be read or written (missing, truncated, foreign, missing topics)."""

    code = "bad_bag"


class SudsPhaseError(SudsError, ValueError):
    """Too little or too irregular data to estimate a gait phase."""

    code = "phase"


class SudsSimulationError(SudsError, FloatingPointError):
    """The simulated physics has no consistent solution (e.g. a softening spring past its stable range).

    A ``FloatingPointError`` too, so numerical code that tries a candidate model and moves on
    when its physics breaks down keeps doing so.
    """

    code = "simulation_failed"


class NotFittedError(SudsError, ValueError, AttributeError):
    """An estimator was used before ``fit`` or ``partial_fit``.

    Like scikit-learn's ``NotFittedError`` it is both a ``ValueError`` and an
    ``AttributeError`` (``hasattr`` on a property that needs the fit is False).
    """

    code = "not_fitted"


def error_code(exc: BaseException) -> str:
    """The code of a suds error; ``internal_error_<Type>`` for anything else (a bug)."""
    if isinstance(exc, SudsError):
        return exc.code
    return f"internal_error_{type(exc).__name__}"
