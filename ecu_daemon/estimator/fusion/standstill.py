"""Standstill: zero-velocity updates and the yaw-rate bias at rest.

At rest the true velocity and yaw rate are zero, so the gyro reading *is* its bias (Park 002 §2.2
uses r = 0 while straight; at rest it holds exactly), and the accelerometers read their bias plus
the gravity of grade and bank, which is exactly what the filter's accelerometer-bias states mean. Detected from the wheel speeds (all below a
crawl) held for a short time, so a brief zero crossing does not count.
"""
from __future__ import annotations

import math

from .. import kalman
from ..kinematic import BAX, BAY, BR, VX, VY

STANDSTILL_SPEED = 0.05  # m/s, every wheel below this
#: m/s: the speed below which a wheel sensor sees no pulses and reads 0 (detect's docstring; typical
#: active sensors 0.1-0.2 m/s): a standstill from the wheels bounds |v| by it (core.STANDSTILL_CREEP_STD)
WHEEL_PULSE_FLOOR_MPS = 0.15
STANDSTILL_HOLD_S = 0.3
ACCEL_GATE = 6.0  # sigma: the accelerometer-bias update's gate at rest; beyond it the car accelerates
#: The yaw-rate bias at rest from each gyro sample once, at the scatter the gyro shows at rest (issue 7,
#: stop 48). Off: every 6 ms step fuses the held sample at R = (2 x max(configured noise, 1e-3))^2,
#: the configured *density* (rad/s/sqrt(Hz)) read as a per-step std, while a sample is held ~10 ms
#: (fused 1-2 times: correlated) and the gyro's per-sample scatter is what it is (drive 2946: 0.0024
#: rad/s; the random drives draw 0.0007-0.0035): b_r's std came out ~1.5x too small (2946: learned
#: 0.0063 for 0.0060 at std 7.6e-5, z 3.5 at rest). On: only a new sample (its receive stamp
#: changed) is fused, at R = the variance of the gyro's new samples at rest (half the mean squared
#: difference of consecutive samples: blind to the bias itself and to its slow walk), floored at
#: the configured noise as a per-sample std (max(noise, 1e-3)^2); no gyro update at rest until
#: GYRO_R_MIN_DIFFS such differences were seen (a variance from a handful of samples could be
#: anything).
MEASURED_GYRO_R = True
GYRO_R_MIN_DIFFS = 20
#: s: two gyro samples further apart than this are not consecutive (a gap, a standstill between)
GYRO_R_MAX_GAP_S = 0.05


class StandstillFusion:
    def __init__(self, dt: float, gyro_noise: float):
        self.hold_steps = int(STANDSTILL_HOLD_S / dt)
        self.count = 0
        self.gyro_R = max(gyro_noise, 1e-3) ** 2 * 4.0
        self.gyro_floor_var = max(gyro_noise, 1e-3) ** 2  # MEASURED_GYRO_R's floor, per sample
        self.r_t = -math.inf  # receive stamp of the last gyro sample seen at rest
        self.r_last = 0.0  # its value
        self.r_n = 0  # consecutive pairs seen at rest
        self.r_sq = 0.0  # their squared differences' sum
        # held CAN samples repeat over several 6 ms steps: noise of 0.05 m/s^2, inflated for that
        self.accel_R = 0.05 ** 2 * 4.0

    def detect(self, wheels_max: float, ax: float = 0.0, bax_var: float = 0.0) -> bool:
        """Every wheel below a crawl, and the accelerometer (``ax`` less its bias state, of
        variance ``bax_var``) inside the gate of the bias update at rest: wheel sensors see no
        pulses below ~0.15 m/s, so a car moving off reads 0 on every wheel for the first tens of
        ms while ax already reads its acceleration (pinning vx at 0 then was 0.13 m/s off)."""
        if wheels_max < STANDSTILL_SPEED and ax * ax <= ACCEL_GATE * ACCEL_GATE * (bax_var + self.accel_R):
            self.count += 1
        else:
            self.count = 0
        return self.count >= self.hold_steps

    def gyro_var(self) -> float:
        """The variance of one gyro sample at rest (MEASURED_GYRO_R), inf until enough were seen."""
        if self.r_n < GYRO_R_MIN_DIFFS:
            return math.inf
        return max(self.gyro_floor_var, 0.5 * self.r_sq / self.r_n)

    def fuse(self, x, P, r_m: float, ax_m: float, ay_m: float, A, r_t=None) -> None:
        """At rest: v = 0 and the accelerometer / gyro biases read directly. ``r_t``: the receive
        stamp of the gyro sample ``r_m`` came from (MEASURED_GYRO_R; None: every step, as before)."""
        for i in (VX, VY):
            kalman.index_update(x, P, -x[i], i, 1e-4, 0.0, A)
        if MEASURED_GYRO_R and r_t is not None:
            if r_t != self.r_t:  # a new sample: counted once
                if r_t - self.r_t <= GYRO_R_MAX_GAP_S:
                    d = r_m - self.r_last
                    self.r_n += 1
                    self.r_sq += d * d
                self.r_t = r_t
                self.r_last = r_m
                R = self.gyro_var()
                if R < math.inf:
                    kalman.index_update(x, P, r_m - x[BR], BR, R, 6.0, A)
        else:
            kalman.index_update(x, P, r_m - x[BR], BR, self.gyro_R, 6.0, A)
        kalman.index_update(x, P, ax_m - x[BAX], BAX, self.accel_R, ACCEL_GATE, A)
        kalman.index_update(x, P, ay_m - x[BAY], BAY, self.accel_R, 6.0, A)
