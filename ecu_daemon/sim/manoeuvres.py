"""Test manoeuvres and the simple driver that flies them.

A :class:`Manoeuvre` is a closed-loop speed profile (piecewise-linear knots) plus a sequence of
timed steering :class:`Phase` s. Path phases (line, lane change, circle) are *anchored* at the
car's pose when the phase starts, so an open-loop phase (J-turn, sine, slalom) can leave the car
anywhere and the next path phase just carries on from there. Open-loop steering is added to the
steering angle held at the phase start, which keeps the trim needed on a banked road.

Every builder starts with ~5 s at standstill (gyro bias at rest) and ~10 s of straight
acceleration (filters align), as the estimator's tests need. On low friction (``mu`` < 0.6) the
builders lower speeds and steering amplitudes so the car stays controllable; the vehicle model
reports a spin (|sideslip| > 25 deg) if it does not.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

from .road import PROFILES
from .vehicle import G, Commands, VehicleParams, VehicleState

# --------------------------------------------------------------------------------- steering specs


@dataclass(frozen=True)
class Line:
    """Follow a straight line through the entry position along the entry course."""


@dataclass(frozen=True)
class Wander(Line):
    """A straight line with a gentle sinusoidal lateral wander (a human driver is never exact)."""

    amplitude_m: float = 0.3
    wavelength_m: float = 180.0


@dataclass(frozen=True)
class LaneChange(Line):
    """ISO 3888-1-like double lane change: offset ``offset_m`` (positive left) and back.

    Lengths: entry lane ``lead_m``, transition ``in_m``, offset lane ``hold_m``, transition back
    ``out_m`` (the defaults are the ISO sections 1-4); straight afterwards.
    """

    offset_m: float = 3.5
    lead_m: float = 15.0
    in_m: float = 30.0
    hold_m: float = 25.0
    out_m: float = 25.0


@dataclass(frozen=True)
class Circle:
    """A circle of ``radius_m`` tangent to the entry course (left turn when ``left``)."""

    radius_m: float = 40.0
    left: bool = True


@dataclass(frozen=True, eq=False)
class RoadPath:
    """Follow a road's centreline (``points``: (n, 2) every ``step_m`` in the anchor frame, from
    :meth:`~ecu_daemon.sim.road.RoadProfile.centreline`)."""

    points: object
    step_m: float = 0.5


@dataclass(frozen=True)
class OpenLoop:
    """Open-loop steering-wheel profile added to the entry steering angle.

    ``kind``: ``jturn`` (ramp at ``rate`` to ``amplitude``, hold ``hold_s``, ramp back),
    ``sine`` / ``slalom`` (``amplitude * sin(2 pi f t)`` for ``cycles`` periods; a slalom fades
    in and out over half a period).
    """

    kind: str
    amplitude_rad: float
    rate_radps: float = math.radians(400.0)
    hold_s: float = 3.0
    freq_hz: float = 0.5
    cycles: float = 1.0

    def angle(self, tau: float) -> float:
        a = self.amplitude_rad
        if self.kind == "jturn":
            ramp = abs(a) / self.rate_radps
            if tau < ramp:
                return a * tau / ramp
            if tau < ramp + self.hold_s:
                return a
            return a * max(0.0, 1.0 - (tau - ramp - self.hold_s) / ramp)
        if self.kind in ("sine", "slalom"):
            end = self.cycles / self.freq_hz
            if tau >= end:
                return 0.0
            env = 1.0
            if self.kind == "slalom":
                fade = 0.5 / self.freq_hz
                env = min(1.0, tau / fade, (end - tau) / fade)
            return a * env * math.sin(2.0 * math.pi * self.freq_hz * tau)
        raise ValueError(f"unknown open-loop steering kind {self.kind!r}")


@dataclass(frozen=True)
class Phase:
    duration_s: float
    steer: object  # Line | Wander | LaneChange | Circle | OpenLoop


@dataclass(frozen=True)
class Manoeuvre:
    """Speed knots ``(t_rel, v)`` and steering phases; the last phase lasts forever."""

    name: str
    speed_knots: tuple
    phases: tuple
    duration_s: float
    road: object = None  # a RoadProfile under the whole drive (bank and grade along the distance)

    def speed(self, t_rel: float) -> tuple[float, float]:
        """(target speed, target acceleration) at ``t_rel`` seconds after the start."""
        ts = [k[0] for k in self.speed_knots]
        i = bisect.bisect_right(ts, t_rel)
        if i == 0:
            return self.speed_knots[0][1], 0.0
        if i >= len(ts):
            return self.speed_knots[-1][1], 0.0
        (t0, v0), (t1, v1) = self.speed_knots[i - 1], self.speed_knots[i]
        a = (v1 - v0) / (t1 - t0)
        return v0 + a * (t_rel - t0), a


# --------------------------------------------------------------------------------- the driver

STEER_LAG_S = 0.12  # path following: driver's steering lag


@dataclass
class _Anchor:
    north: float
    east: float
    course: float  # clockwise from north
    steer0: float
    t0: float


class Driver:
    """Closed-loop speed (PI + feed-forward, traction control, ABS) and phase-wise steering.

    Steering on paths is pure pursuit with an understeer feed-forward; lookahead grows with speed.
    """

    def __init__(self, manoeuvre: Manoeuvre, params: VehicleParams, mu: float, t_start: float,
                 grade_rad: float = 0.0):
        self.m = manoeuvre
        self.p = params
        self.mu = mu
        self.t_start = t_start
        self.grade = grade_rad
        self.kus = params.understeer_gradient()
        self.phase_ends = []
        acc = 0.0
        for ph in manoeuvre.phases:
            acc += ph.duration_s
            self.phase_ends.append(acc)
        self.phase_idx = -1
        self.anchor: _Anchor | None = None
        self.int_v = 0.0
        self.last_t = None
        self.kappa_peak = 2.16 * mu / params.tyre_front.kx1  # slip ratio at peak force (tyre.py)
        self.road_idx = 0  # RoadPath: index of the centreline point nearest the car

    # steering --------------------------------------------------------------------------
    def _phase(self, t_rel: float) -> int:
        i = bisect.bisect_right(self.phase_ends, t_rel)
        return min(i, len(self.m.phases) - 1)

    def _steer(self, s: VehicleState, t_rel: float) -> float:
        i = self._phase(t_rel)
        if i != self.phase_idx:
            course = math.atan2(
                s.vx * math.sin(s.psi) - s.vy * math.cos(s.psi),
                s.vx * math.cos(s.psi) + s.vy * math.sin(s.psi)) if s.vx > 1.0 else s.psi
            self.anchor = _Anchor(s.north, s.east, course, s.steer_sw, t_rel)
            self.phase_idx = i
        spec = self.m.phases[i].steer
        a = self.anchor
        if isinstance(spec, OpenLoop):
            return a.steer0 + spec.angle(t_rel - a.t0)
        # pose in the anchor frame (x along the entry course, y to its left, yaw CCW)
        dn, de = s.north - a.north, s.east - a.east
        cc, sc = math.cos(a.course), math.sin(a.course)
        x = dn * cc + de * sc
        y = dn * sc - de * cc
        yaw = -(s.psi - a.course)
        v = max(s.vx, 0.0)
        ld = max(6.0, 0.55 * v)
        if isinstance(spec, RoadPath):
            pts = spec.points
            lo = self.road_idx
            hi = min(len(pts), lo + 200)
            d2 = (pts[lo:hi, 0] - x) ** 2 + (pts[lo:hi, 1] - y) ** 2
            self.road_idx = lo + int(d2.argmin())
            j = min(len(pts) - 1, self.road_idx + int(round(ld / spec.step_m)))
            xt, yt = float(pts[j, 0]), float(pts[j, 1])
        elif isinstance(spec, Circle):
            sign = 1.0 if spec.left else -1.0
            cy = sign * spec.radius_m
            ang = math.atan2(y - cy, x)  # angle of the car around the centre
            ang_t = ang + sign * ld / spec.radius_m
            xt, yt = spec.radius_m * math.cos(ang_t), cy + spec.radius_m * math.sin(ang_t)
        else:
            xt = x + ld
            yt = _path_y(spec, xt)
        dx, dy = xt - x, yt - y
        yv = -math.sin(yaw) * dx + math.cos(yaw) * dy
        xv = math.cos(yaw) * dx + math.sin(yaw) * dy
        curv = 2.0 * yv / (xv * xv + yv * yv)
        delta = math.atan(self.p.wheelbase_m * curv) + self.kus * v * v * curv
        target = delta * self.p.steering_ratio
        # a human's hands: first-order lag (~0.12 s), so phase changes do not snap the wheel
        if self.last_t is not None:
            dt = s.t - self.last_t
            return s.steer_sw + (target - s.steer_sw) * min(1.0, dt / STEER_LAG_S)
        return target

    # speed -----------------------------------------------------------------------------
    def update(self, s: VehicleState) -> Commands:
        t_rel = s.t - self.t_start
        steer = self._steer(s, t_rel)
        v_t, a_ff = self.m.speed(t_rel)
        dt = 0.0 if self.last_t is None else s.t - self.last_t
        self.last_t = s.t
        p = self.p
        if v_t == 0.0 and abs(s.vx) < 0.5:
            self.int_v = 0.0
            hold = [1500.0, 1500.0, 800.0, 800.0]
            return Commands(steer, (0.0,) * 4, tuple(hold), True)
        err = v_t - s.vx
        self.int_v = max(-1.0, min(1.0, self.int_v + 0.15 * err * dt))
        a_max = min(0.55 * self.mu * G, 3.0)
        a_min = -min(0.7 * self.mu * G, 6.0)
        # reverse gear: the roles of drive and brake swap (a_max / a_min mirror too)
        gear = -1.0 if v_t < 0.0 or s.vx < -0.5 else 1.0
        if gear < 0:
            a_max, a_min = -a_min, -a_max
        a_cmd = max(a_min, min(a_max, a_ff + 0.8 * err + self.int_v))
        f = (p.mass_kg * a_cmd + 0.5 * p.air_density * p.drag_area_m2 * s.vx * abs(s.vx)
             + gear * p.rolling_resistance * p.mass_kg * G + p.mass_kg * G * math.sin(self.grade))
        drive = [0.0] * 4
        brake = [0.0] * 4
        r = p.wheel_radius_m
        if gear * f > 0.0:
            f = gear * min(gear * f, p.max_drive_force_n, p.max_drive_power_w / max(abs(s.vx), 1.0))
            wheels = {"front": (0, 1), "rear": (2, 3), "all": (0, 1, 2, 3)}[p.driven_axle]
            for w in wheels:
                tc = _limiter(gear * s.kappa[w], 0.7 * self.kappa_peak)  # traction control
                drive[w] = f * r / len(wheels) * tc
        else:
            tb = abs(f) * r
            shares = (p.brake_front_share / 2, p.brake_front_share / 2,
                      (1 - p.brake_front_share) / 2, (1 - p.brake_front_share) / 2)
            for w in range(4):
                brake[w] = tb * shares[w] * _limiter(-gear * s.kappa[w], 0.7 * self.kappa_peak)  # ABS
        return Commands(steer, tuple(drive), tuple(brake), False)


def _limiter(kappa: float, threshold: float) -> float:
    """Torque factor of a crude slip controller: 1 below the threshold, 0.1 at twice it."""
    if kappa <= threshold:
        return 1.0
    return max(0.1, 1.0 - (kappa - threshold) / threshold)


def _path_y(spec, x: float) -> float:
    """Lateral offset of a line-type path at along-track ``x`` (anchor frame)."""
    if isinstance(spec, LaneChange):
        s = x - spec.lead_m
        if s <= 0.0:
            return 0.0
        if s < spec.in_m:
            return spec.offset_m * 0.5 * (1.0 - math.cos(math.pi * s / spec.in_m))
        s -= spec.in_m
        if s < spec.hold_m:
            return spec.offset_m
        s -= spec.hold_m
        if s < spec.out_m:
            return spec.offset_m * 0.5 * (1.0 + math.cos(math.pi * s / spec.out_m))
        return 0.0
    if isinstance(spec, Wander):
        return spec.amplitude_m * math.sin(2.0 * math.pi * max(x, 0.0) / spec.wavelength_m)
    return 0.0


# --------------------------------------------------------------------------------- builders

STANDSTILL_S = 5.0
ACCEL_S = 10.0


def _start(v: float) -> list:
    return [(0.0, 0.0), (STANDSTILL_S, 0.0), (STANDSTILL_S + ACCEL_S, v)]


def _low(mu: float) -> bool:
    return mu < 0.6


def straight(mu: float = 1.0) -> Manoeuvre:
    """Standstill, acceleration, gentle speed changes, a stop and standstill at the end (70 s)."""
    knots = _start(15.0) + [(25.0, 15.0), (33.0, 25.0), (43.0, 25.0), (53.0, 10.0), (60.0, 10.0),
                            (66.0, 0.0)]
    return Manoeuvre("straight", tuple(knots), (Phase(1e9, Wander()),), 70.0)


def j_turn(mu: float = 1.0, v: float | None = None) -> Manoeuvre:
    """Step steer left, recover, step steer right, at constant speed (ISO 7401-like), 45 s.

    ``v``: another speed (m/s) with the same steering (None: 14 m/s on low friction, else 22)."""
    v_def, amp = (14.0, math.radians(45.0)) if _low(mu) else (22.0, math.radians(75.0))
    v = v_def if v is None else v
    jl = OpenLoop("jturn", amp, hold_s=4.0)
    jr = OpenLoop("jturn", -amp, hold_s=4.0)
    ramp = abs(amp) / jl.rate_radps
    t_j = 2 * ramp + 4.0 + 1.0
    phases = (Phase(STANDSTILL_S + ACCEL_S + 5.0, Line()), Phase(t_j, jl), Phase(6.0, Line()),
              Phase(t_j, jr), Phase(1e9, Line()))
    return Manoeuvre("j_turn", tuple(_start(v)), phases, 45.0)


def double_lane_change(mu: float = 1.0, v: float | None = None) -> Manoeuvre:
    """Two ISO 3888-1-like lane changes (left, then right) with straights between, 50 s.

    ``v``: another speed (m/s) (None: 12.5 m/s on low friction, else 22)."""
    v = (12.5 if _low(mu) else 22.0) if v is None else v
    phases = (Phase(STANDSTILL_S + ACCEL_S + 5.0, Line()), Phase(10.0, LaneChange(3.5)),
              Phase(6.0, Line()), Phase(10.0, LaneChange(-3.5)), Phase(1e9, Line()))
    return Manoeuvre("double_lane_change", tuple(_start(v)), phases, 50.0)


def slalom(mu: float = 1.0, v: float | None = None, amp_deg: float | None = None) -> Manoeuvre:
    """Open-loop sinusoidal steering (8 cycles) at constant speed, 45 s.

    ``v`` / ``amp_deg``: another speed (m/s) / steering-wheel amplitude (deg) at the same frequency
    (None: the surface's defaults below)."""
    if _low(mu):
        v_def, sl = 13.0, OpenLoop("slalom", math.radians(55.0 if amp_deg is None else amp_deg), freq_hz=0.4, cycles=6)
    else:
        v_def, sl = 18.0, OpenLoop("slalom", math.radians(60.0 if amp_deg is None else amp_deg), freq_hz=0.5, cycles=8)
    v = v_def if v is None else v
    phases = (Phase(STANDSTILL_S + ACCEL_S + 5.0, Line()), Phase(sl.cycles / sl.freq_hz, sl),
              Phase(1e9, Line()))
    return Manoeuvre("slalom", tuple(_start(v)), phases, 45.0)


def sine_steer(mu: float = 1.0) -> Manoeuvre:
    """Two single-period sine steers (left-first, then right-first) at constant speed, 45 s."""
    v, amp, f = (14.0, math.radians(60.0), 0.5) if _low(mu) else (22.0, math.radians(70.0), 0.7)
    s1, s2 = OpenLoop("sine", amp, freq_hz=f), OpenLoop("sine", -amp, freq_hz=f)
    phases = (Phase(STANDSTILL_S + ACCEL_S + 5.0, Line()), Phase(1 / f, s1), Phase(8.0, Line()),
              Phase(1 / f, s2), Phase(1e9, Line()))
    return Manoeuvre("sine", tuple(_start(v)), phases, 45.0)


def steady_circle(mu: float = 1.0, radius_m: float = 40.0, left: bool = True) -> Manoeuvre:
    """Circle of ``radius_m`` with the speed ramped slowly up to ~0.65 g (dry) / ~0.26 g, 70 s."""
    ay_max = (0.26 if _low(mu) else 0.65) * G
    v_max = math.sqrt(ay_max * radius_m)
    v0 = 8.0 if not _low(mu) else 6.0
    t_c = STANDSTILL_S + ACCEL_S + 3.0
    knots = _start(v0) + [(t_c + 2.0, v0), (t_c + 37.0, v_max), (t_c + 44.0, v_max), (t_c + 50.0, v0)]
    phases = (Phase(t_c, Line()), Phase(1e9, Circle(radius_m, left)))
    return Manoeuvre("steady_circle", tuple(knots), phases, 70.0)


def brake_turn(mu: float = 1.0, radius_m: float = 60.0) -> Manoeuvre:
    """Braking in a left-hand circle (60 m): twice from 18 m/s (0.55 g) to 8 m/s at 5 m/s^2, each
    time back up to speed in the circle (55 s): longitudinal and lateral acceleration together,
    what an accelerometer turned about z mixes up."""
    v, lo = (11.0, 6.0) if _low(mu) else (18.0, 8.0)
    t_c = STANDSTILL_S + ACCEL_S + 3.0
    knots = _start(v) + [(t_c + 6.0, v), (t_c + 8.0, lo), (t_c + 14.0, lo), (t_c + 20.0, v), (t_c + 24.0, v),
                         (t_c + 26.0, lo), (t_c + 32.0, lo)]
    phases = (Phase(t_c, Line()), Phase(1e9, Circle(radius_m, True)))
    return Manoeuvre("brake_turn", tuple(knots), phases, 55.0)


def demo() -> Manoeuvre:
    """About 65 s mixing a straight, a lane change, a slalom and a circle (for the live demo)."""
    v = 16.0
    sl = OpenLoop("slalom", math.radians(35.0), freq_hz=0.5, cycles=5)
    phases = (Phase(STANDSTILL_S + ACCEL_S + 4.0, Line()), Phase(8.0, LaneChange(3.5)),
              Phase(3.0, Line()), Phase(sl.cycles / sl.freq_hz, sl), Phase(4.0, Line()),
              Phase(16.0, Circle(40.0, left=False)), Phase(1e9, Line()))
    knots = _start(v) + [(56.0, v), (62.0, 8.0)]
    return Manoeuvre("demo", tuple(knots), phases, 65.0)


def flying(mu: float = 1.0, v: float = 30.0, radius_m: float = 0.0, left: bool = True,
           corner_s: float = 12.0, duration_s: float = 45.0) -> Manoeuvre:
    """A drive that is already under way at t = 0 (a daemon starting while driving).

    ``radius_m`` > 0: mid-corner on that circle for ``corner_s`` seconds (the simulator starts
    the car in steady cornering there), then straight on; speed changes of +-20 % afterwards so
    the GNSS latency is observable. No standstill anywhere.
    """
    knots = [(0.0, v), (corner_s + 3.0, v), (corner_s + 8.0, 0.8 * v), (corner_s + 14.0, 0.8 * v),
             (corner_s + 19.0, v)]
    first = Phase(corner_s, Circle(radius_m, left)) if radius_m > 0 else Phase(corner_s, Wander())
    return Manoeuvre("flying", tuple(knots), (first, Phase(1e9, Wander())), duration_s)


def reversing(mu: float = 1.0, v_back: float = 4.0) -> Manoeuvre:
    """Forward to 10 m/s, stop, reverse at ``v_back`` with a gentle open-loop curve, stop, forward again (60 s)."""
    knots = _start(10.0) + [(22.0, 10.0), (27.0, 0.0), (29.0, 0.0), (32.0, -v_back), (40.0, -v_back),
                            (43.0, 0.0), (45.0, 0.0), (52.0, 10.0)]
    curve = OpenLoop("sine", math.radians(90.0), freq_hz=1 / 16.0, cycles=0.5)  # left for 8 s, back
    phases = (Phase(29.0, Line()), Phase(16.0, curve), Phase(1e9, Line()))
    return Manoeuvre("reversing", tuple(knots), phases, 60.0)


def low_speed(mu: float = 1.0, radius_m: float = 15.0, v_max: float = 10.0) -> Manoeuvre:
    """Low-speed handling (5-13 m/s): a tight circle with the speed ramped 5 -> ``v_max`` -> 5, then a slalom (75 s).

    On a tight circle the kinematic sideslip (rear axle distance / radius) is large at low
    speed: 8-10 deg on 9-10 m radii, as on real handling tracks.
    """
    t_c = STANDSTILL_S + ACCEL_S
    sl = OpenLoop("slalom", math.radians(90.0), freq_hz=0.4, cycles=5)
    knots = _start(5.0) + [(t_c + 5.0, 5.0), (t_c + 30.0, v_max), (t_c + 36.0, v_max), (t_c + 42.0, 8.0),
                           (t_c + 60.0, 8.0)]
    phases = (Phase(t_c, Line()), Phase(40.0, Circle(radius_m, True)), Phase(5.0, Line()),
              Phase(sl.cycles / sl.freq_hz, sl), Phase(1e9, Line()))
    return Manoeuvre("low_speed", tuple(knots), phases, 75.0)


def road_course(mu: float = 1.0, profile: str = "country") -> Manoeuvre:
    """A drive along a :mod:`road <ecu_daemon.sim.road>` profile whose curvature, bank and grade
    vary with distance: ``country`` (15-25 m/s, 150 s) or ``handling`` (6-11 m/s, 110 s), from
    standstill, with speed changes (so GNSS latency and wheel scale stay observable)."""
    prof = PROFILES[profile]()
    if profile == "country":
        v = 14.0 if _low(mu) else 20.0
        knots = _start(v) + [(25.0, v), (35.0, 1.2 * v), (55.0, 1.2 * v), (65.0, 0.8 * v), (85.0, 0.8 * v),
                             (95.0, v), (125.0, v), (132.0, 1.2 * v), (142.0, 0.9 * v)]
        duration = 150.0
    else:
        v = 7.0 if _low(mu) else 9.0
        knots = _start(v) + [(30.0, v), (40.0, 1.2 * v), (55.0, 1.2 * v), (65.0, 0.7 * v), (80.0, 0.7 * v),
                             (90.0, v)]
        duration = 110.0
    phases = (Phase(1e9, RoadPath(prof.centreline(3000.0 if profile == "country" else 1500.0))),)
    return Manoeuvre(f"road_{profile}", tuple(knots), phases, duration, road=prof)


#: manoeuvre kind -> builder(mu, **params) -> Manoeuvre
BUILDERS = {
    "straight": straight,
    "j_turn": j_turn,
    "double_lane_change": double_lane_change,
    "slalom": slalom,
    "sine": sine_steer,
    "steady_circle": steady_circle,
    "brake_turn": brake_turn,
    "demo": lambda mu=1.0: demo(),
    "flying": flying,
    "reversing": reversing,
    "low_speed": low_speed,
    "road_course": road_course,
}
