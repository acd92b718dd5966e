"""The wheels' scale checked without GNSS on a launch: their speed change against integrated ax.

Why: a drive that starts from rest has no turn yet for the gyro's check (wheel_yaw_check.py) and
no GNSS fix until it is past 2 m/s (a cold start: 30 s), so a velocity from the wheels, unchecked,
is not promised from the first metre (its std is beyond what the frame carries). The accelerometer
is a witness independent of the wheels' mapping: over the first ``WLC_DV`` of a launch from
rest, ``s`` (the wheels' scale: 1 when the mapping is right) is their speed change over the
integral of ``ax`` less its bias state. The start is the first live wheel reading (at or above
``WLC_V_ARM``), not the standstill, because wheel sensors read 0 below a crawl (0.15-0.8 m/s)
while the car already moves. The launch is judged early on purpose: the unchecked std (4/3 of the
speed) is beyond what the frame carries from ~1 m/s.

The integral is as good as the bias: the filter learns ``ax``'s bias at rest, grade included
(fusion/standstill.py), and a launch with its std ``sd`` is judged only while ``3 sd T`` and the
noise stay below ``WLC_PRECISION`` of the integral (a flying start's unlearned bias, a crawl
over many seconds, the 0.28 m/s a 3.6x unit error changes: not judged). What remains is the body's pitch under acceleration (~1 deg per
3 m/s^2: 6 % of the change), a grade change over the few metres of the launch, the wheels' lag
and a driven axle's slip (the caller passes the non-driven axle's speed): within ``WLC_AGREE``
(20 %), where the nearest unit errors of WSC_UNITS (0.62x, 1.61x) are 38 % and 61 % off. A
reversed or g-scaled accelerometer gives ``s`` negative or ~10x: nothing is confirmed. Like the
gyro's check it only ever confirms; a launch it cannot judge is left to GNSS.
"""
from __future__ import annotations

import math

WLC_V_ARM = 0.3  # m/s on the wheels: below it a standstill or a crawl (a sensor's dead zone reads 0)
WLC_DV = 1.0  # m/s of wheel speed change over the launch: judged there (vx 1.3 m/s, 0.5 s at 2 m/s^2)
WLC_MAX_S = 5.0  # s: a launch slower than this (a crawl in traffic) is not judged: the bias integrates
WLC_AGREE = 0.2  # |s - 1|: pitch, a grade change, wheel lag, slip; unit errors >= 0.38 off
WLC_PRECISION = 0.1  # the integral's own error (3 sigma of bias x time, noise) as a share of it, at most
WLC_NOISE_MPS = 0.05  # the wheel speed's noise and quantisation at the two ends, its held sample's age


class WheelLaunchCheck:
    """:attr:`confirmed` once the first ``WLC_DV`` of a launch from rest on the wheels matches the
    integrated ax within ``WLC_AGREE`` (module docstring)."""

    def __init__(self) -> None:
        self._integral = math.nan  # m/s of ax integrated since the launch's first live reading
        self._v0 = 0.0  # that reading
        self._elapsed = 0.0
        self._ready = False  # the wheels read below WLC_V_ARM since the last launch (or stale input)
        self.scale = math.nan  # the last judged launch's wheel change over the integrated ax
        self.confirmed = False

    def step(self, v: float, ax: float, bax_std: float, dt: float) -> bool:
        """One step: ``v`` the non-driven wheels' speed as mapped (m/s, NaN: stale or isolated),
        ``ax`` less the filter's bias state, ``bax_std`` that bias's std, ``dt`` the step (s).
        Returns :attr:`confirmed`."""
        if self.confirmed:
            return True
        if not (v == v and ax == ax):
            self._integral = math.nan
            self._ready = False
            return False
        v = abs(v)
        if v < WLC_V_ARM:
            self._integral = math.nan
            self._ready = True
            return False
        if self._integral != self._integral:
            if not self._ready:
                return False  # not from a standstill (a flying start, after a launch): wait for one
            # armed at the first live reading: a dead zone's 0 before it is not a speed
            self._ready = False
            self._integral = 0.0
            self._v0 = v
            self._elapsed = 0.0
            return False
        self._integral += ax * dt
        self._elapsed += dt
        if self._elapsed > WLC_MAX_S:
            self._integral = math.nan
            return False
        dv = v - self._v0
        if dv < WLC_DV:
            return False
        i = self._integral
        self._integral = math.nan  # one judgement per launch
        if 3.0 * bax_std * self._elapsed + WLC_NOISE_MPS > WLC_PRECISION * abs(i):
            return False  # the integral is not precise enough to tell a unit error
        self.scale = dv / i
        if abs(self.scale - 1.0) <= WLC_AGREE:
            self.confirmed = True
        return self.confirmed
