"""How far an all-wheel drive's wheels may run ahead of vx when its tyres are at their limit (issue 7).

Why (random drive 1936: a steady 66 m circle on mu 0.63 up a 7.9 % grade, all four wheels driven at
240 kW, the car ploughing, then spinning out at 1261.6 s): an all-wheel drive has no free-rolling axle,
so every fused wheel is vx plus its own drive slip. ``WheelSpeedFusion.slip_bound`` is the linear law
for the car's kinematic ax (~0 on a circle at a steady speed), and the slip witness (wheel_slip.py)
never saw the slip build: it grew by ~0.1 m/s a second over 10 s, below a 1 s window's margin, while
the tyres' force (the grade's 0.8 m/s^2) kept anchoring the other comparisons. The fused wheels read
0.05 -> 1.0 m/s above the true vx between 1248 and 1261 s (truth.csv: front pair ~1.5 m/s ahead of
its plane's speed at 22-30 deg of front slip angle, rear pair ~1.0-1.3 ahead), the wheel updates
carried it into vx, and vx was published valid 0.92-1.02 m/s off at a 0.30 m/s std over 1260.18-1261.01 s
(124 rows beyond 3 sigma), the 0.8 s before the spin check fired.

The physics: a tyre's longitudinal slip is set by the force it carries. The drive force per mass is
the tyres' longitudinal force (the specific force less the sensor's own offset: the grade in) plus
what the drive overcomes beside it (rolling resistance, the front's lateral force tilted by the
steering: drive_slip.resistance); 1936 at 1259 s: 0.9 + 1.2 = 2.1 m/s^2 where the kinematic ax is 0.1.
Inside its grip a tyre slips ``f_d / (g C_x)`` of the speed (the linear law). Near its friction limit
(combined slip: the lateral force takes most of the grip) a brush tyre's slip vector grows to
``3 mu F_z / C`` at the onset of full sliding, where a linear tyre would carry ``mu F_z`` at a third
of it: so up to ``LIMIT_FACTOR`` = 3 times the linear law's longitudinal slip for the same drive
force, whatever the road's mu (which cancels). Beyond full sliding only the drive's torque limits the
spin, and the spin check takes over. So while the steering says a tyre has left its law (the slip
witness's ``at_limit``: ``law_var_seen`` > 0), the published vx std carries that bound as a uniform
bias (bound / sqrt 3), held with the wheel-slip memory (core.SLIP_MEMORY_S): the slip built while the
force was high does not leave when the force falls (1936 after 1260 s: the drive force falls as the
car slides while the wheels keep their lead). Published only: the filter's own update is unchanged.

Only for an all-wheel drive (the other layouts fuse their undriven pair), only while driving (braking
slips every wheel on any layout: the linear law and the slip witness), above MIN_SPEED_MPS.
"""
from __future__ import annotations

# SLIP_PER_MPS2: slip ratio per m/s^2 of drive force per mass of a tyre inside its grip, 1 / (g C_x),
# C_x = 15 (the soft end of passenger-car tyres): the fused wheels' own linear law
from .fusion.wheel_speed import SLIP_PER_MPS2

#: a brush tyre's slip at the onset of full sliding over the linear slip for the same force (3 mu F_z / C
#: against mu F_z / C)
LIMIT_FACTOR = 3.0
#: m/s: below this the wheels' slip in m/s is small against the std already published
MIN_SPEED_MPS = 5.0


def slip_bound(vx: float, fx: float, resist: float) -> float:
    """m/s: how far the fused wheels of an all-wheel drive at its tyres' limit may read above vx.

    ``fx``: the tyres' longitudinal force per mass (the specific force less the sensor's offset);
    ``resist``: what the drive overcomes beside it (drive_slip.resistance). 0 while not driving."""
    if not abs(vx) >= MIN_SPEED_MPS:
        return 0.0
    fd = fx + resist
    if not fd > 0.0:
        return 0.0
    return LIMIT_FACTOR * SLIP_PER_MPS2 * fd * abs(vx)
