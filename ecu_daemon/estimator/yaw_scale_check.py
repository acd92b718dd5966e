"""How well is the gyro's scale known? A fit of GNSS course changes against the integrated yaw rate.

A yaw-rate scale error s (sensor sensitivity; on a banked road also the tilt: the heading turns at
r / cos(bank)) turns the filter's heading by s x r per second. In a steady corner GNSS course cannot
tell that from sideslip, so the core grows vy's std by s x |r vx| per second (core.YAW_SCALE_STD,
the prior 0.5 %). The scale is observable all the same: over a turn, or a long circle where the
sideslip is about constant, the course changes by the true heading change, and that is
(1 + s)^-1 times the integrated gyro. A constant GNSS latency error does not change that (the
course change over a whole turn is the same, only later), a residual gyro bias does (by bias x
time), which the filter's own yaw-bias state bounds (its std, learned at standstill and on
straights). So the residual of the heading a course implies (with the single-track model's sideslip: the
filter's own vy takes part of the scale error, and a fit against it saw a third of a 1 % error)
against the gyro's heading,

    z = course + beta_model - psi_gyro = c0 + db (t - t_run) + s I + dx (r / vx) - dd r + noise,

with t_run the run's start (a new offset after a gap) and I the bias-corrected yaw rate integrated since the run's start (rad, counterclockwise), is
fitted for [c0 (per run), db (residual bias), s, dx (antenna lever arm x error), dd (latency
error)]: the residual ``lever_arm_check.LeverArmCheck`` fits, with the integral as a fifth
column. The latency error is that of the delay each fix was placed with,
so while the identification still moves the delay (a wrong prior corrected in a circle's first
seconds) the fixes' errors differ by the known moves: every fix is rebased on the current delay
(``lever_arm_check.rebase_latency``), else the move, r x 0.25 s on a 0.56 rad/s circle, is read as
a scale (random drive 417: -2.8 % on an exact gyro, applied, the heading moved 5.5 deg and was
promised to 1.4 deg while 6.5 deg off). The fit's s is the heading error per radian the gyro integrates: s / (1 + s) for a gyro
reading (1 + s) r, which is also what the core's s |r_gyro vx| needs. It is a separate fit, not a fifth column of that one, because the lever-arm flag's timing
was sized on a four-unknown fit (one more unknown widens its dx std and delays its flag), and
because the two need different priors: here the bias column is held by the filter's yaw-bias std
(the lever-arm fit allows a wide 0.3 deg/s drift, which on a steady circle at 0.3 rad/s would leave
s unresolved below 1.7 %), and the scale, a sensor constant, is remembered longer.

The core applies s_hat to the gyro (r = r_m (1 - s_applied)) once the fit resolves it
(``applied()``: |s_hat| beyond APPLY_SIGMA of its std); it feeds the fit the *raw* gyro (the stored
corrected rates divided by the (1 - s_applied) of their step), so the fit keeps estimating the
whole scale, not the residual of its own correction (no feedback loop). ``scale_std()`` is what the
core grows vy's std by and publishes on the heading: |s_hat| + std_s, the whole scale even once it
is applied (what the scale put into heading and vy before it was resolved stays in the state until
courses and the model have separated it, and the fit reads 10-25 % low while the filter's yaw-bias
state takes a part of s r; narrowed to the residual |s_hat - applied| + std_s the 3 % suite cases
fell to 50 % within 3 sigma) until the core has moved its state by what it carries of the applied
scale (``core.Estimator._shift_for_scale``: S x applied, ``scale_sensitivity.py``; not to the fit's
heading, ``heading()``, which early in a drive is drawn with a shrunk scale), then the
residual with what the fit reads low (``core.YAW_SCALE_FIT_LOW``); never below the tilt of a 6 % banked road (BANK_TILT_SCALE: a bank
the window has not seen yet), and not capped. Unobserved (no turning yet) it is the prior, so a
drive without corners publishes what it did before and its gyro is left untouched.

Which prior: 0.5 % is a calibrated gyro's, but an uncalibrated automotive sensor is specified to a
few per cent, and early in a long corner the narrow prior shrinks a real 3 % to a fraction of it
while the heading is already degrees off. The fit is solved with a SENSOR_TOL prior as well; the
data's own scale (that fit with its prior taken out, widened by the model's sideslip error over the
rotation turned) weighs the two priors by their marginal likelihoods (``_select``, P_WIDE a priori).
Once a radian has turned (SELECT_ROT) and the wide prior is the likelier, its fit is the scale (so
it is applied, and the core realigns, with the data's scale, not the shrunk one). The core
publishes on the heading the rms over both of the scale not yet applied (``heading_scale``) times
what the heading still carries of a scale error (``scale_sensitivity.py``: d psi / d s through the
filter's gains).

The scale is a sensor constant: the learned-state file keeps s_hat and its std, and a restart
starts the fit from them (``prior``): as information the fit had gathered, forgotten over WINDOW_S
like the rest (a gyro replaced or re-mounted between drives is relearned, not held by a fixed
prior), never tighter than RESTORE_FLOOR.

A scale that *changes* mid-drive (a temperature jump, a sensor swap, the start of a bank) is not
followed by a 300 s memory: the fit keeps the old scale and its residuals run away in one direction
(a 2 % step on a 0.3 rad/s circle turns the heading 0.34 deg/s away), until the 5-sigma gate drops
every fix. A two-sided CUSUM on the normalised residuals (gated fixes included: they are the
signal) detects it (``changed``). The response: the scale's information is forgotten (marginalised
out like a run's offset, the bias, dx and latency information kept), a restored scale dropped, a
new run opened, and the step's size (the residual over the yaw integrated since the CUSUM last
sat at zero, the change point's estimate) is published on the scale until the refit resolves it.
The core widens vy's and the heading's std by the heading error found at once (``take_change``).
"""
from __future__ import annotations

