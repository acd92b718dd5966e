"""Spin / slide check: is the car still the gripping car the estimator's promise assumes?

Why (issue 7, random drives 89, 166, 205, 239): every aiding source of the filter assumes a car
whose tyres grip. The wheels then measure vx, the single-track model holds vy to a few degrees of
sideslip, and the fault detector's votes (wheels against ax, the gyro against the rear wheels and
ay / vx) compare sensors through a gripping car's kinematics. A car that spins out breaks all of
that at once: the fault detector isolated the wheels, ax, the gyro and GNSS in turn (each
"disagreed" with the rest), and vx was then published valid 15-29 m/s off, the sideslip once
171 deg off, while the model still said ~0 deg.

The physics a spin contradicts and no gripping drive does: lateral kinematics
``ay = dvy/dt + r vx``. A gripping car keeps its sideslip to a few degrees, so ``dvy/dt`` stays
small and ``r vx`` follows ``ay`` (itself at most mu g). A car that slides away turns faster than
its tyres can bend its path: ``|r vx|`` goes far beyond ``|ay|`` (205: ``r vx`` 21 m/s^2 against
an ``ay`` of 6.5), i.e. ``|dvy/dt|`` of a large fraction of g sustained -- vy grows by metres per
second within half a second, the sideslip by tens of degrees. Both conditions are required, the
excess over ``ay`` and a yaw rate beyond what the road's grip could hold on that path, so that a
transient of a hard but gripping manoeuvre (a dry lane change, a slalom on snow) does not count.

Once it has fired, the car is called sliding until the kinematics measured by the wheels (not by
the filter's vx, which the spin has spoiled) are those of a gripping car again for ``GRIP_S``:
``|ay - r v_wheels|`` small and the yaw rate within grip. :attr:`released` is set for one call
then: the estimator re-initialises from that consistent state (its divergence path).

Inputs are SI, ISO 8855 (ay, r positive to the left); the check holds no filter state.
"""
from __future__ import annotations

import math

from ..gravity import G
from .rear_axle_yaw import rear_speed_difference

