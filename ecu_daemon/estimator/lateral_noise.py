"""The lateral accelerometer's white-noise density, measured from its own samples.

vy is the integral of ``ay - r vx``: the accelerometer's white noise integrates into a random walk
of vy whose spectral density *is* the sensor's noise density. That density differs by a factor of
30 between IMUs and mountings: the simulated sensor has 0.05 m/s^2 per 100 Hz sample
(0.005 m/s^2/sqrt(Hz)), the Revs race car's 1.5 m/s^2 (engine and road vibration, 0.15). One
configured constant is either too small for the noisy car (its vy std lies) or far too large
for the quiet one (a steady circle's sideslip std of 1.2-1.5 deg where the estimate is right to
0.1-0.2 deg: needlessly invalid). So the density is measured, as ``max(floor, measured)``:

* the samples are averaged in blocks of ``BLOCK_S``, and the second difference of consecutive
  block means ``m[k] - 2 m[k-1] + m[k-2]`` has variance ``6 q^2 / T`` for white noise of density
  q over blocks of T seconds, while the vehicle's own motion adds only the third derivative of
  ay x T^2 (zero in a steady corner, ~0.3 m/s^2 in a brisk lane change: the measurement then
  errs large, on the safe side). Blocks, not single samples: a sensor or gateway that low-passes
  or resamples the signal (the Revs log, 100 Hz interpolated to 83 Hz, shows half its noise in
  sample-to-sample differences) correlates neighbouring samples, not blocks of several;
* averaged over ``TAU_S`` (vibration changes with speed and road, not from one block to the
  next), and only ever raising the configured floor ``[estimator] lateral_accel_noise_mps2``: a
  signal filtered harder than a block still hides its noise from this test, while its noise at
  the low frequencies that vy integrates is unchanged, so the measurement is not trusted to
  *lower* the noise below what the configuration says.
"""
from __future__ import annotations

import math

TAU_S = 10.0  # averaging time of the mean square (vibration follows speed and road surface)
BLOCK_S = 0.05  # s of samples per block mean (5 samples at 100 Hz)
MAX_TS = 0.05  # s: a longer sample interval (a gap) restarts the block chain
WARM_S = 1.0  # seconds of samples before the measurement may raise the floor


class LateralNoise:
    """``density``: the white-noise density (m/s^2/sqrt(Hz)) that drives vy."""

    def __init__(self, floor: float):
        self.floor = floor
        self.density = floor
        self._t1 = -math.inf
        self._sum = 0.0  # the current block: sum of samples, count, start time
        self._n = 0
        self._t0 = 0.0
        self._m1 = self._m0 = math.nan  # the last two block means
        self._ms = 0.0  # EMA of (second difference)^2 x block length (bias-corrected by _w)
        self._w = 0.0
        self._span = 0.0  # seconds of blocks seen

    def observe(self, t: float, ay: float) -> None:
        """One new lateral-acceleration sample (raw reading, SI) received at ``t``."""
        ts = t - self._t1
        self._t1 = t
        if not (0.0 < ts <= MAX_TS) or not math.isfinite(ay):  # a gap: start a new chain
            self._m0 = self._m1 = math.nan
            self._sum, self._n, self._t0 = (ay, 1, t) if math.isfinite(ay) else (0.0, 0, t)
            return
        if self._n == 0:
            self._t0 = t
        self._sum += ay
        self._n += 1
        span = t - self._t0 + ts  # the block covers n sample intervals
        if span < BLOCK_S:
            return
        m = self._sum / self._n
        self._sum, self._n = 0.0, 0
        m0, m1 = self._m0, self._m1
        self._m0, self._m1 = m1, m
        if m0 != m0:  # NaN: fewer than three blocks since the chain started
            return
        d2 = m - 2.0 * m1 + m0
        g = span / TAU_S
        self._ms += g * (d2 * d2 * span - self._ms)
        self._w += g * (1.0 - self._w)
        self._span += span
        if self._span >= WARM_S:
            measured = math.sqrt(self._ms / self._w / 6.0)
            self.density = measured if measured > self.floor else self.floor