import math

import numpy as np

from . import lever_arm_check
from .lever_arm_check import COURSE_NOISE_RAD, CORR_FIXES, GATE_SIGMA, LEVER_TOL_M, MAX_GAP_S, MIN_SPEED, \
    marginalise_offset, rebase_latency

#: prior std of the scale error: the core's constant before this fit existed (core.YAW_SCALE_STD),
#: an automotive MEMS gyro's sensitivity tolerance after calibration; a drive without corners
#: keeps publishing it (the term is s |r vx|, zero where r is)
SCALE_PRIOR = 0.005
#: a road's cross slope: 6 % (the usual maximum superelevation of urban roads) turns the heading at
#: r / cos(atan 0.06), 0.18 % faster than a level gyro reads; the floor of the published scale,
#: since a bank can start after the window the fit learned the scale in
BANK_TILT_SCALE = 1.0 / math.cos(math.atan(0.06)) - 1.0
#: forgetting time: the scale is a sensor constant (temperature moves it by tenths of a per cent over
#: minutes), the bias the fit's other column holds is bounded by the filter's std at each solve
WINDOW_S = 300.0
#: rad/s: the filter's yaw-bias std is the residual bias prior, but never tighter than this (the
#: filter's bias state is itself corrected during the window, by up to its std at any time)
BIAS_FLOOR = math.radians(0.005)
#: the fit's scale is applied to the gyro once it is this many of its stds from zero: resolved at
#: 3 sigma it is a property of the sensor, not the fit's noise (on Revs, whose gyro has no scale
#: error, applying the fit from one std on -- +0.3 +- 0.16 % for a while -- took the heading RMS
#: from 0.153 to 0.22 deg); below it the gyro is left as it reads and the term keeps the whole
#: |s_hat| + std, as before
APPLY_SIGMA = 3.0

