"""Nonlinear two-track vehicle model: the simulator's ground truth.

States: body velocities ``vx, vy`` at the CG (ISO 8855: x forward, y left), yaw rate ``r``
(positive turning left), heading ``psi`` (clockwise from true north, so ``dpsi/dt = -r``),
position north/east, the four wheel spin speeds; quasi-static body roll and load transfer
(longitudinal and lateral, first-order lagged like a damped suspension).

Road conventions (one place, used by the sensors too):

* ``bank_rad``: the road's roll angle about the vehicle x axis, ISO sign: **positive = left side
  up** (the road falls to the right). Gravity then has the body-y component ``-g sin(bank)``, so a
  car standing on a positive bank measures ``ay = +g sin(bank)`` (its tyres push it up-slope).
  A left-hand banked curve (inside lower) therefore has a *negative* bank. The bank is applied in
  the vehicle frame: exact for a banked circle (bank is radial) and a cambered straight; for
  lane changes and slaloms the heading deviates by a few degrees only.
* ``grade_rad``: **positive = uphill ahead**; gravity's body-x component is ``-g sin(grade)``, a
  car at rest uphill measures ``ax = +g sin(grade)``.
* On a bank the yaw rate ``r`` is about the tilted body z axis (what the gyro measures); the
  heading (about the vertical) changes at ``-r / cos(bank)``, and the horizontal velocity uses
  ``vx cos(grade)``, ``vy cos(bank)``.
* Body roll is quasi-static, ``roll = roll_gradient * fy / g`` with the ISO sign (positive = left
  side up), so in a left turn (``fy > 0``) the body leans outwards, to the right. A body-fixed
  accelerometer thus reads ``acc_y = fy cos(roll) + fz sin(roll)``, about 5 % more than the
  in-plane ``fy`` at the default 3 deg/g; ``roll_gradient_rad_per_g = 0`` switches this off.

Integration: semi-implicit Euler at 1 kHz. The wheel spin equations are stiff at low speed (slip
stiffness over speed), so each wheel is advanced with its tyre and brake torque linearised
implicitly; body states use the forces of the current step. This is unconditionally stable for
the wheels and needs one force evaluation per step (fast in plain Python). Deterministic: no
randomness here at all.

Tyre relaxation (``TyreParams.relaxation_length_m`` > 0 on an axle): each of its tyres
produces its force from a lagged lateral slip (:func:`~ecu_daemon.sim.tyre.relax_step`, a
lag of sigma / v), one more state per wheel. It starts equal to the kinematic slip (a flying start
is in equilibrium) and is zero while latched at standstill. The truth columns ``alpha_f`` /
``alpha_r`` stay the kinematic slip angles (the wheel's velocity direction), not the lagged
ones. With 0 (the default) none of this runs and the model is the instant-tyre one, bit for bit.

Standstill: a stopped car held by the brakes is *latched* (all speeds exactly 0) while the driver
holds it; this avoids sub-mm/s creep of a regularised slip model on a bank.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from . import tyre as tyre_mod
from .tyre import TyreParams

G = 9.80665


@dataclass(frozen=True)
class VehicleParams:
    """A mid-size front-wheel-drive saloon (the defaults)."""

    mass_kg: float = 1600.0
    yaw_inertia_kgm2: float = 2600.0
    lf_m: float = 1.2  # CG to front axle
    lr_m: float = 1.5  # CG to rear axle
    track_m: float = 1.58
    cg_height_m: float = 0.55
    wheel_radius_m: float = 0.32  # true effective rolling radius
    wheel_inertia_kgm2: float = 1.2  # wheel + brake disc + share of driveline
    steering_ratio: float = 15.0  # steering-wheel angle / road-wheel angle
    ackermann: float = 1.0  # 1 = full Ackermann geometry, 0 = parallel steering
    roll_stiffness_front_share: float = 0.55  # share of lateral load transfer taken by the front axle
    roll_gradient_rad_per_g: float = math.radians(3.0)  # body roll per g of lateral specific force
    suspension_lag_s: float = 0.05  # first-order lag of load transfer and roll
    # Front stiffness is lower per unit load than the rear's: it lumps in steering compliance.
    tyre_front: TyreParams = field(default_factory=lambda: TyreParams(ky1=15.0))
    tyre_rear: TyreParams = field(default_factory=lambda: TyreParams(ky1=21.0))
    driven_axle: str = "front"  # front | rear | all
    max_drive_power_w: float = 110e3
    max_drive_force_n: float = 7000.0
    brake_front_share: float = 0.65
    drag_area_m2: float = 0.68  # Cd * A
    air_density: float = 1.2
    rolling_resistance: float = 0.012

    @property
    def wheelbase_m(self) -> float:
        return self.lf_m + self.lr_m

    def static_axle_loads(self, bank_rad: float = 0.0, grade_rad: float = 0.0) -> tuple[float, float]:
        """(front, rear) axle loads at rest on a flat road (N)."""
        w = self.mass_kg * G * math.cos(bank_rad) * math.cos(grade_rad)
        return w * self.lr_m / self.wheelbase_m, w * self.lf_m / self.wheelbase_m

    def axle_cornering_stiffness(self) -> tuple[float, float]:
        """Linearised (Cf, Cr) per axle in N/rad at static load, straight ahead: the 'true' values."""
        ff, fr = self.static_axle_loads()
        return (2.0 * self.tyre_front.cornering_stiffness(ff / 2.0),
                2.0 * self.tyre_rear.cornering_stiffness(fr / 2.0))

    def understeer_gradient(self) -> float:
        """Linear understeer gradient (rad of road-wheel angle per m/s^2 of lateral acceleration)."""
        cf, cr = self.axle_cornering_stiffness()
        return self.mass_kg / self.wheelbase_m * (self.lr_m / cf - self.lf_m / cr)

    def scaled(self, mass: float = 1.0, inertia: float = 1.0, cf: float = 1.0, cr: float = 1.0) -> "VehicleParams":
        """A copy with mass / inertia / front / rear cornering stiffness scaled (for 'wrong' configs)."""
        return replace(self, mass_kg=self.mass_kg * mass, yaw_inertia_kgm2=self.yaw_inertia_kgm2 * inertia,
                       tyre_front=replace(self.tyre_front, ky1=self.tyre_front.ky1 * cf),
                       tyre_rear=replace(self.tyre_rear, ky1=self.tyre_rear.ky1 * cr))


@dataclass(frozen=True)
class Road:
    mu: float = 1.0
    bank_rad: float = 0.0
    grade_rad: float = 0.0
    #: a :class:`~ecu_daemon.sim.road.RoadProfile`: bank and grade follow the distance travelled
    #: (``bank_rad`` / ``grade_rad`` are then ignored)
    profile: object = None
    #: ``(t, mu)``: from the absolute time ``t`` on the friction is ``mu`` (rain starting on a dry
    #: road: the tyres' cornering stiffness stays, their peak force falls); None: ``mu`` throughout
    mu_change: tuple | None = None


class VehicleState(NamedTuple):
    """What the driver model may look at (its 'eyes and seat of the pants'): truth values."""

    t: float
    vx: float
    vy: float
    r: float
    psi: float
    north: float
    east: float
    steer_sw: float
    omega: tuple
    kappa: tuple
    ay: float


class Commands(NamedTuple):
    """Driver outputs, held between driver updates."""

    steer_sw: float  # steering-wheel angle command (rad, positive left)
    drive_torque: tuple  # per wheel (fl, fr, rl, rr), N m, < 0 in reverse gear
    brake_torque: tuple  # per wheel, N m, >= 0 (opposes rotation)
    hold: bool  # brake hold at standstill requested


#: Column names of the truth array produced by :func:`integrate`: one row per integration step,
#: the state at ``t`` and the forces / accelerations computed from it.
TRUTH_COLUMNS = (
    "t", "vx", "vy", "r", "psi", "north", "east", "steer_sw", "delta",
    "omega_fl", "omega_fr", "omega_rl", "omega_rr",
    "fx", "fy",  # specific force in the road-plane body frame (what a level-mounted IMU reads), m/s^2
    "ax", "ay",  # kinematic acceleration of the CG in body axes: dvx/dt - r vy, dvy/dt + r vx
    "acc_x", "acc_y",  # specific force in the rolled body frame (an ideal body-fixed accelerometer)
    "roll", "alpha_f", "alpha_r",
    "fz_fl", "fz_fr", "fz_rl", "fz_rr",
    "bank", "grade", "dist",  # the road under the car (constant unless Road.profile), distance travelled
)


@dataclass
class TruthArrays:
    """Truth at every integration step; ``col(name)`` gives one column as a numpy array."""

    data: np.ndarray  # shape (n, len(TRUTH_COLUMNS))
    dt: float
    road: Road
    params: VehicleParams
    spin_time: float | None = None  # first time |sideslip| exceeded the spin threshold, else None
    max_abs_sideslip: float = 0.0

    def col(self, name: str) -> np.ndarray:
        return self.data[:, TRUTH_COLUMNS.index(name)]

    @property
    def t(self) -> np.ndarray:
        return self.col("t")


SPIN_SIDESLIP_RAD = math.radians(25.0)  # |beta| above this at speed = spun out (not controllable)
# |beta| here is the velocity's angle off the body's long axis in [0, 90] deg, at speed > 3 m/s


def steady_cornering(params: VehicleParams, v: float, radius_m: float, left: bool = True) -> tuple[float, float, float]:
    """(vy, yaw rate, steering-wheel angle) of steady cornering at ``v`` on ``radius_m``, linear model.

    The start state of a flying start mid-corner: close enough to equilibrium that the model
    settles within a second (load transfer and tyre saturation are not in the linear model).
    """
    sign = 1.0 if left else -1.0
    cf, cr = params.axle_cornering_stiffness()
    L = params.wheelbase_m
    ay = v * v / radius_m
    alpha_r = params.mass_kg * params.lf_m / L * ay / cr
    beta = params.lr_m / radius_m - alpha_r
    delta = L / radius_m + params.understeer_gradient() * ay
    return sign * v * math.tan(beta), sign * v / radius_m, sign * delta * params.steering_ratio


def integrate(params: VehicleParams, road: Road, driver, t0: float, duration: float, *,
              dt: float = 1e-3, psi0: float = 0.0, driver_every: int = 10,
              v0: float = 0.0, vy0: float = 0.0, r0: float = 0.0, steer0: float = 0.0) -> TruthArrays:
    """Run the model from rest (or a flying start: ``v0``, ``vy0``, ``r0``, ``steer0``) for ``duration`` s.

    ``driver.update(state: VehicleState) -> Commands`` is called every ``driver_every`` steps
    (100 Hz at the default 1 kHz), like a real driver / controller sampling its senses.
    """
    p = params
    m, iz = p.mass_kg, p.yaw_inertia_kgm2
    lf, lr, half_t, h, L = p.lf_m, p.lr_m, p.track_m / 2.0, p.cg_height_m, p.wheelbase_m
    R, iw = p.wheel_radius_m, p.wheel_inertia_kgm2
    tf, tr = p.tyre_front, p.tyre_rear
    forces = tyre_mod.forces
    relax_step = tyre_mod.relax_step
    sig_f, sig_r = tf.relaxation_length_m, tr.relaxation_length_m
    relax = sig_f > 0.0 or sig_r > 0.0
    ta_lag = [None] * 4  # relaxed tan(alpha) per wheel (None: not yet started, take the kinematic)
    mu = road.mu
    t_mu, mu_new = road.mu_change if road.mu_change is not None else (math.inf, mu)
    prof = road.profile
    bank, grade = (road.bank_rad, road.grade_rad) if prof is None else (float(prof.bank_at(0.0)),
                                                                       float(prof.grade_at(0.0)))
    sb, cb = math.sin(bank), math.cos(bank)
    sg, cg = math.sin(grade), math.cos(grade)
    gx, gy = -G * sg, -G * sb * cg  # gravity in the road-plane body frame
    fz_tot = m * G * cb * cg
    dist = 0.0
    if prof is not None:  # tabulate the profile every 0.1 m once: np.interp per step is slow
        _len = float(max(k[0] for k in prof.bank + prof.grade)) + 100.0
        _s = np.arange(0.0, _len, 0.1)
        _bank, _grade = prof.bank_at(_s).tolist(), prof.grade_at(_s).tolist()
        _nmax = len(_s) - 1
    chi_f = p.roll_stiffness_front_share
    k_roll = p.roll_gradient_rad_per_g / G
    lag = min(1.0, dt / p.suspension_lag_s) if p.suspension_lag_s > 0 else 1.0
    drag = 0.5 * p.air_density * p.drag_area_m2
    f_rr = p.rolling_resistance
    ratio = p.steering_ratio
    ack = p.ackermann
    v_eps = 1.0  # slip regularisation speed (m/s)
    w_eps = 0.5  # brake / rolling-resistance torque smoothing (rad/s)
    xs = (lf, lf, -lr, -lr)
    ys = (half_t, -half_t, half_t, -half_t)

    vx, vy, r = v0, vy0, r0
    psi, north, east = psi0, 0.0, 0.0
    om = [v0 / R] * 4
    kap = [0.0] * 4
    steer = steer0
    fxf, fyf = -gx, -gy  # filtered specific force (load transfer, roll); at rest = -gravity
    latched = v0 == 0.0
    n = int(round(duration / dt)) + 1
    rows = []
    cmd = None
    spin_time = None
    max_beta = 0.0
    rate_limit = math.radians(1000.0) * dt  # steering-wheel rate limit per step (driver + EPS)
    for i in range(n):
        t = t0 + i * dt
        if t >= t_mu:
            mu = mu_new
        if prof is not None:  # the road under the car now: gravity's components and the normal load
            j = min(int(dist * 10.0), _nmax)
            bank, grade = _bank[j], _grade[j]
            sb, cb = math.sin(bank), math.cos(bank)
            sg, cg = math.sin(grade), math.cos(grade)
            gx, gy = -G * sg, -G * sb * cg
            fz_tot = m * G * cb * cg
        if i % driver_every == 0:
            cmd = driver.update(VehicleState(t, vx, vy, r, psi, north, east, steer, tuple(om), tuple(kap),
                                             fyf + gy))
        # steering actuator
        ds = cmd.steer_sw - steer
        steer += rate_limit if ds > rate_limit else (-rate_limit if ds < -rate_limit else ds)
        delta = steer / ratio
        # loads (quasi-static transfer from the lagged specific force)
        fzf = fz_tot * lr / L - m * fxf * h / L
        fzr = fz_tot * lf / L + m * fxf * h / L
        dfl = m * fyf * h / (2.0 * half_t)
        fz = (max(0.0, fzf / 2.0 - chi_f * dfl), max(0.0, fzf / 2.0 + chi_f * dfl),
              max(0.0, fzr / 2.0 - (1.0 - chi_f) * dfl), max(0.0, fzr / 2.0 + (1.0 - chi_f) * dfl))
        roll = k_roll * fyf
        if latched and cmd.hold:
            vx = vy = r = 0.0
            om = [0.0, 0.0, 0.0, 0.0]
            new_om = om
            kap = [0.0] * 4
            fx_s, fy_s = -gx, -gy
            ax = ay = dvx = dvy = dr_ = 0.0
            alpha_f = alpha_r = 0.0
            if relax:
                ta_lag = [0.0] * 4
        else:
            latched = False
            # Ackermann: the inner wheel steers more; left is inner when delta > 0
            if delta != 0.0 and ack > 0.0:
                td = math.tan(delta)
                dl = math.atan(L * td / (L - ack * half_t * td))
                dr = math.atan(L * td / (L + ack * half_t * td))
            else:
                dl = dr = delta
            sfx = sfy = mz = 0.0
            new_om = [0.0] * 4
            alpha_f = alpha_r = 0.0
            for w in range(4):
                xw, yw = xs[w], ys[w]
                d = dl if w == 0 else (dr if w == 1 else 0.0)
                vxw = vx - r * yw
                vyw = vy + r * xw
                if d != 0.0:
                    cd, sd = math.cos(d), math.sin(d)
                    vl = vxw * cd + vyw * sd
                    vt = -vxw * sd + vyw * cd
                else:
                    cd, sd = 1.0, 0.0
                    vl, vt = vxw, vyw
                avl = vl if vl >= 0.0 else -vl
                vd = avl if avl > v_eps else v_eps
                kappa = (om[w] * R - vl) / vd
                ta = -vt / vd
                tf_ = ta  # the slip the tyre's force follows
                if relax:
                    sig = sig_f if w < 2 else sig_r
                    if sig > 0.0:
                        tl = ta_lag[w]
                        tf_ = ta if tl is None else tl  # the force of the deflection now
                        ta_lag[w] = relax_step(tf_, ta, vd, sig, dt)
                if w < 2:
                    fxw, fyw = forces(tf, fz[w], mu, kappa, tf_)
                    alpha_f += 0.5 * math.atan(ta)
                    kx = tf.kx1 * fz[w]
                else:
                    fxw, fyw = forces(tr, fz[w], mu, kappa, tf_)
                    alpha_r += 0.5 * math.atan(ta)
                    kx = tr.kx1 * fz[w]
                kap[w] = kappa
                bx = fxw * cd - fyw * sd
                by = fxw * sd + fyw * cd
                sfx += bx
                sfy += by
                mz += xw * by - yw * bx
                # wheel spin: implicit in the tyre slip stiffness and the brake / rolling torques
                th = math.tanh(om[w] / w_eps)
                tb = cmd.brake_torque[w] + f_rr * fz[w] * R
                torque = cmd.drive_torque[w] - tb * th - R * fxw
                dtorque = R * R * kx / vd + tb * (1.0 - th * th) / w_eps
                new_om[w] = om[w] + dt * torque / (iw + dt * dtorque)
            fx_s = (sfx - drag * vx * (vx if vx >= 0 else -vx)) / m
            fy_s = sfy / m
            ax = fx_s + gx
            ay = fy_s + gy
            dvx = ax + r * vy
            dvy = ay - r * vx
            dr_ = mz / iz
            # the velocity's angle off the body's long axis, either way (a car rolling backwards
            # straight is not sliding); by the speed, not vx: a spin passes vx ~ 0 at speed
            # (the lead's trace of a flying start on mu 0.22 at 28 m/s: 180 deg round, then -20 m/s
            # tail first, spun_out False: by vx > 3 its |beta| > 25 deg was never looked at)
            if vx * vx + vy * vy > 9.0:
                beta = math.atan2(abs(vy), abs(vx))
                if beta > max_beta:
                    max_beta = beta
                if beta > SPIN_SIDESLIP_RAD and spin_time is None:
                    spin_time = t
        fz_s = (fz[0] + fz[1] + fz[2] + fz[3]) / m
        acc_y = fy_s * math.cos(roll) + fz_s * math.sin(roll)
        rows.append((t, vx, vy, r, psi, north, east, steer, delta, om[0], om[1], om[2], om[3],
                     fx_s, fy_s, ax, ay, fx_s, acc_y, roll, alpha_f, alpha_r, fz[0], fz[1], fz[2], fz[3], bank, grade, dist))
        # advance: velocities first, then pose with the new velocities (semi-implicit Euler)
        vx += dt * dvx
        vy += dt * dvy
        r += dt * dr_
        om = new_om
        # |vx|: a car still reversing at 0.5 m/s when the driver's hold comes (manoeuvres.Driver: below
        # 0.5 m/s) is braked to rest like a forward one, not latched at once (an instant stop from -0.5 m/s
        # in the truth, which no estimator can follow: random drives 3292, 3422 ... at the reverse's end)
        if cmd.hold and not latched and -0.1 < vx < 0.1 and -0.1 < vy < 0.1:
            latched = True
        psi -= dt * r / cb
        cps, sps = math.cos(psi), math.sin(psi)
        vhx, vhy = vx * cg, vy * cb
        north += dt * (vhx * cps + vhy * sps)
        east += dt * (vhx * sps - vhy * cps)
        dist += dt * math.hypot(vx, vy)
        fxf += lag * (fx_s - fxf)
        fyf += lag * (fy_s - fyf)
    data = np.array(rows, dtype=float)
    return TruthArrays(data=data, dt=dt, road=road, params=params, spin_time=spin_time,
                       max_abs_sideslip=max_beta)
