"""The sideslip's change that the GNSS course shows against the gyro: a slow slide no accelerometer rule sees.

Why (issue 7, never-seen random drives 2271 and 2318: mu 0.22, a steady circle on a 2.9 deg bank and a
j-turn, both spun): the car slid slowly into its limit on ice, its sideslip growing at ~1 deg/s, and the
single-track model's vy, which reads the tyres as gripping, kept the sideslip's std small. The steering's
misfit did not see it (both axles let go alike) and ``slide_rate.py`` cannot: a slide of 0.25 m/s^2 in
ay - r vx stays below the accelerometer's residual offset's 3 sigma (0.3 m/s^2) over any memory, and a
bank change puts the same into ay (why slide_rate is gated on the friction memory).

The physics that tells a slide from a bank: the course over ground is heading + sideslip, and the gyro
measures the heading's change alone. Between two fixes W seconds apart
``d_course + int(r) dt + d_beta_model`` (the heading clockwise, course + sideslip; r counter-clockwise) is the model's sideslip error's change: a bank enters ay, not the
gyro nor the course, so it cannot open this rule. What else moves it: each course's noise (the fix's
velocity noise over the speed), the gyro's bias error times W and its scale error times the turn, the
receiver's latency error times the yaw rate's change (the largest between the instants the two courses
may really be from: a latency 0.7 s off carries a lane change's 0.3 rad/s into courses taken where r is
0; ``core.COURSE_SLIDE_TIMING``), and the change of the model's own error (a bias
for the corner: the change of its std, and a floor for unmodelled dynamics). Beyond 3
sigma of those, the excess angle times vx is what the model's vy may be off by: it joins the law excess
(``core.COURSE_SLIDE``), which widens the pseudo-measurement, so the filter's sideslip std grows with it.
The gyro's bias is taken as the filter knew it at the older fix: a slide the filter has begun to take into
b_r (a steady circle: a sideslip rate is a gyro bias to the filter) is still counted against it.

The scale term (``core.COURSE_SLIDE_SCALE_SENS``): a scale error s the scale check has not applied turns
the gyro's turn by s x the turn, and the filter's bias state takes part of it in a corner (to the filter a
steady s r is a bias): b_r is off by S_br s (``scale_sensitivity.py``, S through the filter's own gains,
x_err = -S s). Less the bias known at the older fix, the residual carries ``s (turn + S_br(t0) W)``,
signed: in the corner the two cancel as far as b_r took the scale (S_br ~ -r), on the straight after it
the turn is 0 and the bias's share S_br(t0) W is left whole (a flying start with a -5 % gyro: b_r -1.4
deg/s, 7-9 deg over 4 s, which a scale std x the straight's zero turn did not cover). s is the scale's
rms over both priors not applied yet (``YawScaleCheck.heading_scale``, the heading std's own term):
~1.2 % before the fit has seen a turn, the wide prior's posterior once the data select it. That std does
not bound the bias's share (the fit reads the bias-corrected gyro, blind to it: ``BIAS_SHARE_SCALE_SD``),
so this term alone did not make the rule honest about a 5 % gyro (stop 46).
"""
from __future__ import annotations

import math
from collections import deque

WINDOW_S = 4.0  # s between the two fixes compared: a 1 deg/s slide is 4 deg, beyond 3 sigma of ~1 deg
SIGMA = 3.0
MIN_SPEED = 5.0  # m/s: the course's noise grows as 1 / speed
HOLD_S = 1.5  # s a measured excess stands without a newer fix (GNSS at 1 Hz)
# rad: the model's sideslip error is a bias for the whole corner (its parameters and tyre law,
# SingleTrackFusion.model_error): what its change over the window may be is the change of that std,
# plus this much of unmodelled dynamics (a relaxation lag's 0.3 deg, core.MODEL_STEADY_RDOT)
MODEL_FLOOR_RAD = math.radians(0.3)
# The scale the signed term counts at least (0: the scale check's own, YawScaleCheck.heading_scale). The
# share of a scale error the bias state took is invisible to the scale check, which fits the
# bias-corrected gyro: on the -5 % flying start it applied -1.15 % and published 0.45 % while b_r was still
# 1.4 deg/s off, so its std does not bound S_br s. No floor tried at stop 46 separates that from a slide
# (flying_10_gyro_-5pct heading valid above 5 m/s / random drives 2271, 2404, 2827 with COURSE_SLIDE on):
# 0 (the fit's): 0.41 / kept; 0.0122 (the priors' rms): 0.46 / 2404 12 sideslip rows beyond 3 sigma;
# 0.021: 0.64 / 2271 104 and 2827 280 heading rows, 2404 61 sideslip rows; 0.05: the same, 2271 190.
BIAS_SHARE_SCALE_SD = 0.0


