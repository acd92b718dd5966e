"""Braking in a corner: how far the rear axle's slip angle may exceed its tyre law, from the friction
ellipse of the rear at its braking load (issue 7, "the estimate is right, or it says it is not").

Why: the single-track pseudo-measurement asserts the rear tyre law, alpha_r = k phi, with the lateral
force normalised by g. Braking moves load forward (m ax h / L off the rear: with h / L ~ 0.27 and
ax = -4.6 m/s^2 about 30 % of the rear's static load) while the rear brakes take their share of what
is left of the rear's friction ellipse, so the rear axle nears its limit while the front, loaded and
asked less, stays inside its grip. The steering's misfit (``SingleTrackFusion.law_excess_var``, driven
mostly by the front) stays 0, the model keeps its narrow std, and the rear slips degrees beyond the
law (tools/random_drives.py, generator v1: drive 507, mu 0.88, ay 3.8 and ax -4.6 m/s^2: the rear
asked 0.79 g of its load against 0.41 g in the steady corner before, true rear slip 3.4 deg, sideslip
valid 2.3 deg off at a 0.47 deg std, 449 rows beyond 3 sigma; 504 and 637 the same manoeuvre, 301 a
circle on snow, mu 0.35, braked at 1.2 m/s^2: rear slip 4.5 deg, 2.6 deg off).

The rear's demand needs no vy: per unit mass its normal load is (g lf + ax h) / L, its lateral force
(lf ay - Iz/m r_dot) / L (the model's own regressor), its braking force the rear brakes' share of
m ax. What it may carry is mu times its load, and mu is not known; what the road has *shown* it
carries is a lower bound: every force an axle carried on this drive (front or rear, lateral,
braking or driving, computed alike) was at most mu times its load. With mu at that bound the rear's
lateral capacity beside its braking force is sqrt((mu Fz)^2 - Fx^2), and the rear's lateral
utilisation u = Fy / capacity an upper bound of the true one. A brush tyre at lateral utilisation u
slips 3 (1 - (1 - u)^(1/3)) / u times its linear angle (1 at u = 0, 3 at the limit). What braking
adds is that ratio less the one the same lateral force takes at the rear's static load without a
brake force (u0 against the same grip): a steady corner at the most grip the drive has shown is the
law's own range (its saturation term), not braking's (``UNBRAKED_BASE``; the suite's flying_6_r9r_h250
and gyro_scale_+-1pct lost their sideslip availability without it, drag and grade read as braking).
The rear then slips at most the linear angle times 1 + that addition; what this exceeds the law by is
how far the pseudo-measurement may be off: ``SingleTrackFusion.brake_excess_var`` turns it into the
same widening as the steering's misfit (``core.BRAKE_GRIP``). Widening only, never
a measurement of vy: with fresh GNSS the filter's own vy carries the sideslip, and the published std
is the filter's, grown for it. The linear angle is taken with the softer of the configured and the
learned rear compliance: the learned one is fitted in corners without braking and may come out too
stiff (drive 504: 2.9x the true stiffness), which would shrink the bound with it.

Only while braking (the tyres' longitudinal force below -BRAKE_MIN_MPS2): a driven rear at its limit
is drive_slip.py's, and in a steady corner the law's own saturation term is fitted to the drive.
"""
from __future__ import annotations

import math

G = 9.81
#: the front brakes' share of the braking force: a fixed proportioning valve or an EBD map sets it;
#: passenger cars 0.6-0.75 (the simulator's VehicleParams 0.65). The config does not carry it; the
#: rear's share is taken at its usual upper end (a front share of 0.65)
BRAKE_FRONT_SHARE = 0.65
#: m/s^2: the tyres' decelerating force per mass from which the rear brakes are counted as braking
BRAKE_MIN_MPS2 = 0.5
#: s: the longitudinal force is compared low-passed (the lateral one is the model's, low-passed already)
SMOOTH_S = 0.1
#: m/s: below this the grip shown is not collected (launch and parking: the wheels' own noise)
MIN_SPEED_MPS = 3.0
#: the least friction coefficient the road is taken to carry before it has shown any (ice)
MU_FLOOR = 0.15
#: the slip ratio of a brush tyre at its limit against its linear angle
RATIO_AT_LIMIT = 3.0
#: the ratio returned is braking's own addition, 1 + brush(u) - brush(u0) with u0 the same lateral
#: force's utilisation at the rear's static load without brake force: a steady corner at the most
#: grip the drive has shown is no braking effect (the suite's flying_6_r9r_h250 and gyro_scale_+-1pct:
#: a drag or grade deceleration at the corner's own maximum read as u = 1; sideslip invalid while right)
UNBRAKED_BASE = True


