"""Package exceptions.

Every error the package raises on purpose derives from :class:`SudsError`, so a
command-line front end can catch exactly these and print a one-line message.
Each also subclasses the matching built-in so ordinary ``except ValueError``
code keeps working.
"""

from __future__ import annotations


class SudsError(Exception):
    """Base class of every deliberate suds_ros error."""


class SudsConfigError(SudsError, ValueError):
    """A configuration value or argument is out of its allowed range."""


class SudsDataError(SudsError, ValueError):
    """Input data are malformed: NaN, unsorted or duplicate stamps, wrong shapes."""


class SudsBagError(SudsError, OSError):
    """A recording cannot be read or written (missing, truncated, foreign, missing topics)."""


class SudsPhaseError(SudsError, ValueError):
    """Too little or too irregular data to estimate a gait phase."""


class NotFittedError(SudsError, AttributeError):
    """An estimator was used before ``fit`` or ``partial_fit``."""
