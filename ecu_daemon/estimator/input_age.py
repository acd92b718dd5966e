"""The IMU's samples taken to the middle of the step that integrates them.

A step from ``t - dt`` to ``t`` integrates the yaw rate into the heading and the accelerations
into the velocity. The value it holds is the latest CAN sample, received on average half a CAN
period (and up to a whole one) before ``t``: as a rate over the step it is ``age - dt/2`` old. A
constant signal does not care; a changing one does: the heading integrates ``r`` late by that
age, which at a turn-in is a heading error of ``age * delta r`` that only the next GNSS fix
removes, and the GNSS latency identification (latency.py: GNSS speed against the integrated
accelerometer and the wheels) reads the IMU's lag as part of the receiver's latency.

Each signal is carried forward by its own slope: ``(v1 - v0) / (t1 - t0)`` of its last two
samples, low-passed over ``SLOPE_TAU_S`` (causal, no model): ``v + slope * (age - dt/2)``. The raw
two-sample slope is the sensor's noise over one CAN period (a noisy gyro's 10 ms difference, times
a few ms, doubled its noise and took fault_yaw_rate_noisy's heading 8 % invalid); a slope 30 ms
late errs by the signal's curvature times 30 ms times the age, nothing at these ages. The age is capped at ``MAX_AGE_S``: a
signal that stopped is not extrapolated further (its timeout judges it). Samples sharing one
stamp (USB batches) keep the last slope; a non-finite sample clears it.
"""
from __future__ import annotations

import math

#: the age beyond which a sample is not carried further (s): several CAN periods
MAX_AGE_S = 0.05
#: the slope's low-pass time constant (s): a few CAN periods
SLOPE_TAU_S = 0.03


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
                h = t - t0
                self.slope[j] += h / (SLOPE_TAU_S + h) * ((v - self.v[j]) / h - self.slope[j])
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
