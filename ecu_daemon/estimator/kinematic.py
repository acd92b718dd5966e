"""IMU-driven kinematic model: the prediction step of the main filter.

State (ISO 8855 body axes at the CG, heading clockwise from north)::

    x = [vx, vy, psi, b_r, b_ax, b_ay, k_w, g_ay]

``b_*`` are additive sensor biases (measured = true + bias); ``b_ay`` also absorbs the gravity
component of road bank and ``b_ax`` that of grade, which is how bank/grade are kept out of the
sideslip (they are slowly varying, so they look like bias to this model). ``k_w`` scales wheel speed
computed with the configured radius to true speed (tyre wear, pressure, load). ``g_ay`` is a
lateral-accelerometer gain error: body roll is proportional to lateral acceleration (roll
gradient), and a rolled sensor reads g*sin(roll) extra, i.e. ay_m = (1 + g_ay) ay. On real data
(Revs, 1.7 g) this is ~4 % and, unmodelled, it leaks into heading in every long corner.

Continuous model, with r = r_m - b_r, a = a_m - b::

    dvx/dt = ax + r vy        dvy/dt = ay - r vx        dpsi/dt = -r
    with ay = (ay_m - b_ay) / (1 + g_ay) ~ ay_m - b_ay - g_ay ay_m

Discretised with a first-order step at the fixed 6 ms period (inputs held over the step).
"""
from __future__ import annotations

import math

import numpy as np

VX, VY, PSI, BR, BAX, BAY, KW, GAY = range(8)
NX = 8
TWO_PI = 2.0 * math.pi


class KinematicModel:
    """Builds the transition F and process noise Qd for one fixed step (preallocated, reused)."""

    def __init__(self, dt: float, accel_noise: float, yaw_rate_noise: float, yaw_rate_bias_walk: float,
                 accel_bias_walk: float, wheel_scale_walk: float, accel_gain_walk: float = 1e-4):
        self.dt = dt
        self.F = np.eye(NX)
        self.F[VX, BAX] = -dt
        self.F[VY, BAY] = -dt
        self.F[PSI, BR] = dt
        q = np.zeros(NX)
        q[VX] = accel_noise ** 2 * dt
        q[VY] = accel_noise ** 2 * dt
        q[PSI] = yaw_rate_noise ** 2 * dt
        q[BR] = yaw_rate_bias_walk ** 2 * dt
        q[BAX] = accel_bias_walk ** 2 * dt
        q[BAY] = accel_bias_walk ** 2 * dt
        q[KW] = wheel_scale_walk ** 2 * dt
        q[GAY] = accel_gain_walk ** 2 * dt
        self.Qd = np.diag(q)
        self._tmp = np.empty((NX, NX))

    def predict(self, x: np.ndarray, P: np.ndarray, P_out: np.ndarray, r_m: float, ax_m: float,
                ay_m: float) -> None:
        """x <- f(x, u) in place; P_out <- F P F' + Qd. ``self.F`` holds the F used afterwards."""
        dt = self.dt
        vx, vy, psi, b_r, b_ax, b_ay, _, g_ay = x.tolist()
        r = r_m - b_r
        psi -= dt * r
        if psi >= TWO_PI or psi < 0.0:
            psi %= TWO_PI
        x[:3] = (vx + dt * (ax_m - b_ax + r * vy), vy + dt * (ay_m - b_ay - g_ay * ay_m - r * vx), psi)
        F = self.F
        rdt = r * dt
        F[VX, VY] = rdt
        F[VX, BR] = -vy * dt
        F[VY, VX] = -rdt
        F[VY, BR] = vx * dt
        F[VY, GAY] = -ay_m * dt
        np.matmul(F, P, out=self._tmp)
        np.matmul(self._tmp, F.T, out=P_out)
        P_out += self.Qd


def antenna_velocity_ne(x, r: float, lever_x: float, lever_y: float) -> tuple[float, float]:
    """North/east velocity of a GNSS antenna at (lever_x, lever_y) from the CG, body axes."""
    vax = x[VX] - r * lever_y
    vay = x[VY] + r * lever_x
    c = math.cos(x[PSI])
    s = math.sin(x[PSI])
    return vax * c + vay * s, vax * s - vay * c


def gnss_jacobian(x, r: float, lever_x: float, lever_y: float) -> np.ndarray:
    """d[vN, vE]/dx for :func:`antenna_velocity_ne` (r = r_m - b_r at that step)."""
    vax = x[VX] - r * lever_y
    vay = x[VY] + r * lever_x
    c = math.cos(x[PSI])
    s = math.sin(x[PSI])
    H = np.zeros((2, NX))
    H[0, VX] = c
    H[0, VY] = s
    H[0, PSI] = -vax * s + vay * c
    H[0, BR] = lever_y * c - lever_x * s
    H[1, VX] = s
    H[1, VY] = -c
    H[1, PSI] = vax * c + vay * s
    H[1, BR] = lever_y * s + lever_x * c
    return H


def wrap_pi(a: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (a + math.pi) % TWO_PI - math.pi
