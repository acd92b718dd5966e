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

from . import generated as gen

VX, VY, PSI, BR, BAX, BAY, KW, GAY = range(8)
NX = 8
TWO_PI = 2.0 * math.pi
assert gen.MODEL_ROWS == (VX, VY, PSI) and gen.STATE[GAY] == "g_ay"  # the order predict writes


class KinematicModel:
    """Builds the transition F and process noise Qd for one fixed step (preallocated, reused).

    f and F come from ``generated.py`` (SymPy, ``tools/derive_jacobians.py``); F is the identity
    plus the dt-only entries set once here plus the few entries that vary per step.
    """

    def __init__(self, dt: float, accel_noise: float, yaw_rate_noise: float, yaw_rate_bias_walk: float,
                 accel_bias_walk: float, wheel_scale_walk: float, accel_gain_walk: float = 1e-4,
                 lateral_accel_noise: float | None = None):
        self.dt = dt
        self.F = np.eye(NX)
        for (i, j), v in zip(gen.F_CONST, gen.kinematic_F_const(dt)):
            self.F[i, j] = v
        q = np.zeros(NX)
        q[VX] = accel_noise ** 2 * dt
        # vy has its own (smaller) noise: the lateral channel's colored errors (roll, bank) have
        # states of their own (g_ay, b_ay), so only their remainder is white here, and an inflated
        # vy noise makes the sideslip std several times its real error (invalid while right)
        q[VY] = (accel_noise if lateral_accel_noise is None else lateral_accel_noise) ** 2 * dt
        q[PSI] = yaw_rate_noise ** 2 * dt
        q[BR] = yaw_rate_bias_walk ** 2 * dt
        q[BAX] = accel_bias_walk ** 2 * dt
        q[BAY] = accel_bias_walk ** 2 * dt
        q[KW] = wheel_scale_walk ** 2 * dt
        q[GAY] = accel_gain_walk ** 2 * dt
        self.Qd = np.diag(q)
        self.q = q
        self._tmp = np.empty((NX, NX))

    def predict_reference(self, x: np.ndarray, P: np.ndarray, P_out: np.ndarray, r_m: float, ax_m: float,
                          ay_m: float) -> None:
        """x <- f(x, u) in place; P_out <- F P F' + Qd. ``self.F`` holds the F used afterwards.

        The pure-Python (numpy) reference; ``backend.py`` swaps in the compiled one as ``predict``.
        """
        dt = self.dt
        args = (*x.tolist(), r_m, ax_m, ay_m, dt)
        vx, vy, psi = gen.kinematic_f(*args)
        if psi >= TWO_PI or psi < 0.0:
            psi %= TWO_PI
        x[:3] = (vx, vy, psi)
        F = self.F
        for (i, j), v in zip(gen.F_VAR, gen.kinematic_F_var(*args)):
            F[i, j] = v
        np.matmul(F, P, out=self._tmp)
        np.matmul(self._tmp, F.T, out=P_out)
        P_out += self.Qd

    predict = predict_reference

    def predict_from_reference(self, x_prev: np.ndarray, x: np.ndarray, P_prev: np.ndarray, P_out: np.ndarray,
                               A: np.ndarray, r_m: float, ax_m: float, ay_m: float) -> None:
        """One step from the previous history slot into this one: x <- x_prev, then
        :meth:`predict` (x, P_prev -> P_out), then A <- F (the transition the slot stores).

        The estimator's step runs this every 6 ms; the compiled one (``backend.py``) does the
        two copies and the predict in one C call, with the same arithmetic (the same bits).
        """
        x[:] = x_prev
        self.predict_reference(x, P_prev, P_out, r_m, ax_m, ay_m)
        A[:] = self.F

    predict_from = predict_from_reference


def wrap_pi(a: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (a + math.pi) % TWO_PI - math.pi
