"""Fault detection and isolation (FDI): the sources checked against each other every step.

One place decides which source may be fused (PX4 EKF2's shape; openpilot's input checks). Every
check compares two *independent* views of one physical quantity, so a sensor that is wrong but
alive, in range and with good CRCs, is caught by physics rather than by its own plausibility:

* each wheel against the others: its speed, corrected for yaw rate and steering to the CG's vx,
  against the median of the fused pair and the other axle (a single wheel-speed sensor that is
  wrong is replaced by its axle partner, corrected by r * track);
* longitudinal: the change of the wheel speed over a short window against the integrated
  accelerometer (``ax`` vs d(wheel speed)/dt);
* yaw: the gyro against the wheel speed difference of the free-rolling axle, ``(v_rr - v_rl) /
  track`` (the front pair over ``cos(delta)`` on a rear-driven car: a driven axle's wheels slip
  unequally in a corner; the rear pair on all-wheel drive) and against ``ay / vx`` (the gyro is
  blamed only when both disagree with it; ``ay`` when only ``ay / vx`` does);
* lateral: over a sliding window, the change of vy the accelerometer implies, the integral of
  ``ay - r vx``, against the change of the single-track model's vy. A constant ``ay`` error
  integrates into this residual while it only shifts the model's vy (a constant that cancels in
  the change), so it shows within a second even in transients, where ``ay / vx`` needs a wide
  tolerance. It is not an isolation test: a banked road puts the same signature into ``ay``
  (gravity), up to ~1.4 m/s^2 on the Revs track. The residual's rate beyond what bank, roll and
  model errors explain (:attr:`FaultDetector.lat_excess`) is how fast vy may be drifting
  unseen, and the core grows the vy std by it: sideslip is not promised while it lasts;
* GNSS speed against the wheel speed at its time of validity (or, with the wheels out, against the
  filter's velocity; the comparison itself is ``core.Estimator._gnss_agrees_with_wheels``);
* standstill: only when the wheels *and* the filter's IMU-propagated speed (and fresh GNSS) agree;
* stuck: a reading that has not changed by a single count while its witness says it should have
  moved well beyond its noise (a wheel against what the other wheels say it should read; all four
  wheels against the gyro's yaw rate and the integrated ax; the gyro against both its witnesses;
  ay against r vx). No working sensor stays bit-identical through such a change, so this isolates
  at once, before the residual tests (which must tolerate transients) have integrated the error,
  and holds until the reading moves again (a stuck value may happen to agree for a while).

When the longitudinal check fails, wheels and accelerometer are both suspects until the evidence
says which: a GNSS fix taken after the onset (which one it agrees with), else an impossible jump
of one of them at the onset. A suspect or isolated source is not fused, learned quantities that
depend on it are not learned, and the outputs that depend on it are not valid. It returns when it
has agreed with the others for a while (hysteresis, ``_Latch``). Learned states are also bounded
(:func:`clamp_learned`): a fault that slips through cannot drive them somewhere unphysical.

The gyro is isolated when the wheels' yaw rate and ay / vx both disagree with it (a vote in which
ay / vx merely "sides with the wheels" was tried: in transients, with one rear wheel stuck or
noisy, it isolated a good gyro and the repair below then put the wheels' error into the
heading, 15 deg off while valid), and, with ``core.GYRO_WITNESSES_AGREE``, only when the two
also agree with each other (gyro_vote.py: on all-wheel drive the slipping wheels and ay / vx, off by
the sideslip's rate, each disagreed with a right gyro by its own error). At the step the gyro is isolated, the
heading it integrated since the disagreement began (the integral of gyro minus wheels) is taken
back out of the stored steps; while it is out, yaw rate comes from the wheels, the single-track
model (on ay) holds vy, and sideslip is promised only while ay / vx vouches for the wheels. The
heading integrates that substitute, so its std grows by the substitute's own error bound
(:attr:`FaultDetector.substitute_yaw_error`, against ay / vx): the heading flag returns with the
gyro only once GNSS has brought that std back (a std that grew as noise only let a heading 7.9 deg
off be valid at a 1.45 deg std when a gyro isolated in a lane change returned).

Bias state or FDI: the bias states (``b_r``, ``b_ax``, ``b_ay``) follow slow drift, at their
configured random walk; a step in a sensor's offset is FDI's (the random walk would take tens of
seconds to follow it, all the while integrating it into heading and vy), so the source is isolated
and its biases frozen. An offset that stays is a bias again: a gyro isolated for ``RELEARN_S``
whose disagreement with the wheels is a steady offset (no slope against its rate, little scatter)
returns with that offset added to its bias (:meth:`FaultDetector._relearn_bias`).

Isolation is reported as bits of ``Estimate.status`` (``STATUS_*_ISOLATED``, the same values as
:data:`SOURCE_BITS`) and counted per source in :attr:`FaultDetector.events`.
"""
from __future__ import annotations

import math

import numpy as np

from . import estimate as est_mod
from . import bank_rate
from . import gyro_vote
from .kinematic import BAX, BAY, BR, GAY, KW, VX, VY

WHEELS = est_mod.STATUS_WHEELS_ISOLATED
WHEEL_SPEED = est_mod.STATUS_WHEEL_SPEED_ISOLATED
YAW_RATE = est_mod.STATUS_YAW_RATE_ISOLATED
ACCEL_X = est_mod.STATUS_ACCEL_X_ISOLATED
ACCEL_Y = est_mod.STATUS_ACCEL_Y_ISOLATED
GNSS = est_mod.STATUS_GNSS_ISOLATED
#: source name -> isolation bit
SOURCE_BITS = {"wheels": WHEELS, "yaw_rate": YAW_RATE, "accel_x": ACCEL_X, "accel_y": ACCEL_Y, "gnss": GNSS,
               "wheel_speed": WHEEL_SPEED}
# --- each wheel against the others (fl, fr, rl, rr)
WHEEL_TOL_MPS = 0.5  # + WHEEL_TOL_REL * speed: driven-wheel slip stays out of the median
WHEEL_TOL_REL = 0.03
WHEEL_PAIR_SIGMA2 = 9.0  # (3 sigma)^2: a pair's half-difference within it is the configured noise
#: a slide that isolates the gyro (issue 7, stops 48-49). The wheel vote then has r = 0 and cannot
#: put an axle's two wheels, legitimately |r| T apart in a yaw, at one CG speed: it masks good wheels.
#: True: (1) while the vote masks every fused wheel the wheels stay isolated (the return latch, which
#: compares them with a vx the isolation itself has widened to +-4 sigma = 4-4.5 m/s, may not release
#: them in the same step: ``_each_wheel`` says "nothing left to fuse"); (2) a stand-in partner wheel,
#: uncorrected by the unknown r T / 2, carries (T/2 * r_gyro)^2 in ``wheel_z_excess_var`` (the raw
#: gyro less its bias: isolated in a slide, but the wheels' spread confirms it within 5 % in 3661).
#: 3661 88 -> 0, 3834 38 -> 0 vx rows beyond 3 sigma (slide48.md). False: as before stop 49.
SLIDE_WHEEL_HOLD = True

