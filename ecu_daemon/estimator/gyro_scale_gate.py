"""Is the gyro's scale right? No sideslip promise on a yaw rate nobody has checked.

Why: a gyro in deg/s mapped as rad/s (``[inputs.yaw_rate] scale = 57.3`` on a signal already in
rad/s, or the reverse) reads 57x too much: its bias alone (0.5 deg/s) reads 0.5 rad/s at
standstill. ``unit_check`` names the key at start-up from the DBC unit, but the filter still
integrated it, and on dlc_dry the launch published sideslip up to 11 deg off as valid (126 of 129
valid rows beyond 3 sigma, tools/probe_wrong_config.py) before the fault detector isolated the
gyro. ``yaw_scale_check.py`` does not catch it: it fits a scale of a few per cent against GNSS
courses (a 0.5 % prior, a 5 % wide one), needs turning and fixes above its speed, and it bounds
the heading, not the launch's sideslip.

Physics gives the gyro two witnesses that do not involve it: the rear (unsteered) axle's
speed difference, ``(v_rr - v_rl) / T = r`` (ISO 8855, left wheel at y = +T/2; whatever the
sideslip), and the lateral acceleration, ``ay / vx = r`` in a steady turn (``dvy/dt`` and the
bank gravity are what is left). Each witness ``w`` is regressed on the gyro ``g`` (bias-corrected,
as the filter uses it) with an offset held by a prior: ``v_rr - v_rl = k g T + c v`` (c the rear
tyres' radius difference, ~1 %) and ``ay = k g vx + c`` (c a bank's gravity, 6 %, and ay's
bias), by least squares over samples every ``GSC_EVERY`` steps at speed. A steady circle cannot
tell scale from offset: there ``k`` is known to the offset's prior over the turn's reading. ``k`` is 1 for a right
gyro (a track 15 % off, load transfer, ay's dvy/dt: well inside ``GSC_AGREE``), 1/57 or 57 for a
unit error, -1 for a flipped sign. The gyro's scale is

* confirmed once either witness puts ``k`` within ``GSC_AGREE`` of 1 at a std below
  ``GSC_MAX_STD`` (either: wheels swapped left/right flip the wheels' witness, ax/ay swapped
  spoil ay's, and neither is the gyro's fault);
* contradicted once both witnesses put ``k``'s 3-sigma interval outside [1/``GSC_WRONG``,
  ``GSC_WRONG``] (or negative) and agree with each other on it (same sign, within a factor
  ``GSC_WRONG``): one WARNING names ``[inputs.yaw_rate]``. One alone is not enough: its own
  mapping may be the mistake (wheels swapped left/right read -1, one wheel mapped twice 0, ay
  swapped with ax ~0 in a circle), and a wrong mapping also moves the filter's states, so that
  the other witness may read the gyro off as well, but not by the same factor (the probe's wheels
  swapped left/right: -0.70 and +0.32; a gyro in deg/s read as rad/s: 65 and 51).

Sideslip integrates ``ay - r vx``: a scale error of any size is harmless while the gyro reads
what the car does, and ruinous the moment it reads a turn wrong. So sideslip is promised while
the gyro's scale is confirmed, or while it has never been exercised: every sample since the start
had the gyro within ``GSC_QUIET`` of 0, or of the witness closest to it (+ ``GSC_AGREE`` of the
witness). A straight's lane keeping (0.045 rad/s on the suite's
flying straights, with an unlearned 0.5 deg/s bias) is not exercise; a 57x gyro's bias, or its
reading of the first steering correction, is; so is a gyro read 57x too small in a turn. While the
gyro is isolated the sideslip rests on the wheels' yaw rate (fault_detection.py), not on it. The first sample beyond it, before confirmation, withholds the promise until a witness
confirms (a right gyro: within the first lane change); a contradicted scale withholds it for good
(and the heading, which integrates the same gyro). The heading follows the same rule
(:meth:`heading_ok`): where nothing else holds it (reversing below the course's speed) a flipped
gyro turns it by twice the car's rotation before 3 m/s lets the witnesses speak. The rear wheels
witness in both directions: ``(|v_rr| - |v_rl|) sign(vx)`` is ``r T`` for signed and unsigned
wheel speeds alike (switched off at ``vx < 0`` before, the reversing drive had ay alone, which
never contradicts; the formula is ``rear_axle_yaw.py``'s, shared with ``wheel_yaw_check.py``).
"Never exercised" is a rate test and cannot see what the gyro integrates inside ``GSC_QUIET``, nor a
gyro read 1/57x, which is always quiet: until the gyro is confirmed the heading's std carries both
(:meth:`heading_scale_sd`, the rotation the heading owes to the gyro's scale times a flip's error;
:meth:`heading_std`, the rotation the gyro and the rear wheels disagreed on below the fits' speed,
where the wheels still count it). Velocity and heading are also not promised on
a sample whose gyro reads a yaw rate no car makes at its speed (``GSC_R_MIN``'s circle below
``vx = sqrt(GSC_A_MAX GSC_R_MIN)``, ``GSC_A_MAX`` of friction above): a 57x gyro's bias at a
launch (0.5 rad/s at 0.3 m/s) or its reading in a 150 m corner at 30 m/s (11 rad/s), where vx's
``r vy`` term alone put vx 3.2 m/s off while valid (flying_30_r150l_h100). Nothing is fused
differently.
"""
from __future__ import annotations

