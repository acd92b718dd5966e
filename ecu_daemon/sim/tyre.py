"""Magic Formula tyre with combined slip (normalised-slip friction circle) and load-dependent stiffness.

Why this form: the estimator must be tested against a tyre that saturates (so the single-track
model is wrong at the limit), whose cornering stiffness falls with load (so lateral load transfer
matters), and whose peak force scales with road friction ``mu``. Everything is scalar Python
because it runs 4x per step at 1 kHz; numpy call overhead would dominate.

Model, per tyre (slips are dimensionless, forces in N, wheel frame: x rolling direction, y left):

* slip stiffnesses: ``Ky(Fz) = ky1 * Fz0 * sin(2 atan(Fz / (ky2 * Fz0)))`` (Pacejka's degressive
  cornering stiffness), ``Kx(Fz) = kx1 * Fz``; independent of ``mu`` (ice reduces the peak, not
  the initial slope, to first order).
* normalised slips ``nx = Kx*kappa / (mu Fz)``, ``ny = Ky*tan(alpha) / (mu Fz)``, ``n = |(nx, ny)|``.
* the resultant force ``mu * Fz * M(n)`` with the Magic Formula shape
  ``M(n) = sin(C atan(B n - E (B n - atan(B n))))`` and ``B = 1/C`` so that ``M'(0) = 1``; it
  points along ``(nx, ny)``. Hence pure-slip forces start with slopes ``Kx``, ``Ky`` and the
  combined force never exceeds ``mu * Fz`` (friction circle).

Sign: ``alpha`` here is the ISO slip angle with the sign that gives a *positive* force, i.e.
``tan(alpha) = -v_lateral / |v_longitudinal|`` (the tyre pushes against its sliding direction).

Relaxation (``relaxation_length_m`` = sigma > 0): a real tyre's carcass has to deflect before the
contact patch carries the lateral force, so the force follows the slip over a rolled distance
sigma (0.3-0.8 m for a car tyre), a lag of sigma / v: 0.1 s at 5 m/s, 0.02 s at 25 m/s. The
simulator (:func:`relax_step`, used per wheel by :func:`ecu_daemon.sim.vehicle.integrate`) feeds
:func:`forces` a first-order lagged ``tan(alpha)``; the default 0 is the instant tyre every
scenario before it was scored against. Only the lateral slip relaxes: the longitudinal slip's
lag is short next to the wheel-spin dynamics the model already integrates.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class TyreParams:
    """One axle's tyre coefficients (both tyres of an axle are equal)."""

    fz0_n: float = 4000.0  # nominal load
    ky1: float = 15.0  # cornering stiffness / Fz0 at the stiffness-load curve's scale
    ky2: float = 2.0  # load (in Fz0) at which cornering stiffness peaks
    kx1: float = 18.0  # longitudinal slip stiffness per unit load
    shape_c: float = 1.3  # MF shape factor: sliding force = sin(C*pi/2) = 0.89 of the peak
    curv_e: float = -1.5  # MF curvature: puts the peak at n ~ 2.2 (about 8 deg slip angle on dry)
    #: lateral relaxation length sigma (m): the force builds over sigma of rolling; 0 = instant
    relaxation_length_m: float = 0.0

    def cornering_stiffness(self, fz: float) -> float:
        """dFy/dalpha at alpha = 0 for load ``fz`` (N/rad)."""
        if fz <= 0.0:
            return 0.0
        return self.ky1 * self.fz0_n * math.sin(2.0 * math.atan(fz / (self.ky2 * self.fz0_n)))

    def slip_stiffness(self, fz: float) -> float:
        """dFx/dkappa at kappa = 0 (N per unit slip ratio)."""
        return self.kx1 * max(fz, 0.0)


def shape(n: float, c: float, e: float) -> float:
    """Magic Formula shape normalised to unit initial slope: M(n), n >= 0."""
    bn = n / c
    return math.sin(c * math.atan(bn - e * (bn - math.atan(bn))))


def forces(p: TyreParams, fz: float, mu: float, kappa: float, tan_alpha: float) -> tuple[float, float]:
    """(Fx, Fy) in the wheel frame for slip ratio ``kappa`` and ``tan(alpha)`` (sign as module doc)."""
    if fz <= 0.0:
        return 0.0, 0.0
    # inlined cornering_stiffness() and shape(): this runs 4000 times per simulated second
    fz0 = p.fz0_n
    cap = mu * fz
    nx = p.kx1 * fz * kappa / cap
    ny = p.ky1 * fz0 * math.sin(2.0 * math.atan(fz / (p.ky2 * fz0))) * tan_alpha / cap
    n = math.sqrt(nx * nx + ny * ny)
    if n < 1e-12:
        return 0.0, 0.0
    c = p.shape_c
    bn = n / c
    f = cap * math.sin(c * math.atan(bn - p.curv_e * (bn - math.atan(bn)))) / n
    return f * nx, f * ny


def relax_step(lagged: float, tan_alpha: float, speed: float, sigma: float, dt: float) -> float:
    """The relaxed ``tan(alpha)`` ``dt`` later: ``d lagged/dt = (speed / sigma) (tan_alpha - lagged)``.

    Why this form: it is the carcass deflection's equation (sigma d(alpha')/dt + |v| alpha' = |v|
    alpha), so the lag is a distance, sigma / speed in time. Solved exactly over the step (the
    exponential, not Euler), so it is stable for any sigma / speed / dt; ``speed`` must be the
    slip's own regularised speed (> 0, :func:`~ecu_daemon.sim.vehicle.integrate` uses
    ``max(|v|, 1 m/s)``): near standstill the lag then stays at most sigma / (1 m/s), the force
    does not freeze at a stale value while the car creeps. ``sigma <= 0``: no lag.
    """
    if sigma <= 0.0:
        return tan_alpha
    return tan_alpha + (lagged - tan_alpha) * math.exp(-dt * speed / sigma)


def peak_slip(p: TyreParams) -> float:
    """The normalised slip n at which M(n) peaks (scalar search; used for reporting)."""
    best_n, best = 0.0, -1.0
    n = 0.0
    while n < 10.0:
        m = shape(n, p.shape_c, p.curv_e)
        if m > best:
            best_n, best = n, m
        n += 0.001
    return best_n