# --- longitudinal: wheel speed change vs integrated ax over LON_WINDOW_S
LON_WINDOW_S = 0.15
LON_TOL_MPS = 1.0  # + LON_TOL_REL * speed (wheel slip while braking, grade not yet in the bias)
LON_TOL_REL = 0.03
WHEEL_JUMP_MPS = 3.0  # wheel-speed change between two steps no tyre can make (> 500 m/s^2)
AX_IMPLAUSIBLE_MPS2 = 20.0  # beyond any car's longitudinal grip (2 g)
AX_JUMP_MPS2 = 12.0  # change between two steps
JUMP_MEMORY_S = 0.5  # a jump this close to the onset counts as evidence
# --- yaw: gyro vs the free-rolling axle's wheel difference (yaw_pair) and vs ay / vx
YAW_TAU_S = 0.1  # fast test: large faults, wide tolerance
YAW_SLOW_TAU_S = 1.0  # slow test: offsets and stuck values, narrow tolerance
YAW_SLOW_TOL = 0.02  # rad/s, + YAW_SLOW_TOL_REL * |r|, slow test (both witnesses)
YAW_SLOW_TOL_REL = 0.12
#: the ay test's slow tolerance widens by what a road's bank may change within its window (bank_rate.py);
#: False: the flat-road tolerance. Off since stop 43: on the never-seen drives 2161-2400 the allowance (1.0
#: m/s^2 at 12 m/s) also passed a car SLIDING on ice, whose ay - r vx is the sideslip's own rate (2254, flat
#: road, mu 0.10: sideslip published valid 17.5 deg off; 2175 heading 884 rows beyond 3 sigma; 2275 and
#: 2356 sideslip), where the isolated ay had kept the sideslip withheld (2254's own mechanism, the model
#: back at full weight in the slide, is fusion/slide_rate.py's now). It needs a test that tells a bank from
#: a slide before it is on again: 2175, 2275, 2356 clean with it on, and test_banked_ay_isolation.py.
AY_BANK_RATE_ALLOWANCE = False
SCALE_TOL = 0.15  # slope of (gyro - witness) against the yaw rate: a scale error (x1.3: 0.3)
SCALE_MIN_SPREAD = 0.05  # rad/s: the gyro's rate must move this much (std) to tell scale from offset
# the wheels' yaw rate may lag (or lead) the gyro by this much: the ABS ECU's filter and pulse-window
# averaging (tens of ms; lag23 measured a RAV4's wheels 22-37 ms *ahead* of its accelerometer)
WHEEL_YAW_LAG_MAX_S = 0.08
SCALE_LAG_COND = 0.05  # r and rdot must be this far from collinear (1 - corr^2) to fit the lag apart
# The front pair's yaw rate assumes both wheels steer alike; Ackermann geometry steers the inner one
# more, by ~delta^2 T / L, which puts ~|v| |delta|^3 / L (rad/s) into (v_fr - v_fl) / (T cos delta).
# Negligible at a lane change's angles (22 m/s, 0.05 rad: 0.001 rad/s) but not at the front axle's
# limit (random seed 131, a plough on mu 0.23: 0.54 rad of road-wheel angle, the front pair read
# 0.77 rad/s for 0.14). Beyond this the rear pair stands in for an isolated gyro (nothing better)
# but neither pair judges it (as while braking): in a plough or a spin's counter-steer no pair rolls
# kinematically (random seed 55: rear pair at 1 rad of slip read -0.07 rad/s for 0.35).
FRONT_YAW_ACKERMANN_RADPS = 0.01  # a third of YAW_TOL_WHEELS
YAW_TOL_RDOT = 0.1  # s: transients (yaw acceleration) widen the ay / vx tolerances
GYRO_JUMP_RADPS = 0.25  # change between two steps (> 40 rad/s^2) the wheels do not show: a fault
REPAIR_WINDOW_S = 1.0  # how far back the gyro's drift before its isolation is taken out of the heading
REPAIR_LAG_S = 2.0 * 0.1  # the fast test's filter lag (2 YAW_TAU_S): the fault began before it failed
# a gyro isolated this long whose disagreement with the wheels is a steady offset (not a scale, not
# noise, not stuck) has a new bias: handed to the bias state, and the gyro is fused again
RELEARN_S = 20.0
RELEARN_SLOPE = 0.03  # |d(gyro - wheels) / d r_gyro| below this: an offset, not a scale error
RELEARN_RESID = 0.01  # rad/s: rms of the low-passed disagreement about the fit (a noisy gyro has more)
RELEARN_MIN_SPREAD = 0.02  # rad/s: the gyro's spread needed to tell an offset from a scale (or stuck)
YAW_MIN_SPEED = 3.0
# Braking harder than this, the rear wheels' left/right difference is no yaw-rate witness: each
# braked wheel slips by its brake force over its own load (x its slip stiffness), and in a corner the
# load moves to the outer wheel, so the unloaded inner one slips more -- up to its friction limit,
# which the daemon does not know (mu, load transfer, ABS). imu_brake_turn (5 m/s^2 in a 0.55 g
# circle at 18 m/s): the wheels' yaw rate 0.65 rad/s off a right gyro, whose heading and vy stds
# were then widened to 25 deg / 1 m/s. 1 m/s^2 (0.1 g) is above what rolling resistance, drag and
# engine braking of the front axle give a free-rolling rear pair (0.35 m/s^2 at 30 m/s, 0.75 at 50),
# so below it the rear wheels are not braked; above it ay / vx judges the gyro alone (as below
# YAW_MIN_SPEED) and the wheel residuals hold their last value (the suite's 1.3-2 m/s^2 braking
# already put them at 0.7-1.3 x their tolerance).
BRAKE_WITNESS_MPS2 = 1.0
YAW_TOL_WHEELS = 0.03  # rad/s + YAW_TOL_WHEELS_REL * |r| (track and L/R radius errors)
YAW_TOL_WHEELS_REL = 0.15
YAW_TOL_AY = 0.08  # rad/s + YAW_TOL_AY_REL * |r| (dvy/dt / vx is not in the steady-state relation)
YAW_TOL_AY_REL = 0.25
LR_TAU_S = 60.0  # learning of the left/right wheel-radius mismatch (tyre pressure, wear)
LR_MAX = 0.005
WHEELS_BACK_TOL_MPS = 1.0  # isolated wheels return within this (or 4 sigma) of the filter's vx
# --- lateral: window integral of (ay - r vx) vs the single-track model's change of vy
LAT_WINDOW_S = 1.0
LAT_TOL_MPS = 0.3  # model and sensor noise over the window (a difference of two model errors)
LAT_TOL_RDOT_M = 0.5  # x |change of r|: IMU lever arm (rdot * x_imu integrates to x_imu * dr)
LAT_RATE_TOL = 0.8  # m/s^2 beyond which the residual's rate is unexplained (Revs: 99 % below 0.75)
LAT_RATE_TOL_REL = 0.05  # x mean |ay|: roll (gravity in ay) and ay scale errors
LAT_MIN_SPEED = 6.0
# --- stuck: unchanged for STUCK_S while the witness moved by (10 counts of a 0.03 m/s wheel speed,
# 6 deg/s of yaw rate through both witnesses, 1 m/s^2 of r vx)
STUCK_S = 0.25
STUCK_WHEEL_MPS = 0.3
STUCK_YAW_RADPS = 0.1
STUCK_AY_MPS2 = 1.0
WHEEL_KEYS = ("w0", "w1", "w2", "w3")
STUCK_MIN_SPEED_MPS = 3.0  # wheels are judged above this only (below ~0.3 m/s they read 0)
# --- standstill
STANDSTILL_MAX_VX = 1.0  # the IMU-propagated speed must agree that the car stopped
# --- hysteresis (steps at 6 ms)
ON_STEPS = 3
#: rad/s: the yaw rate above which an isolated ay's agreement counts towards its return (a
#: sign-flipped ay disagrees by 2 |r|, twice the ay / vx tolerance from ~0.11 rad/s)
AY_RETURN_MIN_R = 0.1
OFF_STEPS = 170  # ~1 s of agreement before a source returns
GNSS_ON = 2  # an inconsistent fix is never fused; GNSS is reported isolated from the second
GNSS_OFF = 5  # 1 s at 5 Hz
#: the learned states each source drives: frozen while it is isolated (nothing to learn them from)
#: (the ay bias and gain too while the gyro is out: vy's ay - r vx with the wheels' r would teach
#: them the substitute's error times the speed, 0.08 m/s^2 after a stuck gyro)
FROZEN_STATES = {WHEELS: (KW,), YAW_RATE: (BR, BAY, GAY), ACCEL_X: (BAX,), ACCEL_Y: (BAY, GAY)}
#: learned states and their bounds (lower, upper)
LEARNED_BOUNDS = {BR: (-0.1, 0.1), BAX: (-2.0, 2.0), BAY: (-2.0, 2.0), KW: (0.95, 1.05), GAY: (-0.2, 0.2)}


