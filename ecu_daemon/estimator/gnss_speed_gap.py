"""GNSS speed against the filter's speed while vy is not vouched for (issue 7).

Why (random drives 879, 760): after a spin the filter re-initialises (the spin check's release,
or the wheels' divergence) from the wheels, with vy from the single-track model at a gripping
car's std, because the wheel kinematics look like grip again. A car can still be sliding then:
879 re-initialised at 1228.9 s moving 13 m/s almost sideways (sideslip -80 deg, vx 2.2 m/s),
760 at 1234.3 s at 4 m/s backwards-sideways (sideslip -105 deg). The filter took vy ~0 +- 0.1-0.5
m/s, the steered front wheels (``vx cos delta + (vy + lf r) sin delta``) turned that vy into a vx
2.6 m/s (879) and 1.0 m/s (760) off at a 0.13-0.4 m/s std, published valid; and the fault detector,
voting through a gripping car's kinematics, isolated GNSS, the one source that saw it.

The wheels measure the velocity along their planes only; GNSS measures the antenna's speed
whatever the tyres do. Between fixes the car's speed changes no faster than its horizontal
acceleration, which the accelerometers measure (plus their offsets and the road's tilt:
``ACCEL_ERR``), so the last fix's speed, widened by that acceleration integrated from its time of
validity, bounds the speed now. A filter speed (at the antenna) outside those bounds is off by at
least the distance to them; beyond what the estimator already allows GNSS and the wheels to differ
by (lever arm, sideslip, slip, scale: ``core.GNSS_WHEEL_TOL_MPS`` + ``GNSS_WHEEL_TOL_REL``), that
distance floors vx's published std (so vx is not promised beyond the frame's 1.275 m/s). The
bound widens by itself as the fix ages, so nothing is held by a timer (879: a 1 Hz receiver 0.49 s
late left 1.5 s between the re-initialisation and its first fix). Only while the estimate's
sideslip is not valid: where the estimator vouches for vy, the wheels' vx is vouched too, and a
GNSS glitch the wheels contradict stays the glitch ``core.GNSS_CONFLICT_S`` handles. Whether GNSS
was fused, rejected or isolated does not matter: its speed is compared, never fused.
"""
from __future__ import annotations

import math

#: m/s^2: what the measured horizontal acceleration may miss of the speed's rate of change
#: (accelerometer offsets ~0.3 per axis, a road's grade / bank up to ~5 %, margin)
ACCEL_ERR = 1.0


def widening(accel: float, dt: float) -> float:
    """One step's widening of the bound: the measured horizontal acceleration's magnitude
    ``accel`` plus ``ACCEL_ERR``, over the step (m/s)."""
    return (accel + ACCEL_ERR) * dt


def term(ax: float, ay: float, dt: float) -> float:
    """:func:`widening` from the acceleration's components, as the fix's sum stores it."""
    return widening(math.hypot(ax, ay), dt)


def spread_since(terms: list, s: int, last: int, n: int) -> float:
    """The bound's widening from step ``s`` to ``last`` (both stored in a history of ``n`` slots):
    each step's :func:`term` as the estimator stored it in slot ``step % n``, summed in step order
    from 0.0, so the bits are those of :func:`spread_from_rows` over the same steps (a running total
    would subtract two long sums: other bits). ~40 ns a step compiled, where reading the history's
    numpy rows cost ~0.6 us a step (83 steps at every fix of a 0.5 s receiver; perf39)."""
    spread = 0.0
    for j in range(s, last + 1):
        spread += terms[j % n]
    return spread


def spread_from_rows(aux, s: int, last: int, n: int, dt: float, i_ax: int, i_ay: int) -> float:
    """The reference: the same sum read from the history's aux rows (``StepHistory.aux``), as the
    estimator computed it at every fix before perf39 (``tests/test_gnss_speed_gap.py`` compares the
    two bit for bit). Kept literal: the reference the new sum is held to."""
    spread = 0.0
    for j in range(s, last + 1):
        a = aux[j % n]
        spread += (math.hypot(float(a[i_ax]), float(a[i_ay])) + ACCEL_ERR) * dt
    return spread


class GnssSpeedGap:
    """The speed the last usable fix allows now, and the filter's distance beyond it."""

    def __init__(self, tol_mps: float, tol_rel: float):
        self.tol_mps = tol_mps
        self.tol_rel = tol_rel
        self.speed = math.nan  # m/s: the last usable fix's speed
        self.spread = 0.0  # m/s: how far the speed may have moved since that fix's time of validity
        self.gap = 0.0  # m/s: the filter's speed beyond the bound (0: inside, or vy vouched)
        self.events = 0  # steps with a gap (diagnostics, tests)

    def fix(self, speed: float, spread: float) -> None:
        """A usable fix: its ``speed`` and the acceleration integrated from its time of validity to now."""
        self.speed = speed
        self.spread = spread

    def step(self, vx_ant: float, vy_ant: float, accel: float, dt: float, vouched: bool) -> float:
        """One estimator step: the filter's antenna velocity, the measured horizontal acceleration's
        magnitude, ``vouched``: the last estimate's sideslip was valid. Returns the gap."""
        self.spread += widening(accel, dt) if math.isfinite(accel) else math.inf
        gap = 0.0
        s = self.speed
        if not vouched and math.isfinite(s):
            d = abs(math.hypot(vx_ant, vy_ant) - s) - self.spread
            if d > self.tol_mps + self.tol_rel * s:
                gap = d
                self.events += 1
        self.gap = gap
        return gap
