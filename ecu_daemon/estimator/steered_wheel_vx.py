"""What a steered wheel pair's speed says of vx when the tyres are beyond their law (issue 7).

Why (random drives 760, 297: rear-driven cars on ice, mu 0.23 / 0.14, sliding in a lane change
before the spin check fires): the undriven front pair measures the speed along its own plane,
``vx cos(delta) + (vy + lf r) sin(delta)`` (fusion/wheel_speed.py), so the filter turns it into vx
through its own vy: a vy error ``e`` becomes a vx error ``e tan(delta)`` (front pair alone; half
its share on an all-wheel drive). While the tyres grip, vy is the single-track model's within its
std and the steering is small, so that is nothing. In a slide the rear leaves its law by tens of
degrees, the filter's vy stays near the model's at a gripping car's std (760: vy 5.7 m/s off at a
0.29 m/s std; 297: 5.2 off at 0.28) and the driver counter-steers (delta -44 deg, 25 deg): vx was
published valid 4.65 m/s (760) and 2.34 m/s (297) off at a 0.2-0.34 m/s std.

The steering measures how far the tyres are from a gripping car's path without vy or GNSS:
``vx delta - L r`` is ``vx (alpha_f - alpha_r)`` (linearised), the axles' slip difference in m/s of
lateral velocity. With the front inside its law (the usual slide: the rear lets go), that is the
vy the model misses (760 at 1226.8: 6.3 m/s against the 5.7 m/s error). A gripping car's misfit is
its understeer, ~0.5 m/s at 0.8 g and 20 m/s where delta is ~3 deg: 0.03 m/s of vx. So vx's
published std carries ``|d vx / d vy| |vx delta - L r|``; the wheel updates pass that error into vx,
which the wheels pull back once the steering returns, so it is held with the wheel-slip memory
(core.SLIP_MEMORY_S). Both axles sliding alike (random drive 879, 683) shrink the misfit: not
covered here. Published only (the filter's own update is unchanged).

Which axle: the misfit is the front's slip beyond its law when it has the sign of the rear axle's
lateral force (``m ay lf - Iz rdot``, the moment balance about the front axle): a plough, where the rear
grips and its kinematics hold vy. Counted, a plough on ice cost vx validity where GNSS held vx within
0.1-0.4 m/s (random drives 770: 0.839 -> 0.752 above 5 m/s, 383: 0.734 -> 0.667, 683: 1.0 -> 0.98). Only
the rear's slip beyond its law (the other sign) is a vy the model misses; below 5 m/s the sign does
not tell (``PLOUGH_MIN_SPEED``).

The plough's exemption rests on the rear's kinematics holding the filter's vy: ``vy = lr r - vx
tan(alpha_r)`` with ``alpha_r`` a gripping tyre's few degrees, ``r`` the gyro's. With the gyro isolated
(``vy_tied`` False, core.ISOLATED_GYRO_PLOUGH) nothing holds it: vy integrates ``ay - r vx`` with the
substitute yaw rate (the wheels' pair, 0 while the wheels are out too), the model's vy rests on the same
substitute, and an error in r of 0.9 rad/s at 11 m/s turns vy by 10 m/s per second. Random drive 1761
(rear-driven, 222 kW, mu 1.04, spun out at 1224.2 s): the spin isolated a right gyro; after the spin
check released (1227.4 s) the car ploughed out at the limit (front slip 12 deg, rear 5-9, true sideslip
within 2 deg, r 0.9 rad/s, 18 deg of road-wheel angle) while the filter's vy went 3.5 -> 8.6 m/s off at a
0.5-0.6 m/s std; the front pair's ``vx cos(delta) + (vy + lf r) sin(delta)`` put it into vx, published
valid 0.79-0.92 m/s off at 0.19-0.23 m/s (66 rows beyond 3 sigma, 1230.0-1230.6 s). The wheels measured
the speed along their plane correctly: it is the vy they are read with that was wrong. So with the gyro
isolated every misfit counts, the plough's sign too (the misfit is read with the substitute r the
filter's vy integrates, so it carries that r's error as well).
"""
from __future__ import annotations

import math


def vx_per_vy(frac: float, delta: float) -> float:
    """|d vx / d vy| of ``WheelSpeedFusion.as_vx``: how much of a vy error the fused wheels put into vx."""
    if not frac or not math.isfinite(delta):
        return 0.0
    return abs(frac * math.sin(delta) / (frac * math.cos(delta) - frac + 1.0))


def vx_error_bound(frac: float, vx: float, r: float, delta: float, wheelbase: float,
                   rear_force: float = math.nan, vy_tied: bool = True) -> float:
    """m/s: the vx error a vy off by the steering's misfit puts through the steered wheels.

    ``rear_force``: the rear axle's lateral force up to a positive factor (``m ay lf - Iz rdot``, the
    moment balance about the front axle); NaN: unknown. A misfit of its sign is the front's slip beyond
    its law (a plough): the rear grips, its kinematics hold vy, and nothing is added -- unless ``vy_tied``
    is False (the gyro isolated: the filter's vy integrates a substitute yaw rate, nothing holds it)."""
    g = vx_per_vy(frac, delta)
    if g == 0.0:
        return 0.0
    m = vx * delta - wheelbase * r
    if m * rear_force > 0.0 and abs(vx) >= PLOUGH_MIN_SPEED and PLOUGH_SIGN and vy_tied:
        return 0.0
    return g * abs(m)


#: a misfit of the rear force's sign is a plough (no vy missed); False: every misfit counts
PLOUGH_SIGN = True
#: m/s: below this (spin_check.MIN_SPEED) the slip angles of a car turning or sliding slowly are not
#: small and the linearised misfit does not say which axle left its law (760 at 35.9 s: 2.2 m/s,
#: front slip 67 deg, rear 38: both, with the misfit of the plough's sign)
PLOUGH_MIN_SPEED = 5.0