class CourseSlide:
    """Course change less the gyro's turn less the model's sideslip change, over WINDOW_S."""

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        self.fixes: deque = deque()  # (t, course, course_var, turn, bias, beta_model, model_var, r, span, r_lo, r_hi, s_br)
        self.turn = 0.0  # the gyro's raw turn since the first fix (rad)
        self.span = 0.0  # the time it spans (s)
        self.var = 0.0  # the excess of the last fix ((m/s)^2)
        self.t_var = -math.inf
        self.angle = 0.0  # the last mismatch (rad, signed) and its 3 sigma, for the log / tests
        self.lim = 0.0
        self.d_scale = 0.0  # the last d m / d s (rad per unit scale), for the log / tests

    def observe(self, t: float, course: float, course_std: float, yaw_sum: float | None, dt_sum: float,
                bias: float, bias_std: float, beta_model: float, model_std: float, r: float, vx: float,
                speed: float, latency_std: float, scale_std: float, now: float, r_lo: float | None = None,
                r_hi: float | None = None, s_br: float | None = None) -> None:
        """One fix at its time of validity ``t``: ``yaw_sum`` the stored bias-corrected yaw rates' sum
        since the previous fix (None: no continuous history, start over), ``dt_sum`` the time it spans,
        ``bias`` the filter's gyro bias there; ``now`` the step it arrives at (the hold runs from it);
        ``r_lo`` / ``r_hi`` the yaw rate's least and largest over the instants the course may really be
        from (the latency's error: default ``r``), so that the timing term is the largest change of r
        between the two courses' true instants, not its change between the fixes' nominal ones.
        ``s_br``: d b_r / d s at this fix (the bias state's scale sensitivity); ``scale_std`` is then the
        unapplied scale's rms and the scale term signed (module docstring). None: the stop-45 term,
        ``scale_std`` x the turn."""
        if yaw_sum is None or not speed >= MIN_SPEED or not vx >= MIN_SPEED:
            self.reset()
            return
        fx = self.fixes
        if fx:
            # the gyro's raw turn (the corrected sum plus the bias it was corrected by) and its time
            self.turn += yaw_sum + bias * dt_sum
            self.span += dt_sum
        if r_lo is None or r_hi is None:
            r_lo = r_hi = r
        fx.append((t, course, course_std * course_std, self.turn, bias, beta_model, model_std * model_std, r,
                   self.span, r_lo, r_hi, s_br))
        while len(fx) > 1 and t - fx[1][0] >= WINDOW_S:
            fx.popleft()
        t0, c0, cv0, turn0, b0, beta0, mv0, r0, span0, r0_lo, r0_hi, s_br0 = fx[0]
        if t - t0 < WINDOW_S or len(fx) < 2:
            return
        dturn = self.turn - turn0 - b0 * (self.span - span0)  # less the bias known at the older fix
        # the heading is clockwise (course + sideslip), the gyro's turn counter-clockwise (ISO 8855)
        m = math.remainder(course - c0 + dturn + (beta_model - beta0), 2.0 * math.pi)
        # the scale's share: d m / d s, the turn and the older fix's bias error signed together
        if s_br0 is None:
            d_scale = dturn
        else:
            d_scale = dturn + s_br0 * (self.span - span0)
            scale_std = max(scale_std, BIAS_SHARE_SCALE_SD)
        self.d_scale = d_scale
        var = (cv0 + course_std * course_std + (bias_std * (t - t0)) ** 2 + (scale_std * d_scale) ** 2
               + (latency_std * max(r_hi - r0_lo, r0_hi - r_lo)) ** 2 + (model_std - math.sqrt(mv0)) ** 2 + MODEL_FLOOR_RAD ** 2)
        lim = SIGMA * math.sqrt(var)
        self.angle, self.lim = m, lim
        e = abs(m) - lim
        self.var = (e * vx) ** 2 if e > 0.0 else 0.0
        self.t_var = now

    def excess_var(self, t: float) -> float:
        """(m/s)^2 the model's vy may be off by, as of the last fix (0 once it is HOLD_S old)."""
        return self.var if t - self.t_var <= HOLD_S else 0.0
