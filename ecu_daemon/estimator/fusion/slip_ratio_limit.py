"""Tyres at their limit in the longitudinal direction, seen by the wheels' slip ratio: the lateral
law's slip angle is then too small by the same factor as the slip ratio is too large (issue 7,
"the estimate is right, or it says it is not"; core.SLIP_RATIO_LIMIT).

Why: the single-track pseudo-measurement asserts the rear tyre law, alpha_r = k phi, with the lateral
force normalised by g. A car braking (or driving) on ice uses nearly all of its tyres' grip
longitudinally, and what is left for the lateral force is small (the friction ellipse): a lateral
force far below mu g then takes a slip angle several times the law's. Random drive 1481
(tools/random_drives.py, generator v1: all-wheel drive, straight, mu 0.241 -> 0.10 at 37.8 s,
-4 % grade, 25 m/s): from 42 s the brakes hold the car on the downhill, the tyres carry -0.94
m/s^2 against mu g = 0.98 (friction use 1.0), the wheels run 3.3 % (front) and 2.9 % (rear) slow
(a linear tyre: 0.5-0.6 %), and a lateral acceleration of 0.3-0.4 m/s^2 takes 1.6 deg of rear slip
where the law says 0.24; the model held vy at the law's value at a 0.2 deg std, the sideslip was
published valid 1.3 deg off: 1479 of 10381 valid rows beyond 3 sigma. Nothing else saw it: the
steering's misfit (both axles leave their law alike), brake_grip.py (its grip shown starts at
MU_FLOOR 0.15, above the road's 0.10, and only grows, so a friction drop leaves the rear's
lateral capacity overstated: it found u 0.02-0.46, ratio 1.00-1.04), drive_slip.py (a rear-driven car's
drive only) and the law excess's hold (nothing to hold: no misfit).

The physics: a tyre's force points along its stiffness-weighted slip vector (C_x kappa, C_y
tan(alpha)) (the brush model's combined slip, the similarity method; the simulator's tyre.py alike),
inside the grip and at the limit, so F_y / F_x = C_y tan(alpha) / (C_x kappa). The linear law's
angle for the same F_y is tan(alpha_law) = F_y / C_y, hence

    tan(alpha) / tan(alpha_law) = C_x kappa / F_x = kappa / kappa_lin,

with kappa_lin = F_x / C_x the slip ratio a linear tyre takes for the longitudinal force it carries.
Inside its grip a tyre slips kappa_lin and the ratio is 1 (the law holds); at its limit the wheel
slips several times kappa_lin, and the slip angle with it, at any lateral force, however small.
The slip ratio is measured without the lateral dynamics: the wheel-slip witness
(wheel_slip.py: the wheels' speed against the integrated accelerometer, only slip beyond its own
errors, a lower bound) gives kappa on any drivetrain; F_x per load is the tyres' longitudinal force
per mass over g (the axles' shares taken alike), kappa_lin with C_x = 15 (the soft end of
passenger-car tyres, wheel_speed.SLIP_PER_MPS2: the ratio understated where a tyre is stiffer).
The ratio feeds ``SingleTrackFusion.brake_excess_var`` (the rear's linear angle, the softer of the
configured and learned compliance, times the ratio, beyond the law): a widening of the
pseudo-measurement (and the model's bound off), never a measurement of vy; with fresh GNSS the
filter's own vy, from the courses, carries the sideslip and its std grows for it.

Not while the witness's slip is within KAPPA_TOL of the linear tyre's (wheel-radius differences
between axles, the witness's margins), nor below MIN_SPEED_MPS, nor while the tyres carry less than
MIN_FX_MPS2 longitudinally (kappa / F_x is the ratio of two small numbers there: random drive 1456,
a front-driven car in a dry 0.6 g corner, the witness read 5-6 % of slip on the free rear wheels
at |fx| 0.15 m/s^2, where they slipped 0.1 %). And the witness holds the largest ratio it has seen
for the manoeuvre (right for vx's std, an ABS keeps its slip), which is stale once the brake is
released: 1456 again, after an ABS stop in a corner (17 % at -4.6 m/s^2) it held 17 % through the
corner that followed (|f| 1.3 m/s^2, the wheels at 0.2 %), and the rule, taking it as current,
withheld the sideslip for the rest of the drive. A tyre carrying well below the force it was seen
slipping at is back inside its grip (the friction ellipse's radius is the most it can carry), so
a held ratio counts only while the tyres' force |(fx, fy)| stays above HOLD_SHARE of the most
they carried while the witness's ratio rose, and fx keeps the direction it had then (braking slip
is not held by a drive force; 1503: the free rear wheels' braking slip held through the
acceleration out of the corner). The force is low-passed over SMOOTH_S (the
accelerometer's noise).
"""
from __future__ import annotations