#: Model selection for the heading (``heading_scale``): the 0.5 % prior is a calibrated gyro's; an
#: uncalibrated automotive yaw-rate sensor's sensitivity is specified to a few per cent, so a gyro
#: may also be a draw from this wider prior. Early in a long corner the fit with the 0.5 % prior
#: shrinks a real 3 % scale to 0.45 +- 0.46 % (suite circle, 25 s) while the heading is already
#: 2 deg off: the data's own scale (3.2 +- 1.2 % then) is what says which prior it came from.
SENSOR_TOL = 0.05
#: prior probability of the wide component: a gyro beyond its calibrated 0.5 % is the exception
#: (the mixture then publishes ~1.2 % on a corner's first radian, 0.5 % once the data agree with
#: the narrow prior, and the wide posterior once they contradict it)
P_WIDE = 0.05
#: rad: the rotation the fit must have integrated before its data may select the wide prior. Below
#: it a sensor-tolerance scale turns the heading by less than SENSOR_TOL x 1 rad = 2.9 deg, what a
#: lane change at the friction limit leaves in the single-track model's sideslip (mu03_outage_30s:
#: the wide fit read +17 % from +-0.25 rad of a lane change on mu 0.3 with an exact gyro); the suite
#: circle's 3 % is selected at 1.7 rad
SELECT_ROT = 1.0

#: a restored scale's std is never below this: a MEMS gyro's sensitivity moves by about 0.1 %
#: with temperature between drives, and the restored value is itself the fit's estimate, biased low
#: by ~10 % of the scale where the filter's yaw-bias state took part of it; 0.2 % also lets a
#: circle's courses (std ~0.1 % within a minute) override it when the sensor changed
RESTORE_FLOOR = 0.002

#: CUSUM drift per fix, in residual stds: the fix variance is already inflated by CORR_FIXES for
#: the correlated course noise, so a fit with no change has |e| / std around 1 / sqrt(CORR_FIXES)
#: (0.45); the single-track model's bias over a corner can hold it near that for seconds, so 0.75
#: std per fix is subtracted and only a residual beyond that accumulates
CUSUM_DRIFT = 0.75
#: CUSUM alarm: 15 residual stds accumulated beyond the drift (about 20 fixes, 2 s at 10 Hz, of a
#: residual at 1.5 std: a heading ~1.5 course stds off for seconds); on synthetic circles with course
#: noise up to 1 deg and constant scales up to 3 % it never fired in 300 s, a drift of 0.5 with an
#: alarm of 10 did
CUSUM_ALARM = 15.0
#: the detector runs only once the fit knows the scale to this (RESTORE_FLOOR's 0.2 %): a change is
#: relative to a known scale; before that a runaway is the fit still learning (the scale itself,
#: or the bias and latency early in a drive: mu03_outage_30s fired at 23 s, 6.8 deg, with no scale
#: error at all)
CHANGE_KNOWN = RESTORE_FLOOR
#: a residual counts at most this many stds: one wild fix (a multipath course) must not alarm alone
CUSUM_CLIP = 8.0


_ZEROS = np.zeros(5)  # regressors that add nothing: the second solve of the same information


