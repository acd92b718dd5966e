"""Online GNSS latency identification.

The receiver reports velocity some hundreds of ms after its time of validity. The delay shows
as a time shift between the GNSS speed and the speed from the wheel sensors. Yoon & Peng (003
§3; 000 §4.4.1.1) identify it offline by comparing the two during smooth acceleration; this is
the same idea online, as a regression per candidate delay:

    gnss_speed(t_rx) / ratio(t_rx - delay)  ~  a * wheel_speed(t_rx - d) + b     for every d on the 6 ms grid

with exponentially forgotten sufficient statistics, so the scale a (wheel radius error) and the
offset b cannot bias the timing. ``ratio`` is the antenna's speed |v + r x lever| over the speed
the wheels read, from the filter's history at the current delay estimate: the wheels read vx
where the receiver reads the antenna, and in a tight circle the two differ by several per cent,
a ratio that steps at the corner's exit (measured: -0.13 s on a 9 m circle at 6 m/s without it).

The wheels are not a clean clock: a braked wheel turns slower than the car by v * kappa
(kappa ~ ax * m / C_x), which reads as a delay error of about v * m / C_x in braking phases
(simulated: +0.04 s at 25 m/s, +0.12 s at 50 m/s), and real wheel-speed signals are filtered and
lag. On an all-wheel drive every fused wheel slips in traction too, so the wheels lead the car by
v / (C_x g) on every speed change, and no unbraked window has a speed change to time the GNSS: there
the expected slip (the wheel fusion's ``SLIP_PER_MPS2``) is taken out of the regressor (:meth:`observe`). So a velocity receiver's speed is also regressed on the integrated accelerometer
(:class:`SpeedIntegral`: no slip, no lag; its bias and the integration constant are a ramp and an
offset in the fit), and the two likelihood-ratio profiles add, each by its information (the
std counts the GNSS fixes' own noise, which is in both residuals, once: :func:`combined_profile`),
except that wheels whose best delay the accelerometer rejects are left out (``attach``); without it
the wheels' fixes whose window does not brake judge them the same way (:meth:`observe`). The
accelerometer alone is not enough: its integral breaks off while the sideslip is unknown
mid-corner (and after a GNSS outage, until vy is known again), and it carries less information
than the wheels (on Revs the latency std would stay wide and the heading invalid). A break-off
loses the integral's constant, not the timing its run showed: the earlier runs' cost profiles
stand in, added to the new run's, until that has a profile of its own
(:meth:`LatencyEstimator.forget`), so the accelerometer goes on judging the wheels through a
corner (circle_dry: the corner-biased wheels timed the GNSS alone as the circle ended, +0.036 s),
except a run that ended no longer clean (the grade changed along it: its fit was bent).

The residual sum of squares of each candidate is its cost; the minimum, refined by a parabola, is
the delay. It moves only when the data reject the current delay (a likelihood-ratio test on the
cost profile), with a slew limit; otherwise the prior (config ``delay_s``) stands, and nothing
drifts on a drive without speed changes. While the accelerometer has a profile, the wheels
reject the delay only with it (see :meth:`_refine`): braked wheels and wheels in a corner are
biased clocks (flying_50_straight, dual_circle, bank_circle were 0.024-0.036 s off by them).
Rejected by wheels and accelerometer that agree, the delay moves on into the data's 1-sigma set
rather than stopping at the edge of what they reject (4 sigma: two_rx_slalom stopped 0.027 s
short); when they disagree (on Revs the accelerometer reads the car's pitch under hard braking),
only to that edge, unless the clean unbraked wheel fixes put it later (``CLEAN_LATE_CHASE``: their
one remaining bias, a lagging signal, reads early, so a later best goes on into their 1-sigma set).
Agreeing is mutual: neither rejects the other's best. Wheel signals through a first-order lag
are a clock late by its time constant, sharp enough to reject the accelerometer's best while
inside its 4-sigma set (wheel_lag_0.06_grade: -0.046 s when that counted as agreeing).

Course changes against the integrated yaw rate would add lateral information, but they carry the
sideslip's own errors into the timing, which on real data biased it; measured on Revs and the
simulator. ``std_s`` is the 1-sigma of the estimate, which the GNSS fusion turns into velocity
noise (|a| * std), so GNSS is de-weighted in hard manoeuvres until the delay is known.

A heading-only receiver (``role = "heading"``) has no speed to regress: its heading change
between two samples is regressed on the integrated yaw rate over the same interval delayed by
each candidate (:meth:`LatencyEstimator.observe_series`, fed by :class:`YawIntegral`), the
same statistics and decision rule; the integrated gyro, not the filter's heading, because the
filter's heading is pulled towards the receiver at the current latency estimate.
"""
from __future__ import annotations

import logging
import math

import numpy as np

from .fusion.wheel_speed import SLIP_PER_MPS2
from .history import AUX_AX, AUX_AY, AUX_DELTA, AUX_R, AUX_WHEEL, StepHistory
from .kinematic import VX, VY

log = logging.getLogger(__name__)

