"""The step rule, in one place: step k (time k * dt) uses every input stamped at or before k * dt.

Everything that decides which step an input belongs to (the estimator's queue, the pipeline's
inbox, replay) calls these two functions, so live and replay cannot disagree by an epsilon.
Input times are rounded to 1 us and steps are milliseconds apart, so a tolerance of a millionth
of a step only absorbs the floating-point error of ``t / dt``.
"""
from __future__ import annotations

import math

import numpy as np

EPS_STEPS = 1e-6


def step_of(t: float, dt: float) -> int:
    """The first step that uses an input stamped ``t``."""
    return math.ceil(t / dt - EPS_STEPS)


def steps_of(t: np.ndarray, dt: float) -> np.ndarray:
    """:func:`step_of` of every time in ``t`` at once (the same float operations, so the same
    steps): offline replay hands whole logs over."""
    return np.ceil(t / dt - EPS_STEPS).astype(np.int64)


def last_step_at(t: float, dt: float) -> int:
    """The last step whose time is at or before ``t``."""
    return math.floor(t / dt + EPS_STEPS)