def clamp_learned(x: np.ndarray) -> None:
    """Keep every learned state in its physical range (wheel scale +-5 %, biases, ay gain)."""
    for i, (lo, hi) in LEARNED_BOUNDS.items():
        v = x[i]
        if v < lo:
            x[i] = lo
        elif v > hi:
            x[i] = hi


class _Latch:
    """A failing check isolates after ``on`` verdicts in a row; ``off`` passing ones release it."""

    __slots__ = ("on", "off", "bad", "good", "active", "events")

    def __init__(self, on: int, off: int):
        self.on, self.off = on, off
        self.bad = self.good = self.events = 0
        self.active = False

    def update(self, failing: bool | None) -> bool:
        if failing is None:  # no verdict possible now
            return self.active
        if failing:
            self.good = 0
            self.bad += 1
            if not self.active and self.bad >= self.on:
                self.active = True
                self.events += 1
        else:
            self.bad = 0
            self.good += 1
            if self.active and self.good >= self.off:
                self.active = False
        return self.active

    def trip(self) -> bool:
        """A failing verdict that isolates at once (a fault no transient explains)."""
        self.bad = max(self.bad, self.on - 1)
        return self.update(True)


class _StuckRef:
    """One watched reading of :meth:`FaultDetector._unchanged`: its value and its witness's when it
    last changed, that step, and whether it was found stuck since. Updated in place: ten readings
    are watched every step, and a new tuple for each (the record before perf49) was ten allocations
    and ten frees a step; the values kept and compared are the same objects."""

    __slots__ = ("value", "witness", "k", "stuck")

    def __init__(self):
        self.value = self.witness = math.nan
        self.k = 0
        self.stuck = False