#: rad: sideslip change over the last ~TAU_S, from ``(ay - r vx) / vx`` (= d beta / dt), beyond
#: which the car is leaving its grip range. A gripping car's sideslip swings by a few degrees (a dry
#: lane change +-3 deg, on snow +-5 deg, over a second); a car that spins out turns it by tens of
#: degrees in half a second (205: 33 deg in 1 s). Per speed, not in m/s^2: at 50 m/s a 1.5 deg
#: weave of a gripping car is 8 m/s^2 of |ay - r vx| for 0.15 s (flying_50_r400r_h300).
SLIDE_RAD = 0.12
#: m/s^2: |r vx| beyond which no tyre on any road holds the path (~1.2 g, dry asphalt and margin)
GRIP_MPS2 = 1.2 * G
#: s: the leaky integral's memory: long enough to see a slide build up, short enough that the
#: bias and bank errors of ay (<= 0.5 m/s^2, a 0.025 rad drift at 10 m/s) do not add up
TAU_S = 0.5
#: s: low-pass of the wheels' kinematic excess while waiting for grip (a spike is not grip lost)
RELEASE_TAU_S = 0.15
#: m/s^2: |ay - r v_wheels| below which the car grips again (sensor errors, bank, transients)
RELEASE_MPS2 = 1.5
#: s: how long the wheels' kinematics must be a gripping car's before the slide is over
GRIP_S = 1.0
#: m/s: below this the check does not fire (r vx is small, the sideslip not meaningful)
MIN_SPEED = 5.0
#: A yaw rate beyond the grip of *this* road (issue 7, spin50; random drives 4288, AWD, mu 0.33, and
#: 4143, RWD, mu 0.41): GRIP_MPS2 is a dry road's grip, so a slide on a wet or snowy road never reached
#: it: 4288 turned its sideslip by 30 deg in 1 s at r vx 10.2-10.9 m/s^2 (dbeta 7.5-9.4 deg, past
#: SLIDE_RAD), 4143 by 60 deg at 5.9-7.7 m/s^2, neither fired; the fault detector isolated the good ay
#: (and in 4288 the gyro) instead, vy stopped following the slide and vx (4288: 2.03 m/s off at 0.17)
#: and the heading (4143: 4.9 deg off at 1.0) were promised. The road's grip is what the tyres deliver,
#: and the accelerometer measures it: a car whose path turns (r vx) at ROAD_GRIP_FACTOR times the
#: lateral acceleration its tyres produce, while its sideslip moves by SLIDE_RAD, is not on its tyres'
#: path (4288: 3.2 times, 4143: 2.0 times). ROAD_GRIP_FLOOR_MPS2: r vx below it is no slide whatever
#: ay says (gentle driving, ay's bias and bank errors <= 0.5 m/s^2). Off: on the 23 spun dev drives it took
#: vx 46 -> 0 rows beyond 3 sigma but sideslip 15 -> 55, 3703 breaking (fires on a slide main missed, and
#: the filter re-initialised at 1228.7 published sideslip 1.74 deg off at 0.50 at 4.2 m/s); 36 ordinary
#: drives (3841-3876) unchanged. Needs the re-initialised model made honest first (spin50.md).
SLIDE_ROAD_GRIP = False
ROAD_GRIP_FACTOR = 1.8
ROAD_GRIP_FLOOR_MPS2 = 3.0
#: The slide is over only when the steering agrees too (issue 7, spin50; random drive 4081: RWD, mu
#: 0.21). ``|ay - r v_wheels| < RELEASE_MPS2`` is dvy/dt of a gripping car, but a car sliding sideways
#: slowly on ice decelerates its vy at no more than mu g (2.1 m/s^2 there), and with the wheels' speed
#: standing in for vx (itself 1-3 m/s, the wheels turning with the car) the test read 0.2-0.8 m/s^2:
#: released at 1232.25 with the car 112 deg sideways (vy 3.8 m/s, rear slip -63 deg, r 0.56 rad/s).
#: The filter re-initialised from front wheels 60 deg off their rolling direction and published vx
#: -1.73 m/s valid (std 0.43) for a true 0.12. Rigid-body kinematics of a gripping car need no vy:
#: both axles roll along their wheels, so ``L r = vx tan(delta)`` up to the axles' slip-angle
#: difference, ``|L r - vx tan(delta)| = |vx| |alpha_F - alpha_R|`` (the understeer K ay: <= 0.04 rad
#: on dry asphalt at the limit, K <= 0.004 rad per m/s^2). 4081 at the release: L r 1.41 m/s against
#: vx tan(delta) 0.24, a misfit of 1.17 m/s (the car turned 5 times faster than its steering allows).
#: Both signs of the speed are tried (unsigned wheel speeds when reversing), the steering must be fresh.
#: The yaw test sees only the axles' slip *difference*; a car sliding sideways on both axles alike
#: passes it (4081 at 1233.0: front and rear slip -60 and -62 deg, misfit 0.45 m/s). The steered
#: wheels see the front axle's own slip: a wheel rolls at its contact point's speed along its plane,
#: so ``v_front cos(delta) - v_rear = sin(delta) cos(delta) (vy + lf r - vx tan(delta))``, zero for a
#: gripping front axle (``vy + lf r = vx tan(delta)``) at any steering; 4081: 0.88 m/s at 1232.5,
#: 1.58 at 1233.0 (countersteer 0.34-0.55 rad), 0.17 at 1235.0 once it gripped. Its tolerance is
#: STEER_TOL_MPS plus the wheels' longitudinal slip (WHEEL_SLIP_REL of the speed).
RELEASE_STEERING = True
#: rad: slip-angle difference of the two axles a gripping car stays within (4x dry-road limit understeer)
STEER_SLIP_RAD = 0.15
#: m/s: the steering's offset and ratio errors and the wheels' noise at walking pace
STEER_TOL_MPS = 0.5
#: drive / brake slip of a gripping car's wheels (slip ratio) that the front/rear comparison allows
WHEEL_SLIP_REL = 0.1


