"""Braked wheels locking at low speed: the wheel speed falls away from the car's, and means nothing.

Why (issue 7, vx std): below walking pace an ABS no longer acts (and the sim has none there), so a
car braked to a stop on a low-friction road locks its wheels while it still slides: on ice (mu
0.14-0.26, random drives 3319, 3422, 3475 at the stop before reversing) the wheels fell from 0.55 to
0 m/s within 50 ms (8-9 m/s^2) while the accelerometer read the car's -mu g (~2.2 m/s^2). Each wheel
update (every 18 ms, innovation ~0.1 m/s, inside its 5-sigma gate at vx's std of 0.07) pulled vx
after the wheels, and vx was published 0 +- 0.06 for 0.1-0.16 s while the car slid at 0.3-0.4 m/s
(16-27 rows beyond 3 sigma per drive). ``fusion/wheel_slip.py`` measures the same loss but for the
slip *ratio* above 2 m/s, low-passed over 0.1 s and past a 0.1 m/s margin: a lock at 0.5 m/s is
over before it shows.

A wheel can lose speed faster than the car only by slipping: from the last moment the tyres
carried no longitudinal force (the anchor, the witness's ANCHOR_AX_MPS2), the accelerometer,
integrated, carries the car's speed; what the wheels have lost beyond it, less the comparison's
own error (the wheels' noise now and at the anchor, the ax bias x time), is slip the wheels have
shown. Below ``wheel_slip.MIN_SPEED_MPS`` that is a lock, and a locked (or locking) wheel says
nothing of the car's speed: its update is skipped, vx runs on the accelerometer (and GNSS) with P
growing as it does, until the wheels are back with the car (they spin up again once released, or
the car has slid to the wheels' 0) or the tyres carry no force. Not a wider R: a locked wheel's
error is not noise about the car's speed, and a wide update still pulls vx toward 0 over a few
steps. Only the braking direction counts (a wheel-speed lag reads the other way).
"""
from __future__ import annotations

import math

from .wheel_slip import ANCHOR_AX_MPS2, MIN_SPEED_MPS, WHEEL_SMOOTH_S

#: sigmas of the comparison's own error a loss must exceed to be a lock
LOCK_SIGMAS = 3.0


class WheelLock:
    """The fused wheels against the accelerometer integrated since the tyres last carried no force."""

    def __init__(self, dt: float, wheel_noise2: float):
        self.dt = dt
        self.wheel_noise2 = wheel_noise2
        self.pull = min(1.0, dt / WHEEL_SMOOTH_S)  # the anchor follows the wheels complementarily
        self.v_ref = math.nan  # the car's speed as the accelerometer carries it from the anchor
        self.bax = 0.0  # the filter's ax bias at the anchor
        self.bax_var = 0.0
        self.t = 0.0  # s since the anchor
        self.anchored = False
        self.locked = False  # the wheels are slower than the car beyond the comparison's error

    def step(self, v_wheels: float, ax_m: float, bax: float, bax_var: float, r_vy: float, fx: float) -> bool:
        """One step; True while the fused wheels are locked (their update carries no speed).

        ``v_wheels``: the fused wheels as the car's vx (nan when not fused); ``ax_m``: the
        accelerometer as the filter integrates it; ``bax``, ``bax_var``: the filter's ax bias and its
        variance; ``r_vy``: vx's other rate; ``fx``: the tyres' longitudinal force per mass."""
        if not math.isfinite(v_wheels) or abs(fx) < ANCHOR_AX_MPS2 or not math.isfinite(self.v_ref):
            if self.anchored and math.isfinite(self.v_ref) and math.isfinite(v_wheels):
                self.v_ref += (ax_m - bax + r_vy) * self.dt
                self.v_ref += self.pull * (v_wheels - self.v_ref)
            else:
                self.v_ref = v_wheels
            self.anchored = math.isfinite(v_wheels)
            self.bax = bax
            self.bax_var = bax_var
            self.t = 0.0
            self.locked = False
            return False
        self.anchored = False
        self.t += self.dt
        self.v_ref += (ax_m - self.bax + r_vy) * self.dt
        lost = self.v_ref - v_wheels  # > 0: the wheels slower than the car (moving forwards)
        if self.v_ref < 0.0:
            lost = -lost
        if fx * self.v_ref >= 0.0:  # not braking: traction or a lag, not a lock
            lost = 0.0
        # the wheels' noise now and (smoothed) at the anchor, the bias's drift since
        sigma2 = self.bax_var * self.t * self.t + self.wheel_noise2 * (1.0 + 0.5 * self.pull)
        self.locked = abs(self.v_ref) < MIN_SPEED_MPS and lost > LOCK_SIGMAS * math.sqrt(sigma2)
        return self.locked
