"""The stored steps a GNSS fix may truly be from, and a stored signal's secant over them.

Why: a fix fused at stored step ``s`` (its reception ``k_rx`` minus the delay in use) carries the
whole change of what it measures between ``s`` and its true instant, not the tangent at ``s``
(``latency_sensitivity.timing_secant``). Three terms need that window and that secant: the speed
fix's along-track timing term (``core.Estimator._along_timing``: the secant of the speed, the
integrated ax), a course's heading slope (``_course_timing_slope``: the integrated yaw rate) and
the velocity's across-track sensitivity (``_sensitivity_fused``: the window only, its own
secant). They were written out twice; the window is one rule: ``s`` +- ``n`` steps (never after the
reception), widened to the receiver's whole range ``[k_rx - max_steps, k_rx]`` when the caller
says the latency may be anywhere in it, clipped to the history and always holding ``s``.
Plain Python (not in ``compiled_python.MODULES``): it runs once per fix, not per step.
"""
from __future__ import annotations

import numpy as np

from .latency_sensitivity import timing_secant


def steps(oldest: int, last: int, s: int, k_rx: int, n: int, range_steps: int | None) -> tuple[int, int]:
    """(lo, hi): the stored steps ``s - n .. min(s + n, k_rx)``, and ``k_rx - range_steps .. k_rx``
    too when ``range_steps`` is given, within ``oldest .. last`` and holding ``s``."""
    lo, hi = s - n, min(s + n, k_rx)
    if range_steps is not None:
        lo, hi = min(lo, k_rx - range_steps), k_rx
    return max(lo, oldest), max(min(hi, last), s)


def rows(n_slots: int, lo: int, hi: int) -> np.ndarray:
    """The history's ring slots of stored steps lo..hi."""
    return np.arange(lo, hi + 1) % n_slots


def secant(aux: np.ndarray, n_slots: int, column: int, lo: int, hi: int, s: int, dt: float, span: float,
           slope: float) -> float:
    """``timing_secant`` about step ``s`` of the stored rate ``aux[:, column]`` integrated over the
    steps lo..hi (the change it makes from ``s`` to each instant the fix may be from); ``slope``: the
    tangent at ``s``, ``span``: the lag beyond which a secant counts as ``span``."""
    y = np.cumsum(aux[rows(n_slots, lo, hi), column]) * dt
    return timing_secant(y, s - lo, dt, span, slope)
