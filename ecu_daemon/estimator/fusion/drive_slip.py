"""A driven rear axle at its friction limit, seen by its wheels' slip against the free front: the
rear tyre law's slip angle is then wrong, and this says by how much (issue 7, mode A with power on).

Why: the single-track pseudo-measurement asserts the rear tyre law, alpha_r = k phi, with the
lateral force normalised by g. A rear-driven car on ice with the power on uses the rear tyres'
grip for the drive force too (the friction ellipse): at a lateral acceleration far below mu g the
rear tyres are on their limit and slip several times the law's angle (tools/random_drives.py seed
40: mu 0.21, ay 0.16 g, ax 0.03 g: rear slip 2.6-3.3 deg, the law 0.6 deg). The steering's misfit
(``SingleTrackFusion.law_excess_var``) does not see it there, as the front is near its own limit
too (both axles leave their law alike), so the model held vy 1.5-1.9 deg off at a 0.5 deg std.

The driven wheels measure it. Their speed against the free-rolling front wheels is the rear
wheels' longitudinal slip ratio kappa, the lesser of the two sides (see ``DriveSlip.step``). A
tyre well inside its grip slips ``F_x / (C_x F_z)``, below ``KAPPA_PER_FORCE`` times its normalised
drive force; far beyond that it is on its limit (seed 40: the less-slipping side 2.2 % ahead, where
a linear tyre (C_x 15) would be 0.8 %). On its limit a tyre's force points along its slip vector
(isotropic sliding friction): ``tan(alpha) / kappa = F_y / F_x``, so the rear slip angle is
``atan(kappa F_yr / F_xr)``, with F_yr from the force balance (the model's own regressor) and F_xr
the tyres' longitudinal force per mass (the accelerometer less its offset). F_xr leaves out the
rolling resistance and drag the drive also overcomes (the angle overstated), while the less-slipping
side is the outer, loaded wheel, whose own F_y / F_x is above the axle's (understated). On seed 40
the two about cancel: through the corner the angle reads 0.9 -> 1.2 -> 2.1-2.9 -> 3.4-3.9 deg where
the rear slips 0.9 -> 1.4 -> 2.0-2.6 -> 2.9-4.1 deg (vx 8.5 -> 9.2 -> 9.8 -> 10.1-10.5 m/s). It is used
as a widening of the law, not as a measurement of vy: the pseudo-measurement gives way, and GNSS,
fresh, holds vy (the published std is the filter's own).

Only for a rear-driven car (the front pair rolls free; on a front-driven one the front law is not
in the pseudo-measurement, and an all-wheel drive has no free axle), while driving.

"While driving" is the drive force the rear tyres carry, not the net force the accelerometer
measures (``resist``, core.DRIVE_RESISTANCE): at a steady speed the drive pushes against the tyres'
rolling resistance and the front tyres' lateral force, which the steered wheels tilt backwards
(F_yf sin(delta)), so the net force is ~0 (its offset error either side) while the driven wheels
carry a tenth of a g or more. Random drive 279 (rear drive, steady 44 m circle at 7 m/s, the road's
friction 0.216 -> 0.105): both axles at their limit, the rear wheels 1.3 -> 2.9 % ahead of the free
front while the net force read -0.03 to -0.11 m/s^2 (its offset ~0.13 low); the gate on the net
force kept the rule silent and the model held the sideslip at 1.2 deg while the car slid from
-0.1 to -3 deg (103 rows valid beyond 3 sigma, 3.46 deg off). The resistance is the lower end of
passenger-car rolling resistance (``ROLLING_RESISTANCE``) plus the front's tilted lateral force
(aerodynamic drag left out: the drive force stays understated, the gate errs towards silence).
The angle keeps the net force (above: the cancellation drive 40 was measured on).
"""
from __future__ import annotations

import math