class FaultDetector:
    """Cross-checks of wheels, IMU and GNSS; :attr:`isolated` is the mask of sources not to fuse."""

    def __init__(self, dt: float, track_m: float, lf_m: float = 1.2, driven_axle: str = "front",
                 measured_speed=None, model_vy=None, lr_m: float = 1.5, witnesses_must_agree: bool = False):
        """``measured_speed(fl, fr, rl, rr)``: the wheel speed the filter fuses (``WheelSpeedFusion``);
        ``model_vy(vx, r, ay, rdot)``: the single-track model's vy (None: no lateral window check);
        ``lr_m``: CG to rear axle (the kinematic dvy/dt = lr * rdot in the ay / vx check);
        ``witnesses_must_agree``: the gyro is isolated only when its witnesses agree (gyro_vote.py)."""
        self.witnesses_must_agree = witnesses_must_agree
        self.lr_m = lr_m
        self.dt = dt
        self.track = track_m
        self.lf = lf_m
        self.fused_wheels = {"all": (0, 1, 2, 3), "rear": (0, 1)}.get(driven_axle, (2, 3))
        self._fused_mask = sum(1 << j for j in self.fused_wheels)  # the fused wheels' bits in wheel_mask
        self._other_wheels = tuple(j for j in range(4) if j not in self.fused_wheels)
        # the yaw witness: the axle whose wheels roll free, the one the speed fusion trusts (a driven
        # axle's wheels slip unequally in a corner: random seed 21, a rear-driven car at 0.6 of its
        # rear grip, read 0.10 rad/s on the rear wheels for 0.25 on gyro and front wheels, and the
        # scale test isolated the good gyro at every turn-in); the rear one on all-wheel drive
        self.yaw_pair = self.fused_wheels if len(self.fused_wheels) == 2 else (2, 3)
        self.yaw_pair_mask = (1 << self.yaw_pair[0]) | (1 << self.yaw_pair[1])
        self._measured = measured_speed or (lambda fl, fr, rl, rr: 0.5 * (rl + rr))
        self.wheel_latches = [_Latch(ON_STEPS, OFF_STEPS) for _ in range(4)]
        self.wheel_mask = 0  # bit i: wheel i (fl, fr, rl, rr) disagrees with the others
        self.wheel_z = math.nan  # the wheel speed to fuse, isolated wheels replaced
        #: m^2/s^2: what the fused wheels' disagreement among themselves says wheel_z may be off,
        #: beyond their configured noise (one wheel off by e moves a pair's mean by e / 2)
        self.wheel_z_excess_var = 0.0
        self._wheel_r2 = 0.0
        n = max(2, int(round(LON_WINDOW_S / dt)))
        self._ring_v = [math.nan] * n  # wheel speed (scaled) per step
        self._ring_a = [0.0] * n  # cumulative integral of ax per step
        self._n = n
        self._cum_a = 0.0
        self._v_prev = math.nan
        self._ax_prev = math.nan
        self.lon = _Latch(ON_STEPS, OFF_STEPS)
        self._model_vy = model_vy
        nl = max(2, int(round(LAT_WINDOW_S / dt)))
        self._lat_n = nl
        self._lat_ring = [None] * nl  # per step: (integral of ay - r vx, integral of |ay|, model vy, r)
        self._lat_filled = False  # any entry of the ring set since it was last emptied
        self._lat_cum = 0.0
        self._lat_k = 0
        self._lat_abs = 0.0
        self.lat_residual = 0.0  # m/s, the last window's residual (0 when no verdict)
        self.lat_excess = 0.0  # m/s^2, its rate beyond the explained (0 when none or no verdict)
        self.lat_unexplained = 0.0  # m/s^2, its rate beyond the model's tolerance alone (before bank / roll)
        self.lon_onset = -1  # step at which the present longitudinal disagreement started
        self.lon_culprit = 0  # WHEELS | ACCEL_X while the longitudinal check fails
        self._wheel_jump_k = -10 ** 9
        self._ax_jump_k = -10 ** 9
        self._gnss_wheel_verdict: tuple[int, bool] | None = None  # (validity step, wheels agree)
        self.wheels_back = _Latch(1, OFF_STEPS)  # isolated wheels: agree with the filter again
        self.gyro = _Latch(ON_STEPS, OFF_STEPS)
        self.ay = _Latch(ON_STEPS, OFF_STEPS)
        self.gnss = _Latch(GNSS_ON, GNSS_OFF)
        self._a_yaw = dt / (YAW_TAU_S + dt)
        self._a_slow = dt / (YAW_SLOW_TAU_S + dt)
        self.e_ws = 0.0  # the same, slow
        self.e_as = 0.0
        self.rdot_abs = 0.0  # slowly decaying peak of |yaw acceleration|
        self._r_prev = math.nan  # gyro and wheel yaw rate at the previous step
        self._rw_prev = math.nan
        self._rg_lp = math.nan  # the gyro's rate through YAW_TAU_S, and its slope (the scale test's timing term)
        self._rdot_g = 0.0
        self.yaw_suspect = False  # a yaw check fails but the culprit is not yet known
        nr = max(2, int(round(REPAIR_WINDOW_S / dt)))
        self._yaw_ring = [0.0] * nr  # per step: integral of (gyro - wheels' yaw rate) dt
        self._yaw_cum = 0.0
        self._w_fail_since = -1  # first step of the present run of gyro-vs-wheels failures (-1: none)
        self._repair_lag = int(round(REPAIR_LAG_S / dt))
        #: at the step the gyro is isolated: (first step, heading corrections from it on), else None
        self.heading_repair: tuple[int, list] | None = None
        self._relearn = [0.0] * 6  # while isolated: n, sums of r, r^2, e, e r, e^2 (r gyro, e = e_w)
        #: (new bias - old, its variance) at the step an isolated gyro's steady offset becomes its bias
        self.bias_relearn: tuple[float, float] | None = None
        self.yaw_disagreement = 0.0  # rad/s, gyro vs witness while suspect (0 otherwise)
        #: rad, at the first step the gyro is suspect: what it integrated against the wheels over the
        #: fast test's lag before (the drift began before the test could fail), else 0
        self.yaw_catch_up = 0.0
        #: rad/s, while the gyro is isolated: how fast its substitute may be off (the core grows the
        #: heading's std by it, linearly: a bias, not noise); 0 otherwise
        self.substitute_yaw_error = 0.0
        self.e_sub = 0.0  # low-passed substitute yaw rate - ay / vx
        self._gyro_suspect = False
        self._suspect_k = -(1 << 62)  # last step the gyro was suspect
        # weighted means of 1, r, r^2, d_w, r d_w, d_a, r d_a, rdot, rdot^2, r rdot, rdot e_w, e_w, r e_w
        # (scale test)
        self._scale = [0.0] * 13
        self._scale_ay = [0.0] * 3  # the same of rdot e_a, e_a, r e_a (gyro_vote.py's timing term for ay / vx)
        self.witnesses_agree = False  # ay / vx passes the gyro's ay test against the wheels' yaw rate
        self.wheels_vouch_gyro = False  # the wheels' yaw rate passes the gyro (ay's substitute r vx)
        self._a_lr = dt / (LR_TAU_S + dt)
        self.e_w = 0.0  # low-passed gyro - wheel yaw rate
        self.e_a = 0.0  # low-passed gyro - ay / vx
        self.lr = 0.0  # learned (v_right - v_left) / v of the witness pair at zero yaw rate
        self.r_wheels = math.nan  # yaw rate from the witness pair (yaw_pair; substitute for a faulty gyro)
        self.ax_wheels = 0.0  # d(wheel speed)/dt over the window (substitute for a faulty ax)
        self.wheels_isolated = False
        self.isolated = 0
        self.events = {name: 0 for name in SOURCE_BITS}
        self.new_isolation = 0  # bits isolated at this step (the core widens their covariance)
        self.frozen: dict[int, float] = {}  # state index -> value held while its source is isolated
        self._stuck_steps = max(1, int(round(STUCK_S / dt)))
        # per watched reading: its value, the witness's value and the step when it last changed, and
        # whether it was found stuck since
        self._stuck_ref: dict[str, _StuckRef] = {}
        self.stuck_wheels = 0  # bit i: wheel i stuck (replaced like a wheel the others outvote)
        self.wheels_stuck = False  # all four stuck together (no wheel left to vote)
        self.gyro_stuck = False
        self._k = 0
        self._rw_lp = math.nan  # the wheels' yaw rate, low-passed (YAW_TAU_S): the stuck-ay witness
        self.ay_stuck = False

    # ------------------------------------------------------------------------------------------
    def step(self, k: int, wheels: tuple, wheels_ok: bool, r_m: float, ax_m: float, ay_m: float,
             imu_ok: bool, x, p_vx: float, wheel_r2: float, delta: float = 0.0,
             rdot: float = 0.0) -> int:
        """Run every check for step k (x: the latest state, a list or an array). Returns the isolation mask.

        ``wheels``: (fl, fr, rl, rr) raw readings; ``p_vx``: variance of vx; ``wheel_r2``: the
        wheel measurement's noise variance; ``delta``: road-wheel angle (NaN: unknown).
        """
        before = self.isolated
        if type(x) is not list:
            x = x.tolist()  # Python floats: every check below is scalar arithmetic
        kw = x[KW]
        self._k = k
        self._wheel_r2 = wheel_r2
        fl, fr, rl, rr = wheels
        if wheels_ok:
            r = (r_m - x[BR]) if imu_ok and not before & YAW_RATE else 0.0
            fl, fr, rl, rr = self._each_wheel(wheels, r, delta, x[VY])
            self.wheel_z = self._measured(fl, fr, rl, rr)
            if SLIDE_WHEEL_HOLD and self.wheel_mask and imu_ok and before & YAW_RATE:
                # a stand-in partner with the yaw rate unknown to the vote: off by up to |r| T / 2
                self.wheel_z_excess_var = (0.5 * self.track * (r_m - x[BR])) ** 2
        else:
            self.wheel_z = math.nan
        v = self.wheel_z * kw if wheels_ok else math.nan
        ax = ax_m - x[BAX] if imu_ok else math.nan
        self._longitudinal(k, v, ax, ax_m if imu_ok else math.nan)
        self._all_wheels_stuck(k, wheels, wheels_ok, r_m - x[BR] if imu_ok else math.nan)
        self._wheels_return(v, x[VX], p_vx, wheel_r2)
        if SLIDE_WHEEL_HOLD and wheels_ok and self.wheel_mask & self._fused_mask == self._fused_mask:
            self.wheels_isolated = True  # the vote's own verdict: no fused wheel to return with
            self.wheels_back.good = 0
        left, right, judge = self._yaw_wheels(fl, fr, rl, rr, delta)
        self._yaw(k, left, right, wheels_ok and not self.wheel_mask & self.yaw_pair_mask, r_m, ay_m, imu_ok, x,
                  rdot, ax < -BRAKE_WITNESS_MPS2 or not judge)
        iso = WHEEL_SPEED if self.wheel_mask else 0
        if self.lon.active:
            iso |= self.lon_culprit
        if self.wheels_isolated:
            iso |= WHEELS
        if self.gyro.active:
            iso |= YAW_RATE
        if self.ay.active:
            iso |= ACCEL_Y
        if self.gnss.active:
            iso |= GNSS
        if iso == before:  # the usual step: nothing newly isolated or released
            self.new_isolation = 0
            return iso
        self.new_isolation = iso & ~before
        for bit, states in FROZEN_STATES.items():
            if iso & bit and not before & bit:
                self.frozen.update((j, x[j]) for j in states if j not in self.frozen)
        for bit, states in FROZEN_STATES.items():
            if before & bit and not iso & bit:  # released: thawed unless another isolated source holds it
                held = {j for b, st in FROZEN_STATES.items() if iso & b for j in st}
                for j in states:
                    if j not in held:
                        self.frozen.pop(j, None)
        for name, bit in SOURCE_BITS.items():
            if self.new_isolation & bit:
                self.events[name] += 1
        self.isolated = iso
        return iso

    def _yaw_wheels(self, fl: float, fr: float, rl: float, rr: float, delta: float) -> tuple:
        """The yaw witness's (left, right) speeds along the body's x axis: the rear pair as read, the
        front pair (the free-rolling axle of a rear-driven car) divided by cos(delta). A steered
        wheel at (lf, +-T/2) reads (vx -+ r T/2) cos(delta) + (vy + lf r) sin(delta) (the wheel
        vote's model, :meth:`_each_wheel`): the lateral term is alike on both and cancels in the
        difference, so (v_fr - v_fl) / cos(delta) = r T as on the rear axle. Steering unknown
        (NaN): cos(delta) = 1, off by < 0.5 % below 0.1 rad (any corner above ~10 m/s). With the
        wheels steered so far that Ackermann geometry's unequal angles matter
        (FRONT_YAW_ACKERMANN_RADPS), the rear pair is the substitute and no pair judges the gyro
        (the third value, False: ``_yaw`` treats it as braking)."""
        if self.yaw_pair[0] != 0:
            return rl, rr, True
        if not math.isfinite(delta):
            return fl, fr, True
        ad = abs(delta)
        if 0.5 * abs(fl + fr) * ad * ad * ad > FRONT_YAW_ACKERMANN_RADPS * (self.lf + self.lr_m):
            return rl, rr, False
        c = math.cos(delta)
        return fl / c, fr / c, True

    def _unchanged(self, key: str, k: int, value: float, witness: float, tol: float) -> bool:
        """Has ``value`` stayed bit-identical for STUCK_S while ``witness`` (what it should read, or
        a quantity that moves with it) moved by more than ``tol`` since its last change? Once
        found stuck it stays so until the value changes (the truth may come back past it)."""
        ref = self._stuck_ref.get(key)
        if ref is None or value != ref.value or not math.isfinite(witness) or not math.isfinite(ref.witness):
            if ref is None:
                ref = self._stuck_ref[key] = _StuckRef()
            ref.value, ref.witness, ref.k, ref.stuck = value, witness, k, False
            return False
        if ref.stuck:
            return True
        if k - ref.k >= self._stuck_steps and abs(witness - ref.witness) > tol:
            ref.value, ref.witness, ref.k, ref.stuck = value, witness, k, True
            return True
        return False

    def _each_wheel(self, w: tuple, r: float, delta: float, vy: float) -> tuple:
        """Each fused wheel against the others; returns the readings with a wrong one replaced."""
        h = 0.5 * self.track * r
        c, s = (math.cos(delta), math.sin(delta)) if math.isfinite(delta) else (1.0, 0.0)
        lat = (vy + self.lf * r) * s
        cv = ((w[0] - lat) / c + h, (w[1] - lat) / c - h, w[2] + h, w[3] - h)  # each as the CG's vx
        fused = self.fused_wheels
        if len(fused) == 4:
            srt = sorted(cv)
            med = 0.5 * (srt[1] + srt[2])
        else:  # the fused pair and the other axle's mean (driven wheels slip: one vote, not two)
            a, b = fused
            o0, o1 = self._other_wheels
            med = sorted((cv[a], cv[b], 0.5 * (cv[o0] + cv[o1])))[1]
        tol = WHEEL_TOL_MPS + WHEEL_TOL_REL * abs(med)
        stuck = 0
        for j in range(4):  # what each wheel should read, from the other three
            others = (cv[0] + cv[1] + cv[2] + cv[3] - cv[j]) / 3.0
            # not near rest: a wheel-speed sensor reads 0 below ~1 km/h, one wheel after another
            should = others - (cv[j] - w[j]) if abs(others) > STUCK_MIN_SPEED_MPS else math.nan
            if self._unchanged(WHEEL_KEYS[j], self._k, w[j], should, STUCK_WHEEL_MPS):
                stuck |= 1 << j
        if stuck & ~self.stuck_wheels & self.yaw_pair_mask:  # a yaw witness newly out: its residual is stale
            self.e_w = self.e_ws = 0.0
        self.stuck_wheels = stuck
        mask = 0
        for j in fused:
            latch = self.wheel_latches[j]
            if latch.trip() if stuck & 1 << j else latch.update(abs(cv[j] - med) > tol):
                mask |= 1 << j
        self.wheel_mask = mask
        if not mask:
            # a wheel too noisy for the vote's tolerance (set wide for slip) is not out yet, but its
            # pair disagrees: beyond 3 sigma of the configured noise, the excess is wheel_z's error
            if len(fused) == 4:
                dev = 0.25 * (srt[3] - srt[0])
            else:
                dev = 0.5 * (cv[fused[0]] - cv[fused[1]])
            self.wheel_z_excess_var = max(0.0, dev * dev - WHEEL_PAIR_SIGMA2 * 0.5 * self._wheel_r2)
            return w
        self.wheel_z_excess_var = 0.0
        out = list(w)
        for j in fused:
            if mask & 1 << j:
                p = j ^ 1  # axle partner: fl<->fr, rl<->rr
                if mask & 1 << p:
                    self.wheels_isolated = True  # both of an axle: nothing left to fuse
                    return w
                d = 2.0 * h * (c if j < 2 else 1.0)  # right wheel minus left wheel
                out[j] = w[p] - d if j % 2 == 0 else w[p] + d
        return tuple(out)

    def _longitudinal(self, k: int, v: float, ax: float, ax_raw: float) -> None:
        n = self._n
        i = k % n
        isfinite = math.isfinite
        if isfinite(ax):
            self._cum_a += ax * self.dt
        cum_a = self._cum_a
        ring_v = self._ring_v
        ring_a = self._ring_a
        v_old = ring_v[i]
        a_old = ring_a[i]
        ring_v[i] = v
        ring_a[i] = cum_a
        v_prev = self._v_prev
        if isfinite(v) and isfinite(v_prev) and abs(v - v_prev) > WHEEL_JUMP_MPS:
            self._wheel_jump_k = k
        ax_ok = isfinite(ax_raw)
        if ax_ok and (abs(ax_raw) > AX_IMPLAUSIBLE_MPS2 or (
                isfinite(self._ax_prev) and abs(ax_raw - self._ax_prev) > AX_JUMP_MPS2)):
            self._ax_jump_k = k
        self._v_prev = v
        self._ax_prev = ax_raw
        verdict = None
        if isfinite(v) and isfinite(v_old) and isfinite(ax):
            dv = v - v_old
            self.ax_wheels = dv / (n * self.dt)
            res = dv - (cum_a - a_old)
            verdict = abs(res) > LON_TOL_MPS + LON_TOL_REL * abs(v)
        lon = self.lon
        if ax_ok and abs(ax_raw) > AX_IMPLAUSIBLE_MPS2:
            verdict = True  # beyond any tyre: not fused even for the steps the window needs
            lon.bad = max(lon.bad, lon.on - 1)
        was = lon.active
        if lon.update(verdict) and not was:
            self.lon_onset = k
            self.lon_culprit = WHEELS | ACCEL_X
        if lon.active:
            self._attribute(k)
        else:
            self.lon_culprit = 0

    def _attribute(self, k: int) -> None:
        """Which of wheels / accelerometer broke the longitudinal check (both until known).

        Evidence, strongest first: one of them keeps jumping (an intermittent sensor: a GNSS fix
        that happens to fall between its drop-outs must not bring it back); a GNSS fix taken
        while the disagreement lasts (the one it sides with is right; not after a step that
        has passed the window: a wheel sensor recovering); an impossible jump at the onset.
        """
        mem = JUMP_MEMORY_S / self.dt
        wj_now = k - self._wheel_jump_k <= mem
        aj_now = k - self._ax_jump_k <= mem
        if wj_now != aj_now:
            self.lon_culprit = WHEELS if wj_now else ACCEL_X
            return
        g = self._gnss_wheel_verdict
        if self.lon.bad and g is not None and g[0] >= self.lon_onset:
            self.lon_culprit = ACCEL_X if g[1] else WHEELS
            return
        if self.lon_culprit != WHEELS | ACCEL_X:
            return  # decided earlier; kept until new evidence
        wj = abs(self._wheel_jump_k - self.lon_onset) <= mem
        aj = abs(self._ax_jump_k - self.lon_onset) <= mem
        if wj != aj:
            self.lon_culprit = WHEELS if wj else ACCEL_X

    def _all_wheels_stuck(self, k: int, wheels: tuple, wheels_ok: bool, r: float) -> None:
        """All four wheels frozen together (a dead wheel-speed ECU repeating its last frame):
        no wheel can outvote the others, so the IMU is the witness: the rear wheels' difference
        should have followed the gyro's yaw rate (track * r), their speed the integrated ax."""
        if not wheels_ok:
            return
        was = self.wheels_stuck
        if not max(abs(wheels[0]), abs(wheels[1]), abs(wheels[2]), abs(wheels[3])) > STUCK_MIN_SPEED_MPS:
            r = math.nan  # near rest (sensors' dead band): no verdict, the references restart
        turn = self._unchanged("wheels_r", k, wheels, self.track * r, STUCK_WHEEL_MPS)
        # ax is a witness only while nothing speaks against it (implausible, jumping, isolated)
        ax_trusted = (not self.isolated & ACCEL_X and not self.lon_culprit & ACCEL_X
                      and k - self._ax_jump_k > JUMP_MEMORY_S / self.dt)
        speed = self._unchanged("wheels_a", k, wheels, self._cum_a if ax_trusted and r == r else math.nan,
                                STUCK_WHEEL_MPS)
        self.wheels_stuck = turn or speed
        if self.wheels_stuck:
            self.wheels_isolated = True
            self.wheels_back.active = True
            self.wheels_back.good = 0
            if not was:
                self.e_w = self.e_ws = 0.0

    def _wheels_return(self, v: float, vx: float, p_vx: float, wheel_r2: float) -> None:
        """Isolated wheels come back only when they agree with the filter's (IMU/GNSS) speed."""
        if self.wheels_stuck:
            return
        if self.lon.active:
            if self.lon_culprit & WHEELS:
                self.wheels_isolated = True
                self.wheels_back.good = 0
            else:  # the accelerometer broke the check: the wheels are the witness, fused again
                self.wheels_isolated = False
            return
        if not self.wheels_isolated:
            return
        if not math.isfinite(v):
            return
        tol = max(WHEELS_BACK_TOL_MPS, 4.0 * math.sqrt(p_vx + wheel_r2))
        self.wheels_back.active = True
        self.wheels_isolated = self.wheels_back.update(abs(v - vx) > tol)

    def _yaw(self, k: int, left: float, right: float, wheels_ok: bool, r_m: float, ay_m: float, imu_ok: bool,
             x: list, rdot: float, braking: bool = False) -> None:
        if not imu_ok:
            self.yaw_catch_up = 0.0
            return
        a_slow = self._a_slow
        a_yaw = self._a_yaw
        rdot_abs = self.rdot_abs = max(abs(rdot), self.rdot_abs - a_slow * self.rdot_abs)
        wide = YAW_TOL_RDOT * rdot_abs
        vx = x[VX]
        kw = x[KW]
        r_g = r_m - x[BR]
        v_axle = 0.5 * (left + right) * kw  # the witness axle's speed (yaw_pair)
        # the gyro's yaw acceleration through the same low-pass as e_w and the wheels' rate, so that
        # the scale test's LP(d) = s LP(r) + tau LP(rdot) holds as the filters are linear (against the
        # core's rdot, 0.05-0.08 s late, and a raw d_w, a wheel lead of 0.04 s read as a gyro scale)
        rg_lp = self._rg_lp
        self._rg_lp = r_g if rg_lp != rg_lp else rg_lp + a_yaw * (r_g - rg_lp)
        self._rdot_g = 0.0 if rg_lp != rg_lp else (self._rg_lp - rg_lp) / self.dt
        wheels_yaw = wheels_ok and not (self.isolated & WHEELS) and v_axle > YAW_MIN_SPEED
        # the wheels' yaw rate still stands in for an isolated gyro while braking (nothing better),
        # but it judges the gyro only while the witness pair rolls free (BRAKE_WITNESS_MPS2)
        have_w = wheels_yaw and not braking
        e_w = self.e_w
        e_ws = self.e_ws
        if wheels_yaw:
            r_wheels = self.r_wheels = ((right - left) * kw - self.lr * v_axle) / self.track
            rw_lp = self._rw_lp
            self._rw_lp = r_wheels if rw_lp != rw_lp else rw_lp + a_yaw * (r_wheels - rw_lp)
            d = r_g - r_wheels
        if have_w:
            e_w = self.e_w = e_w + a_yaw * (d - e_w)
            e_ws = self.e_ws = e_ws + a_slow * (d - e_ws)
            self._yaw_cum += d * self.dt
            if self.gyro.active:  # e_w against the gyro's own rate: both nearly free of wheel noise
                a = self._relearn
                a[0] += 1.0
                a[1] += r_g
                a[2] += r_g * r_g
                a[3] += e_w
                a[4] += e_w * r_g
                a[5] += e_w * e_w
        elif not wheels_yaw:
            r_wheels = self.r_wheels = self._rw_lp = math.nan
        ring = self._yaw_ring
        ring[k % len(ring)] = self._yaw_cum
        ay = ay_m - x[BAY] - x[GAY] * ay_m
        # an isolated gyro is not the lateral check's yaw rate: its substitute (the wheels') is what
        # the filter integrates vy with, so that is what the check must judge (a stuck gyro left
        # in here read as an ay fault of 10 m/s^2 and kept sideslip invalid the whole fault)
        self._lateral(vx, r_wheels if self.gyro.active and wheels_yaw else r_g, ay, rdot)
        have_a = vx > 2.0 * YAW_MIN_SPEED
        e_a = self.e_a
        e_as = self.e_as
        if have_a:
            # ay = dvy/dt + r vx: the kinematic dvy/dt = lr * rdot (the large term at low speed:
            # 0.25 rad/s at 6 m/s and 1 rad/s^2) is taken out, the rest of the transient is in
            # ``wide`` (not the model's full dvy/dt: it differentiates ay's noise)
            d = r_g - (ay - self.lr_m * rdot) / vx
            e_a = self.e_a = e_a + a_yaw * (d - e_a)
            e_as = self.e_as = e_as + a_slow * (d - e_as)
        # onset only: an isolated gyro returns by the level tests (a scaled one is right while r ~ 0,
        # and is out again within ON_STEPS of the next corner, the slope still in memory)
        scale_fail = have_a and have_w and not self.gyro.active and self._scale_test(self._rw_lp, r_g - r_wheels, d,
                                                                                    self._rdot_g, self.e_w)
        ref = abs(r_wheels) if have_w else abs(r_g)
        # the wheel relation is kinematic (no transient term); ay / vx misses dvy/dt / vx
        tol_w = YAW_TOL_WHEELS + YAW_TOL_WHEELS_REL * ref
        slow = YAW_SLOW_TOL + YAW_SLOW_TOL_REL * ref
        w_fail = have_w and (abs(e_w) > tol_w or abs(e_ws) > slow)
        fast_a = have_a and abs(e_a) > YAW_TOL_AY + YAW_TOL_AY_REL * ref + wide
        a_fail = fast_a or (have_a and abs(e_as) > slow + wide)
        # ay's own isolation: a bank changing no faster than a road's is followed by b_ay
        # (bank_rate.py), so its slow residual is not ay's fault. Only the verdict on ay widens: the
        # residual beyond the flat road's tolerance still makes the yaw witnesses suspect (sideslip
        # not promised while it is), and the gyro's vote is main's (widening it cost the suite's
        # fault_yaw_rate_offset its availability target). Not while ay is isolated: b_ay is frozen then and
        # follows nothing (a 2 m/s^2 offset at 22 m/s returned within the allowance 0.7 s before it
        # ended, suite fault_accel_y_offset).
        a_fail_ay = a_fail
        if AY_BANK_RATE_ALLOWANCE and a_fail and not self.ay.active:
            a_fail_ay = fast_a or abs(e_as) > slow + wide + bank_rate.slow_ay_allowance(vx, YAW_SLOW_TAU_S)
        if scale_fail:  # both witnesses: the gyro's disagreement grows with its own rate
            w_fail = a_fail = True
        jump = (have_w and abs(r_m - self._r_prev) > GYRO_JUMP_RADPS
                and not abs(r_wheels - self._rw_prev) > 0.5 * GYRO_JUMP_RADPS)
        self._r_prev = r_m
        self._rw_prev = r_wheels
        gyro = self.gyro
        ay_latch = self.ay
        if jump:  # no car turns that fast: not integrated even for the steps the vote needs
            w_fail = a_fail = True
            gyro.bad = max(gyro.bad, gyro.on - 1)
        # stuck gyro: both witnesses (the wheels' yaw rate, and ay / vx when there) moved, it did not
        was_stuck = self.gyro_stuck
        g_w = self._unchanged("gyro_w", k, r_m, r_g - e_w if have_w else math.nan, STUCK_YAW_RADPS)
        g_a = self._unchanged("gyro_a", k, r_m, r_g - e_a if have_a else math.nan, STUCK_YAW_RADPS)
        gyro_stuck = self.gyro_stuck = g_w and (g_a or not have_a)
        if gyro_stuck:
            w_fail = True
            gyro.bad = max(gyro.bad, gyro.on - 1)
            if not was_stuck:  # its drift began when it last changed, not when the residual showed it
                since = self._stuck_ref["gyro_w"].k
                self._w_fail_since = since if self._w_fail_since < 0 else min(self._w_fail_since, since)
        elif was_stuck:  # moving again: the residuals of the stuck stretch say nothing about it now
            self.e_w = self.e_ws = self.e_a = self.e_as = 0.0
        # stuck ay: r vx moved, ay did not (r from the wheels, low-passed, else from a trusted gyro)
        was_ay = self.ay_stuck
        ay_w = self._unchanged("ay_w", k, ay_m, self._rw_lp * vx if have_a and have_w else math.nan,
                               STUCK_AY_MPS2)
        ay_g = self._unchanged("ay_g", k, ay_m, r_g * vx if have_a and not have_w and not gyro.active
                               else math.nan, STUCK_AY_MPS2)
        ay_stuck = self.ay_stuck = ay_w or ay_g
        if was_ay and not ay_stuck:  # ay's residual against the gyro restarts from the wheels' view
            self.e_a, self.e_as = self.e_w, self.e_ws
        # three witnesses of one yaw rate: the odd one out is blamed; two cannot tell
        a_witness = have_a and not ay_latch.active
        # any yaw witness out of line: sideslip is not promised until the vote is clear
        self.yaw_suspect = w_fail or a_fail
        self.wheels_vouch_gyro = have_w and not w_fail
        # how fast the heading may be drifting meanwhile, when the gyro is the one the check
        # points at (the wheels disagree with it, or ay does and no wheels can say otherwise)
        gyro_suspect = w_fail or (a_fail and not have_w)
        self.yaw_disagreement = ((abs(e_w) if have_w else abs(e_a) if have_a else 0.0)
                                 if gyro_suspect else 0.0)
        # the fast test fails a filter lag after the fault began: the heading drifted unseen meanwhile
        # (from the last suspect step on at most: the stds grew for the drift of a suspect stretch)
        catch_up = 0.0
        if gyro_suspect and not self._gyro_suspect and have_w:
            start = max(k - self._repair_lag, self._suspect_k + 1)
            if start < k:
                catch_up = abs(ring[k % len(ring)] - ring[start % len(ring)])
        self.yaw_catch_up = catch_up
        self._gyro_suspect = gyro_suspect
        if gyro_suspect:
            self._suspect_k = k
        # the two witnesses against each other: with the gyro isolated, the wheels' yaw rate (its
        # substitute) is vouched for by ay only while this holds
        self.witnesses_agree = (a_witness and have_w
                                and abs(e_a - e_w) <= YAW_TOL_AY + YAW_TOL_AY_REL * ref + wide
                                and abs(e_as - e_ws) <= slow + wide)
        if not w_fail:
            self._w_fail_since = -1
        elif self._w_fail_since < 0:
            self._w_fail_since = k
        was = gyro.active
        verdict = (w_fail and (a_fail or not a_witness)) if have_w else None
        if self.witnesses_must_agree and not was:  # two witnesses that contradict each other cannot tell
            verdict = gyro_vote.onset_verdict(verdict, self.witnesses_agree, a_witness,
                                              jump or gyro_stuck)
        if gyro.update(verdict):
            if not was:
                self._plan_heading_repair(k)
                self._relearn = [0.0] * 6
            elif self._relearn[0] * self.dt >= RELEARN_S:
                self._relearn_bias()
        elif was and self._scale[0] > 0.0:  # back: a slope from the fault (a zero, a stuck value) is not its
            self._scale = [0.0] * 13
            self._scale_ay = [0.0] * 3
        # while the gyro is out, the heading integrates its substitute (the wheels' yaw rate; 0
        # without wheels): how fast that may be off, measured against its one independent witness
        # (ay / vx, low-passed as e_a) plus that witness's transient allowance, else the wheels'
        # own kinematic tolerance. Even the free-rolling pair's yaw rate is off by more than a
        # random walk describes (track, radius and lag errors; all-wheel drive has no free axle).
        if have_a:
            e_sub = self.e_sub = self.e_sub + a_yaw * (((r_wheels if wheels_yaw else 0.0)
                                                        - (ay - self.lr_m * rdot) / vx) - self.e_sub)
        else:
            e_sub = self.e_sub = 0.0
        if gyro.active:
            self.substitute_yaw_error = (abs(e_sub) + wide if a_witness
                                         else YAW_TOL_WHEELS + YAW_TOL_WHEELS_REL * ref + wide)
        else:
            self.substitute_yaw_error = 0.0
        # ay is judged against a gyro the wheels vouch for (a gyro fault leaves both residuals
        # high for as long as they decay; that is not ay's fault)
        if ay_stuck:
            ay_latch.trip()
        else:
            ay_verdict = (a_fail_ay and not w_fail) if (have_w and have_a and not gyro.active) else None
            # an ay isolated a second time returns only on agreement that would have shown its
            # fault: driving straight, ay ~ r vx ~ 0 whatever its sign or scale (a sign-flipped ay
            # went back in on every straight of the demo drive and out again 0.1-0.3 s into each
            # turn, 2.7 deg off while valid meanwhile). The first time, a straight's agreement
            # still counts: a fault that came and went (the suite's 5 s offset, stuck, zero ay)
            # shows on a straight too, and ay's sideslip would otherwise wait for the next corner.
            if (ay_verdict is not None and not ay_verdict and ay_latch.active and ay_latch.events >= 2
                    and ref < AY_RETURN_MIN_R):
                ay_verdict = None
            ay_latch.update(ay_verdict)
        if have_w and not w_fail and not gyro.active and self.isolated == 0 and v_axle > 2.0 * YAW_MIN_SPEED:
            mis = ((right - left) * kw - self.track * r_g) / v_axle
            self.lr += self._a_lr * (mis - self.lr)
            self.lr = min(max(self.lr, -LR_MAX), LR_MAX)

    def _scale_test(self, r_w: float, d_w: float, d_a: float, rdot: float = 0.0, e_w: float = 0.0) -> bool:
        """A scaled gyro (x1.3) disagrees by 0.3 r: inside the level tests' tolerances, which grow
        with |r| for track, radius and transient errors, but a slope of the disagreement against
        the yaw rate (weighted over YAW_SLOW_TAU_S) that neither witness has: the wheels' track and
        radius errors and ay's roll gravity give a few %. Both must show it, alike. The rate is
        the wheels', low-passed: the gyro's own noise against itself would read as a slope.

        The wheels' yaw rate comes through the ABS ECU's filtering and pulse-window averaging: a
        lag ``tau`` against the gyro makes ``d_w = tau * rdot``, and while a lane change builds up
        its yaw rate that rides on r (wheel_lag_0.04_dlc_1hz: slope 0.16-0.21 from a 0.04 s lag,
        the gyro isolated and the heading 'repaired' by the lag's disagreement, 1.2 deg off). So
        the wheels' slope is also fitted together with a timing term (e_w = c + s r + tau rdot, the
        three through the same low-pass YAW_TAU_S, rdot the gyro's), tau within
        +-WHEEL_YAW_LAG_MAX_S (either sign: the wheels may also lead the IMU). The timing term may
        explain a slope away, never make one: the smaller of the two slopes counts (a noisy rear
        wheel fits any tau, and at the bound it made a slope of its own: a good gyro isolated)."""
        r_g = r_w
        m = self._scale
        a = self._a_slow
        for j, v in enumerate((1.0, r_g, r_g * r_g, d_w, r_g * d_w, d_a, r_g * d_a,
                               rdot, rdot * rdot, r_g * rdot, rdot * e_w, e_w, r_g * e_w)):
            m[j] += a * (v - m[j])
        if self.witnesses_must_agree:
            ma = self._scale_ay
            e_a = self.e_a
            for j, v in enumerate((rdot * e_a, e_a, r_g * e_a)):
                ma[j] += a * (v - ma[j])
        w = m[0]
        mr = m[1] / w
        var_r = m[2] / w - mr * mr
        if not var_r > SCALE_MIN_SPREAD * SCALE_MIN_SPREAD:
            return False
        s_w = (m[4] / w - mr * m[3] / w) / var_r
        mq = m[7] / w
        var_q = m[8] / w - mq * mq
        cov_rq = m[9] / w - mr * mq
        det = var_r * var_q - cov_rq * cov_rq
        if var_q > 0.0 and det > SCALE_LAG_COND * var_r * var_q:
            me = m[11] / w
            cov_re = m[12] / w - mr * me
            tau = (var_r * (m[10] / w - mq * me) - cov_rq * cov_re) / det
            tau = min(max(tau, -WHEEL_YAW_LAG_MAX_S), WHEEL_YAW_LAG_MAX_S)
            s_t = (cov_re - tau * cov_rq) / var_r
            if abs(s_t) < abs(s_w):
                s_w = s_t
        s_a = (m[6] / w - mr * m[5] / w) / var_r
        if self.witnesses_must_agree and var_q > 0.0 and det > SCALE_LAG_COND * var_r * var_q:
            ma = self._scale_ay
            s_a = gyro_vote.ay_slope(s_a, var_r, var_q, cov_rq, det, ma[0] / w - mq * ma[1] / w,
                                     ma[2] / w - mr * ma[1] / w)
        fail = (s_w > SCALE_TOL and s_a > SCALE_TOL) or (s_w < -SCALE_TOL and s_a < -SCALE_TOL)
        if fail and self.witnesses_must_agree:  # a scale error puts one slope into both (gyro_vote.py)
            return gyro_vote.slopes_agree(s_w, s_a)
        return fail

    def _plan_heading_repair(self, k: int) -> None:
        """The gyro is isolated at step k: the heading it integrated since the disagreement began
        (the fast test's lag before the first failure, at most REPAIR_WINDOW_S back) drifted by the
        integral of gyro minus wheels; the core adds that back to the stored steps (psi' = -r)."""
        ring = self._yaw_ring
        n = len(ring)
        since = self._w_fail_since if self._w_fail_since >= 0 else k
        onset = max(since - self._repair_lag, k - n + 1)
        base = ring[onset % n]
        self.heading_repair = (onset, [ring[j % n] - base for j in range(onset, k + 1)])

    def _relearn_bias(self) -> None:
        """The isolated gyro against the wheels over the last RELEARN_S: (gyro - wheels) = b + s
        r_gyro fitted; a steady offset (s ~ 0, little scatter) is a bias the bias state learns
        from now on (its random walk could not follow the step), so the gyro is released with it.
        A scaled gyro (s = 0.3 / 1.3 for x1.3), a noisy one, or one that does not move (stuck, or
        a straight road that cannot tell offset from scale) stays out; the window starts again."""
        n, sr, srr, sd, sdr, sdd = self._relearn
        self._relearn = [0.0] * 6
        mr, md = sr / n, sd / n
        var_r = srr / n - mr * mr
        if not var_r > RELEARN_MIN_SPREAD ** 2:
            return
        cov = sdr / n - mr * md
        slope = cov / var_r
        resid2 = sdd / n - md * md - slope * cov
        if abs(slope) >= RELEARN_SLOPE or resid2 >= RELEARN_RESID ** 2:
            return
        b = md - slope * mr
        # its variance: the scatter over one sample per OFF_STEPS (the residual is correlated)
        self.bias_relearn = (b, max(resid2, 0.0) / max(n / OFF_STEPS, 1.0))
        g = self.gyro
        g.active = False
        g.bad = g.good = 0
        for name in ("e_w", "e_ws", "e_a", "e_as"):  # the residuals are against the new bias
            setattr(self, name, getattr(self, name) - b)

    def _lateral(self, vx: float, r: float, ay: float, rdot: float) -> None:
        """Residual of ay against r * vx plus the model's change of vy over the last window, and
        the rate of it no bank, roll or model error explains (:attr:`lat_excess`)."""
        if self._model_vy is None:
            return
        if not vx > LAT_MIN_SPEED:
            if self._lat_filled:  # (emptied once, not re-allocated every slow step)
                self._lat_ring = [None] * self._lat_n
                self._lat_filled = False
            self.lat_residual = self.lat_excess = self.lat_unexplained = 0.0
            return
        dt = self.dt
        lat_cum = self._lat_cum = self._lat_cum + (ay - r * vx) * dt
        lat_abs = self._lat_abs = self._lat_abs + abs(ay) * dt
        vy_m = self._model_vy(vx, r, ay, rdot)
        n = self._lat_n
        i = self._lat_k % n
        self._lat_k += 1
        ring = self._lat_ring
        old = ring[i]
        ring[i] = (lat_cum, lat_abs, vy_m, r)
        self._lat_filled = True
        if old is None:
            return
        w = n * dt
        res = (lat_cum - old[0]) - (vy_m - old[2])
        self.lat_residual = res
        unexplained = self.lat_unexplained = max(abs(res) - LAT_TOL_MPS - LAT_TOL_RDOT_M * abs(r - old[3]), 0.0) / w
        self.lat_excess = max(unexplained - LAT_RATE_TOL - LAT_RATE_TOL_REL * (lat_abs - old[1]) / w, 0.0)

    # ------------------------------------------------------------------------------------------
    def check_gnss(self, s: int, wheels_agree: bool | None, filter_agree: bool) -> bool | None:
        """Is a GNSS speed (validity step s) consistent with the other sources? None: cannot tell.

        ``wheels_agree``: its speed against the wheel speed at step s (None: no wheel speed);
        ``filter_agree``: against the filter's vx there, within its uncertainty. The wheels are
        the witness while they are trusted; while the longitudinal check fails (or the wheels are
        isolated) the fix is instead the witness that tells wheels from accelerometer, and is
        itself checked against the filter.
        """
        wheels_usable = wheels_agree is not None and not (self.isolated & WHEELS)
        if wheels_agree is not None and (self.lon.active or self.wheels_isolated):
            self._gnss_wheel_verdict = (s, wheels_agree)
            wheels_usable = False
        if wheels_usable:
            ok = wheels_agree
        elif self.isolated & ACCEL_X and wheels_agree is None:
            ok = None  # neither wheels nor accelerometer to compare with
        else:
            ok = filter_agree
        self.gnss.update(None if ok is None else not ok)
        return ok

    def gnss_implausible(self) -> None:
        """A GNSS speed no car can have: a GNSS fault without needing a witness."""
        self.gnss.update(True)

    @property
    def gnss_isolated(self) -> bool:
        return self.gnss.active

    def standstill_plausible(self, vx: float, gnss_speed: float) -> bool:
        """Wheels say 'stopped': do the IMU-propagated speed (and a fresh GNSS speed) agree?"""
        if self.isolated & WHEELS:
            return False
        if abs(vx) > STANDSTILL_MAX_VX:
            return False
        return not (math.isfinite(gnss_speed) and gnss_speed > STANDSTILL_MAX_VX)
