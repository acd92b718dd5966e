"""The grip a spin has shown: after it, tyres carrying that much again are at the road's limit.

Why (issue 7, random drive 3169 of tools/random_drives.py, generator v1: all-wheel drive, mu 0.473
-> 0.191 at 26.2 s, 3.2 deg uphill, GNSS 1 Hz at 0.72 s): the car spins out (1227-1240 s; the spin
check fires, nothing is promised), grips again, and drives off at the road's limit: from 1242 s to
1260 s its tyres carry 0.93-0.96 of mu g (|(fx, fy)|, the drive up the grade and the corner sharing
one friction ellipse). The sideslip wanders 0 -> 17 -> 2 -> 43 deg, both axles at -12..-14 deg of
slip at 1248 s, where the rear law says ~0.6 deg. The single-track pseudo-measurement asserts that
law; the steering's misfit sees nothing (both axles leave the law alike, the steering stays at
L r / vx); the slip witness (wheel_slip.py) anchored on wheels already slipping after the spin's
re-initialisation and saw no slip; the kinematic integrals (slide_rate.py, the fault detector's
lateral window) saw 0.33 m/s^2 of ay - r vx against the model, which the filter's ay bias (wide
again after the re-initialisation) took up. With the heading just aligned from a course (std
1.3-2.3 deg) and the 1 Hz courses going into it, the model was vy's one witness, and the sideslip was
published valid at -2.2 deg +- 0.4-0.65 for a true 0..+11 (735 rows beyond 3 sigma, worst 13.1 deg).

The physics: a car that spins has shown the road's grip. While it slides, its tyres are saturated:
the force they carry, |(fx, fy)| per mass, is the friction ellipse's radius, mu g (3169: 0.85-0.92 of
mu g through its whole spin). After the spin that radius is still the most the tyres can carry, so
a tyre carrying near it again (HOLD_SHARE of it: a Magic Formula tyre at 80 % of its peak force is
already well beyond its linear slip, friction_limit.HOLD_SHARE) is at its limit, where no law bounds
its slip angle: the model's vy is no witness then, and core leaves it out (``core.SPIN_GRIP``):
vy has the kinematics and GNSS, its std grows as they leave it, and the sideslip is promised when
they carry it. Below the share the tyres are inside their grip and the model is back. A force beyond
the grip / HOLD_SHARE with the car not sliding says the road grips better (a friction rise): the
memory ends (as friction_limit.py's).

The force is the specific force less the sensor's own offsets (grade and bank left in: the tyres
hold the car on them), low-passed over SMOOTH_S (the accelerometer's noise, a bump's spike); the
grip is the largest low-passed force seen while the spin check holds the car sliding.
"""
from __future__ import annotations

import math

# the share of the spin's grip above which the tyres are at the road's limit again: friction_limit's
# (80 % of a tyre's peak force is well beyond its linear slip); the force's low-pass: slip_ratio_limit's
from .friction_limit import HOLD_SHARE
from .slip_ratio_limit import SMOOTH_S

#: sigmas of the force's offsets a force must exceed the grip by before the road is taken to grip
#: better: the offsets move in and after a spin (3169: b_ay by 0.35 m/s^2 between the slide and the
#: drive off, |f| 1.5 in the spin, 1.9-2.0 after it, truth 0.88-0.94 of mu g in both)
SIGMA = 3.0


class SpinGrip:
    """The most force the tyres carried in a spin; :meth:`step`: do they carry near it again?"""

    def __init__(self, dt: float) -> None:
        self.a = min(dt / SMOOTH_S, 1.0)
        self.f = 0.0  # the tyres' force per mass |(fx, fy)|, low-passed (m/s^2)
        self.grip = 0.0  # the most the tyres carried while the car slid (0: no spin seen)
        self.at_limit = False

    def step(self, sliding: bool, fx: float, fy: float, f_std: float = 0.0) -> bool:
        """One step: ``sliding`` the spin check's verdict, ``fx``, ``fy`` the tyres' force per mass
        (m/s^2), ``f_std`` the std of the offsets taken out of them (the road filters'); returns (and keeps in :attr:`at_limit`) whether the car, not sliding, carries at least
        HOLD_SHARE of the grip a spin has shown."""
        self.at_limit = False
        if not (fx == fx and fy == fy):
            return False
        f = self.f = self.f + self.a * (math.hypot(fx, fy) - self.f)
        if sliding:
            if f > self.grip:
                self.grip = f
            return False
        if self.grip <= 0.0:
            return False
        # more than the spin's grip beyond the offsets' errors, gripping: the road grips better
        if f > self.grip / HOLD_SHARE + SIGMA * f_std:
            self.grip = 0.0
            return False
        self.at_limit = f >= HOLD_SHARE * self.grip
        return self.at_limit
