"""Road grade and bank, and the body's roll on its suspension: a small filter beside the main one.

Why beside it: the main filter's accelerometer-bias states hold sums it has no need to split,
``b_ax = o_x + g sin(grade)`` and ``b_ay = o_y + g (1 + g_ay) sin(bank) cos(grade)`` (``o``: the
sensor's own zero offset; ``g_ay``: the lateral gain error, i.e. body roll, see ``kinematic.py``);
its velocity model uses the sums. Splitting them needs slow, separate information about the
offsets, so two 2-state Kalman filters do it here and the 8-state filter stays as it is:

* grade ``[grade, o_x]``: the main filter's ``b_ax`` (its variance inflated for the correlation of
  successive values, and for the road it averaged: a grade walks per metre travelled, see
  ``GRADE_WALK_M``), and the GNSS vertical velocity (UBX velD): at speed
  ``tan(grade) = -v_down / v_horizontal`` measures grade directly and so makes ``o_x`` observable.
  NMEA has no vertical velocity; its GGA altitude differenced over the distance travelled measures
  the grade instead (``altitude_grade.py``, its own noise model and gate); without an altitude grade
  rests on the offset's prior. Nor, in effect, does a
  capture whose velD is exactly 0: that is what encoders write when they have no vertical velocity
  (our own real-data tools do), while a real receiver's noise makes an exact 0 mm/s rare at speed;
  such fixes are skipped and counted, never taken as "flat".
* bank ``[bank, o_y]``: the main filter's ``b_ay`` only. A constant bank and a constant offset
  read the same in every sensor the daemon has, so ``o_y`` keeps its prior (configured, or what
  earlier drives left) and the bank's std never drops below ``prior / g``: it is flagged valid
  only when that prior is tight enough.

Roll (the body on its suspension, relative to the road plane; ISO sign: left side up):
``roll = (g_ay / g) f_y``, ``f_y`` the lateral specific force. A rolled accelerometer reads
``g sin(roll)`` more, which is the gain error the main filter learns, so ``g_ay / g`` is the roll
gradient (rad per m/s^2); its std adds a floor for the accelerometer's own scale error. The body
follows the force through its damped suspension, so ``f_y`` is lagged (``ROLL_LAG_S``) and the size
of that lag's correction is counted in the std as wholly uncertain (real suspensions differ). Where
the road's bank changes, the gain takes part of the change as roll: the roll's std counts the bank
variance the main filter's b_ay walk charged (:meth:`RoadAttitude.step`).

Two optional sources make bank (and grade) observable and the roll better:

* a dual-antenna baseline's **elevation** (u-blox NAV-RELPOSNED relPosD against relPosN/E, see
  :class:`BaselineMount`): across the car it is bank + body roll, along it grade + body pitch, at
  any speed. It is fused at its time of validity (the body roll of that step, kept in a short
  ring) into the channel the baseline leans on, with noise from the receiver's accD (only a
  fixed carrier solution), its own gate, and the body roll's (or pitch's) uncertainty counted as
  correlated over ``ELEVATION_CORR`` samples. The mounting elevation's std is a bias no number
  of samples removes: a floor under the published std of that channel.
* a **roll-rate gyro** (``[inputs.roll_rate]``, :class:`RollGyro`): ``[roll, gyro bias, roll
  gradient]``, the gyro integrated every step and the suspension model ``roll = k f_y`` (lagged)
  as a pseudo-measurement; the gyro sees each change of the lateral force turn into roll, which
  identifies the roll gradient directly (the gain state mixes it with the accelerometer's own
  scale error and learns it only slowly), and fills the suspension's transients.

Angles: grade positive uphill ahead, bank positive left side up (road falls to the right), as
the simulator's ``vehicle.py``; all in rad.
"""
from __future__ import annotations

import logging
import math

import numpy as np

from ..gravity import G
from . import kalman
from .altitude_grade import ALT_GATE_SIGMA, AltitudeGrade
from .roll_gyro_check import RollGyroCheck

log = logging.getLogger(__name__)

