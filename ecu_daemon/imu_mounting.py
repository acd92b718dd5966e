"""An IMU that is not at the CG and not aligned with the body: its readings to CG / body axes.

Why: the estimator's model takes yaw rate and specific force *at the CG in body axes*. A real ESC
sensor cluster sits tens of cm from the CG and is mounted within a degree or two of the body
axes. A body-fixed accelerometer at ``d`` (from the CG, body axes) reads

    f_imu = f_cg + omega_dot x d + omega x (omega x d)        (rigid body)

in body axes, and the sensor reports that rotated into its own axes, ``R^T f_imu``, where ``R``
holds the sensor's axes in body coordinates (``v_body = R v_sensor``). In a slalom (yaw
acceleration ~1 rad/s^2) 0.5 m ahead is 0.5 m/s^2 of lateral error; 2 deg of mounting yaw turns
8 m/s^2 of braking into 0.28 m/s^2 of lateral acceleration: both far above the filter's
lateral-acceleration noise.

One rotation convention for the simulator and the estimator: ``mounting_rpy_deg = [roll, pitch,
yaw]``, intrinsic z-y-x (yaw about body z up, then pitch about the new y, then roll about the new
x), ``R = Rz(yaw) Ry(pitch) Rx(roll)``; yaw positive turns the sensor's x axis to the left (ISO
8855), as the magnetometer's ``mount_yaw_deg`` of the simulator.

:func:`sensor_readings` is the forward model (the simulator's, vectorised, full 3-D);
:class:`ImuMount` is its inverse at the estimator's edge, from what the CAN bus carries: one yaw
gyro and two accelerometer axes (see its docstring for the two assumptions that takes).
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from .gravity import G

#: Window of the causal yaw-acceleration fit (s). A least-squares line through the gyro samples
#: of the last 40 ms: its slope is the yaw acceleration W/2 = 20 ms ago (a lag: 20 ms x the 5
#: rad/s^3 of a hard 0.5 Hz slalom x 0.6 m = 0.06 m/s^2 at the peaks), and its noise at 100 Hz
#: with 0.08 deg/s gyro noise is ~0.05 rad/s^2 (0.03 m/s^2 at 0.6 m). A shorter window trades lag
#: for noise 1:W^-1.5; 40 ms balances them for lever arms up to ~1 m.
RDOT_WINDOW_S = 0.04
#: at least this many gyro samples in the fit (a 50 Hz gyro: 80 ms)
RDOT_MIN_SAMPLES = 3


def rotation(rpy_deg) -> np.ndarray:
    """``R`` (3 x 3): the sensor's axes in body coordinates, ``v_body = R @ v_sensor``."""
    r, p, y = (math.radians(float(a)) for a in rpy_deg)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def sensor_readings(f_cg: np.ndarray, omega: np.ndarray, omega_dot: np.ndarray, position_m,
                    rpy_deg) -> tuple[np.ndarray, np.ndarray]:
    """What a body-fixed IMU at ``position_m`` mounted at ``rpy_deg`` reads: (specific force,
    angular rate), each (n, 3) in the sensor's axes, from the CG's specific force and the body's
    angular rate and acceleration, each (n, 3) in body axes."""
    d = np.asarray(position_m, dtype=float)
    f = f_cg + np.cross(omega_dot, d) + np.cross(omega, np.cross(omega, d))
    rt = rotation(rpy_deg).T
    return f @ rt.T, omega @ rt.T


def is_identity(position_m, rpy_deg) -> bool:
    """True for an IMU at the CG on the body axes (nothing to convert)."""
    return all(float(a) == 0.0 for a in position_m) and all(float(a) == 0.0 for a in rpy_deg)


