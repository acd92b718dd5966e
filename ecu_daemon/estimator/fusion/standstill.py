"""Standstill: zero-velocity updates and the yaw-rate bias at rest.

At rest the true velocity and yaw rate are zero, so the gyro reading *is* its bias (Park 002 §2.2
uses r = 0 while straight; at rest it holds exactly), and the accelerometers read their bias plus
the gravity of grade and bank, which is exactly what the filter's accelerometer-bias states mean. Detected from the wheel speeds (all below a
crawl) held for a short time, so a brief zero crossing does not count.
"""
from __future__ import annotations

from .. import kalman
from ..kinematic import BAX, BAY, BR, VX, VY

STANDSTILL_SPEED = 0.05  # m/s, every wheel below this
#: m/s: the speed below which a wheel sensor sees no pulses and reads 0 (detect's docstring; typical
#: active sensors 0.1-0.2 m/s): a standstill from the wheels bounds |v| by it (core.STANDSTILL_CREEP_STD)
WHEEL_PULSE_FLOOR_MPS = 0.15
STANDSTILL_HOLD_S = 0.3
ACCEL_GATE = 6.0  # sigma: the accelerometer-bias update's gate at rest; beyond it the car accelerates


class StandstillFusion:
    def __init__(self, dt: float, gyro_noise: float):
        self.hold_steps = int(STANDSTILL_HOLD_S / dt)
        self.count = 0
        self.gyro_R = max(gyro_noise, 1e-3) ** 2 * 4.0
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

    def fuse(self, x, P, r_m: float, ax_m: float, ay_m: float, A) -> None:
        for i in (VX, VY):
            kalman.index_update(x, P, -x[i], i, 1e-4, 0.0, A)
        kalman.index_update(x, P, r_m - x[BR], BR, self.gyro_R, 6.0, A)
        kalman.index_update(x, P, ax_m - x[BAX], BAX, self.accel_R, ACCEL_GATE, A)
        kalman.index_update(x, P, ay_m - x[BAY], BAY, self.accel_R, 6.0, A)