class SpinCheck:
    """Latched slide / spin detector (see the module docstring for why)."""

    def __init__(self, dt: float, track_m: float, wheelbase_m: float = math.nan):
        self.dt = dt
        self.track = track_m
        self.wheelbase = wheelbase_m
        self.steer_misfit = 0.0  # |L r - v tan(delta)| (m/s) at the last sliding step (RELEASE_STEERING)
        self.front_misfit = 0.0  # |v_front cos(delta) - v_rear| (m/s), the same step
        self._decay = 1.0 - dt / TAU_S
        self._a = dt / (RELEASE_TAU_S + dt)
        self.excess = 0.0  # ay - r vx (m/s^2) at the last step
        self.dbeta = 0.0  # leaky integral of (ay - r vx) / vx: the sideslip change of the last ~TAU_S (rad)
        self.release_excess = 0.0  # low-passed ay - r v_wheels while sliding
        self.active = False
        self.released = False  # True for the one step at which a slide ends
        self.events = 0  # slides seen (diagnostics)
        self.peak = 0.0  # largest min(|dbeta| / SLIDE_RAD, |r vx| / GRIP_MPS2) so far (1: fired)
        self.fired_t = math.nan
        self._grip_steps = 0
        self._grip_need = int(round(GRIP_S / dt))

    def step(self, t: float, vx: float, r: float, ay: float, v_wheels: float, rl: float, rr: float,
             usable: bool, delta: float = math.nan, fl: float = math.nan, fr: float = math.nan) -> bool:
        """One estimator step; returns :attr:`active`.

        ``vx``: the filter's speed; ``r``, ``ay``: the gyro and lateral accelerometer as measured,
        less their bias states (not the fault detector's substitutes: a spin is what makes it
        isolate a good gyro); ``v_wheels``: the wheels' speed and ``rl``, ``rr`` the rear wheels
        (m/s, scale applied; NaN when stale); ``usable``: the IMU is fresh; ``delta``: the road
        wheel angle (rad, offset removed; NaN when the steering is stale or unknown); ``fl``, ``fr``: the
        front wheels as ``rl``, ``rr``.
        """
        self.released = False
        if not usable:
            self.dbeta = 0.0
            return self.active
        a = self._a
        e = self.excess = ay - r * vx
        fast = abs(vx) > MIN_SPEED
        self.dbeta = self.dbeta * self._decay + (e / abs(vx) * self.dt if fast else 0.0)
        # the rear wheels' yaw rate (rear_axle_yaw.py: signed or unsigned wheel speeds, either direction)
        r_w = rear_speed_difference(rl, rr, vx) / self.track
        if fast and r_w * r > 0.0:  # how close to firing the drive came (diagnostics, tests)
            m = min(abs(self.dbeta) / SLIDE_RAD, abs(r * vx) / GRIP_MPS2)
            if m > self.peak:
                self.peak = m
        if not self.active:
            # the rear wheels' difference confirms a yaw rate of the gyro's sign and at least half its
            # size (rigid-body kinematics, sliding or not): a stuck or offset gyro is no spin
            rvx = abs(r * vx)
            beyond = rvx > GRIP_MPS2 or (SLIDE_ROAD_GRIP and rvx > max(ROAD_GRIP_FACTOR * abs(ay), ROAD_GRIP_FLOOR_MPS2))
            if (fast and abs(self.dbeta) > SLIDE_RAD and beyond
                    and r_w * r > 0.5 * r * r):
                self.active = True
                self.events += 1
                self.fired_t = t
                self._grip_steps = 0
                self.release_excess = e
            return self.active
        if not math.isfinite(v_wheels):
            self._grip_steps = 0
            return True
        self.release_excess += a * ((ay - r * v_wheels) - self.release_excess)
        grip = abs(self.release_excess) < RELEASE_MPS2 and abs(r * v_wheels) < GRIP_MPS2
        if RELEASE_STEERING and grip:
            # the steering's kinematics (RELEASE_STEERING): a stale steering or no wheelbase leaves
            # the wheels' test alone (as before)
            L = self.wheelbase
            if math.isfinite(delta) and math.isfinite(L):
                tv = v_wheels * math.tan(delta)
                lr = L * r
                m = self.steer_misfit = min(abs(lr - tv), abs(lr + tv))
                grip = m <= abs(v_wheels) * STEER_SLIP_RAD + STEER_TOL_MPS
                vr = 0.5 * (rl + rr)
                f = self.front_misfit = abs(0.5 * (fl + fr) * math.cos(delta) - vr)
                if not f <= STEER_TOL_MPS + WHEEL_SLIP_REL * abs(vr):  # NaN (stale fronts): no grip
                    grip = False
        if grip:
            self._grip_steps += 1
            if self._grip_steps >= self._grip_need:
                self.active = False
                self.released = True
                self.dbeta = 0.0
        else:
            self._grip_steps = 0
        return self.active