MIN_SPEED = 3.0  # m/s: below walking pace wheel sensors read zero
MIN_UPDATES = 30  # informative fixes before the prior is left
LR_REJECT = 16.0  # likelihood ratio (4 sigma: GNSS and wheel errors are correlated over fixes)
JUDGE_SPAN_S = 0.2  # the accelerometer vouches for wheels it agrees with once its own 4-sigma set is this narrow
LR_ARRIVE = 1.0  # a refuted delay moves on until the data's 1-sigma set holds it (not only their 4-sigma one)
MAX_SLEW_S = 0.004  # per fix (x4 for a very clear minimum)
PRIOR_STD_S = 0.15
FIXED_STD_S = 0.01
MIN_STD_S = 0.005  # the 6 ms candidate grid, refined by a parabola
STD_FALL = 0.98  # per informative fix: the std shrinks by e in ~10 s at 5 Hz
MIN_SPEED_SPREAD = 0.3  # m/s: the regression needs some speed variation in its memory
SLIP_FREE_ACCEL = 0.1  # m/s^2: decelerating less than this, the wheels' slip is below their noise
RATIO_ERROR = 0.005  # the antenna-to-wheel ratio's error from the filter's vy (the corner exit's step is 4 %)
FIXED_WARN_RUN = 100  # consecutive refinements refuting a fixed delay before the warning
AX_SMOOTH_S = 0.1  # s: the braking test averages the accelerometer over this (its noise)
# Clean unbraked wheel fixes (``slip_free``: undriven or slip-corrected wheels, not braking, the
# antenna reading what they read) that refute the delay as too *short* carry it on into their
# 1-sigma set, even when the accelerometer is too broad to agree (_refine). Why: the one bias such
# wheels have left is their signal's lag (filtered sensors, CAN), which makes them read *early*; a
# later best is not a lag. Stopping at the edge of what they reject (as for clocks that disagree)
# held random drive 2660 (a launch at 2.2 m/s^2, prior 0 for a true 0.107 s, the accelerometer's
# 4-sigma set 0.006-0.5 s) at 0.036 s, and the turn that followed published the sideslip 1.4 deg
# off as valid. Earlier stays as before (wheel_lag_0.06_grade: lagging wheels pulled it -0.046 s).
CLEAN_LATE_CHASE = True
# s: the wheels' speed is averaged over this, centred, at every candidate delay (observe). Why: each
# candidate reads one stored sample, and a wheel sample's own noise (0.02-0.03 m/s) differs from one
# 6 ms candidate to the next, so where the speed changes little the cost profile is ragged: its best
# is the luckiest sample of ~130, and the likelihood ratio, scaled by that best's residual, rejected
# a right delay. Random drives 2711, 2737, 2751 (wheels the only timing, prior the truth) ended
# 0.168, 0.072, 0.061 s off; simulated with noise-free wheels, 0.000. A centred average does not
# move a clock (a ramp or a kink is matched where it is); 0 keeps the single samples.
# Off at stop 46 (the lead's CI of the integration): with it on, the fleet's simulated 14 s drives
# learned no latency at all, so no vehicle had one for the second pass (tests/test_fleet.py
# test_a_second_pass_replays_each_drive_from_its_vehicles_latency: 0 drives restarted, >= 3 wanted;
# test_a_partial_second_pass_replays_only_its_drives); both pass with it 0. Not traced: the broader,
# honest profile of a short drive may reject its prior later. On random drives 2641-2760 (lat46, with
# CLEAN_LATE_CHASE) it took latency within 0.03 s from 65.5 to 72.3 %. Its tests run it at 0.1.
WHEEL_SMOOTH_S = 0.0
# A refutation needs the information to make it (_refine). Why: the cost profile's likelihood ratios
# are read as chi-square, but a speed that is an affine function of time (a constant acceleration)
# has no timing in it at all: y = a x(t - d) + b fits every d equally, the shift going into b. Only
# the acceleration's *changes* within the forgotten window time the GNSS. What is left of a flat
# profile is noise that differs from candidate to candidate (each reads its own wheel sample: the
# GNSS noise times that sample's noise, ~2 sqrt(N) sigma_w sigma_g over the fixes), max over ~130
# candidates. Random drive 3358 (a straight launch at a steady 1.19 m/s^2, 1208-1219 s, prior = truth
# 0.066 s): the wheels' profile ragged between 3.6 and 16.8 with its best at 0.324 s, the
# accelerometer's flat (0.2-1.0), the prior's 16.5 > LR_REJECT "refuted", the two clocks "agreeing"
# (neither rejects the other's best) and the delay chased to 0.3215 s, which the corner after it
# fused as a sideslip 2.3 deg off while valid. The information per reference is the Fisher
# information of the linearised model: the regressor's slope across the candidates at the current
# delay (its least-squares slope over +-TIMING_SLOPE_S, a wheel sample's noise averaged out), less
# what the fit's own regressors (scale, offset, ramp) explain, summed over the forgotten fixes, over
# the residual variance per fix. The data refute the current delay only if that information could
# put LR_REJECT between it and the best: info * (best - current)^2 >= LR_REJECT.
TIMING_INFORMATION = True
TIMING_SLOPE_S = 0.25  # s: half the span the regressor's slope is fitted over (its sample noise)
# The identified delay's std is at least what the timing information supports (_refine): 1 / sqrt(info),
# the delay error at which the linearised likelihood ratio reaches 1 (the same information that
# TIMING_INFORMATION gates the refutation with), not only the half-width of the cost profile's 4-sigma
# set. Why: where the speed's acceleration hardly changes, the profile is mostly the wheels' per-candidate
# sample noise, ragged, and a ragged profile's 4-sigma set is narrower than the information in it; a
# delay held because nothing refutes it then claimed a std the data never gave. Random drive 3991 (AWD,
# low-speed growing circle, prior 0.321 s, true 0.078): held at 0.024 s with a std of 0.011-0.015 s
# (3.7-4.3 sigma; the profile's width 0.008 s, 1 / sqrt(info) 0.016-0.024 s). Synthetic (a launch of
# 0 -> 0.3 m/s^2 then a steady ramp, tests/test_latency_information_std.py): the profile's best scatters
# by 0.19 s over seeds, 1 / sqrt(info) 0.13 s, the std was as low as 0.058 s, now >= 0.093 s. It does not
# cover a biased clock (wheels or the accelerometer's integrand in a corner: 3974 keeps 0.235 +- 0.011-0.014
# s for 0.274): the information measures noise, not bias. False: main's behaviour, bit for bit.
INFORMATION_STD = True


_FLOAT_MAX = float(np.finfo(np.float64).max)


def nan_to_num(d: np.ndarray) -> np.ndarray:
    """``np.nan_to_num(d)`` of a float64 array (NaN 0.0, +-inf the largest finite float), the same
    bits by four ufuncs. Why: numpy's wraps them in Python (type checks, finfo, copies), which on
    the one- and two-row windows :func:`_antenna_to_wheel` reads at every
    GNSS fix cost more than the rest of that function (random drive 1442, 10 Hz GNSS: 191 calls,
    0.061 of the function's 0.096 s in cProfile). tests/test_latency_shift.py compares the two."""
    return np.minimum(np.maximum(np.where(np.isnan(d), 0.0, d), -_FLOAT_MAX), _FLOAT_MAX)


def _antenna_to_wheel(X: np.ndarray, aux: np.ndarray, lever: tuple[float, float], wheels) -> np.ndarray:
    """Per history row: the antenna's speed over the speed the fused wheels read (at the true
    radius), from the filter's velocity, the yaw rate and the steering angle."""
    vx, vy, r = X[:, VX], X[:, VY], aux[:, AUX_R]
    ant = np.hypot(vx - r * lever[1], vy + r * lever[0])
    if wheels is not None and wheels.frac:
        d = nan_to_num(aux[:, AUX_DELTA])
        f = wheels.frac
        read = vx * (1.0 - f) + f * (vx * np.cos(d) + (vy + wheels.lf * r) * np.sin(d))
    else:
        read = vx
    return np.where(read > 1.0, ant / np.maximum(read, 1.0), 1.0)