class YawScaleCheck:
    """One receiver's course-against-gyro scale fit (information form, exponentially forgotten):
    unknowns [offset of the current run, residual bias (rad/s), scale error, dx, latency error]."""

    N = 5

    def __init__(self, lever_x: float, prior: tuple[float, float] | None = None):
        self.lever_x = lever_x
        self.info = np.zeros((self.N, self.N))
        self.rhs = np.zeros(self.N)
        self.scale = 0.0
        self.scale_sd = SCALE_PRIOR
        # what the learned-state file restored: the scale's information, forgotten as the fixes' is
        # (kept apart: dropped at once if this drive's own fixes disagree with it, a changed sensor)
        self.restored = prior is not None
        self.r_info = self.r_rhs = 0.0
        if self.restored:
            s0, sd0 = float(prior[0]), max(float(prior[1]), RESTORE_FLOOR)
            self.r_info = 1.0 / sd0 ** 2
            self.r_rhs = s0 / sd0 ** 2
            info = self.r_info + 1.0 / SCALE_PRIOR ** 2  # with the prior, as _solve combines them
            self.scale = float(self.r_rhs / info)
            self.scale_sd = math.sqrt(1.0 / info)
        self.t_run = 0.0
        self.t_last = -math.inf
        self.psi_gyro = 0.0
        self.yaw_int = 0.0
        self.k_last = -1
        self.n = 0
        self.gated = 0
        self.theta = np.zeros(self.N)
        self.cov = None
        self.wide = (0.0, SENSOR_TOL ** 2)  # the scale's posterior under the wide prior (mean, var)
        self.p_wide = P_WIDE
        # the single-track model's sideslip error at the last fix (rad) and the largest rotation the
        # fit has integrated within its memory (rad): a model bias held over a corner reads as a
        # scale of bias / rotation (``_select``)
        self.model_rad = 0.0
        self.rot_seen = 0.0
        # scale-change detection (module docstring): CUSUM sums, the yaw integral where each last
        # sat at zero (the change point's estimate), alarms, the step's size, the heading error
        # found at the alarm (rad) for the core to take once
        self.cusum_hi = self.cusum_lo = 0.0
        self.int_hi = self.int_lo = 0.0
        self.changes = 0
        self.step = 0.0
        self.change_heading = 0.0
        # the delay the fixes in the information were placed with (``rebase_latency``; None: none yet)
        self.delay_s = None

    def restart(self) -> None:
        """Forget the gyro integral (a filter reset): the next fix opens a new offset."""
        self.k_last = -1

    def observe(self, t: float, k: int, dt: float, r_sum: float | None, course: float, sigma_v: float, speed: float,
                vx: float, vy: float, r: float, lever_y: float, latency_std_s: float, bias_std: float,
                vy_std: float = 0.0, delay_s: float | None = None) -> None:
        """As ``LeverArmCheck.observe``, plus ``bias_std``: the filter's yaw-rate bias std (rad/s);
        ``vy`` is the single-track model's (not the filter's, which takes part of a scale error into
        its sideslip, so that a fit against it saw a third of a 1 % error) and ``vy_std`` its error;
        ``delay_s`` the delay this fix was placed with (the latency column is rebased on it:
        ``lever_arm_check.rebase_latency``; None: the fixes' delays are taken as one)."""
        self.delay_s = rebase_latency(self.info, self.rhs, self.theta, 4, self.delay_s, delay_s)
        if speed < MIN_SPEED or vx < MIN_SPEED:
            self.k_last = -1
            return
        ratio = r / vx
        beta = math.atan2(vy + r * self.lever_x, vx - r * lever_y)
        new_run = self.k_last < 0 or r_sum is None or t - self.t_last > MAX_GAP_S or k <= self.k_last
        if new_run:
            self._new_run(course + beta)
            self.t_run = t
        else:
            turned = r_sum * dt
            self.psi_gyro -= turned  # clockwise, as the heading
            self.yaw_int += turned
        if (self.n or self.restored) and t > self.t_last > -math.inf:
            f = math.exp(-(t - self.t_last) / WINDOW_S)
            self.info *= f
            self.rhs *= f
            self.r_info *= f
            self.r_rhs *= f
            self.rot_seen *= f
        self.k_last = k
        self.t_last = t
        self.model_rad = vy_std / vx
        self.rot_seen = max(self.rot_seen, abs(self.yaw_int))
        h = np.array((1.0, t - self.t_run, self.yaw_int, ratio, -r))
        # the lever-arm checks' kernels (compiled by ``backend.select``): h' theta and h' cov h
        pred, spread = lever_arm_check.fit_predict(h, self.theta, self.cov) if self.cov is not None else (0.0, 0.0)
        # unwrapped about the fit's prediction: a 3 % scale error turns the gyro heading by more
        # than pi over 17 laps of a circle
        z = pred + math.remainder(course + beta - self.psi_gyro - pred, 2.0 * math.pi)
        # the model's error is a bias over a corner (its offset and, as the speed changes, part of
        # its slope are the fit's own columns): counted as fix noise correlated like the course's
        var = ((sigma_v / speed) ** 2 + COURSE_NOISE_RAD ** 2 + (vy_std / vx) ** 2) * CORR_FIXES
        if new_run:
            self.cusum_hi = self.cusum_lo = 0.0
            self.int_hi = self.int_lo = 0.0
        if not new_run and self.cov is not None:
            e = z - pred
            sv = var + spread
            if self.scale_sd < CHANGE_KNOWN and self._cusum(e, sv, course + beta):
                return
            if e * e > GATE_SIGMA ** 2 * sv:
                self.gated += 1
                return
        self.n += 1
        self._solve(latency_std_s, bias_std, h, z, var)

    def _cusum(self, e: float, sv: float, psi0: float) -> bool:
        """Accumulate the normalised residual; on an alarm forget the scale and open a new run
        (True: this fix starts it and is not fitted against the old scale)."""
        u = max(-CUSUM_CLIP, min(CUSUM_CLIP, e / math.sqrt(sv)))
        self.cusum_hi = max(0.0, self.cusum_hi + u - CUSUM_DRIFT)
        self.cusum_lo = max(0.0, self.cusum_lo - u - CUSUM_DRIFT)
        if self.cusum_hi == 0.0:
            self.int_hi = self.yaw_int
        if self.cusum_lo == 0.0:
            self.int_lo = self.yaw_int
        if max(self.cusum_hi, self.cusum_lo) < CUSUM_ALARM:
            return False
        turned = abs(self.yaw_int - (self.int_hi if self.cusum_hi >= CUSUM_ALARM else self.int_lo))
        self.changes += 1
        # the heading error the old scale left since the change, and the step (its size per radian
        # turned since the change point; at least the prior: a step too small to size is not zero)
        self.change_heading = max(self.change_heading, abs(e))
        self.step = max(abs(e) / max(turned, 1e-3), SCALE_PRIOR)
        forget_column(self.info, self.rhs, 2)
        self.r_info = self.r_rhs = 0.0
        self.restored = False
        self._new_run(psi0)
        self.cusum_hi = self.cusum_lo = 0.0
        self.int_hi = self.int_lo = 0.0
        return True

    def take_change(self) -> float:
        """The heading error (rad) an alarm found, once (the core widens its covariance by it)."""
        e, self.change_heading = self.change_heading, 0.0
        return e

    def _new_run(self, psi0: float) -> None:
        """A new gyro integral and offset: the old offset is marginalised out (Schur complement),
        the bias, scale, dx and latency information is kept across the break."""
        self.psi_gyro = psi0
        self.yaw_int = 0.0
        self.cov = None
        marginalise_offset(self.info, self.rhs)
        self.theta[0] = 0.0

    def _solve(self, latency_std_s: float, bias_std: float, h: np.ndarray, z: float, var: float) -> None:
        """Add the fix (regressors h, value z, noise variance var) and solve under both scale priors:
        one ``fit_update`` each (the second adds exact zeros), no inverse built in Python."""
        sb = max(bias_std, BIAS_FLOOR)
        prior = np.array((1e-9, 1.0 / (sb * sb), 1.0 / SCALE_PRIOR ** 2, 1.0 / LEVER_TOL_M ** 2,
                          1.0 / max(latency_std_s, 1e-3) ** 2))
        theta, cov = np.empty(self.N), np.empty((self.N, self.N))
        if not lever_arm_check.fit_update(self.info, self.rhs, h, z, var, prior, theta, cov):
            return
        theta, cov = self._with_restored(theta, cov, drop=True)
        prior[2] = 1.0 / SENSOR_TOL ** 2
        tw, cw = np.empty(self.N), np.empty((self.N, self.N))
        if lever_arm_check.fit_update(self.info, self.rhs, _ZEROS, 0.0, 1.0, prior, tw, cw):
            tw, cw = self._with_restored(tw, cw, drop=False)
            self._select(float(tw[2]), float(cw[2, 2]))
            if self.p_wide > 0.5:  # the data favour the wide prior: its fit is the scale (and heading)
                theta, cov = tw, cw
        self.theta = theta
        self.cov = cov
        self.scale = float(self.theta[2])
        self.scale_sd = math.sqrt(max(cov[2, 2], 0.0))

    def _with_restored(self, theta: np.ndarray, cov: np.ndarray, drop: bool) -> tuple[np.ndarray, np.ndarray]:
        """The restored scale as one more observation of s (information form: a rank-1 update);
        dropped for good (``drop``) where this drive's own fit disagrees with it beyond 3 sigma."""
        if not self.r_info:
            return theta, cov
        s0 = self.r_rhs / self.r_info
        if (theta[2] - s0) ** 2 > 9.0 * (cov[2, 2] + 1.0 / self.r_info):
            if drop:
                self.r_info = self.r_rhs = 0.0
            return theta, cov
        c = cov[:, 2].copy()
        g = c / (cov[2, 2] + 1.0 / self.r_info)
        return theta + g * (s0 - theta[2]), cov - np.outer(g, c)

    def _select(self, s_w: float, v_w: float) -> None:
        """Which prior the data favour (SENSOR_TOL): the wide fit's scale undone of its prior is the
        data's own (s_d +- v_d, widened by the model's bias over the rotation seen); its marginal
        likelihood under either prior, N(s_d; 0, v_d + prior^2), weighs the two (a Bayes factor),
        P_WIDE a priori."""
        self.wide = (s_w, v_w)
        lam = 1.0 / v_w - 1.0 / SENSOR_TOL ** 2
        if lam <= 1.0 / (10.0 * SENSOR_TOL) ** 2 or self.rot_seen < SELECT_ROT:  # too little turned yet
            self.p_wide = P_WIDE
            return
        s_d = s_w / (v_w * lam)
        # the fit counts the model's sideslip error as noise correlated over a few fixes; at the
        # friction limit it is a bias over the whole corner, which a scale of bias / rotation explains
        # (mu03_outage_30s: +11 % from a quarter radian, no scale error at all): the data's scale is
        # not known better than that
        v_d = 1.0 / lam + (self.model_rad / max(self.rot_seen, 1e-3)) ** 2

        def log_l(prior_var):
            return -0.5 * (s_d * s_d / (v_d + prior_var) + math.log(v_d + prior_var))

        d = log_l(SENSOR_TOL ** 2) - log_l(SCALE_PRIOR ** 2)
        odds = P_WIDE / (1.0 - P_WIDE) * math.exp(min(d, 50.0))
        self.p_wide = odds / (1.0 + odds)

    def heading_scale(self, applied: float = 0.0) -> float:
        """The rms over both priors (mixture posterior, ``_select``) of the scale less ``applied``:
        what the gyro, corrected by that, still turns the heading by per radian, for the core's
        heading std (the narrow fit alone is overconfident while a large scale is still shrunk by
        its prior, and the applied scale is then the shrunk one); never below ``scale_std()``'s floor."""
        s_w, v_w = self.wide
        m2 = ((1.0 - self.p_wide) * ((self.scale - applied) ** 2 + self.scale_sd ** 2)
              + self.p_wide * ((s_w - applied) ** 2 + v_w))
        return max(math.sqrt(m2), self.scale_std(applied))

    def heading(self, t: float) -> tuple[float, float]:
        """The heading the fit says at time t of its last fix (rad, as the filter's: the gyro heading
        + offset + residual bias + s x integral, the courses' lever-arm and latency terms left out)
        and its variance; NaN before a solve."""
        if self.cov is None or t != self.t_last:
            return math.nan, math.nan
        g = np.array((1.0, t - self.t_run, self.yaw_int, 0.0, 0.0))
        return self.psi_gyro + float(g @ self.theta), float(g @ self.cov @ g)

    def applied(self) -> float:
        """The scale the core applies to the gyro: s_hat once resolved (APPLY_SIGMA), else 0."""
        return self.scale if abs(self.scale) > APPLY_SIGMA * self.scale_sd else 0.0

    def scale_std(self, applied: float = 0.0) -> float:
        """The scale error left with ``applied`` on the gyro (the core uses the whole, applied = 0:
        see the module docstring); after a detected change at least the step until the refit
        resolves the new scale."""
        if self.step and self.applied():
            self.step = 0.0
        return max(abs(self.scale - applied) + self.scale_sd, BANK_TILT_SCALE, self.step)


def forget_column(info: np.ndarray, rhs: np.ndarray, j: int) -> None:
    """Forget unknown j of an information-form fit in place (its Schur complement), keeping what the
    data said about the others; it restarts from its prior (the solve's regularisation)."""
    a = info[j, j]
    if a > 0.0:
        c = info[j].copy()
        info -= np.outer(c, c) / a
        rhs -= c * (rhs[j] / a)
    info[j, :] = 0.0
    info[:, j] = 0.0
    rhs[j] = 0.0