import math

G = 9.81
#: the normalised longitudinal slip stiffness C_x / F_z a tyre inside its grip has at least (the soft
#: end of passenger-car tyres; wheel_speed.SLIP_PER_MPS2, drive_slip.KAPPA_PER_FORCE)
CX_NORM = 15.0
#: slip ratio the linear tyre's is exceeded by before the tyre is taken as at its limit: axles' radii
#: differing by up to ~1 % (wear, size) while one wheel scale is learned (drive_slip.KAPPA_TOL)
KAPPA_TOL = 0.01
#: m/s^2: the longitudinal force per mass the ratio is taken at at least (brake_grip.BRAKE_MIN_MPS2)
MIN_FX_MPS2 = 0.5
#: share of the force the tyres carried when the witness's ratio last rose below which a held ratio
#: no longer counts: the low-passed force's noise (~0.03 m/s^2) and a path's lateral wander at the
#: limit (drive 1481: |f| 0.91-1.08 m/s^2 through its braking) stay above it, a released brake not
HOLD_SHARE = 0.8
#: s: the force is compared low-passed (the witness's wheels are, over the same time)
SMOOTH_S = 0.1
#: m/s: below this no ratio (the witness's own floor is 2 m/s; the model's is higher)
MIN_SPEED_MPS = 5.0


class SlipRatioLimit:
    """The tyres' slip ratio against a linear tyre's for the force they carry: the slip-angle ratio."""

    def __init__(self, dt: float) -> None:
        self.a = min(dt / SMOOTH_S, 1.0)
        self.reset()

    def reset(self) -> None:
        self.fx = 0.0  # the tyres' longitudinal force per mass, low-passed
        self.kappa = 0.0  # the witness's ratio at the last step
        self.f_seen = 0.0  # the most force |(fx, fy)| the tyres carried when the witness's held ratio rose
        self.fx_seen = 0.0  # the longitudinal force then (its sign: braking or driving slip)
        self.ratio = 1.0  # tan(alpha) / tan(alpha_law) at the last step (1: inside the grip)

    def step(self, vx: float, kappa: float, fx: float, fy: float) -> float:
        """``kappa``: the slip ratio the wheels show beyond their errors (wheel_slip.SlipWitness.ratio,
        magnitude, held by the witness), ``fx``, ``fy``: the tyres' force per mass (m/s^2, the
        specific force less the sensor's offsets: grade and bank in; ``fy`` low-passed already);
        returns the factor (>= 1) by which the rear slip angle exceeds the linear law's, 1.0 inside
        the grip."""
        self.ratio = 1.0
        if fx == fx:
            self.fx += self.a * (fx - self.fx)
        f = math.hypot(self.fx, fy) if fy == fy else abs(self.fx)
        if kappa < self.kappa or kappa <= 0.0:  # the witness started over: a new hold
            self.f_seen = 0.0
            self.fx_seen = 0.0
        elif kappa > self.kappa:  # slip seen now: the most force it was seen at, and its direction
            self.f_seen = max(self.f_seen, f)
            self.fx_seen = self.fx
        self.kappa = kappa
        if not (abs(vx) >= MIN_SPEED_MPS and kappa > 0.0 and abs(self.fx) >= MIN_FX_MPS2
                and self.fx * self.fx_seen > 0.0 and f >= HOLD_SHARE * self.f_seen):
            return 1.0
        lin = abs(self.fx) / (G * CX_NORM)
        if kappa <= lin + KAPPA_TOL:
            return 1.0
        self.ratio = kappa / lin
        return self.ratio
