"""The steering-wheel reading when the car drives straight (the steering offset), learned while it does.

Why its own module: it is a small estimator with its own evidence rule and its own uncertainty,
which the fleet calibration weighs across drives (issue 12).

Evidence: on a gentle path (speed above 8 m/s, |r| < 0.01 rad/s, |ay| < 0.3 m/s^2, where tyre
slip and understeer are a few hundredths of a degree at the road wheel) the kinematic (Ackermann)
relation says the driver holds ``ratio * L * r / vx`` at the steering wheel, so each sample
``z = reading - ratio * L * r / vx`` is the offset plus the driver's small corrections. Before,
the raw reading was averaged: a road that curves more one way than the other (a race track)
dragged the mean towards that side (Revs: 0.87 deg learned for a 2 deg offset after 550 s).
The kinematic term uses the bias-corrected yaw rate, so it is only taken once the yaw-rate bias
is known well enough that its error moves z by less than the driver's own scatter
(:data:`MAX_BIAS_STD_RADPS`); before that the raw reading is used, as before.

Mean: cumulative (gain 1/n) until the gain reaches :data:`GAIN_FLOOR`, then exponential: the
first drive is not pulled towards the config's 0 (the old fixed gain learned only 79-92 % of the
offset on 1-minute drives, so the fleet's combined value was 0.86 of the truth) and a slowly
changing offset (a kerb strike) is still followed. A value restored from the state file counts
as ``1 / GAIN_FLOOR`` samples, so a restart continues where the last drive stopped.

Std: the samples are not independent (a driver's correction lasts about a second), so the std of
the mean is the samples' scatter over the number of *independent* samples, n dt / (2 T_c) with
T_c = :data:`CORRELATION_S` (the effective sample size of a first-order correlated series).
"""
from __future__ import annotations

import math

MIN_SPEED_MPS = 8.0
MAX_YAW_RATE_RADPS = 0.01
MAX_LATERAL_ACCEL_MPS2 = 0.3
#: 12 s of straight driving at 6 ms: the memory once learned (the gain of the old running mean)
GAIN_FLOOR = 0.0005
#: a driver's steering correction lasts about a second: the correlation time of the samples
CORRELATION_S = 1.0
#: yaw-rate bias std under which the kinematic term is trusted: 0.001 rad/s moves z by at most
#: ratio * L * 0.001 / 8 m/s ~ 0.3 deg at the wheel for a 15:1 ratio, below a driver's scatter
MAX_BIAS_STD_RADPS = 0.001
#: scatter assumed before the samples give one (rad at the steering wheel): 1 deg
PRIOR_SCATTER_RAD = math.radians(1.0)


class SteeringOffset:
    """Running estimate of the steering-wheel angle reading (rad) when driving straight."""

    def __init__(self, dt: float, ratio: float, wheelbase: float, restored: float | None):
        self.dt = dt
        self.ratio = ratio
        self.wheelbase = wheelbase
        self.offset = 0.0 if restored is None else float(restored)
        # samples behind the mean (a restored value counts as a whole memory's worth)
        self.n = 0.0 if restored is None else 1.0 / GAIN_FLOOR
        self.var = 0.0  # the samples' scatter around the mean (exponentially weighted)

    def observe(self, reading: float, r: float, vx: float, ay: float, bias_std: float) -> bool:
        """One step's steering-wheel reading with the bias-corrected yaw rate r, speed vx, lateral
        acceleration ay and the yaw-rate bias std; True when it was evidence (a gentle path)."""
        if not (vx > MIN_SPEED_MPS and abs(r) < MAX_YAW_RATE_RADPS and abs(ay) < MAX_LATERAL_ACCEL_MPS2):
            return False
        z = reading
        if bias_std < MAX_BIAS_STD_RADPS:
            z -= self.ratio * self.wheelbase * r / vx
        self.n += 1.0
        g = max(1.0 / self.n, GAIN_FLOOR)
        e = z - self.offset
        self.offset += g * e
        self.var = (1.0 - g) * (self.var + g * e * e)  # West's running variance, same memory
        return True

    def std(self) -> float:
        """1-sigma of the offset (rad): the scatter over the independent samples behind it (the
        exponential memory holds at most 2 / GAIN_FLOOR - 1 samples). The measured scatter is
        pooled with :data:`PRIOR_SCATTER_RAD` as one more independent sample, because the first
        second of correlated samples shows almost none. NaN before any evidence."""
        if self.n <= 0.0:
            return math.nan
        n_eff = min(self.n, 2.0 / GAIN_FLOOR - 1.0)
        m = n_eff * self.dt / (2.0 * CORRELATION_S)  # independent samples
        var = (self.var * m + PRIOR_SCATTER_RAD ** 2) / (m + 1.0)
        return math.sqrt(var / max(m, 1.0))
