"""The wheels' scale checked without GNSS: the rear axle's right-minus-left speed against the gyro.

Why: until a witness has checked the wheels' scale (:class:`~.input_consistency.WheelScaleCheck`),
a velocity from the wheels rests on a mapping nobody checked, and its std carries that (a third
of the speed and more): more than the CAN frame's VX_STD can carry, so the velocity is not
promised. GNSS is that witness at its first fix above 2 m/s, but a cold start takes ~30 s, and
a right mapping withheld that long is "invalid while right". The gyro is a second witness,
independent of the wheels' mapping: on an axle that is not steered each wheel rolls along the
body's x axis, so its ground speed is ``vx -/+ r T/2`` (ISO 8855: left wheel at y = +T/2), and

    v_rr - v_rl = s r T + c v

(in either direction of travel and for signed or unsigned wheel speeds as ``rear_axle_yaw.py``
takes them: the magnitudes' difference, signed by the direction of travel)
exactly, whatever the sideslip, where ``s`` is the scale of the wheel speeds (1 when the mapping
is right, 3.6 for km/h read as m/s, 0.45 for an mph factor on m/s ...; the left-right
difference carries the same factor as each wheel), ``T`` the configured track and ``c`` the
relative difference of the two tyres' rolling radii (wear, pressure: ~1 %, on a straight the only
term). The check fits ``s`` and ``c`` together by least squares over samples at speed
(``WYC_MIN_SPEED``); ``c`` is what the straights show, ``s`` what the turns add, so a single
steady circle (r T and v proportional) identifies neither and confirms nothing.

It confirms the scale when ``s`` lies within ``WYC_AGREE`` of 1 (a track 10 % off, tyre load
transfer, slip of a driven rear axle: well inside; the nearest unit errors, 1.61x and 0.62x, and
1/3.6, 0.45, 2.24, 3.6 far outside) with a std below ``WYC_MAX_STD``, after ``WYC_MIN_TURN_RAD``
of turning. A gyro read in the wrong unit or sign gives ``s`` far from 1 as well (-1, 57, 1/57):
a mis-scaled gyro never confirms the wheels (nor do wheels and gyro wrong by the same factor,
which no unit error makes). It only ever confirms: a scale it cannot judge (no turns, front-only
wheels, a slide) is left to GNSS, and a verdict of "wrong" stays GNSS's
(:class:`~.input_consistency.WheelScaleCheck`), whose log line names the unit.

The residual scatter of the fit (wheel-speed noise and quantisation, the gyro's timing against
the wheels, slip) sets ``s``'s std, counted once per ``WYC_EVERY`` steps (the samples between are
the same held CAN values, not new information); samples under hard longitudinal acceleration
(``WYC_MAX_AX``: wheel spin, ABS) are left out.
"""
from __future__ import annotations

import math

from .line_fit import LineFit
from .rear_axle_yaw import rear_mean_speed, rear_speed_difference

WYC_EVERY = 10  # steps between samples (60 ms): CAN wheel speeds at 50-100 Hz, their noise correlated
WYC_MIN_SPEED = 3.0  # m/s, mean rear wheel speed: below, the wheels' quantisation and the ABS's 0 rule
WYC_MIN_R = 0.05  # rad/s (3 deg/s): a sample counts as turning from here (the gyro bias is < 0.01)
WYC_MIN_TURN_RAD = 0.35  # 20 deg of heading change while turning: one turn at a junction, one lane change
WYC_AGREE = 0.2  # |s - 1|: a 10 % track error, load transfer, a driven axle's slip; unit errors >= 0.38 off
WYC_MAX_STD = 0.05  # s's std: 0.2 from 1 is then 4 sigma, a 1.61x unit error 8 sigma beyond the window
WYC_MAX_AX = 3.0  # m/s^2: beyond, wheel spin or ABS braking moves the two rear wheels apart
WYC_NOISE_FLOOR = 0.03  # m/s, the residual's std never taken below (two wheels' noise, 0.02 each)


class WheelYawCheck:
    """Least-squares fit of ``v_rr - v_rl = s r T + c v`` (module docstring); :attr:`confirmed`
    once ``s`` is 1 within ``WYC_AGREE`` at a std below ``WYC_MAX_STD``."""

    def __init__(self, track_m: float):
        self.track = track_m
        # regressors a = r T, b = v; target d = v_rr - v_rl; no prior on c (straights measure it)
        self.fit = LineFit()
        self.turn = 0.0  # rad of heading change over the turning samples
        self.scale = math.nan  # s, the wheels' scale as the gyro sees it
        self.scale_std = math.inf
        self.offset = math.nan  # c, the rear tyres' relative radius difference
        self.confirmed = False

    @property
    def n(self) -> int:
        """The samples the fit has taken."""
        return self.fit.n

    def step(self, rl: float, rr: float, r: float, ax: float, dt: float, vx: float) -> bool:
        """One sample every ``WYC_EVERY`` steps: ``rl``, ``rr`` the rear wheel speeds as mapped
        (m/s, signed or unsigned), ``r`` the bias-corrected yaw rate (rad/s), ``ax`` the
        longitudinal acceleration, ``dt`` the time the sample stands for (s), ``vx`` the filter's
        (its sign, the direction of travel, is what the wheels' magnitudes lack: rear_axle_yaw.py);
        any NaN: nothing to judge (a stale or isolated input). Returns :attr:`confirmed`."""
        if self.confirmed:
            return True
        # the rear axle's difference and mean in the direction of travel: ``v_rr - v_rl`` alone
        # reads a right gyro as s = -1 reversing on unsigned wheel speeds, and those samples stay
        # in the fit (no confirmation after them either: tests/test_wheel_yaw_check.py)
        v = rear_mean_speed(rl, rr, vx)
        if not (v == v and r == r and ax == ax) or abs(v) < WYC_MIN_SPEED or abs(ax) > WYC_MAX_AX:
            return False
        fit = self.fit
        fit.add(r * self.track, v, rear_speed_difference(rl, rr, vx))
        if abs(r) >= WYC_MIN_R:
            self.turn += abs(r) * dt
        if self.turn < WYC_MIN_TURN_RAD or fit.n < 3:
            return False
        if not fit.solve(1e-12):
            return False  # r T and v proportional: a steady circle tells s from c apart by nothing
        s = fit.k
        self.scale, self.offset = s, fit.c
        self.scale_std = math.sqrt(fit.k_var(fit.residual_var(WYC_NOISE_FLOOR)))
        if abs(s - 1.0) <= WYC_AGREE and self.scale_std <= WYC_MAX_STD:
            self.confirmed = True
        return self.confirmed
