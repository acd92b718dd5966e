"""The IMU's samples taken to the middle of the step that integrates them.

A step from ``t - dt`` to ``t`` integrates the yaw rate into the heading and the accelerations
into the velocity. The value it holds is the latest CAN sample, received on average half a CAN
period (and up to a whole one) before ``t``: as a rate over the step it is ``age - dt/2`` old. A
constant signal does not care; a changing one does: the heading integrates ``r`` late by that
age, which at a turn-in is a heading error of ``age * delta r`` that only the next GNSS fix
removes, and the GNSS latency identification (latency.py: GNSS speed against the integrated
accelerometer and the wheels) reads the IMU's lag as part of the receiver's latency.

Each signal is carried forward by its own slope ``(v1 - v0) / (t1 - t0)`` over its last two
samples (causal, no model): ``v + slope * (age - dt/2)``. The age is capped at ``MAX_AGE_S``: a
signal that stopped is not extrapolated further (its timeout judges it). Samples sharing one
stamp (USB batches) keep the last slope; a non-finite sample clears it.
"""
from __future__ import annotations

import math

#: the age beyond which a sample is not carried further (s): several CAN periods
MAX_AGE_S = 0.05


class InputAge:
    """Last two samples' slope of each of ``n`` inputs; ``at_mid`` gives the value at a step's middle."""

    def __init__(self, n: int, dt: float):
        self.half_dt = 0.5 * dt
        self.slope = [0.0] * n
        self.v = [math.nan] * n
        self.t = [-math.inf] * n

    def observe(self, j: int, t: float, v: float) -> None:
        """Input ``j``'s sample ``v`` received at ``t`` (in arrival order)."""
        t0 = self.t[j]
        if math.isfinite(v) and math.isfinite(self.v[j]):
            if t > t0:
                self.slope[j] = (v - self.v[j]) / (t - t0)
        else:
            self.slope[j] = 0.0
        self.v[j] = v
        self.t[j] = t

    def at_mid(self, j: int, v: float, t_step: float) -> float:
        """The held value ``v`` of input ``j`` carried to the middle of the step ending at ``t_step``."""
        age = min(t_step - self.t[j], MAX_AGE_S)
        return v + self.slope[j] * (age - self.half_dt)

    def reset(self) -> None:
        """Forget every slope (a gap: the next samples start afresh)."""
        n = len(self.slope)
        self.slope = [0.0] * n
        self.v = [math.nan] * n
        self.t = [-math.inf] * n