class LatencyEstimator:
    def __init__(self, dt: float, prior_s: float, max_s: float, enabled: bool = True,
                 forgetting: float = 0.995, prior_std_s: float = PRIOR_STD_S, min_spread: float = MIN_SPEED_SPREAD,
                 extra: int = 0, fixed: bool = False):
        self.dt = dt
        self.min_spread = min_spread  # of the regressor (its unit) for the timing to be informative
        self.enabled = enabled
        # ``fixed`` ([gnss] estimate_delay = false): the configured delay is used as it is, but the
        # identification still runs as its monitor: data that refute it widen its std (see _refine)
        self.fixed = fixed
        self.refuted_logged = False
        self.refuted_run = 0  # consecutive refinements that refuted the fixed delay
        self.delay_s = prior_s
        # a fixed (configured, not estimated) latency is taken as good to a few ms; an estimated
        # one starts as uncertain as its prior (the config's, or the one identified before a
        # restart) and tightens as the identification settles
        self.prior_std_s = min(max(prior_std_s, MIN_STD_S), PRIOR_STD_S)
        self.std_s = self.prior_std_s if enabled and not fixed else FIXED_STD_S
        self.max_steps = max(2, int(max_s / dt))
        w = max(1, min(self.max_steps, round(AX_SMOOTH_S / dt)))
        self._box = np.full(w, 1.0 / w)
        # the wheels' centred average over the candidates (WHEEL_SMOOTH_S), normalised where it
        # runs past the window's ends
        h = max(0, min(self.max_steps // 2, int(round(0.5 * WHEEL_SMOOTH_S / dt))))
        self._wheel_box = np.ones(2 * h + 1)
        self._wheel_norm = np.convolve(np.ones(self.max_steps + 1), self._wheel_box, mode="same")
        n = self.max_steps + 1
        # the per-fix window (observe's latency_window, SpeedIntegral.observe's speed_window), consumed
        # within the fix (observe_series reads it into the statistics; nothing keeps it)
        self._window_x = np.empty(n)
        self._window_rate = np.empty(n)
        self.forgetting = forgetting
        # sufficient statistics of y = [x, e..., 1] . theta per candidate (x: delayed wheel speed,
        # e: ``extra`` regressors common to all candidates, y: GNSS speed): Z'Z, Z'y and y'y
        self.p = 2 + extra
        self.zz = np.zeros((n, self.p, self.p))
        self.zy = np.zeros((n, self.p))
        self.syy = 0.0
        self.updates = 0
        self.cost = np.zeros(n)
        # the cost profiles of the reference's earlier runs (forget()), forgotten as the statistics
        # are: their residual sums per candidate, fixes (weighted) and parameters spent
        self.past_cost: np.ndarray | None = None
        self.past_n = 0.0
        self.past_p = 0
        self.past_updates = 0
        self.references = [self]  # the timing references whose statistics decide (attach())
        self.owner: LatencyEstimator | None = None  # the estimator this one's statistics feed
        self.slip_free: LatencyEstimator | None = None  # the wheels' fixes without braking (observe)
        # the GNSS fixes' own speed noise variance (m^2/s^2; NaN: unknown), set by the fusion per
        # fix: the part every reference's residual shares (combined_profile)
        self.gnss_var = math.nan
        # the timing information's statistics (TIMING_INFORMATION): the forgotten Gram matrix of
        # [slope, x, extras..., 1] at the current candidate, and the earlier runs' information
        # (forget), forgotten as the statistics are; None: this reference does not keep them
        self.info_zz: np.ndarray | None = None
        self.past_info = 0.0
        h = max(1, min(self.max_steps // 2, int(round(TIMING_SLOPE_S / dt))))
        i = np.arange(2 * h + 1) - h
        self._slope_w = i / float(np.dot(i, i))  # least-squares slope over 2h + 1 candidates

    def observe(self, k_rx: int, speed: float, hist: StepHistory, lever: tuple[float, float] = (0.0, 0.0),
                wheels=None) -> None:
        """Feed one GNSS fix received just before step k_rx (history ends at k_rx - 1).

        ``lever``: the antenna's position from the CG; ``wheels``: the wheel-speed fusion whose
        measured speed the history holds (its front share ``frac``, ``lf``, ``use_all``).
        The wheels read vx (the front pair turned with the steering) where the receiver reads
        the antenna's speed |v + r x lever|: in a tight circle at 6 m/s the two differ by 4 %,
        and that ratio steps at a corner's exit, which a plain regression reads as timing
        (-0.13 s on a 9 m circle). So the GNSS speed is divided by the filter's ratio of the
        two at the current delay estimate, the same for every candidate: a step in it that the
        current delay places wrong costs every candidate alike and moves none.

        Braked wheels turn slower than the car by v * kappa (kappa ~ |ax| m / C_x), a speed
        error proportional to the deceleration: that is a timing error of v m / C_x however hard
        the braking. The fixes whose window does not brake (undriven wheels do not slip
        otherwise; on an all-wheel drive traction counts too) are also kept apart
        (``slip_free``): while the accelerometer reference (:class:`SpeedIntegral`, no slip) has a
        profile, it judges all the wheels' fixes (the braking ones carry most of a race car's
        timing: Revs kept its latency std at 0.013 s instead of 0.031 s at the 90th percentile);
        while it has none (mid-corner, after an outage), the unbraked fixes judge them."""
        if not self.enabled or speed < MIN_SPEED:
            return
        # candidate validity steps k_rx - 1 - m: a delay of (m + 1) steps
        if k_rx - 1 - self.max_steps < hist.oldest():  # the oldest candidate: they fall with m
            return  # not enough history yet (start-up / after a reset)
        use_all = wheels is not None and wheels.use_all
        # the wheels' speed x at every candidate (all finite and above MIN_SPEED, or no fix), the
        # speed's rate (vx ax + vy ay) / |v| over the window (not ax alone: in a sideslipping
        # circle ax reads a share of the centripetal acceleration) and the ratio's vy error (below),
        # in one pass over the history (latency_window_reference: what it computes)
        x, rate = self._window_x, self._window_rate
        vy_err = latency_window(hist.X, hist.aux, hist.P, k_rx - 1, lever[0], SLIP_PER_MPS2 if use_all else None,
                                MIN_SPEED, x, rate)
        if vy_err is None:
            return
        if len(self._wheel_box) > 1:
            x = np.convolve(x, self._wheel_box, mode="same") / self._wheel_norm
        # the rate averaged over a tenth of a second (sensor noise)
        ax = np.convolve(rate, self._box, mode="valid")
        # Fused wheels that are all driven (all-wheel drive) slip on every speed change: they read
        # v (1 + kappa), kappa = a / (C_x g) for the specific force a, so their speed leads the car
        # by v / (C_x g), 0.1 s at 20 m/s: a late bias of the timing in traction and braking alike,
        # and no window without slip has a speed change to time the GNSS instead (slip_free). So
        # their expected slip (the fusion's own C_x, SLIP_PER_MPS2) comes out of the regressor.
        # Random drive 217 (AWD, 19.5 m/s, the accelerometer broken off every few fixes by the
        # grade): the noise-free simulated wheels put the delay at 0.724 s for a true 0.639 (the
        # car's speed: 0.622; with the slip taken out: 0.616), and the identification left its
        # 0.80 s prior only to 0.78. Undriven wheels slip only when braked, which the braking test
        # below and the accelerometer already keep out of the timing: they are left as they read.
        # (latency_window divides x by 1 + SLIP_PER_MPS2 rate when use_all)
        slip_free = (np.abs(ax) if use_all else -ax).max() <= SLIP_FREE_ACCEL
        # the ratio carries the filter's vy error, |vy_ant| / |v|^2 of it (relative): on
        # a flying start mid-corner the sideslip is not known yet, and its convergence is a ramp
        # in the ratio that reads as timing; those fixes wait (vy_err: the window's largest
        # |vy + r lever_x| times vy's std)
        if not vy_err <= RATIO_ERROR * max(speed, MIN_SPEED) ** 2:
            self._refine()  # no new data; the std's fall (a time constant) goes on
            return
        # the GNSS speed as the wheels would read it, through the ratio at the current delay: one
        # factor for every candidate, so the timing comes from the wheels' own speed changes and
        # not from the filter's ratio (which a slalom at constant speed modulates, and whose
        # errors would then read as timing)
        c = candidate_index(self.delay_s, self.dt, self.max_steps)
        s = (k_rx - 1 - c) % hist.n
        ratio = _antenna_to_wheel(hist.X[s:s + 1], hist.aux[s:s + 1], lever, wheels)[0]
        if slip_free:
            # ... and where the antenna and the wheels read the same speed over the window: in a
            # corner the filter's error in their ratio drifts with the speed and steps at the exit
            # (lowspeed_r10: 0.558 s for 0.4; dual_circle: 0.48)
            ends = [(k_rx - 1) % hist.n, (k_rx - 1 - self.max_steps) % hist.n]  # the newest and oldest candidate
            ends = _antenna_to_wheel(hist.X[ends], hist.aux[ends], lever, wheels)
            slip_free = abs(ends[0] - 1.0) <= RATIO_ERROR and abs(ends[-1] - 1.0) <= RATIO_ERROR
        info = timing_point(x, c, self._slope_w) if TIMING_INFORMATION else None
        if slip_free:
            if self.slip_free is None:
                self.slip_free = LatencyEstimator(self.dt, self.delay_s, (self.max_steps + 0.5) * self.dt,
                                                  forgetting=self.forgetting, min_spread=self.min_spread)
            self.slip_free._accumulate(x, speed / ratio, (), info)
        self.observe_series(x, speed / ratio, (), info)

    def observe_series(self, x: np.ndarray, y: float, extra: tuple[float, ...] = (),
                       info: tuple[float, float] | None = None) -> None:
        """One observation ``y ~ a * x[m] + c . extra + b`` for every candidate m (``x[m]``: the
        reference signal at the candidate validity step, a delay of m + 1 steps). ``info``: the
        regressor's (slope across the candidates, value) at the current delay (:func:`timing_point`),
        for the timing information (TIMING_INFORMATION); None: not kept."""
        if not self.enabled:
            return
        self._accumulate(x, y, extra, info)
        self._refine()

    def _accumulate(self, x: np.ndarray, y: float, extra: tuple[float, ...] = (),
                    info: tuple[float, float] | None = None) -> None:
        lam = self.forgetting
        accumulate(self.zz, self.zy, x, extra, y, lam)
        if info is not None:
            z = np.array((info[0], info[1], *extra, 1.0))
            if self.info_zz is None:
                self.info_zz = np.zeros((len(z), len(z)))
            self.info_zz *= lam
            self.info_zz += np.outer(z, z)
            self.past_info *= lam
        self.syy = lam * self.syy + y * y
        self.updates += 1
        if self.past_cost is not None:
            # the earlier runs' evidence fades at the same rate as this run's oldest fixes; once
            # it weighs less than the parameters it spent it tells nothing and goes
            self.past_cost = lam * self.past_cost
            self.past_n *= lam
            if self.past_n <= self.past_p:
                self._drop_past()

    def _drop_past(self) -> None:
        self.past_info = 0.0
        self.past_cost = None
        self.past_n = 0.0
        self.past_p = 0
        self.past_updates = 0

    def shift(self, offsets: tuple[float, ...]) -> None:
        """Re-anchor the regressors: x and the extras from now on are read less ``offsets`` (an
        integral and a time that would otherwise grow without bound); the fit is unchanged."""
        if self.info_zz is not None:
            # the same re-anchoring of the information's Gram [slope, x, extras..., 1]
            m = np.eye(len(self.info_zz))
            m[1:-1, -1] = -np.asarray(offsets, dtype=float)
            self.info_zz = m @ self.info_zz @ m.T
        if self.p in (3, 4) and shift_bits_match() and shift_statistics(self.zz, self.zy, offsets):
            return  # the einsums' bits, in place (shift_statistics_reference: why)
        m = np.eye(self.p)
        m[:-1, -1] = -np.asarray(offsets, dtype=float)
        # C order, as accumulate() updates them in place (the same values, copied if einsum chose another layout)
        self.zz = np.ascontiguousarray(np.einsum("ij,kjl,ml->kim", m, self.zz, m))
        self.zy = np.ascontiguousarray(np.einsum("ij,kj->ki", m, self.zy))

    def forget(self, keep: bool = True) -> None:
        """Drop the statistics (the reference broke off); the delay and its std stand.

        ``keep``: the run's cost profile is kept (:attr:`past_cost`) and adds to the next runs'
        ones until one has a profile of its own (:meth:`_profile_of_statistics`). What breaks off when the sideslip is unknown mid-corner is the accelerometer
        integral's constant, not the timing its fixes showed, which was fitted with that run's own
        offset, scale and ramp. Without it, every corner left the accelerometer without a profile
        for 30 fixes and the wheels timed the GNSS alone with their corner bias (circle_dry:
        +0.036 s as the circle ended). Not kept (:class:`SpeedIntegral`) when the run ended because
        it was no longer a clean reference (the grade changed along it: its fit was bent before it
        broke off; road_country: +0.144 s with those runs kept)."""
        if keep and self.updates > self.p + 1:
            c = np.empty(len(self.zz))
            if latency_costs(np.ascontiguousarray(self.zz), np.ascontiguousarray(self.zy), self.syy,
                             self.min_spread ** 2 * self.zz[0, -1, -1] * 0.1, c):
                self.past_cost = c if self.past_cost is None else self.past_cost + c
                self.past_info += self._run_information()
                self.past_n += float(self.zz[0, -1, -1])
                self.past_p += self.p
                self.past_updates += self.updates
        self.zz[:] = 0.0
        self.zy[:] = 0.0
        self.syy = 0.0
        self.updates = 0
        if self.info_zz is not None:
            self.info_zz[:] = 0.0

    def _run_information(self) -> float:
        """The current run's timing information, unscaled: the slope's forgotten sum of squares
        less what the fit's regressors (x, extras, offset) explain ((m/s per candidate)^2)."""
        g = self.info_zz
        if g is None or not self.updates > g.shape[0]:
            return 0.0
        a = g[1:, 1:]
        b = g[1:, 0]
        try:
            sol = np.linalg.solve(a, b)
        except np.linalg.LinAlgError:
            return 0.0
        return max(float(g[0, 0] - b @ sol), 0.0)

    def information(self, s2: float) -> float:
        """The timing information of this reference's profile (1/s^2: the likelihood ratio a delay
        error of 1 s would show, linearised), its residual variance per fix ``s2``; inf when this
        reference keeps no information statistics (a heading receiver's: no gate)."""
        if self.info_zz is None:
            return math.inf
        return (self._run_information() + self.past_info) / (max(s2, 1e-12) * self.dt ** 2)

    def attach(self, other: "LatencyEstimator") -> None:
        """Identify the delay from ``other``'s statistics too (another timing reference of the
        same receiver): the likelihood-ratio profiles add, so each counts by its information; the
        std counts what their residuals share (the GNSS fixes' own noise) once (:func:`combined_profile`)."""
        self.references.append(other)
        other.owner = self

    _chasing = False  # refuted by clocks that agree: moving to their best, not only to the edge of what they reject
    _chasing_clean = False  # refuted as too short by the clean wheel fixes: on into their 1-sigma set
    _profile_memo: tuple | None = None  # (statistics, profile, cost) of the last _profile_of_statistics

    def _profile(self) -> tuple[np.ndarray, bool, float] | None:
        """:meth:`_profile_of_statistics`, kept while the statistics stay bit for bit the same.

        Why: a fix refines its receiver once per reference it feeds (the wheels, then the
        accelerometer), and each refinement reads every reference's profile, so half the
        profiles (167 stacked solves each, most of a GNSS step) were of statistics that had not
        changed. The key is the statistics themselves, so whatever changes them, the profile is
        computed again; a kept one is the same bits."""
        key = (self.updates, self.syy, self.zz.tobytes(), self.zy.tobytes(), self.past_n, self.past_updates)
        memo = self._profile_memo
        if memo is not None and memo[0] == key:
            self.cost = memo[2]
            return memo[1]
        profile = self._profile_of_statistics()
        self._profile_memo = (key, profile, self.cost)
        return profile

    def _profile_of_statistics(self) -> tuple[np.ndarray, bool, float] | None:
        """The likelihood-ratio statistic of every candidate against the best, whether the
        minimum is very clear, and the best fit's residual variance per fix (m^2/s^2 for a speed
        reference: what :func:`combined_profile` weighs the shared GNSS noise against); None while
        the statistics carry no timing information."""
        past = self.past_cost
        if self.updates + self.past_updates < MIN_UPDATES:
            return None
        zz = self.zz
        n = zz[0, -1, -1]
        c = np.empty(len(zz))
        p = self.p
        if not (self.updates > p + 1 and latency_costs(np.ascontiguousarray(zz), np.ascontiguousarray(self.zy),
                                                       self.syy, self.min_spread ** 2 * n * 0.1, c)):
            if past is None:
                return None  # the regressor has hardly varied: no timing information
            c[:] = 0.0  # this run has none (yet): the earlier runs' alone
            n, p = 0.0, 0
        elif self.updates >= MIN_UPDATES and past is not None:
            # A run with a profile of its own judges alone: the earlier runs only bridge the gap a
            # break-off leaves. The accelerometer's slow errors (pitch under hard braking, a grade)
            # differ from run to run, and summed over a race track's many corners they biased the
            # judge (Revs: latency 0.384 s for 0.400, sideslip RMS 0.217 -> 0.234 deg)
            self._drop_past()
            past = None
        if past is not None:
            # independent runs, each fitted with its own constants: their costs add
            c = c + past
            n, p = n + self.past_n, p + self.past_p
        self.cost = c
        i = int(c.argmin())
        # RSS excess over the residual variance per fix
        s2 = max(c[i], 1e-12) / max(n - p, 1.0)
        return (c - c[i]) / s2, bool(c[i] < 0.2 * median(c)), s2

    def _refine(self) -> None:
        if self.owner is not None:
            self.owner._refine()
            return
        profiles = [ref._profile() for ref in self.references]
        owners = {id(p): ref for ref, p in zip(self.references, profiles) if p is not None}  # (TIMING_INFORMATION)
        judge = profiles[-1] if len(profiles) > 1 else None
        if judge is None and self.slip_free is not None and profiles[0] is not None:
            # no accelerometer to judge the wheels: their fixes without braking judge them all
            # instead (braking slip shows as a timing bias), as the accelerometer would
            sf = self.slip_free._profile()
            if sf is not None and sf[0][int(profiles[0][0].argmin())] > LR_REJECT:
                profiles[0] = sf
                owners[id(sf)] = self.slip_free
        if judge is not None:
            # The last reference attached (the accelerometer's) has no lag and no slip; the
            # others (the wheels) have both, and they show as a timing bias. A reference whose
            # best delay it rejects is biased and left out.
            wheels = [p for p in profiles[:-1] if p is not None]
            profiles = [p for p in wheels if judge[0][int(p[0].argmin())] <= LR_REJECT] + [judge]
            # two clocks that agree: the data's best is where the delay goes, not only the edge of
            # what they reject; that disagree (on Revs the accelerometer reads the car's pitch under
            # hard braking: 0.37 s for 0.40), only as far as the data reject the delay. Agreeing is
            # mutual: the wheels must not reject the accelerometer's best either. A first-order lag
            # of the wheel signals is a delay of its time constant in their clock; sharp wheels a
            # lag away from a broad accelerometer passed its 4-sigma test and pulled the delay to
            # theirs (wheel_lag_0.06_grade: -0.046 s)
            ja = int(judge[0].argmin())
            agree = (bool(wheels) and len(profiles) == len(wheels) + 1
                     and all(p[0][ja] <= LR_REJECT for p in wheels))
        else:
            agree = False
        profiles = [p for p in profiles if p is not None]
        if not profiles:
            return
        # The summed profile decides (whether the data refute the delay, and where it goes: the
        # thresholds below were set on it); the std is read from the same profile less what the
        # references share (combined_profile): the fixes' own noise, in every reference's
        # residual, counts once in what the std promises. Moving on the shared-out profile
        # instead slowed the identification on the simulator's drives by half the information
        # (their residuals are the GNSS noise), and the stiffness regression learned from
        # courses placed with the prior for longer (slalom_dry: k_r 30 % off; lat34)
        lr = profile_sum(profiles)
        share = information_share(profiles, self.gnss_var)
        cur = candidate_index(self.delay_s, self.dt, len(lr) - 1)
        # Likelihood-ratio statistic of every candidate against the best (lr - lr[i], i its
        # argmin). Its profile gives both the decision (move only when the data reject the
        # current delay) and an honest std (the width of the set of delays the data cannot reject;
        # several near-equal minima, as a weakly excited drive has, make it wide instead of
        # picking one by noise). refine_scan_reference: what is read of it.
        scan = refine_scan(lr, share, LR_REJECT, cur)
        if scan is None:
            return  # the best at either end of the candidates
        i, y0, y1, y2, first, last, at_cur = scan
        est = parabola_delay(y0, y1, y2, i, self.dt)
        width_std = 0.5 * (last - first + 1) * self.dt / math.sqrt(LR_REJECT)
        prior_std = self.prior_std_s
        # The wheels are a biased clock (braking slip, the antenna-to-wheel ratio's errors in a
        # corner, filtered sensors). While the accelerometer (no slip) has a profile, they refute
        # the delay only with it: it refutes it itself, or it is sharp (its 4-sigma set within
        # JUDGE_SPAN_S) and agrees with them, or clean unbraked wheel fixes refute it and it does
        # not contradict them. A broad or stale accelerometer profile passing braked wheels took
        # flying_50_straight 0.032 s off, and wheels in a circle dual_circle 0.036 s.
        refuted = at_cur > LR_REJECT
        info = math.inf
        if TIMING_INFORMATION and (refuted or INFORMATION_STD):
            # the references' information, what their residuals share counted once (the std's share);
            # a reference without information statistics (a heading receiver's) does not gate
            info = share * sum(owners[id(p)].information(p[2]) if id(p) in owners else math.inf for p in profiles)
        if refuted and TIMING_INFORMATION:
            refuted = info * (est - self.delay_s) ** 2 >= LR_REJECT
        clean = None  # the clean wheel fixes' (profile, best) while the accelerometer does not reject their best
        if (refuted or self._chasing_clean) and judge is not None:
            sf = self.slip_free._profile() if self.slip_free is not None else None
            if sf is not None and judge[0][int(sf[0].argmin())] <= LR_REJECT:
                clean = (sf[0], int(sf[0].argmin()))
        if refuted and judge is not None:
            sharp = np.count_nonzero(judge[0] < LR_REJECT) * self.dt <= JUDGE_SPAN_S
            refuted = (judge[0][cur] > LR_REJECT or (agree and sharp)
                       or (clean is not None and clean[0][cur] > LR_REJECT))
        if self.fixed:
            # The user fixed the delay: it stays. But a delay the data refute is not good to a few
            # ms: its std widens at once to the distance to the data's best (plus their width), so
            # the fixes in a manoeuvre are de-weighted and the heading / sideslip std carry it
            # (a fixed 0.3 s for a true 0.4 published sideslip 2.9 deg off as valid, 3 sigma held
            # on 78 % of the rows). Not refuted, it narrows back as an estimate does. The warning
            # (once) waits for a refutation that lasts: on the demo drive a right fixed delay was
            # refuted for at most 36 refinements in a row, one 0.05-0.1 s off for 258-348.
            wide = abs(est - self.delay_s) + width_std if refuted else 0.0
            self.refuted_run = self.refuted_run + 1 if refuted else 0
            if self.refuted_run >= FIXED_WARN_RUN and not self.refuted_logged:
                self.refuted_logged = True
                log.warning("GNSS delay fixed at %.3f s ([gnss] estimate_delay = false), but the speeds put it "
                            "at %.3f s: its std is widened to %.3f s (set delay_s, or estimate_delay = true)",
                            self.delay_s, est, wide)
            self.std_s = min(PRIOR_STD_S, max(FIXED_STD_S, wide, STD_FALL * self.std_s))
            return
        if refuted and agree:
            self._chasing = True
        elif self._chasing and (not agree or at_cur <= LR_ARRIVE):
            self._chasing = False
        # the clean wheel fixes put the delay later than it is (CLEAN_LATE_CHASE): where the rules
        # above stop it (at the edge of what the data reject), it moves on towards their best (not
        # the summed one: that holds the braked fixes' late bias) until their 1-sigma set holds it
        target = est if refuted or self._chasing else None
        if (CLEAN_LATE_CHASE and clean is not None and clean[1] > cur and clean[0][cur] > LR_ARRIVE
                and (refuted or self._chasing_clean)):
            self._chasing_clean = True
            if target is None:
                c, j = clean
                inner = 0 < j < len(c) - 1
                target = parabola_delay(c[j - 1], c[j], c[j + 1], j, self.dt) if inner else (j + 1) * self.dt
        else:
            self._chasing_clean = False
        if target is not None:
            # Slew-limited: a wrong step in the delay costs more than a slow convergence; a
            # very clear minimum may move faster. The prior is refuted: only the data count.
            slew = MAX_SLEW_S * (4.0 if any(p[1] for p in profiles) else 1.0)
            self.delay_s += max(-slew, min(slew, 0.3 * (target - self.delay_s)))
            prior_std = math.inf
        data_std = max(width_std, abs(est - self.delay_s))
        if INFORMATION_STD and TIMING_INFORMATION:
            # the profile's width is no std where its raggedness, not the information, narrows it:
            # the data cannot tell apart delays within 1 / sqrt(info) (INFORMATION_STD)
            data_std = max(data_std, 1.0 / math.sqrt(info) if info > 0.0 else PRIOR_STD_S)
        std = min(PRIOR_STD_S, max(MIN_STD_S, 1.0 / math.sqrt(prior_std ** -2 + data_std ** -2)))
        # rises at once, falls slowly: on real data (RAV4) the profile's second minimum comes
        # and goes from one fix to the next, and a std that followed it would promise too much
        self.std_s = max(std, STD_FALL * self.std_s)


def candidate_index(delay_s: float, dt: float, max_steps: int) -> int:
    """The candidate a delay names: candidate m is validity step k_rx - 1 - m (m = 0..max_steps),
    a delay of d s is m = round(d / dt) - 1, held to the candidates. One rule for the ratio's
    current candidate (:meth:`LatencyEstimator.observe`), the refinement's (``_refine``) and the
    timing information's (:meth:`SpeedIntegral.observe`'s ``timing_point``)."""
    return min(max(int(round(delay_s / dt)) - 1, 0), max_steps)


def timing_point(x: np.ndarray, c: int, w: np.ndarray) -> tuple[float, float]:
    """The regressor's least-squares slope across the candidates (per candidate; weights ``w`` over
    2h + 1 of them) around candidate ``c`` (the window held inside the candidates), and its value at
    ``c``: what the timing information of a fix is read from (TIMING_INFORMATION)."""
    n = len(w)
    lo = min(max(c - n // 2, 0), max(len(x) - n, 0))
    seg = x[lo:lo + n]
    if len(seg) < n:
        return 0.0, float(x[c])
    return float(np.dot(w, seg)), float(x[c])


def parabola_delay(y0: float, y1: float, y2: float, i: int, dt: float) -> float:
    """The delay at the vertex of the parabola through a profile's values ``y0, y1, y2`` at the
    candidates i - 1, i, i + 1 (candidate i is a delay of i + 1 steps of ``dt``), its offset from i
    held within half a candidate; i itself where the three do not curve upwards. Read of the summed
    profile's best and of the clean wheel fixes' (:meth:`LatencyEstimator._refine`)."""
    den = y0 - 2.0 * y1 + y2
    off = 0.5 * (y0 - y2) / den if den > 0 else 0.0
    return (i + 1 + max(-0.5, min(0.5, off))) * dt


def shared_correlation(resid_var: list[float], gnss_var: float = math.nan) -> float:
    """The correlation of the timing references' residuals (0..1), averaged over their pairs.

    Every reference (the wheels, the integrated accelerometer) is regressed against the same GNSS
    speeds: a residual is ``e_gnss + e_ref``, and ``e_gnss`` is the same fix's error in every one,
    so two references' residuals share the variance ``gnss_var`` (the fixes' own speed noise, as
    the fusion knows it: the receiver's sAcc or the configured NMEA figure, or less where the
    wheels have shown the scatter smaller, ``gnss_noise``). Their correlation is
    ``gnss_var / sqrt(var_i var_j)``. It cannot exceed ``sqrt(min / max)`` (the shared part is at
    most the smaller variance), which is also what stands when the noise is unknown (NaN): an upper
    bound, which on clean GNSS halves the information of references whose own errors dominate."""
    var = [max(float(v), 0.0) for v in resid_var]
    k = len(var)
    if k < 2:
        return 0.0
    total = 0.0
    for i in range(k):
        for j in range(i + 1, k):
            hi = max(var[i], var[j])
            if not hi > 0.0:
                rho = 1.0  # both fit the fixes exactly: nothing but what they share
            else:
                rho = math.sqrt(min(var[i], var[j]) / hi)
                if gnss_var >= 0.0 and rho > 0.0:  # (False for NaN: unknown noise, the bound stands)
                    rho = min(rho, gnss_var / math.sqrt(var[i] * var[j]))
            total += rho
    return total / (k * (k - 1) / 2)


def combined_profile(profiles: list, gnss_var: float = math.nan) -> np.ndarray:
    """The references' likelihood-ratio profiles ``(lr, clear, residual variance)`` as one.

    Summed, as independent evidence would be, and divided by ``1 + (k - 1) rho``
    (:func:`shared_correlation`): the information of k equally informative estimates whose errors
    correlate by rho. Why: a plain sum counts the GNSS fixes' noise once per reference; on random
    drive 20 (NMEA 4 Hz, a 0.58 s receiver configured 0.78 s, the only speed changes the ends of
    one slow ramp) wheels and accelerometer both put the delay at ~0.80 s, the sum made its std
    0.05 s, and the circle's courses, fused 0.2 s off, were promised to 0.6 deg of heading while
    3 deg off."""
    return profile_sum(profiles) * information_share(profiles, gnss_var)


def profile_sum(profiles: list) -> np.ndarray:
    """``np.sum([p[0] for p in profiles], axis=0)``, the same bits without stacking the profiles
    into a new array first: numpy's sum over the stacked axis is a +0.0 plus each row in turn
    (measured: 20 000 random stacks of 1 to 4 rows with zeros of both signs, tests/test_latency_shift.py).
    Why: at every refinement (twice a fix), a few percent of a fix's latency work in plain Python."""
    lr = 0.0 + profiles[0][0]
    for p in profiles[1:]:
        lr = lr + p[0]
    return lr


def information_share(profiles: list, gnss_var: float = math.nan) -> float:
    """``1 / (1 + (k - 1) rho)``: the share of the k references' summed likelihood ratio that is
    information not counted twice (:func:`combined_profile`); 1 for one reference."""
    if len(profiles) < 2:
        return 1.0
    return 1.0 / (1.0 + (len(profiles) - 1) * shared_correlation([p[2] for p in profiles], gnss_var))


def refine_scan_reference(lr: np.ndarray, share: float, reject: float, cur: int):
    """:meth:`LatencyEstimator._refine`'s reading of its summed profile ``lr``: None when its best
    candidate i (numpy's argmin: the first minimum, the first NaN if any) is at either end; else
    ``(i, y0, y1, y2, first, last, at_cur)`` of ``d = lr - lr[i]``: d at i - 1, i, i + 1 (the parabola
    through the minimum), the first and last candidate with ``share * d < reject`` (the set the
    data cannot reject; IndexError if empty) and d at ``cur`` (the current delay's).
    ``backend.select`` swaps in the compiled one (``_kernels.c``: the same elementwise operations,
    without the profile's temporaries and ~12 numpy calls a refinement, three a fix: the same
    bits, tests/test_refine_scan.py)."""
    i = int(lr.argmin())
    if i == 0 or i == len(lr) - 1:
        return None
    d = lr - lr[i]
    inside = np.flatnonzero(share * d < reject)
    return (i, float(d[i - 1]), float(d[i]), float(d[i + 1]), int(inside[0]), int(inside[-1]), float(d[cur]))


refine_scan = refine_scan_reference


def latency_window_reference(X: np.ndarray, aux: np.ndarray, P: np.ndarray, last: int, lever_x: float,
                             slip: float | None, min_speed: float, x_out: np.ndarray, rate_out: np.ndarray):
    """:meth:`LatencyEstimator.observe`'s window over its candidate delays m = 0..len(x_out)-1 (history
    slot ``(last - m) % n``): None if a wheel speed is not finite or below ``min_speed`` (the
    outputs then unspecified); else the wheel speeds into ``x_out`` (divided by 1 + slip rate unless
    ``slip`` is None: an all-wheel drive's expected slip), the speed's rate (vx ax + vy ay) / max(|v|, 1)
    into ``rate_out``, and the largest |vy + r lever_x| times vy's std (NaN if any is NaN), a float.
    ``backend.select`` swaps in the compiled one (``_kernels.c``: the same elementwise operations
    per row, without the gathers of whole history rows and ~15 numpy calls of ~160 values a fix:
    the same bits, tests/test_latency_window.py)."""
    slot = (last - np.arange(len(x_out))) % len(X)
    a = aux[slot]
    x = a[:, AUX_WHEEL]
    if not np.isfinite(x).all() or x.min() < min_speed:
        return None
    Xs = X[slot]
    vx, vy = Xs[:, VX], Xs[:, VY]
    rate = (vx * a[:, AUX_AX] + vy * a[:, AUX_AY]) / np.maximum(np.hypot(vx, vy), 1.0)
    if slip is not None:
        x = x / (1.0 + slip * rate)
    x_out[:] = x
    rate_out[:] = rate
    vy_ant = np.abs(vy + a[:, AUX_R] * lever_x)
    vy_std = np.sqrt(np.maximum(P[slot, VY, VY], 0.0))
    return float((vy_ant * vy_std).max())


latency_window = latency_window_reference


def speed_window_reference(v: np.ndarray, vel: np.ndarray, last: int, total: float, lever_x: float,
                           lever_y: float, out: np.ndarray) -> None:
    """:meth:`SpeedIntegral.observe`'s regressor at every candidate m = 0..len(out)-1 (ring slot
    ``(last - m) % n``), into ``out``: the integral less its anchor ``total``, plus the antenna's
    speed over the CG's from the stored vx, vy and yaw rate (``vel``) and the lever arm.
    ``backend.select`` swaps in the compiled one (``_kernels.c``: the same elementwise operations,
    without this one's gathers and ~10 numpy calls a fix: the same bits, tests/test_latency_window.py)."""
    slot = (last - np.arange(len(out))) % len(v)
    vx, vy, r = vel[slot].T
    lever_part = np.hypot(vx - r * lever_y, vy + r * lever_x) - np.hypot(vx, vy)
    out[:] = v[slot] - total + lever_part


speed_window = speed_window_reference


def latency_costs_reference(zz: np.ndarray, zy: np.ndarray, syy: float, floor: float, c: np.ndarray) -> bool:
    """Each candidate's residual sum of squares into c (``zz``, ``zy``, ``syy``: the sufficient
    statistics per candidate); False (c untouched) unless the regressor's variation that the offset
    (and the extras: a ramp) do not explain exceeds ``floor`` at every candidate. ``backend.select``
    swaps in the compiled one (``_kernels.c``: the same math, each candidate's solves by elimination)."""
    cxx = zz[:, 0, 0] - np.einsum("ki,ki->k", zz[:, 0, 1:], np.linalg.solve(zz[:, 1:, 1:], zz[:, 1:, 0:1])[:, :, 0])
    if not (cxx.min() > floor):
        return False
    # residual sum of squares of the least-squares fit per candidate
    theta = np.linalg.solve(zz, zy[:, :, None])[:, :, 0]
    c[:] = np.maximum(syy - np.einsum("ki,ki->k", theta, zy), 0.0)
    return True


latency_costs = latency_costs_reference


def shift_statistics_reference(zz: np.ndarray, zy: np.ndarray, offsets: tuple[float, ...]) -> bool:
    """:meth:`LatencyEstimator.shift`'s two einsums (``M zz_k M'`` and ``M zy_k`` for every candidate
    k, ``M`` the identity less ``offsets`` in its last column), in place and with their bits; False
    (nothing written: the caller keeps its einsums) unless every statistic and offset is finite.
    ``backend.select`` swaps in the compiled one (``_kernels.c``: the same operations per entry,
    without this one's broadcast temporaries).

    Why: the accelerometer's statistics (3 regressors) are re-anchored at every fix, and the two
    einsums were the largest single numpy cost of a fix (callgrind, random drive 1442 with 10 Hz
    GNSS, its first 21 s, plain Python: 95.8 M of the measured steps' 1607.8 M instructions, 6.0 %,
    in 260 einsums; with nan_to_num and profile_sum, -7.2 % plain and -9.0 % compiled in all). ``M`` is the identity but for one column, so each of the p x p entries of
    ``M zz_k M'`` is at most four products: zz_im, zz_ip (-o_m), (-o_i) zz_pm and
    ((-o_i) zz_pp) (-o_m) (p the constant's index); the rest are M's zeros. numpy's einsum adds
    each entry's products, zeros included, to a +0.0 with M's column j outer and l inner, each
    product multiplied left to right; a finite product with a zero is +-0.0, which leaves such a
    sum as it was; so these four in that order after a +0.0 are its bits (``zy``: two products,
    either order the same sum). Measured against the einsums for 3 and 4 regressors
    (tests/test_latency_shift.py; numpy 2.4's einsum sums 2 regressors in another order, so the
    caller keeps the einsums there) and probed once per process (:func:`shift_bits_match`). With an
    inf or NaN the einsums' 0 * inf terms are NaN, which this does not reproduce: then False."""
    for o in offsets:
        if not math.isfinite(o):
            return False
    if not (np.isfinite(zz).all() and np.isfinite(zy).all()):
        return False
    no = np.zeros(zz.shape[1])
    no[:-1] = offsets
    # M's last column less its diagonal 1 (zz_im covers that product): -0.0 there, whose products
    # are +-0.0 terms that leave a sum as it was
    no = -no
    s = (0.0 + zz) + zz[:, :, -1:] * no
    s = s + no[:, None] * zz[:, -1:, :]
    zz[...] = s + (no[:, None] * zz[:, -1:, -1:]) * no
    zy[...] = (0.0 + zy) + no * zy[:, -1:]
    return True


shift_statistics = shift_statistics_reference

_shift_checked: tuple | None = None  # (the shift_statistics probed, whether it matched)


def shift_bits_match() -> bool:
    """Does :func:`shift_statistics` (whichever is installed) give this numpy's einsum bits on fixed
    probes (3 regressors, as the estimator's, with zeros of both signs)? Once per process; where an
    einsum sums in another order (another numpy), :meth:`LatencyEstimator.shift` keeps the einsums."""
    global _shift_checked
    if _shift_checked is None or _shift_checked[0] is not shift_statistics:
        rng = np.random.default_rng(43)
        ok = True
        for t in range(8):
            zz = rng.standard_normal((170, 3, 3)) * 10.0 ** rng.uniform(-3, 6, (170, 3, 3))
            zz = zz + zz.transpose(0, 2, 1)
            zz[rng.random(zz.shape) < 0.1] = 0.0 if t % 2 else -0.0
            zy = rng.standard_normal((170, 3)) * 10.0 ** rng.uniform(-3, 6, (170, 3))
            off = (float(rng.standard_normal() * 50.0), float(rng.uniform(0.0, 2.0)))
            m = np.eye(3)
            m[:-1, -1] = -np.asarray(off)
            want = (np.einsum("ij,kjl,ml->kim", m, zz, m), np.einsum("ij,kj->ki", m, zy))
            ok = ok and shift_statistics(zz, zy, off) and zz.tobytes() == want[0].tobytes() \
                and zy.tobytes() == want[1].tobytes()
        _shift_checked = (shift_statistics, bool(ok))
    return _shift_checked[1]


def accumulate_reference(zz: np.ndarray, zy: np.ndarray, x: np.ndarray, extra: tuple[float, ...], y: float,
                         lam: float) -> None:
    """One observation into the forgotten sufficient statistics, in place: per candidate k with
    regressors z_k = [x_k, extra..., 1], zz_k <- lam zz_k + z_k z_k' and zy_k <- lam zy_k + z_k y.
    ``backend.select`` swaps in the compiled one (``_kernels.c``: the same elementwise operations,
    so the same bits, without the per-fix temporaries)."""
    z = np.stack((x, *(np.full_like(x, e) for e in extra), np.ones_like(x)), axis=1)
    zz[...] = lam * zz + z[:, :, None] * z[:, None, :]
    zy[...] = lam * zy + z * y


accumulate = accumulate_reference


def median_reference(c: np.ndarray) -> float:
    """numpy's median of the cost profile, as a float (``_kernels.c``'s ``median``: the same value
    by a sort in C, without numpy.median's ~10 us of Python per profile)."""
    return float(np.median(c))


median = median_reference


HEADING_SPREAD_RAD = 0.01  # heading change between samples: turning, not straight-line noise
MAX_HEADING_GAP_S = 1.5  # two heading samples further apart than this are not paired


class YawIntegral:
    """The yaw rate integrated step by step (clockwise, as a heading), kept for the last
    ``n`` steps: the reference of a heading-only receiver's latency identification."""

    def __init__(self, dt: float, max_delay_s: float):
        self.dt = dt
        self.n = int(math.ceil((max_delay_s + MAX_HEADING_GAP_S) / dt)) + 4
        self.psi = np.zeros(self.n)
        self.total = 0.0
        self.last = -1  # last step stored
        self.first = 0  # first step of the current unbroken run
        self.prev: dict[int, tuple[int, float]] = {}  # receiver -> (step received, vehicle heading)

    def step(self, k: int, r: float) -> None:
        if k != self.last + 1:
            self.first = k
            self.prev.clear()
        self.total -= r * self.dt
        self.psi[k % self.n] = self.total
        self.last = k

    def pair(self, receiver: int, k_rx: int, heading: float, lat: LatencyEstimator) -> None:
        """A heading sample of ``receiver`` received just before step ``k_rx``: regress its change
        since the previous one on the gyro's over the same interval, delayed by each candidate."""
        prev = self.prev.get(receiver)
        self.prev[receiver] = (k_rx, heading)
        if prev is None:
            return
        k0, h0 = prev
        m = np.arange(lat.max_steps + 1)
        c1, c0 = k_rx - 1 - m, k0 - 1 - m
        if not (0 < (k_rx - k0) * self.dt <= MAX_HEADING_GAP_S and c0[-1] >= max(self.first, self.last - self.n + 1)
                and c1[0] <= self.last):
            return
        x = self.psi[c1 % self.n] - self.psi[c0 % self.n]
        y = math.remainder(heading - h0, 2.0 * math.pi)
        lat.observe_series(x, y)


MAX_RATE_ERROR = 0.02  # m/s^2: the integrand's error budget (0.1 m/s, a GNSS speed noise, in 5 s)


class SpeedIntegral:
    """The rate of the car's speed d|v|/dt = (vx ax + vy ay) / |v| integrated step by step, kept
    for the last steps: a timing reference for GNSS speed that does not go through the wheels.

    Each GNSS speed is regressed on the integral at each candidate validity step, with a scale
    (accelerometer scale, pitch), an offset and a ramp in time (the integration constant and the
    accelerometer's bias or a grade: they drift the integral linearly). Wheels lag (real ABS
    sensors are filtered) and slip when braking (v * kappa), both of which bias a timing read
    from them; the accelerometer has neither."""

    def __init__(self, dt: float, max_delay_s: float):
        self.dt = dt
        self.n = int(math.ceil(max_delay_s / dt)) + 4
        self.v = np.zeros(self.n)
        self.vel = np.zeros((self.n, 3))  # the filter's vx, vy and the yaw rate: the lever arm's share
        # the same two arrays as the per-step writer sees them: compiled, typed memoryviews
        # (latency.pxd), so each step stores four C doubles instead of making two numpy
        # assignments (one from a tuple); in plain Python just the arrays again
        self._vm = self.v
        self._velm = self.vel
        self.total = 0.0
        self.last = -1
        self.first = 0
        self.anchor: dict[int, tuple[int, float]] = {}  # receiver -> (step, integral) its regressors are read from
        self.bent: set[int] = set()  # receivers whose last run ended unusable (step): its timing is not kept

    def step(self, k: int, vx: float, vy: float, r: float, ax: float, ay: float, vy_std: float = 0.0,
             usable: bool = True) -> None:
        """Step k: the filter's velocity at the CG (vy with its std), the yaw rate, the measured
        longitudinal acceleration (raw: a constant bias is the ramp's, while the filter's bias
        estimate moves as it converges) and the lateral one. ``usable``: the IMU is.

        The integrand's vy ay / |v| ~ r vy carries the filter's vy error times r; while that
        exceeds ``MAX_RATE_ERROR`` (sideslip not yet known mid-corner) the integral breaks off
        and starts again afterwards with a new constant, instead of bending the fit."""
        if k != self.last + 1 or not usable or abs(r) * vy_std > MAX_RATE_ERROR:
            if not usable:
                # a run that ends unusable (the grade changed along it, the IMU, reversing) was
                # bent before it broke off: its receivers' timing is not kept (forget); one that
                # ends on the sideslip's test or a gap was within its error budget
                self.bent.update(self.anchor)
            self.first = k + 1
            self.anchor.clear()
        # the speed's rate d|v|/dt = (vx ax + vy ay) / |v| (turning does not change |v|)
        v = math.hypot(vx, vy)
        total = self.total + ((vx * ax + vy * ay) / v if v > 1.0 else ax) * self.dt
        self.total = total
        i = k % self.n
        self._vm[i] = total
        velm = self._velm
        velm[i, 0] = vx
        velm[i, 1] = vy
        velm[i, 2] = r
        self.last = k

    def observe(self, receiver: int, k_rx: int, speed: float, lat: LatencyEstimator,
                lever: tuple[float, float] = (0.0, 0.0)) -> None:
        """A forward GNSS speed of ``receiver`` (antenna at ``lever`` from the CG) received just
        before step ``k_rx``. The antenna's speed differs from the CG's by the yaw rate times the
        lever arm: small, but it changes with the yaw rate, as at a corner's exit, and that change
        would read as timing, so it is added to the integral from the filter's state."""
        if not lat.enabled or not math.isfinite(speed) or speed < MIN_SPEED:
            return
        # candidate validity steps k_rx - 1 - m, m = 0..lat.max_steps: all in the stored run
        if not (k_rx - 1 - lat.max_steps >= max(self.first, self.last - self.n + 1) and k_rx - 1 <= self.last):
            return
        prev = self.anchor.get(receiver)
        if prev is None:
            # a new run of the integral: its constant is unknown; the last run's timing stands unless it was bent
            lat.forget(keep=receiver not in self.bent)
            self.bent.discard(receiver)
        else:
            lat.shift((self.total - prev[1], (self.last - prev[0]) * self.dt))
        self.anchor[receiver] = (self.last, self.total)
        x = lat._window_x  # the estimator's per-fix buffer, consumed within observe_series
        speed_window(self.v, self.vel, k_rx - 1, self.total, lever[0], lever[1], x)
        info = None
        if TIMING_INFORMATION:
            d = (lat.owner or lat).delay_s  # the receiver's current delay (the owner identifies it)
            info = timing_point(x, candidate_index(d, lat.dt, lat.max_steps), lat._slope_w)
        lat.observe_series(x, speed, (0.0,), info)