UPDATE_EVERY = 17  # main-filter steps between updates from its bias states (~0.1 s)
CORRELATION_S = 5.0  # the main filter's bias estimates are correlated over about this long
ANGLE_WALK = math.radians(0.3)  # rad/sqrt(s): how fast road grade and bank wander
#: rad/sqrt(m): the grade's walk per metre travelled. Roads change grade over vertical curves
#: designed by their K value, tens of metres per % of grade change: K 20 m/% over a 100 m curve is a
#: 5 % (2.9 deg) change, 0.29 deg/sqrt(m) as a random walk; K 50 m/% over 200 m, 0.16. (Per second
#: the old 0.3 deg/sqrt(s) is 0.07 deg/sqrt(m) at 20 m/s: a +-5 % grade over 500 m outran it.)
GRADE_WALK_M = math.radians(0.15)
#: rad: 1-sigma of the most a road's bank changes from one curve to the next (2.5 % crossfall to up
#: to 8 % superelevation the other way: ~6 deg at most), the cap of the roll's road doubt
BANK_SWING = math.radians(3.0)
#: m/s^2: above this lateral force the roll carries the whole road doubt (a bank change the gain
#: took shows as roll in proportion to the force, see RoadAttitude.set_roll)
ROLL_DOUBT_FORCE = 1.0
OFFSET_WALK = 2e-4  # m/s^2/sqrt(s): accelerometer offset drift (temperature)
ANGLE_PRIOR = math.radians(10.0)  # 1-sigma of an unknown road angle
OFFSET_LEARNED_FLOOR = 0.02  # m/s^2: a restored offset is never trusted better than this
VERTICAL_MIN_SPEED = 5.0  # m/s: below, v_down / v_horizontal is noise
VERTICAL_ACC_FACTOR = 1.5  # receivers' vertical velocity accuracy / their (horizontal) sAcc
GATE_SIGMA = 5.0
ANGLE_STD_VALID = math.radians(0.5)  # a valid grade / bank / roll promises this 1-sigma or better
GAIN_FLOOR = 0.02  # accelerometer scale error (datasheet sensitivity) the gain state holds besides roll
ROLL_LAG_S = 0.05  # the body follows the lateral force through its suspension, about this late
ELEVATION_GATE_SIGMA = 4.0
ELEVATION_ACC_FLOOR_M = 0.002  # accD below this: no moving-base receiver is that good in height
ELEVATION_CORR = 10  # samples (2 s at 5 Hz) over which the body roll's / pitch's error stays the same
PITCH_STD = math.radians(0.3)  # body pitch on its suspension (dive, squat): not modelled, allowed for
ROLL_UPDATE_EVERY = 3  # steps between suspension pseudo-measurements of the roll-rate filter
ROLL_MODEL_STD = math.radians(0.15)  # the suspension model's error (dynamics, road input) ...
ROLL_MODEL_CORR_S = 0.5  # ... which lasts about this long (so it is not averaged away faster)
ROLL_RATE_BIAS_PRIOR = math.radians(1.0)  # rad/s: a MEMS roll gyro's bias before it is learned
#: rad/s: a restored roll-gyro bias (learned-state file) is never trusted better than this: a MEMS
#: gyro's bias moves by about that much from one power-up to the next (as the yaw-rate bias's 0.3 deg/s)
ROLL_RATE_BIAS_LEARNED_FLOOR = math.radians(0.3)
ROLL_GRADIENT_WALK = 1e-5  # rad per m/s^2 per sqrt(s): load and tyre change the roll gradient slowly
#: roll gradients a car can have (rad per m/s^2: 0 to 10 deg/g; bodies lean out of the turn): one
#: outside says the gyro is not what its mapping claims (sign, scale), and the roll is not promised
ROLL_GRADIENT_RANGE = (0.0, math.radians(10.0) / G)


#: the Jacobian of a direct measurement of a channel's angle (GNSS vertical velocity, altitude),
#: built once instead of at every fix (issue 10); read-only, as the update only reads it
ANGLE_H = np.array([1.0, 0.0])
ANGLE_H.flags.writeable = False


