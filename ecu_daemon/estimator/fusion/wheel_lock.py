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

A wheel can lose speed faster than the car only by slipping. The car's speed is carried by the
accelerometer, pulled toward the wheels complementarily (WHEEL_SMOOTH_S) while they are with the car:
no lag, and a bias drifts it by b x 0.1 s only. (Not from the last force-free moment, as the witness's
comparisons: a car braking 5 s to its stop has an ax-bias allowance of 0.3 m/s by then, and drive
3051's lock, 0.28 m/s, drowned in it.) Wheels below that reference by more than the comparison's error
(their noise now and smoothed) while braking are a lock below ``wheel_slip.MIN_SPEED_MPS``; the
reference then runs on the accelerometer alone, and the lock holds until the wheels are back with it
(within the bias x time since the onset). A locked (or
locking) wheel says nothing of the car's speed: its update is skipped, vx runs on the accelerometer
(and GNSS) with P growing as it does, until the wheels are back with the car (they spin up again once
released, or the car has slid to the wheels' 0). A wheel reading 0 below its sensor's floor (~0.15
m/s) while the car still decelerates is no speed either. Not a wider R: a locked wheel's error is not
noise about the car's speed, and a wide update still pulls vx toward 0 over a few steps. Only the
braking direction counts (a wheel-speed lag reads the other way).
"""
from __future__ import annotations

import math

from .wheel_slip import MIN_SPEED_MPS, WHEEL_SMOOTH_S

#: sigmas of the comparison's own error a loss must exceed to be a lock
LOCK_SIGMAS = 3.0


class WheelLock:
    """The fused wheels against the car's speed as the accelerometer carries it (see the module doc)."""

    def __init__(self, dt: float, wheel_noise2: float):
        self.dt = dt
        self.wheel_noise2 = wheel_noise2
        self.pull = min(1.0, dt / WHEEL_SMOOTH_S)  # the reference follows the wheels complementarily
        self.v_ref = math.nan  # the car's speed: the accelerometer, pulled to the wheels while unlocked
        self.bax = 0.0  # the filter's ax bias at the lock's onset (later it may take up the slide)
        self.bax_var = 0.0
        self.t = 0.0  # s since the lock's onset
        self.locked = False  # the wheels are slower than the car beyond the comparison's error

    def step(self, v_wheels: float, ax_m: float, bax: float, bax_var: float, r_vy: float, fx: float) -> bool:
        """One step; True while the fused wheels are locked (their update carries no speed).

        ``v_wheels``: the fused wheels as the car's vx (nan when not fused); ``ax_m``: the
        accelerometer as the filter integrates it; ``bax``, ``bax_var``: the filter's ax bias and its
        variance; ``r_vy``: vx's other rate; ``fx``: the tyres' longitudinal force per mass."""
        if not math.isfinite(v_wheels) or not math.isfinite(self.v_ref):
            self.v_ref = v_wheels
            self.locked = False
            return False
        locked_before = self.locked
        if locked_before:
            self.t += self.dt
        else:
            self.bax = bax
            self.bax_var = bax_var
            self.t = 0.0
        self.v_ref += (ax_m - self.bax + r_vy) * self.dt
        v_ref = self.v_ref
        locked = False
        # braking (traction or a lag is no lock) below the ABS's range: the only place a lock is judged
        # (the rest of the drive pays the reference's update alone)
        if abs(v_ref) < MIN_SPEED_MPS and not fx * v_ref >= 0.0:
            lost = v_ref - v_wheels  # > 0: the wheels slower than the car (moving forwards)
            if v_ref < 0.0:
                lost = -lost
            if locked_before:
                # the lock holds until the wheels are back with the car (spun up again, or the car has
                # slid to the wheels' 0): within the bias's drift since the onset. Not within their noise
                # as well: the configured noise (~0.08 m/s a sample) would end it with the car still
                # 0.24 m/s above locked wheels (drive 3422), and the next updates pull vx to them
                bound2 = self.bax_var * self.t * self.t
            else:
                # a lock begins beyond the wheels' noise (now, and smoothed in the reference)
                bound2 = self.wheel_noise2 * (1.0 + 0.5 * self.pull)
            locked = lost > LOCK_SIGMAS * math.sqrt(bound2)
        if not locked:
            self.v_ref += self.pull * (v_wheels - self.v_ref)
        self.locked = locked
        return locked
