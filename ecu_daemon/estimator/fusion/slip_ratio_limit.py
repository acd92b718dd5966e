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
lateral capacity overstated: it found u 0.3, ratio 1.03), drive_slip.py (a rear-driven car's
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
between axles, the witness's margins), nor below MIN_SPEED_MPS; the force is floored at
MIN_FX_MPS2 (the witness holds a slip ratio through a manoeuvre; over a vanishing force it would
be an unbounded angle). The force is low-passed over SMOOTH_S (the accelerometer's noise).
"""
from __future__ import annotations

G = 9.81
#: the normalised longitudinal slip stiffness C_x / F_z a tyre inside its grip has at least (the soft
#: end of passenger-car tyres; wheel_speed.SLIP_PER_MPS2, drive_slip.KAPPA_PER_FORCE)
CX_NORM = 15.0
#: slip ratio the linear tyre's is exceeded by before the tyre is taken as at its limit: axles' radii
#: differing by up to ~1 % (wear, size) while one wheel scale is learned (drive_slip.KAPPA_TOL)
KAPPA_TOL = 0.01
#: m/s^2: the longitudinal force per mass the ratio is taken at at least
MIN_FX_MPS2 = 0.3
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
        self.ratio = 1.0  # tan(alpha) / tan(alpha_law) at the last step (1: inside the grip)

    def step(self, vx: float, kappa: float, fx: float) -> float:
        """``kappa``: the slip ratio the wheels show beyond their errors (wheel_slip.SlipWitness.ratio,
        magnitude), ``fx``: the tyres' longitudinal force per mass (m/s^2, the specific force less the
        sensor's offset: grade in); returns the factor (>= 1) by which the rear slip angle exceeds the
        linear law's, 1.0 inside the grip."""
        self.ratio = 1.0
        if fx == fx:
            self.fx += self.a * (fx - self.fx)
        if not (abs(vx) >= MIN_SPEED_MPS and kappa > 0.0):
            return 1.0
        lin = max(abs(self.fx), MIN_FX_MPS2) / (G * CX_NORM)
        if kappa <= lin + KAPPA_TOL:
            return 1.0
        self.ratio = kappa / lin
        return self.ratio