class _Channel:
    """One ``[angle, offset]`` Kalman filter; the measurement is linearised per update."""

    def __init__(self, offset: float, offset_std: float):
        self.x = np.array([0.0, offset])
        self.P = np.diag([ANGLE_PRIOR ** 2, offset_std ** 2])
        # the same arrays for the every-step readers (std, RoadAttitude.set_roll): compiled, typed
        # memoryviews (road.pxd) whose reads are C doubles instead of numpy scalars; plain Python:
        # the arrays again. x and P are only ever changed in place, never rebound
        self._xm = self.x
        self._Pm = self.P
        self.updates = 0
        self.floor2 = 0.0  # variance of a bias under the angle no update removes (a mounting elevation)

    def predict(self, dt: float) -> None:
        self.P[0, 0] += ANGLE_WALK ** 2 * dt
        self.P[1, 1] += OFFSET_WALK ** 2 * dt

    def update(self, innovation: float, H: np.ndarray, R: float, gate: float = GATE_SIGMA) -> bool:
        # the numpy scalar update every source shares (Joseph form, gated); the compiled one is
        # sized for the 8-state filter
        if not (math.isfinite(innovation)
                and kalman.scalar_update_reference(self.x, self.P, innovation, H, R, gate)):
            return False
        self.updates += 1
        return True

    def gravity_update(self, b: float, var_b: float, gain: float) -> bool:
        """The main filter's bias sum ``b = offset + gain * g * sin(angle)``."""
        # the state as Python floats (ndarray.item): float arithmetic, not numpy scalar arithmetic,
        # the same IEEE operations on the same doubles (issue 10)
        a = self.x.item(0)
        h = self.x.item(1) + gain * G * math.sin(a)
        H = np.array([gain * G * math.cos(a), 1.0])
        return self.update(b - h, H, var_b)

    @property
    def std(self) -> float:
        if self.floor2:
            return math.sqrt(max(self._Pm[0, 0], 0.0) + self.floor2)
        return math.sqrt(max(self._Pm[0, 0], 0.0))


class BaselineMount:
    """A dual-antenna baseline whose elevation is fused: its heading offset from the vehicle's
    (rad, clockwise: 90 deg = pointing right) and its elevation on a level car (rad, rover above
    the base positive) with that elevation's std (rad)."""

    def __init__(self, offset_rad: float, elevation_rad: float, elevation_std_rad: float):
        self.sin, self.cos = math.sin(offset_rad), math.cos(offset_rad)
        self.elevation = elevation_rad
        self.elevation_std = elevation_std_rad

    def lateral(self) -> bool:
        """Across the car more than along it: its elevation is about bank (else about grade)."""
        return abs(self.sin) >= abs(self.cos)


