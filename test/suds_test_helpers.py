"""Helpers shared by tests anywhere in test/ (not a test module; importable because pytest puts test/ on sys.path).

Use: ``from suds_test_helpers import circular_rms``.
"""

from __future__ import annotations

import numpy as np


def circular_rms(estimate: np.ndarray, reference: np.ndarray) -> float:
    """RMS of the wrapped phase error ``estimate - reference`` after removing its circular mean (rad).

    A phase estimate is defined up to one constant offset, so the offset (the
    circular mean of the error) is removed before the RMS is taken.
    """
    d = np.asarray(estimate, dtype=float) - np.asarray(reference, dtype=float)
    e = np.angle(np.exp(1j * (d - np.angle(np.mean(np.exp(1j * d))))))
    return float(np.sqrt(np.mean(e**2)))