#: slip ratio per unit of normalised drive force (F_x / F_z) a tyre inside its grip takes at most:
#: 1 / C_x for C_x = 15, the soft end of passenger-car tyres (as wheel_speed.SLIP_PER_MPS2). The
#: force is the net one, below the drive's by drag and rolling resistance (the threshold lower: at
#: 40 m/s by about half), the load the rear's static share, below its share under drive (the
#: threshold higher); KAPPA_TOL covers what is left
KAPPA_PER_FORCE = 1.0 / 15.0
#: slip ratio neither the law nor the limit explains: front and rear tyre radii differ (wear, size)
#: by up to ~1 % while the wheel scale learns one, and the smoothed wheels' noise
KAPPA_TOL = 0.01
#: s: the wheels and the force are compared low-passed (a wheel sample's noise is 0.02-0.05 m/s)
SMOOTH_S = 0.1
#: m/s: below this a slip ratio is the wheels' noise and quantisation
MIN_SPEED_MPS = 5.0
#: m/s^2: the drive force per mass the angle is taken at at least (kappa / F_x is noise near 0)
MIN_FX_MPS2 = 0.3
G = 9.81
#: rolling resistance coefficient the drive overcomes at least (passenger-car tyres on a road 0.010-0.015;
#: the lower end, so the drive force and the rule's reach are understated rather than overstated)
ROLLING_RESISTANCE = 0.010


class DriveSlip:
    """The driven rear axle's slip ratio against the free front, and the slip angle it implies."""

    def __init__(self, dt: float, driven_axle: str, lf: float, lr: float):
        self.on = driven_axle == "rear"
        self.a = min(dt / SMOOTH_S, 1.0)
        self.rear_share = lf / (lf + lr)  # the rear axle's static share of the weight
        self.reset()

    def reset(self) -> None:
        self.kappa = 0.0
        self.fx = 0.0
        self.alpha = 0.0  # the rear slip angle (rad, magnitude) the limit implies; 0: inside the grip

    def step(self, vx: float, fl: float, fr: float, rl: float, rr: float, delta: float, fx: float,
             fy_rear: float, resist: float = 0.0) -> float:
        """One step: the wheel speeds (same scale), the road-wheel angle (NaN: unknown), the tyres'
        longitudinal force per mass ``fx`` and the rear axle's lateral force per mass ``fy_rear``,
        ``resist`` the force per mass the drive overcomes beside ``fx`` (:func:`resistance`; 0: the
        net force alone, main's rule); returns the rear slip angle magnitude (rad) the friction
        limit implies, 0 inside the grip."""
        self.alpha = 0.0
        if not self.on:
            return 0.0
        if not (vx >= MIN_SPEED_MPS and math.isfinite(delta) and math.isfinite(fl + fr + rl + rr)):
            self.kappa = 0.0
            self.fx = fx if math.isfinite(fx) else 0.0
            return 0.0
        c = math.cos(delta)  # the front wheels roll along their heading
        if fl < MIN_SPEED_MPS * c or fr < MIN_SPEED_MPS * c:
            return 0.0
        # each rear wheel against the front one on its side (the same track: the yaw rate's speed
        # difference cancels), the lesser slip: an open differential gives both the torque the
        # inner, unloaded wheel can carry, which spins it in a dry corner while the loaded outer
        # wheel, which carries the axle's lateral force, rolls inside its grip (random drive 230:
        # 0.6 g at 40 m/s, the pair's mean 4 % ahead of the front, the rear law right)
        kappa = min(rl * c / fl, rr * c / fr) - 1.0
        a = self.a
        self.kappa += a * (kappa - self.kappa)
        self.fx += a * (fx - self.fx)
        f = self.fx
        fd = f + resist  # the drive force per mass the rear tyres carry
        if fd <= 0.0:
            return 0.0
        lin = KAPPA_PER_FORCE * fd / (G * self.rear_share)
        if self.kappa <= lin + KAPPA_TOL:
            return 0.0
        self.alpha = math.atan(self.kappa * abs(fy_rear) / max(f, MIN_FX_MPS2))
        return self.alpha


def resistance(fy_front: float, delta: float) -> float:
    """The force per mass (m/s^2) a drive overcomes beside the net longitudinal force: the lower
    end of rolling resistance and the front axle's lateral force per mass ``fy_front`` tilted by
    the road-wheel angle ``delta`` (along the car's -x: F_yf sin(delta))."""
    return ROLLING_RESISTANCE * G + fy_front * math.sin(delta)
