"""Wheel speeds -> longitudinal velocity (with the wheel-radius scale state k_w).

Uses the wheels least disturbed by drive torque: the rear pair on a front-driven car and vice
versa (Park 002 eq. 1). Averaging a left/right pair cancels the yaw-rate term (r * track / 2);
the front pair sees vx cos(delta) + (vy + lf r) sin(delta). Slip under braking/traction is
handled by inflating the noise with |ax| and by the innovation gate (a locked or spinning wheel
fails it rather than dragging vx). Moderate slip passes the gate and, lasting a whole manoeuvre,
is a bias the filter cannot average away: ``slip_bound`` sizes it for the published vx std.
"""
from __future__ import annotations

import math

import numpy as np

from .. import generated as gen
from .. import kalman
from ..kinematic import NX

WHEEL_GATE_SIGMA = 5.0
#: slip ratio per m/s^2 of deceleration: 1 / (g C_x) for a normalised longitudinal slip stiffness
#: C_x ~ 15, the soft end of passenger-car tyres (an axle braking its own share of the load)
SLIP_PER_MPS2 = 1.0 / (9.81 * 15.0)
WHEEL_H_COLS = tuple(j for _, j in gen.WHEEL_SPEED_H)


class WheelSpeedFusion:
    def __init__(self, driven_axle: str, lf: float, noise_mps: float):
        self.use_front = driven_axle == "rear"
        self.use_all = driven_axle == "all"
        # share of the fused mean that comes from the front pair ('all': half of it)
        self.frac = 1.0 if self.use_front else 0.5 if self.use_all else 0.0
        self.lf = lf
        self.noise2 = noise_mps * noise_mps
        self.h = np.zeros(NX)
        self.rejected = 0
        self.consecutive_rejects = 0  # a long run means the filter and the wheels disagree

    def measured_speed(self, fl: float, fr: float, rl: float, rr: float) -> float:
        """The raw wheel-derived speed this source fuses (configured radius, no scale)."""
        if self.use_all:
            return 0.25 * (fl + fr + rl + rr)
        if self.use_front:
            return 0.5 * (fl + fr)
        return 0.5 * (rl + rr)

    def as_vx(self, z: float, k_w: float, vy: float, r: float, delta: float) -> float:
        """The fused wheels' speed ``z`` as the car's vx (the inverse of the measurement model)."""
        f = self.frac
        if not f:
            return z * k_w
        return (z * k_w - f * (vy + self.lf * r) * math.sin(delta)) / (f * math.cos(delta) - f + 1.0)

    def slip_bound(self, vx: float, ax: float) -> float:
        """Largest speed error (m/s) longitudinal slip of the fused wheels puts into vx: braking
        slows every wheel, traction speeds up only driven ones (all of them on an all-wheel drive)."""
        a = abs(ax) if self.use_all else max(-ax, 0.0)
        return SLIP_PER_MPS2 * a * abs(vx)

    def fuse(self, x: np.ndarray, P: np.ndarray, z: float, delta: float, r: float, ax: float, A=None,
             excess_var: float = 0.0) -> bool:
        """``excess_var``: what the fused wheels' disagreement says z may be off beyond the noise."""
        h = self.h
        c0, c1, c2, c3 = WHEEL_H_COLS
        args = (*x.tolist(), r, self.lf, self.frac, delta if self.frac else 0.0)
        (pred,) = gen.wheel_speed(*args)
        h[c0], h[c1], h[c2], h[c3] = gen.wheel_speed_H(*args)  # (h.put: 3x slower, every step)
        R = self.noise2 + (0.02 * ax) ** 2 + (0.002 * pred) ** 2 + excess_var
        ok = kalman.scalar_update(x, P, z - pred, h, R, WHEEL_GATE_SIGMA, A)
        if ok:
            self.consecutive_rejects = 0
        else:
            self.rejected += 1
            self.consecutive_rejects += 1
        return ok