import math

from .line_fit import LineFit
from .rear_axle_yaw import rear_mean_speed, rear_speed_difference
from .slow_exercise import SlowExercise
from . import slow_turn_heading

GSC_EVERY = 10  # steps between samples (60 ms): CAN wheel speeds and IMU at 50-100 Hz, noise correlated
GSC_MIN_SPEED = 3.0  # m/s: below, the wheels' quantisation and ay / vx's division by a small speed
GSC_QUIET = 0.03  # rad/s (1.7 deg/s): a straight's gyro noise and residual bias; a 57x bias is 0.5
GSC_AGREE = 0.3  # |k - 1|: track 15 % off, load transfer, ay's dvy/dt and roll; unit errors are >= 0.98 off
GSC_MAX_STD = 0.1  # k's std for a confirmation: 0.3 from 1 is then 3 sigma (a 6 % bank in a 6 m/s^2 circle)
GSC_WRONG = 2.0  # k beyond [1/2, 2] at 3 sigma contradicts (57x, 1/57, -1 far beyond; 1.15 track inside)
GSC_WHEEL_FLOOR = 0.03  # m/s, the rear speed difference's residual std never taken below (two wheels' noise)
GSC_RADIUS_DIFF = 0.01  # the rear tyres' relative radius difference (wear, pressure), the offset's prior
GSC_AY_FLOOR = 0.1  # m/s^2, ay's residual std never taken below (noise, roll, dvy/dt)
GSC_AY_OFFSET = 0.6  # m/s^2, ay's offset prior: a 6 % bank's gravity, ay's bias, the gyro's bias x vx
GSC_R_MIN = 4.0  # m: no car turns tighter (a curb-to-curb circle of ~10 m is a 5 m radius at the CG)
GSC_A_MAX = 12.0  # m/s^2: no tyre holds more (1.2 g), so |r| <= this / vx at speed
GSC_MAX_AX = 3.0  # m/s^2: beyond, wheel spin or ABS braking moves the two rear wheels apart
GSC_STILL = 0.2  # m/s: below, the car stands (a few wheel quanta; it turns at most v / GSC_R_MIN)
GSC_SLOW_SIGMA = 2.0  # the slow turn the gyro and the wheels disagree on, as that many heading stds
# the scale error an unconfirmed gyro may have while it reads quiet, as a std: a flipped sign's -2
# (the heading turned by twice the rotation, the other way) at 2 sigma, so that the heading's own
# error on top of it still fits in 3; 2x and 1/2x (GSC_WRONG) are within 1 sigma
GSC_UNCONFIRMED_SCALE_SD = 1.0


class _Fit(LineFit):
    """Least squares ``d = k a + c b`` (``line_fit.LineFit``): ``a`` what the witness reads for the
    gyro's rate, ``b`` the offset's regressor, ``c`` held by a prior (``c_sd``): a steady circle
    (``a`` and ``b`` in proportion) then bounds ``k`` by the offset the prior allows (c_sd b / a),
    instead of nothing. ``k`` and its std are updated from the fifth sample on."""

    def __init__(self, c_sd: float, floor: float):
        LineFit.__init__(self, (floor / c_sd) ** 2)  # the prior's weight, noise at the floor
        self.floor = floor
        self.k_std = math.inf

    def observe(self, a: float, b: float, d: float) -> None:
        self.add(a, b, d)
        if self.n < 5 or not self.solve():
            return
        self.k_std = math.sqrt(self.k_var(self.residual_var(self.floor)))

    def agrees(self) -> bool:
        return abs(self.k - 1.0) <= GSC_AGREE and self.k_std <= GSC_MAX_STD

    def refutes(self) -> bool:
        lo, hi = self.k - 3.0 * self.k_std, self.k + 3.0 * self.k_std
        return self.k_std < math.inf and (hi < 1.0 / GSC_WRONG or lo > GSC_WRONG)