class ImuMount:
    """The estimator's edge: raw yaw-rate / accel_x / accel_y samples -> CG, body axes.

    Called once per sample as it enters the estimator (``convert``), in input order, so the
    conversion is causal: each sample is converted with the latest gyro and accelerometer samples
    at or before it. What the bus does not carry is assumed, and says why:

    * the gyro measures about the sensor's z axis only: ``r_s = R[0,2] p + R[1,2] q + R[2,2] r``;
      roll and pitch rates (a few deg/s of body roll) times the mounting's roll / pitch (a degree
      or two: 0.03) are left out, so ``r = r_s / R[2,2]``;
    * the sensor's z specific force is not on the bus: the body's is taken as ``g`` (a level car;
      on a 6 % bank or in 0.8 g of body roll it is 0.2-0.5 % less, times a mounting roll / pitch of
      0.03: below 2 mm/s^2), which gives the sensor's z and then the body's x and y;
    * the lever arm's rotation is the yaw motion only (``omega = (0, 0, r)``): body roll and pitch
      accelerations times the IMU's height are left out (the position's z is accepted for
      completeness and does not enter). ``r`` is the raw gyro (its bias, 0.5 deg/s, changes the
      centripetal term by 2 r b |d|: ~5 mm/s^2 at 0.5 rad/s and 0.6 m); the yaw acceleration is
      the slope of a least-squares line through the gyro samples of the last ``RDOT_WINDOW_S``
      (causal: only samples already received; irregular and batched stamps are fine).
    """

    def __init__(self, position_m, rpy_deg, i_yaw: int, i_ax: int, i_ay: int):
        self.dx, self.dy = float(position_m[0]), float(position_m[1])
        self.R = rotation(rpy_deg)
        self.i_yaw, self.i_ax, self.i_ay = i_yaw, i_ax, i_ay
        R = self.R
        self._r_scale = 1.0 / R[2, 2]
        self.r = 0.0  # body yaw rate (rad/s), latest
        self.rdot = 0.0  # causal yaw acceleration (rad/s^2)
        self.fs = [0.0, 0.0]  # latest raw sensor x, y specific force
        self._gyro: deque = deque()  # (t, r) of the fit window

    @classmethod
    def from_config(cls, imu, i_yaw: int, i_ax: int, i_ay: int) -> "ImuMount | None":
        """``None`` for an IMU at the CG on the body axes: the samples pass unchanged."""
        if is_identity(imu.position_m, imu.mounting_rpy_deg):
            return None
        return cls(imu.position_m, imu.mounting_rpy_deg, i_yaw, i_ax, i_ay)

    def convert(self, j: int, t: float, v: float) -> float:
        """The CG / body-axis value of input ``j``'s sample ``v`` received at ``t``."""
        if j == self.i_yaw:
            r = v * self._r_scale
            if not math.isfinite(r):
                return r
            self.r = r
            self._fit_rdot(t, r)
            return r
        k = 0 if j == self.i_ax else 1
        if not math.isfinite(v):
            return v
        self.fs[k] = v
        R = self.R
        sx, sy = self.fs
        sz = (G - R[2, 0] * sx - R[2, 1] * sy) / R[2, 2]  # body z specific force = g
        f = R[k, 0] * sx + R[k, 1] * sy + R[k, 2] * sz  # body axes, at the IMU
        r, rdot = self.r, self.rdot
        if k == 0:
            return f + rdot * self.dy + r * r * self.dx
        return f - rdot * self.dx + r * r * self.dy

    def _fit_rdot(self, t: float, r: float) -> None:
        g = self._gyro
        g.append((t, r))
        while len(g) > RDOT_MIN_SAMPLES and g[0][0] < t - RDOT_WINDOW_S:
            g.popleft()
        n = len(g)
        if n < 2:
            return
        tm = sum(s[0] for s in g) / n
        rm = sum(s[1] for s in g) / n
        stt = sum((s[0] - tm) ** 2 for s in g)
        if stt <= 1e-12:  # every stamp the same (a USB batch): keep the last slope
            return
        self.rdot = sum((s[0] - tm) * (s[1] - rm) for s in g) / stt