def brush_ratio(u: float) -> float:
    """A brush tyre's slip angle at lateral utilisation ``u`` (force over its capacity, 0..1) over the
    linear angle of the same force: 3 (1 - (1 - u)^(1/3)) / u, 1 at u = 0, 3 at u = 1."""
    if u <= 1e-6:
        return 1.0
    if u >= 1.0:
        return RATIO_AT_LIMIT
    return 3.0 * (1.0 - (1.0 - u) ** (1.0 / 3.0)) / u


class BrakeGrip:
    """The friction ellipse of the rear axle at its braking load, against the grip the road has shown."""

    def __init__(self, dt: float, driven_axle: str, lf: float, lr: float, cg_height: float):
        self.lf = lf
        self.lr = lr
        self.L = lf + lr
        self.h = cg_height
        self.a = min(dt / SMOOTH_S, 1.0)
        # each axle's share of a drive force (the simulator's and most cars' all-wheel drive: even)
        self.drive_front = {"front": 1.0, "rear": 0.0}.get(driven_axle, 0.5)
        self.mu_shown = MU_FLOOR
        self.ax = 0.0
        self.u = 0.0  # the rear's lateral utilisation bound at the last step (0: not braking)
        self.ratio = 1.0

    def reset(self) -> None:
        """A filter re-initialisation: the low-pass starts again; the road's grip shown stays (same road)."""
        self.ax = 0.0
        self.u = 0.0
        self.ratio = 1.0

    def step(self, vx: float, ax: float, fy_front: float, fy_rear: float) -> float:
        """One step: ``ax`` the tyres' longitudinal force per mass (the specific force less the
        sensor's offset and the grade), ``fy_front``, ``fy_rear`` the axles' lateral forces per mass
        (the model's regressors); returns the ratio (>= 1) by which the rear may slip beyond its
        linear angle while braking (1 + braking's addition, ``UNBRAKED_BASE``), 1.0 otherwise."""
        self.u = 0.0
        self.ratio = 1.0
        if not (math.isfinite(ax) and math.isfinite(fy_front) and math.isfinite(fy_rear)):
            return 1.0
        a = self.ax = self.ax + self.a * (ax - self.ax)
        L = self.L
        fz_f = (G * self.lr - a * self.h) / L
        fz_r = (G * self.lf + a * self.h) / L
        if fz_f <= 0.0 or fz_r <= 0.0:
            return 1.0
        if a < 0.0:
            fx_f = BRAKE_FRONT_SHARE * a
            fx_r = a - fx_f
        else:
            fx_f = self.drive_front * a
            fx_r = a - fx_f
        n_f = math.hypot(fx_f, fy_front) / fz_f
        n_r = math.hypot(fx_r, fy_rear) / fz_r
        if vx >= MIN_SPEED_MPS:
            # every force an axle carried is at most mu times its load (the rear's now included)
            self.mu_shown = max(self.mu_shown, n_f, n_r)
        if not (a < -BRAKE_MIN_MPS2 and vx >= MIN_SPEED_MPS):
            return 1.0
        cap2 = (self.mu_shown * fz_r) ** 2 - fx_r * fx_r
        u = 1.0 if cap2 <= 0.0 else min(abs(fy_rear) / math.sqrt(cap2), 1.0)
        self.u = u
        self.ratio = brush_ratio(u)
        if UNBRAKED_BASE:
            # what braking adds: the same lateral force at the rear's static load and no brake force
            # slips brush_ratio(u0) already (a steady corner at the grip shown: the law's own range)
            u0 = min(abs(fy_rear) / (self.mu_shown * G * self.lf / L), 1.0)
            self.ratio = 1.0 + max(self.ratio - brush_ratio(u0), 0.0)
        return self.ratio