def _same_scale(a: float, b: float) -> bool:
    """Two witnesses' k say the same scale: one sign, within a factor GSC_WRONG."""
    return a * b > 0.0 and max(abs(a), abs(b)) <= GSC_WRONG * min(abs(a), abs(b))


class GyroScaleGate:
    """The gyro's scale against the rear wheels' and ay's yaw rates; :meth:`sideslip_ok` says
    whether a sideslip may be promised on it (module docstring)."""

    def __init__(self, track_m: float, sample_dt: float = GSC_EVERY * 0.006):
        self.track = track_m
        self.sample_dt = sample_dt  # s between two samples (GSC_EVERY steps)
        # the rotation the gyro and the rear wheels disagree on while moving below GSC_MIN_SPEED
        # (rad, summed until the gyro is confirmed): what an unconfirmed gyro's scale may have put
        # into the heading where no fit can judge it (:meth:`heading_std`)
        self.slow_turn = 0.0
        # rear wheels: v_rr - v_rl = k r T + c v, c the two tyres' radius difference (~1 %)
        self.wheels = _Fit(GSC_RADIUS_DIFF, GSC_WHEEL_FLOOR)
        # ay = k r vx + c, c the bank's gravity and ay's bias
        self.lateral = _Fit(GSC_AY_OFFSET, GSC_AY_FLOOR)
        self.confirmed = False
        self.contradicted = False
        self.exercised = False  # a sample beyond GSC_QUIET while not confirmed
        # ... split by speed: below GSC_MIN_SPEED forgotten in time (slow_exercise.py, core.SLOW_TURN_FORGOTTEN)
        self.by_speed = SlowExercise(sample_dt)
        self.implausible = False  # the last sample read a yaw rate no car makes at its speed
        self.logged = False

    def step(self, rl: float, rr: float, g: float, ay: float, vx: float, ax: float, g_raw: float) -> bool:
        """One sample (the caller calls it every ``GSC_EVERY`` steps): ``rl``, ``rr`` the rear wheel
        speeds as mapped (m/s; NaN: no wheel witness), ``g`` the bias-corrected gyro (rad/s), ``ay``
        the lateral acceleration as mapped (NaN: no ay witness), ``vx`` the filter's, ``ax`` the
        longitudinal acceleration as mapped; ``g_raw`` the gyro as mapped, not bias-corrected.
        The fits take the inputs as mapped: the filter's bias states absorb what a wrong mapping
        puts into them (wheels swapped left/right moved ay's bias until ay read 0.3x the gyro's
        r vx on the flying start); the quiet and plausibility tests take ``g``, which is what the
        filter integrates. True the first time the scale is
        contradicted (the caller logs :meth:`message`)."""
        if self.confirmed or not g == g:
            self.implausible = False
            return False
        # the yaw rate a car can make at this speed: the tightest circle below, the friction above
        # (plus twice the quiet margin for a bias not learned yet); beyond it the gyro's reading
        # is no motion of this car
        s = abs(vx)
        r_max = min(s / GSC_R_MIN, GSC_A_MAX / s if s > 0.0 else math.inf) + 2.0 * GSC_QUIET
        self.implausible = abs(g) > r_max
        # the rear wheels' yaw rate in either direction (rear_axle_yaw.py): reversing, v_rr - v_rl = r T still holds for
        # signed speeds, and unsigned ones read |v_rr| - |v_rl| = -r T, so the magnitudes' difference
        # times the direction of travel (the filter's vx) is r T both ways and for both encodings
        # (reversing with the wheels' witness off, a flipped gyro was judged by ay alone and never
        # contradicted: 649 heading rows valid beyond 3 sigma, up to 52.5 deg, on the suite's reversing)
        ww = rear_speed_difference(rl, rr, vx) / self.track
        vs = rear_mean_speed(rl, rr, vx)
        v = abs(vs)
        # what a scale error can have done at this sample: the gyro's reading, or its distance to the
        # witness closest to it beyond GSC_AGREE of the witness, whichever is less (either witness
        # may be off by its own mapping or offset: a 6 % bank is 0.18 rad/s of ay / vx at 4.5 m/s,
        # one wheel-speed quantum 0.04 rad/s over the track)
        witnesses = []
        if ww == ww and v >= GSC_MIN_SPEED:
            witnesses.append(ww)
        if ay == ay and s >= GSC_MIN_SPEED:
            witnesses.append(ay / vx)
        dev = abs(g)  # near 0 is quiet whatever the witnesses say (a bank's ay / vx, wheel quanta)
        for w in witnesses:
            dev = min(dev, abs(g - w) - GSC_AGREE * abs(w))
        if dev > GSC_QUIET:
            self.exercised = True
        # no sideslip is promised below GSC_MIN_SPEED nor reversing (core: vx > MIN_SPEED_SIDESLIP)
        # (the rear wheels count the turn where both move: below, an exercised sample is never forgiven)
        self.by_speed.sample(dev > GSC_QUIET, s < GSC_MIN_SPEED or vx < 0.0, len(witnesses) > 0,
                             s >= GSC_STILL and abs(rl) > 0.0 and abs(rr) > 0.0)
        if s < GSC_MIN_SPEED:
            # below the fits' speed the wheels still count the rotation, one quantum at a time:
            # summed, their disagreement with the gyro is what its scale did to the heading (the
            # tyres' radius difference, where the fit has seen it, taken out); both wheels moving:
            # an ABS reports 0 below its own minimum speed, and one wheel at 0 in a turn would
            # read the whole other wheel's speed as rotation
            if s >= GSC_STILL and abs(rl) > 0.0 and abs(rr) > 0.0:
                d = self._counted_disagreement(g, ww, vs)
                self.slow_turn += d * self.sample_dt
                self.by_speed.turn(d, ww)
            return False
        if vx < 0.0 and ww == ww and abs(rl) > 0.0 and abs(rr) > 0.0:
            # reversing at speed: the wheels count the turn for slow_exercise.py as below it (1209:
            # a reverse curve at 3.0 m/s, where ay / vx with a bank exercised a right gyro)
            self.by_speed.turn(self._counted_disagreement(g, ww, vs), ww)
        if ww == ww and v >= GSC_MIN_SPEED and abs(ax) <= GSC_MAX_AX:  # either way (ww above)
            self.wheels.observe(g_raw * self.track, vs, ww * self.track)
        if ay == ay:
            self.lateral.observe(g_raw * vx, 1.0, ay)
        fits = [f for f in (self.wheels, self.lateral) if f.k_std < math.inf]
        if any(f.agrees() for f in fits):
            self.confirmed = True
            self.contradicted = self.implausible = False
            return False
        # both witnesses, each refuting: one alone may be the wrong mapping (wheels swapped left /
        # right read -1, one wheel mapped twice 0, ay swapped with ax ~0 in a circle)
        if (len(fits) == 2 and all(f.refutes() for f in fits) and not self.contradicted
                and _same_scale(self.wheels.k, self.lateral.k)):
            self.contradicted = True
            if not self.logged:
                self.logged = True
                return True
        return False

    def _counted_disagreement(self, g: float, ww: float, vs: float) -> float:
        """The gyro's yaw rate less the rear wheels' (rad/s), with the tyres' radius difference taken
        out where the wheels' fit has seen it: what a slow (or reversing) sample counts."""
        c = self.wheels.c if self.wheels.k_std < math.inf else 0.0
        return g - ww + c * vs / self.track

    def motion_ok(self) -> bool:
        """Velocity and heading may rest on this gyro: not contradicted, and its last sample a yaw
        rate this car can make (vx integrates r vy, the heading r itself)."""
        return not (self.contradicted or self.implausible)

    def heading_ok(self) -> bool:
        """A heading may rest on this gyro: :meth:`motion_ok`, and its scale confirmed or never
        exercised (:meth:`sideslip_ok`). The heading integrates r itself: a flipped gyro turns it by
        twice the car's rotation, and where nothing else holds it (reversing below the course's
        speed, or before the first fix) that was published as valid until both witnesses
        contradicted the gyro (the suite's reversing, ``yaw_sign``: 262 rows beyond 3 sigma, up to
        12.6 deg, in the 1.6 s of its reverse curve before 3 m/s let the witnesses speak)."""
        return self.motion_ok() and self.sideslip_ok()

    def heading_scale_sd(self) -> float:
        """The yaw-rate scale error the heading's std must carry for this gyro (times the rotation
        it still owes to the gyro's scale, ``scale_sensitivity.py``): 0 once confirmed, else
        ``GSC_UNCONFIRMED_SCALE_SD``. Why: "never exercised" only says each sample read less than
        ``GSC_QUIET``; reversing out of a standstill a flipped gyro turned the heading by twice the
        car's rotation inside that band before any witness had the speed to object (the suite's
        reversing, ``yaw_sign``: 42 heading rows beyond 3 sigma, up to 1.73 deg, at 0.33 deg of
        std). With it the heading's std carries that rotation (the same rows: 1.95 sigma at most)
        and is withheld once a flip could be beyond ``HEADING_STD_VALID``'s 3 sigma. A gyro read
        1/57x integrates almost nothing, so this cannot bound it (:meth:`heading_ok`)."""
        return 0.0 if self.confirmed else GSC_UNCONFIRMED_SCALE_SD

    def heading_scale_sd_counted(self) -> float:
        """:meth:`heading_scale_sd` with a forgiven slow turn's scale as the rear wheels measured it
        (slow_turn_heading.py, core.HEADING_SLOW_TURN_FORGOTTEN)."""
        if self.confirmed:
            return 0.0
        if self.contradicted:
            return GSC_UNCONFIRMED_SCALE_SD
        return slow_turn_heading.scale_sd(self.by_speed, GSC_UNCONFIRMED_SCALE_SD)

    def heading_ok_forgetting(self) -> bool:
        """:meth:`heading_ok` with a slow turn the rear wheels counted alike forgotten, as for the
        sideslip (:meth:`sideslip_ok_forgetting`; slow_turn_heading.py)."""
        return self.motion_ok() and self.sideslip_ok_forgetting()

    def heading_std(self) -> float:
        """The heading std (rad) this gyro owes for the slow turns no fit could judge: the rotation
        the gyro and the rear wheels disagreed on below ``GSC_MIN_SPEED`` until the gyro is
        confirmed, as ``GSC_SLOW_SIGMA`` stds. Why: a gyro read 1/57x (rad/s mapped as deg/s) reads
        quiet, so neither "exercised" nor :meth:`heading_scale_sd` (its own rotation) sees it; the
        suite's reversing curve below 3 m/s turned the car 4 deg under it (212 heading rows valid
        beyond 3 sigma, up to 6.2 deg, until both fits contradicted it at 31.67 s)."""
        return 0.0 if self.confirmed else abs(self.slow_turn) / GSC_SLOW_SIGMA

    def heading_set(self) -> None:
        """The heading was just set from a course or a baseline, not from the gyro: the slow turns
        before it owe it nothing (a launch's first metres, before any heading existed, had put
        that debt on every later heading: 0.2 s later to valid on the suite's noisy-wheel launches,
        34 valid rows on gyro_scale_-3pct)."""
        self.slow_turn = 0.0

    def sideslip_ok(self) -> bool:
        """A sideslip may rest on this gyro: its scale confirmed, or never exercised yet."""
        return self.confirmed or not (self.exercised or self.contradicted)

    def sideslip_ok_forgetting(self) -> bool:
        """:meth:`sideslip_ok` with a slow turn no witness could judge forgotten once its memory is
        gone (slow_exercise.py)."""
        return self.confirmed or not (self.by_speed.at_speed or self.by_speed.slow or self.contradicted)

    def message(self) -> str:
        """The log line: the key, what each witness reads."""
        parts = ["%s reads %.3gx the gyro" % (name, f.k) for name, f in
                 (("the rear wheels' (v_rr - v_rl) / track", self.wheels), ("ay / vx", self.lateral))
                 if f.k_std < math.inf]
        return ("[inputs.yaw_rate] scale: %s: the gyro reads %.3gx the yaw rate (a deg/s vs rad/s unit "
                "error is 57.3x, a flipped sign -1); sideslip and heading are not promised"
                % (", ".join(parts), 1.0 / self._k() if self._k() else math.inf))

    def _k(self) -> float:
        f = min((self.wheels, self.lateral), key=lambda f: f.k_std)
        return f.k