class RollGyro:
    """Body roll ``[roll, gyro bias, roll gradient k]`` from a roll-rate gyro and the suspension.

    Predict: ``roll += (p_m - b_p - r sin(grade)) dt`` (the gyro measures the body's rate about
    its own x axis: on a grade a turn adds ``r sin(grade)`` to it; a change of bank passes through
    as roll until the suspension model pulls it back, so the bank's walk is process noise).
    Update every ``ROLL_UPDATE_EVERY`` steps: ``0 = roll - k f_lp`` (``f_lp`` the lagged lateral
    force), noise ``ROLL_MODEL_STD`` counted over its correlation time.
    """

    def __init__(self, dt: float, gyro_noise: float, bias_walk: float, roll: float, k: float, k_std: float,
                 f_lp: float, bias: float = 0.0, bias_std: float = ROLL_RATE_BIAS_PRIOR):
        """``bias`` / ``bias_std``: the gyro bias's prior (rad/s; a restored one, else 0 +- the
        datasheet's ``ROLL_RATE_BIAS_PRIOR``)."""
        self.dt = dt
        self.x = np.array([roll, bias, k])
        self.P = np.diag([(f_lp * k_std) ** 2 + ROLL_MODEL_STD ** 2, bias_std ** 2, k_std ** 2])
        self.F = np.array([[1.0, -dt, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        self.Q = np.diag([(gyro_noise ** 2 + ANGLE_WALK ** 2) * dt, bias_walk ** 2 * dt, ROLL_GRADIENT_WALK ** 2 * dt])
        self.R = ROLL_MODEL_STD ** 2 * ROLL_MODEL_CORR_S / (ROLL_UPDATE_EVERY * dt)
        self.n = 0
        self.rejected = 0
        self.last_rejected = False  # the last suspension pseudo-measurement was gated out

    def step(self, p_m: float, r: float, grade: float, f_lp: float, var_f: float) -> None:
        """One step: ``p_m`` the measured roll rate (NaN: stale, the roll is held and widened)."""
        x, P = self.x, self.P
        if p_m == p_m:
            x[0] += (p_m - x[1] - r * math.sin(grade)) * self.dt
            self.P = P = self.F @ P @ self.F.T + self.Q
        else:
            P[0, 0] += (ROLL_RATE_BIAS_PRIOR ** 2) * self.dt
        self.n += 1
        if self.n % ROLL_UPDATE_EVERY:
            return
        H = np.array([1.0, 0.0, -f_lp])
        y = x[2] * f_lp - x[0]
        self.last_rejected = not kalman.scalar_update_reference(x, P, y, H, self.R + x[2] * x[2] * var_f, GATE_SIGMA)
        if self.last_rejected:
            self.rejected += 1
            P[0, 0] += y * y  # the gyro and the suspension disagree: the roll is that uncertain

    def plausible(self) -> bool:
        """The learned roll gradient is one a car can have (else the gyro's mapping is wrong)."""
        lo, hi = ROLL_GRADIENT_RANGE
        k, sd = self.x[2], math.sqrt(max(self.P[2, 2], 0.0))
        return k + 3.0 * sd >= lo and k - 3.0 * sd <= hi


class RoadAttitude:
    """Grade, bank and roll from the main filter's state and GNSS vertical velocity (see module doc)."""

    def __init__(self, dt: float, offset_std: float, learned: dict,
                 baselines: list[BaselineMount | None] | None = None, history: int = 0,
                 roll_gyro: tuple[float, float] | None = None):
        """``baselines``: per receiver index, the baseline whose elevation is fused (None: not);
        ``history``: steps of body roll kept for their time of validity; ``roll_gyro``: the roll
        gyro's (noise, bias walk), None when no roll rate is mapped."""
        def prior(key: str) -> tuple[float, float]:
            if key in learned:
                return learned[key], max(learned.get(key.replace("_mps2", "_std_mps2"), offset_std),
                                         OFFSET_LEARNED_FLOOR)
            return 0.0, offset_std
        self.dt = dt
        self.dist = 0.0  # metres travelled since the last update (the grade's walk)
        self.bank_walk_seen = 0.0  # (m/s^2)^2: the main filter's road-driven b_ay variance counted so far
        self.var_gay_seen = 0.0
        self.roll_doubt = 0.0  # rad^2: road bank changes the main filter's gain may have taken as roll
        self.grade = _Channel(*prior("accel_x_offset_mps2"))
        self.bank = _Channel(*prior("accel_y_offset_mps2"))
        self.vertical_fused = 0
        self.vertical_zero = 0  # exact-0 velD fixes skipped (see module doc)
        self.altitude = AltitudeGrade(ANGLE_WALK)
        self.altitude_fused = 0
        self.altitude_rejected = 0
        self.roll = 0.0
        self.roll_std = math.pi
        self.fy_lp = math.nan
        self._lp = dt / (ROLL_LAG_S + dt)
        self.baselines = list(baselines) if baselines and any(baselines) else []
        self.elevation_fused = 0
        self.elevation_rejected = 0
        self._k = 0
        self._ring = np.full((max(history, 1), 3), np.nan) if any(self.baselines) else None
        self.roll_gyro_params = roll_gyro
        self.gyro: RollGyro | None = None
        self.roll_check: RollGyroCheck | None = None  # the gyro's mapping against the lateral force
        # the roll gyro's bias from an earlier drive (value, std), kept even while no gyro is mapped
        self.roll_bias0: tuple[float, float] | None = None
        if "roll_rate_bias_radps" in learned:
            self.roll_bias0 = (learned["roll_rate_bias_radps"],
                               max(learned.get("roll_rate_bias_std_radps", ROLL_RATE_BIAS_PRIOR),
                                   ROLL_RATE_BIAS_LEARNED_FLOOR))

    def step(self, k: int, b_ax: float, var_bax: float, b_ay: float, var_bay: float, g_ay: float,
             vx: float = 0.0, bank_walk: float = 0.0, var_gay: float = 0.0, update: bool = True) -> None:
        """Every step: the distance travelled (``vx``), the main filter's road-driven b_ay variance so
        far (``bank_walk``, :mod:`bank_walk`) and its gain's variance; every ``UPDATE_EVERY`` steps
        the walks, and (``update``: the accelerometers are heard) the bias sums at step k.

        The roll's road doubt: where the road's bank changes, the main filter splits the change of
        ``b_ay`` between ``b_ay`` and the gain ``g_ay`` (a bias and a gain read the same within one
        corner), and the gain's share is roll (``g_ay / g * f_y``) by as much as the bank moved. The
        main filter's own ``P[g_ay]`` does not hold it (its b_ay walk is sized for sideslip, and a
        country road's bank moves more), so it is counted here: the bank variance charged, capped at
        ``BANK_SWING``, shrunk as the main filter learns its gain (``P[g_ay]`` falling)."""
        self._k = k
        dv = bank_walk - self.bank_walk_seen
        self.bank_walk_seen = bank_walk
        if dv > 0.0:
            self.roll_doubt = min(self.roll_doubt + dv / (G * G), BANK_SWING * BANK_SWING)
        if 0.0 < var_gay < self.var_gay_seen:
            self.roll_doubt *= var_gay / self.var_gay_seen
        self.var_gay_seen = var_gay
        self.dist += abs(vx) * self.dt
        if k % UPDATE_EVERY:
            return
        period = UPDATE_EVERY * self.dt
        inflate = CORRELATION_S / period
        for ch in (self.grade, self.bank):
            ch.predict(period)
        # the grade moves where the car travels (vertical curves); the main filter's b_ax averages
        # the last CORRELATION_S of road, so it lags a changing grade by that much road's walk
        self.grade.P[0, 0] += GRADE_WALK_M * GRADE_WALK_M * self.dist
        lag_var = (G * GRADE_WALK_M) ** 2 * self.dist / period * CORRELATION_S
        self.dist = 0.0
        if not update:
            return
        self.grade.gravity_update(b_ax, (var_bax + lag_var) * inflate, 1.0)
        self.bank.gravity_update(b_ay, var_bay * inflate, (1.0 + g_ay) * math.cos(self.grade.x[0]))

    def fuse_vertical(self, vel_d: float, speed: float, speed_acc: float) -> bool:
        """A GNSS vertical velocity with its horizontal speed (m/s) and speed accuracy."""
        if not (math.isfinite(vel_d) and math.isfinite(speed_acc) and speed >= VERTICAL_MIN_SPEED):
            return False
        if vel_d == 0.0:
            self.vertical_zero += 1
            return False
        z = math.atan2(-vel_d, speed)
        R = (VERTICAL_ACC_FACTOR * speed_acc / speed) ** 2
        if self.grade.update(z - self.grade.x.item(0), ANGLE_H, R):
            self.vertical_fused += 1
            return True
        return False

    def fuse_altitude(self, g, speed: float, forward: bool) -> bool:
        """A fused fix (``GnssSample``): its speed extends the distance travelled, its altitude
        (NMEA GGA, at its own epoch) closes a segment whose climb measures the grade."""
        alt = self.altitude
        alt.speed(g.fix_time_utc_s, speed, forward)
        m = alt.measure(g.alt_m, g.alt_time_utc_s)
        if m is None:
            return False
        z, R = m
        if self.grade.update(z - self.grade.x.item(0), ANGLE_H, R, ALT_GATE_SIGMA):
            self.altitude_fused += 1
            return True
        self.altitude_rejected += 1
        return False

    def set_roll(self, ay_m: float, g_ay: float, var_gay: float, ay_doubt: float = 0.0) -> None:
        """Body roll from the measured lateral acceleration ``ay_m`` and the gain state;
        ``ay_doubt`` (m/s^2): how far ``ay_m`` disagrees with its witness (yaw rate x speed), a
        possible error of the force the roll is computed from (a sensor fault not yet isolated)."""
        # the offset as a Python float (plain Python: a numpy scalar read, which would keep the
        # force's low-pass and the roll numpy scalars for the drive; compiled, a C double either way)
        fy = (ay_m - float(self.bank._xm[1])) / (1.0 + g_ay)
        lp = self.fy_lp = fy if self.fy_lp != self.fy_lp else self.fy_lp + self._lp * (fy - self.fy_lp)
        self.roll = g_ay / G * lp
        k2 = (g_ay * g_ay + var_gay) / (G * G)  # the roll gradient's square, its uncertainty included
        d = fy - lp  # squared as d * d: compiled, gcc turns pow(d, 2.0) into d * d, which differs
        # from Python's d ** 2 (libm pow) in the last bit for ~1 in 1000 values
        self.roll_std = math.sqrt((lp / G) ** 2 * (var_gay + GAIN_FLOOR ** 2) + k2 * (d * d)
                                  + k2 * (self.bank._Pm[1, 1] + ay_doubt * ay_doubt)
                                  + self.roll_doubt * min(1.0, lp * lp / (ROLL_DOUBT_FORCE * ROLL_DOUBT_FORCE)))
        if self._ring is not None:
            self._ring[self._k % len(self._ring)] = (self._k, self.roll, self.roll_std)

    def set_roll_gyro(self, ay_m: float, g_ay: float, var_gay: float, ay_doubt: float, p_m: float, r: float) -> None:
        """Body roll with a roll-rate gyro (``p_m``, rad/s; NaN when stale) and the body yaw rate
        ``r``: :class:`RollGyro`, started from the suspension model of :meth:`set_roll`.

        The gyro's mapping is judged by :class:`roll_gyro_check.RollGyroCheck`: found wrong, the
        roll is the suspension model's (:meth:`set_roll`, which also keeps the force's low-pass);
        not yet judged (before the first turn), the gyro's, with a std that also covers its
        disagreement with the model (a right gyro is then invalid at worst, in the first turn-in,
        while the model's early roll gradient is still poor: 1.6 deg off in roll_rate_dlc's)."""
        self.set_roll(ay_m, g_ay, var_gay, ay_doubt)
        lp = self.fy_lp
        var_f = self.bank.P[1, 1] + ay_doubt * ay_doubt
        gy = self.gyro
        if gy is None:
            k_std = math.sqrt(var_gay + GAIN_FLOOR ** 2) / G
            gy = self.gyro = RollGyro(self.dt, *self.roll_gyro_params, g_ay / G * lp, g_ay / G, k_std, lp,
                                      *(self.roll_bias0 or ()))
            self.roll_check = RollGyroCheck(self.dt)
        grade = float(self.grade.x[0])
        p = p_m - gy.x[1] - r * math.sin(grade)
        gy.step(p_m, r, grade, lp, var_f)
        chk = self.roll_check
        was = chk.wrong
        if chk.step(p, lp) and not was:
            log.warning("[inputs.roll_rate]: its roll does not follow the lateral force (roll gradient %.2f "
                        "deg/g, correlation %.2f): %s; roll from the suspension model until it does",
                        math.degrees(chk.gradient * G), chk.corr, chk.likely())
        if chk.wrong:  # the suspension model's roll (set_roll's, above)
            return
        roll_m, std_m = self.roll, self.roll_std
        self.roll = float(gy.x[0])
        self.roll_std = math.sqrt(max(gy.P[0, 0], 0.0) + gy.x[2] * gy.x[2] * var_f) if gy.plausible() else math.pi
        if not chk.trusted:
            d = self.roll - roll_m
            self.roll_std = math.sqrt(self.roll_std * self.roll_std + std_m * std_m + d * d)
        if self._ring is not None:
            self._ring[self._k % len(self._ring)] = (self._k, self.roll, self.roll_std)

    def fuse_elevation(self, s: int, g) -> bool:
        """A dual-antenna sample's baseline elevation (``GnssHeadingSample`` with ``down_m``), valid
        at step s, into bank (a lateral baseline) or grade (a longitudinal one); counted."""
        mount = self.baselines[g.source] if 0 <= g.source < len(self.baselines) else None
        if mount is None:
            return False
        d, hz, acc = g.down_m, g.horizontal_m, g.down_acc_m
        if not (g.valid and g.carr_soln == 2 and math.isfinite(d) and math.isfinite(acc) and hz > 0.0):
            self.elevation_rejected += 1  # no fixed carrier solution: decimetres in height
            return False
        length = math.hypot(hz, d)
        z = math.atan2(-d, hz) - mount.elevation
        var_z = (max(acc, ELEVATION_ACC_FLOOR_M) / length) ** 2
        row = self._ring[s % len(self._ring)] if self._ring is not None else None
        if row is not None and row[0] == s:
            roll, roll_std = float(row[1]), float(row[2])
        else:  # that step's roll is not kept (the IMU was out): today's, no better than its std
            roll, roll_std = self.roll, self.roll_std
        gam = float(self.grade.x[0])
        phi = float(self.bank.x[0]) + roll
        so, co = mount.sin, mount.cos
        u = max(-1.0, min(1.0, co * math.sin(gam) - so * math.cos(gam) * math.sin(phi)))
        c = max(math.sqrt(1.0 - u * u), 1e-6)
        d_phi = -so * math.cos(gam) * math.cos(phi) / c
        d_gam = (co * math.cos(gam) + so * math.sin(gam) * math.sin(phi)) / c
        roll_var = roll_std * roll_std * ELEVATION_CORR
        if mount.lateral():
            ch, H = self.bank, np.array([d_phi, 0.0])
            R = var_z + d_gam * d_gam * self.grade.P[0, 0] + d_phi * d_phi * roll_var
            floor = mount.elevation_std / abs(d_phi)
        else:
            ch, H = self.grade, np.array([d_gam, 0.0])
            R = (var_z + d_phi * d_phi * (self.bank.P[0, 0] + roll_var)
                 + d_gam * d_gam * PITCH_STD * PITCH_STD * ELEVATION_CORR)
            floor = mount.elevation_std / abs(d_gam)
        if ch.update(z - math.asin(u), H, R, ELEVATION_GATE_SIGMA):
            ch.floor2 = floor * floor
            self.elevation_fused += 1
            return True
        self.elevation_rejected += 1
        return False

    def valid(self, ch: _Channel) -> bool:  # core.Estimator._road has this test inline (issue 10)
        return ch.updates > 0 and ch.std < ANGLE_STD_VALID

    def learned(self) -> dict:
        """The sensor offsets and (with a roll gyro, or restored from an earlier drive) the roll
        gyro's bias, with their stds: the next drive's priors."""
        out = {"accel_x_offset_mps2": float(self.grade.x[1]),
               "accel_x_offset_std_mps2": float(math.sqrt(self.grade.P[1, 1])),
               "accel_y_offset_mps2": float(self.bank.x[1]),
               "accel_y_offset_std_mps2": float(math.sqrt(self.bank.P[1, 1]))}
        if self.gyro is not None:
            out["roll_rate_bias_radps"] = float(self.gyro.x[1])
            out["roll_rate_bias_std_radps"] = float(math.sqrt(max(self.gyro.P[1, 1], 0.0)))
        elif self.roll_bias0 is not None:
            out["roll_rate_bias_radps"], out["roll_rate_bias_std_radps"] = map(float, self.roll_bias0)
        return out
