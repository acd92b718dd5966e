"""Road grade and bank, and the body's roll on its suspension: a small filter beside the main one.

Why beside it: the main filter's accelerometer-bias states hold sums it has no need to split,
``b_ax = o_x + g sin(grade)`` and ``b_ay = o_y + g (1 + g_ay) sin(bank) cos(grade)`` (``o``: the
sensor's own zero offset; ``g_ay``: the lateral gain error, i.e. body roll, see ``kinematic.py``);
its velocity model uses the sums. Splitting them needs slow, separate information about the
offsets, so two 2-state Kalman filters do it here and the 8-state filter stays as it is:

* grade ``[grade, o_x]``: the main filter's ``b_ax`` (its variance inflated for the correlation of
  successive values), and the GNSS vertical velocity (UBX velD): at speed
  ``tan(grade) = -v_down / v_horizontal`` measures grade directly and so makes ``o_x`` observable.
  NMEA has no vertical velocity: grade then rests on the offset's prior. Nor, in effect, does a
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
of that lag's correction is counted in the std as wholly uncertain (real suspensions differ).

Angles: grade positive uphill ahead, bank positive left side up (road falls to the right), as
the simulator's ``vehicle.py``; all in rad.
"""
from __future__ import annotations

import math

import numpy as np

from . import kalman

G = 9.80665
UPDATE_EVERY = 17  # main-filter steps between updates from its bias states (~0.1 s)
CORRELATION_S = 5.0  # the main filter's bias estimates are correlated over about this long
ANGLE_WALK = math.radians(0.3)  # rad/sqrt(s): how fast road grade and bank wander
OFFSET_WALK = 2e-4  # m/s^2/sqrt(s): accelerometer offset drift (temperature)
ANGLE_PRIOR = math.radians(10.0)  # 1-sigma of an unknown road angle
OFFSET_LEARNED_FLOOR = 0.02  # m/s^2: a restored offset is never trusted better than this
VERTICAL_MIN_SPEED = 5.0  # m/s: below, v_down / v_horizontal is noise
VERTICAL_ACC_FACTOR = 1.5  # receivers' vertical velocity accuracy / their (horizontal) sAcc
GATE_SIGMA = 5.0
ANGLE_STD_VALID = math.radians(0.5)  # a valid grade / bank / roll promises this 1-sigma or better
GAIN_FLOOR = 0.02  # accelerometer scale error (datasheet sensitivity) the gain state holds besides roll
ROLL_LAG_S = 0.05  # the body follows the lateral force through its suspension, about this late


class _Channel:
    """One ``[angle, offset]`` Kalman filter; the measurement is linearised per update."""

    def __init__(self, offset: float, offset_std: float):
        self.x = np.array([0.0, offset])
        self.P = np.diag([ANGLE_PRIOR ** 2, offset_std ** 2])
        self.updates = 0

    def predict(self, dt: float) -> None:
        self.P[0, 0] += ANGLE_WALK ** 2 * dt
        self.P[1, 1] += OFFSET_WALK ** 2 * dt

    def update(self, innovation: float, H: np.ndarray, R: float) -> bool:
        # the numpy scalar update every source shares (Joseph form, gated); the compiled one is
        # sized for the 8-state filter
        if not (math.isfinite(innovation)
                and kalman.scalar_update_reference(self.x, self.P, innovation, H, R, GATE_SIGMA)):
            return False
        self.updates += 1
        return True

    def gravity_update(self, b: float, var_b: float, gain: float) -> bool:
        """The main filter's bias sum ``b = offset + gain * g * sin(angle)``."""
        a = self.x[0]
        h = self.x[1] + gain * G * math.sin(a)
        H = np.array([gain * G * math.cos(a), 1.0])
        return self.update(b - h, H, var_b)

    @property
    def std(self) -> float:
        return math.sqrt(max(self.P[0, 0], 0.0))


class RoadAttitude:
    """Grade, bank and roll from the main filter's state and GNSS vertical velocity (see module doc)."""

    def __init__(self, dt: float, offset_std: float, learned: dict):
        def prior(key: str) -> tuple[float, float]:
            if key in learned:
                return learned[key], max(learned.get(key.replace("_mps2", "_std_mps2"), offset_std),
                                         OFFSET_LEARNED_FLOOR)
            return 0.0, offset_std
        self.dt = dt
        self.grade = _Channel(*prior("accel_x_offset_mps2"))
        self.bank = _Channel(*prior("accel_y_offset_mps2"))
        self.vertical_fused = 0
        self.vertical_zero = 0  # exact-0 velD fixes skipped (see module doc)
        self.roll = 0.0
        self.roll_std = math.pi
        self.fy_lp = math.nan
        self._lp = dt / (ROLL_LAG_S + dt)

    def step(self, k: int, b_ax: float, var_bax: float, b_ay: float, var_bay: float, g_ay: float) -> None:
        """Every ``UPDATE_EVERY`` steps: the main filter's bias sums at step k."""
        if k % UPDATE_EVERY:
            return
        period = UPDATE_EVERY * self.dt
        inflate = CORRELATION_S / period
        for ch in (self.grade, self.bank):
            ch.predict(period)
        self.grade.gravity_update(b_ax, var_bax * inflate, 1.0)
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
        if self.grade.update(z - self.grade.x[0], np.array([1.0, 0.0]), R):
            self.vertical_fused += 1
            return True
        return False

    def set_roll(self, ay_m: float, g_ay: float, var_gay: float, ay_doubt: float = 0.0) -> None:
        """Body roll from the measured lateral acceleration ``ay_m`` and the gain state;
        ``ay_doubt`` (m/s^2): how far ``ay_m`` disagrees with its witness (yaw rate x speed), a
        possible error of the force the roll is computed from (a sensor fault not yet isolated)."""
        fy = (ay_m - self.bank.x[1]) / (1.0 + g_ay)
        lp = self.fy_lp = fy if self.fy_lp != self.fy_lp else self.fy_lp + self._lp * (fy - self.fy_lp)
        self.roll = g_ay / G * lp
        k2 = (g_ay * g_ay + var_gay) / (G * G)  # the roll gradient's square, its uncertainty included
        self.roll_std = math.sqrt((lp / G) ** 2 * (var_gay + GAIN_FLOOR ** 2) + k2 * (fy - lp) ** 2
                                  + k2 * (self.bank.P[1, 1] + ay_doubt * ay_doubt))

    def valid(self, ch: _Channel) -> bool:
        return ch.updates > 0 and ch.std < ANGLE_STD_VALID

    def learned(self) -> dict:
        return {"accel_x_offset_mps2": float(self.grade.x[1]),
                "accel_x_offset_std_mps2": float(math.sqrt(self.grade.P[1, 1])),
                "accel_y_offset_mps2": float(self.bank.x[1]),
                "accel_y_offset_std_mps2": float(math.sqrt(self.bank.P[1, 1]))}
