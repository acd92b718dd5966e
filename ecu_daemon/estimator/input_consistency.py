"""Slow longitudinal consistency: do the wheels' speed changes have the accelerometer's scale and sign?

Why a second, slow check beside the fault detector's 0.15 s longitudinal test: that test must
tolerate wheel slip transients, so its tolerance (1 m/s + 3 % of speed per window) hides any
error that is *proportional* to the speed change. Two configuration errors a user makes on day
one are exactly that: wheel speeds in km/h mapped as m/s (every speed change 3.6x what ax
integrates to) and an accelerometer whose x axis points backwards (every change of the opposite
sign). Four agreeing wheels then outvote the one GNSS receiver, and vx was published valid
tens of m/s off. Over a 2 s window the integral of ax and the change of the wheel speed must
agree within what physics allows:

* the accelerometer's bias error and a grade change: ``LON2_TOL_MPS`` over the window;
* wheel slip (driving and ABS braking, up to ~15 % on ice) and a wrong wheel radius:
  ``LON2_TOL_SPEED`` of the speed, and ``LON2_TOL_SCALE`` of the speed change itself.

A window beyond that cannot be a tyre or a sensor's noise: one of the two is mis-scaled or
mis-signed, and nothing in the window says which (GNSS may be the arbiter, but the wheels have
already outvoted it), so velocity is not promised while windows fail and ``LON2_HOLD_S`` after
the last. Nothing is fused differently: this check only withholds the promise. While the fault
detector has isolated the wheels or ax it has found the culprit (a sensor fault, not a mapping
error) and the filter no longer fuses it: the check stands aside and starts afresh after.

An accelerometer *offset* is not a scale error: it is a bias, it fails windows at a steady speed,
where no mapping error can. With the wheel speed changing by at most ``LON2_STEADY_MPS`` over
the window, a failing residual needs an ax scale beyond -1.5x or +4.6x (tolerance below at
v = 0), never a reversed axis or wheels 3.6x off: what it shows is ax's bias (a fault the filter
carries as a bias; between wheel samples it moves vx by bias x 10 ms). If the latest GNSS speed
check, fresh, also confirms the wheels (``wheels_confirmed``: a receiver independent of both),
vx, which the steady wheels hold, is right: such a window is counted in :attr:`offsets` and
withholds nothing. Without that confirmation a frozen wheel reading while the car brakes
looks the same, and the window fails as before.
"""
from __future__ import annotations

import math

from .line_fit import LineFit

LON2_WINDOW_S = 2.0  # long enough for a gentle acceleration to show a 3.6x scale (1 m/s^2: 7 m/s vs 2)
LON2_EVERY = 10  # steps between samples of the window's ring (60 ms): the check is slow by design
LON2_TOL_MPS = 1.0  # accelerometer bias error (0.2 m/s^2) and grade change over the window
LON2_TOL_SPEED = 0.05  # wheel slip change over the window, as a share of the speed
LON2_TOL_SCALE = 0.35  # ... and of the speed change: wheel radius error, slip growing with deceleration
LON2_HOLD_S = 5.0  # the promise stays withheld this long after the last failing window
# a steady wheel speed: no reversed ax nor any wheel scale can fail a window that changes less
# (module docstring); 0.5 m/s over 2 s is 0.25 m/s^2 of mean acceleration
LON2_STEADY_MPS = 0.5


class LongitudinalScaleCheck:
    """Wheel speed change against integrated ax over ``LON2_WINDOW_S``; :attr:`failing` while they
    disagree in scale or sign beyond physics (module docstring)."""

    def __init__(self, dt: float):
        self.dt = dt
        self._n = max(2, int(round(LON2_WINDOW_S / (LON2_EVERY * dt))))
        self._ring_v = [math.nan] * self._n
        self._ring_a = [math.nan] * self._n
        self._j = 0
        self._cum_a = 0.0
        self._a_ok = True  # every ax sample since the ring's oldest entry was finite
        self._hold = int(round(LON2_HOLD_S / dt))
        self._last_fail_k = -(1 << 62)
        self.failing = False
        self.residual = 0.0  # m/s, the last window's wheel change minus ax's integral
        self.failures = 0  # windows that failed, over the drive
        self.offsets = 0  # failing windows at a steady, GNSS-confirmed wheel speed (an ax bias), not held

    def reset(self) -> None:
        """The fault detector has isolated the wheels or ax (it knows which is wrong and the filter
        no longer fuses it): its verdict stands, and this check starts afresh when both return."""
        self._ring_v = [math.nan] * self._n
        self._ring_a = [math.nan] * self._n
        self._cum_a = 0.0
        self._last_fail_k = -(1 << 62)
        self.failing = False

    def step(self, k: int, v_wheels: float, ax: float, wheels_confirmed: bool = False) -> bool:
        """One estimator step: ``v_wheels`` the fused wheel speed (scaled; NaN: none), ``ax`` the
        bias-corrected longitudinal acceleration (NaN: none), ``wheels_confirmed`` whether a fresh
        GNSS speed check agrees with the wheels. Returns :attr:`failing`."""
        if ax == ax:
            self._cum_a += ax * self.dt
        else:
            self._cum_a = math.nan  # a gap: the integral restarts with the ring below
        if k % LON2_EVERY == 0:
            n = self._n
            j = self._j
            v_old = self._ring_v[j]
            a_old = self._ring_a[j]
            cum = self._cum_a
            if cum != cum:
                cum = self._cum_a = 0.0
                self._ring_a = [math.nan] * n  # older integrals are of another run
                a_old = math.nan
            self._ring_v[j] = v_wheels
            self._ring_a[j] = cum
            self._j = (j + 1) % n
            if v_wheels == v_wheels and v_old == v_old and a_old == a_old:
                dv_a = cum - a_old
                res = (v_wheels - v_old) - dv_a
                self.residual = res
                tol = (LON2_TOL_MPS + LON2_TOL_SPEED * max(abs(v_wheels), abs(v_old))
                       + LON2_TOL_SCALE * abs(dv_a))
                if abs(res) > tol:
                    if wheels_confirmed and abs(v_wheels - v_old) <= LON2_STEADY_MPS:
                        self.offsets += 1  # ax's bias at a steady, confirmed speed (docstring)
                    else:
                        self._last_fail_k = k
                        self.failures += 1
        self.failing = k - self._last_fail_k <= self._hold
        return self.failing


# --- lateral: the accelerometer's ay against the yaw rate times the speed
LAT2_TAU_S = 0.05  # low-pass of both sides: ay's noise (0.05-0.3 m/s^2), CAN timing; short, as a
#                    wrong ay corrupts vy within 0.03 s of a turn-in
LAT2_MIN_SPEED = 3.0  # m/s: below it sideslip is not promised anyway (core.MIN_SPEED_SIDESLIP)
# m/s: from here up the fault detector's ay / vx vote judges ay (fault_detection, 2 x YAW_MIN_SPEED),
# and vy's own rate is no longer the kinematic lr rdot: a 50 m/s swerve has ay - r vx = -10 m/s^2
# for 0.3 s with the sideslip right (flying_50_r400r_h300 lost 5 % of its valid rows to this check)
LAT2_MAX_SPEED = 6.0
LAT2_TOL_MPS2 = 2.5  # ay's unlearned bias (0.3), a banked track's gravity (1.4 on the Revs track),
#                      body roll's (0.5 at 1 g); 1.5 withheld 2.2 % of Revs' right sideslip
LAT2_TOL_REL = 0.5  # x |r vx|: vy's own rate at the limit (a race car at 1.7 g) and in transients
LAT2_TOL_RDOT_M = 2.5  # x peak |yaw acceleration|: kinematic dvy/dt = lr rdot (lr <= 1.7 m) and
#                       an IMU up to 0.8 m ahead of or behind the CG that nobody configured
LAT2_RDOT_MEMORY_S = 0.5  # the peak |rdot| decays over this (the low-passed sides lag the transient)
LAT2_HOLD_S = 2.0  # sideslip stays withheld this long after the last failing step


class LateralScaleCheck:
    """The lateral accelerometer against its witness ``r vx`` (``ay = dvy/dt + r vx`` at the CG):
    :attr:`failing` while they disagree beyond what bias, bank, roll and vy's own rate allow.

    Why: the fault detector judges ay by ``ay / vx`` against the gyro only above 6 m/s (at low
    speed that ratio magnifies every bias), but a configuration error -- ay in g mapped as m/s^2,
    a signal already in m/s^2 given a g scale (9.81x), a reversed axis -- is wrong at any speed:
    at 5 m/s on a 15 m circle the 9.81x ay put sideslip 75 deg off while it was promised (the
    single-track model and vy's integration both take ay). In acceleration units the tolerance
    does not depend on the speed; this check covers the speeds below the fault detector's
    (``LAT2_MIN_SPEED`` to ``LAT2_MAX_SPEED``), where vy's rate is the kinematic lr rdot. Like :class:`LongitudinalScaleCheck` it only withholds the
    sideslip promise, for ``LAT2_HOLD_S`` after the last failing step. While the fault detector
    has isolated the gyro or ay (their substitutes are fused then) it judges nothing, but a hold
    already running goes on: the vy that the wrong ay integrated is not right the moment ay is
    isolated.
    """

    def __init__(self, dt: float):
        self.dt = dt
        self._a = dt / (LAT2_TAU_S + dt)
        self._rdot_decay = math.exp(-dt / LAT2_RDOT_MEMORY_S)
        self._hold = int(round(LAT2_HOLD_S / dt))
        self._ay = self._rv = math.nan
        self._rdot = 0.0
        self._last_fail_k = -(1 << 62)
        self.failing = False
        self.residual = 0.0  # m/s^2, low-passed ay - r vx
        self.failures = 0  # steps that failed, over the drive

    def step(self, k: int, ay: float, r: float, vx: float, rdot: float) -> bool:
        """One estimator step: ``ay`` bias-corrected, ``r`` the bias-corrected yaw rate, ``vx``
        the filter's, ``rdot`` the yaw acceleration; NaN ``ay`` or ``r``: no judgement (gyro or
        ay isolated, IMU stale), the low-passes restart. Returns :attr:`failing`."""
        rv = r * vx
        if ay != ay or rv != rv:
            self._ay = self._rv = math.nan
        elif self._ay != self._ay:
            self._ay, self._rv = ay, rv
        else:
            a = self._a
            self._ay += a * (ay - self._ay)
            self._rv += a * (rv - self._rv)
            self._rdot = max(abs(rdot), self._rdot * self._rdot_decay)
            if LAT2_MIN_SPEED < abs(vx) <= LAT2_MAX_SPEED:
                res = self.residual = self._ay - self._rv
                if abs(res) > LAT2_TOL_MPS2 + LAT2_TOL_REL * abs(self._rv) + LAT2_TOL_RDOT_M * self._rdot:
                    self._last_fail_k = k
                    self.failures += 1
        self.failing = k - self._last_fail_k <= self._hold
        return self.failing


# --- the wheels' scale against GNSS speed over ground: a wrong unit is not tyre wear
WSC_MIN_SPEED = 2.0  # m/s, the larger of the two speeds: below it a ratio is noise and lever arm
WSC_SLACK_MPS = 0.4  # GNSS speed noise, the antenna's lever arm x yaw rate, a latency error x accel
WSC_AGREE_REL = 0.15  # |wheels - GNSS| within this share of the larger: ratio 0.85-1.18, what tyre
#                       wear, pressure, load and slip explain (the filter's wheel scale learns the rest)
WSC_WRONG_REL = 0.25  # ... beyond this share: ratio outside 0.75-1.33, no tyre does that
# s: a latency prior this far off (a 0.1 s prior for a 0.8 s receiver, the default ring horizon)
# dates each fix where the speed was |ax| x this different: during a launch the wheels read 2.9x a
# GNSS speed 0.7 s old (dlc_dry, 2.5 m/s^2 at 1-3 m/s) and were called a unit error. Widens only
# the "wrong" verdict: an agreeing fix stays as strict (a unit error must not agree by timing)
WSC_TIMING_S = 0.8
WSC_FIXES = 2  # consecutive wrong fixes before the verdict (one fix may be a glitch); one agreeing
#               fix confirms (a glitch that happens to match a unit error's ratio is not a risk)
# Before the first fix a velocity from the wheels rests on a mapping nobody checked: its std says
# so by a wheel scale anywhere from a fifth of the truth up (the slowest unit error below is 1/3.6;
# the filter's vx fell to 0.24x of the truth on a flying start in a 14 m circle with 0.28x wheels):
# vx up to 4 |vx| off, at 3 sigma 4/3 |vx| (a too-fast unit error is off by less than its reading).
# Standing still (vx 0) is right whatever the scale.
WSC_UNCHECKED_REL = 4.0 / 3.0
# the unit errors a mapping makes, as the ratio wheels / true speed they give
WSC_UNITS = ((3.6, "km/h read as m/s"), (1 / 3.6, "m/s given a km/h scale (1/3.6)"),
             (1 / 0.44704, "mph read as m/s"), (0.44704, "m/s given an mph scale (0.447)"),
             (1.609344, "mph given a km/h scale"), (1 / 1.609344, "km/h given an mph scale"))


class WheelScaleCheck:
    """The fused wheel speed against each GNSS speed over ground: has anyone checked the wheels'
    scale, and is it a scale a tyre can have?

    Why: a wheel speed mapped in the wrong unit (an mph factor on a signal already in m/s: 0.45x;
    km/h read as m/s: 3.6x) is four agreeing sensors, so the filter trusts them over the one
    receiver; :class:`LongitudinalScaleCheck` sees only the *change* of speed, within a
    tolerance a 0.45x scale at 2 m/s^2 does not break, and the GNSS-conflict rule waits 8 s for a
    glitch to end. dlc_dry with 0.45x wheels published vx valid 11.6 m/s off for 10 s, a flying
    start at 30 m/s 16.7 m/s off from its first step. GNSS speed measures |v| directly: a ratio
    far outside what tyre wear, pressure and slip explain (``WSC_WRONG_REL``) is a configuration
    error, not something for the wheel-scale state to learn slowly (it is bounded, and the fix
    that would teach it is rejected as disagreeing with the wheels).

    :attr:`confirmed`: a fix found the wheels' scale within
    ``WSC_AGREE_REL``; until then a velocity from the wheels rests on a mapping nobody checked
    (a flying start has nothing else until its first fix): its std carries ``WSC_UNCHECKED_REL``
    and sideslip, which that vx integrates into vy, is not promised. A configuration
    does not change while the daemon runs: once confirmed, later disagreements are sensor or
    GNSS faults, the fault detector's and the GNSS-conflict rule's. :attr:`wrong`: ``WSC_FIXES``
    consecutive fixes beyond ``WSC_WRONG_REL`` before that; :meth:`observe` returns True once, for
    the one log line (:meth:`message`).
    """

    def __init__(self) -> None:
        self.confirmed = False
        self.wrong = False
        # A witness without GNSS (a launch, the gyro) tells a unit error from a tyre, not a tyre 5 %
        # from one 15 % off: the relative scale error it leaves (1 sigma), carried in the published
        # vx std until a fix measures the scale (then WheelScaleSeed.gap does; 0 when a fix confirmed)
        self.witness_rel = 0.0
        self.ratio = math.nan  # wheels / GNSS of the last fix judged
        self._disagree = 0
        self._lo = math.inf  # the ratios of the current disagreeing run
        self._hi = -math.inf
        self._speed = math.nan  # the larger speed of the current disagreeing run's last fix

    def observe(self, wheels: float, gnss: float, accel: float = 0.0) -> bool:
        """One GNSS fix: ``wheels`` the fused, scaled wheel speed at its time of validity,
        ``gnss`` its speed over ground (both m/s; NaN wheels: nothing to judge), ``accel`` the
        longitudinal acceleration then (m/s^2: a latency error's share, ``WSC_TIMING_S``). True
        when this fix makes :attr:`wrong` (the caller logs :meth:`message`)."""
        if self.confirmed or not (wheels == wheels and gnss == gnss):
            return False
        w, g = abs(wheels), abs(gnss)
        top = max(w, g)
        if top < WSC_MIN_SPEED:
            return False
        d = abs(w - g)
        self.ratio = w / g if g > 0.0 else math.inf
        if d <= WSC_SLACK_MPS + WSC_AGREE_REL * top:
            self._disagree = 0
            self._lo, self._hi = math.inf, -math.inf
            self.confirmed = True
            self.wrong = False
            return False
        if d <= WSC_SLACK_MPS + WSC_WRONG_REL * top + WSC_TIMING_S * abs(accel):
            return False  # neither a tyre nor clearly a unit (or a latency error): wait for the next fix
        self._disagree += 1
        self._lo = min(self._lo, self.ratio)
        self._hi = max(self._hi, self.ratio)
        self._speed = g
        if self._disagree >= WSC_FIXES and not self.wrong:
            self.wrong = True
            return True
        return False

    def confirm(self, scale_rel: float = 0.0) -> None:
        """Another witness found the wheels' scale right (the gyro against the rear axle's speed
        difference, wheel_yaw_check.py; a restart's learned state): as an agreeing fix would. Not
        after GNSS has found it wrong (two fixes beyond any tyre outweigh an indirect witness).
        ``scale_rel``: the relative scale error that witness leaves possible (1 sigma), which the
        published vx std carries until a GNSS fix measures the scale (:attr:`witness_rel`)."""
        if not self.wrong:
            self.confirmed = True
            self.witness_rel = scale_rel

    def message(self) -> str:
        """The log line: which inputs, the ratio, the likely unit error."""
        r = math.sqrt(self._lo * self._hi) if self._hi < math.inf else self._hi
        guess = "a wrong scale or wheel radius"
        for q, what in WSC_UNITS:
            if 0.0 < r < math.inf and abs(math.log(r / q)) < 0.15:  # the units are >= 0.33 apart
                guess = f"looks like {what}"
                break
        return (f"[inputs.wheel_speed_fl/fr/rl/rr]: the wheel speeds read {r:.2f}x the GNSS speed "
                f"over ground ({self._lo:.2f}-{self._hi:.2f} over {self._disagree} fixes, GNSS "
                f"{self._speed:.1f} m/s): no tyre does that, the mapping's scale is wrong ({guess}); "
                f"velocity and sideslip are not promised until the wheels agree with GNSS")


# --- the wheels' scale from many agreeing fixes: a wrong tyre size in the config is learned once
KWS_MIN_SPEED = 5.0  # m/s: GNSS speed noise (~0.1 m/s) stays within 2 % of a fix's ratio
KWS_MAX_AX = 1.0  # m/s^2: drive / brake slip (wheel_speed.SLIP_PER_MPS2: 0.7 %) and a latency error
#                   of 0.05 s (0.05 m/s) stay small against the speed
KWS_MAX_LATERAL = 0.15  # |vy + r lever_x| / speed: the antenna's lateral speed taken out of |v| moves
#                         the ratio by at most ~1 %, so a vy error of 0.2 m/s moves it by < 0.5 %
KWS_FIXES = 10  # steady fixes in the window before a verdict, at least a third of them in each half ...
# ... spanning this long: a scale is constant, a GNSS glitch is not, and lasts seconds (5 s in the
# suite; core.GNSS_CONFLICT_S, twice that, is how long a conflict must last to be no glitch): a
# glitch that scales the speed by a tyre's 10 % for 5 s fills at most one half of the window, and
# the halves' means then disagree (KWS_HALVES_REL). With 3 s it re-seeded dlc_dry's right wheels 11 % off.
KWS_SPAN_S = 8.0
KWS_WINDOW_S = 12.0  # the window: the steady fixes of the last 12 s (fix times)
KWS_MAX_SPREAD = 0.02  # std of the window's ratios: above it they are not one scale (slip, a glitch)
KWS_HALVES_REL = 0.01  # the means of the window's older and newer half: one scale agrees with itself
KWS_STD_FLOOR = 0.003  # what no averaging removes: lever arm, sideslip, slip left within the limits
KWS_FAR = 0.03  # within its bounds the filter learns the scale itself; beyond this it did not
KWS_HALF_WIDTH = 0.05  # re-centred bounds: what tyre wear, pressure and load move a radius by
# the widest scale a re-seed may take: where WheelScaleCheck stops calling a ratio a tyre
# (WSC_WRONG_REL), so a seed never explains away a unit error
KWS_TOTAL = (1.0 - WSC_WRONG_REL, 1.0 / (1.0 - WSC_WRONG_REL))
KWS_GAP_GAIN = 0.3  # low-pass of each fix's ratio for the published gap (~3 fixes)
KWS_GAP_MIN_SPEED = WSC_MIN_SPEED  # m/s, the larger speed: the published gap from the fix that confirms the wheels
# --- a re-seeded scale is a hypothesis: at one speed a scale and an offset are the same thing
KWS_FIT_WINDOW_S = 120.0  # the steady fixes the wheels = s v + o fit uses (a config does not change)
KWS_FIT_SPAN_REL = 0.15  # the fit's speeds must span this share of their mean: apart enough for an
#                         offset of 0.5 m/s to move the ratio by more than the window's spread
KWS_FIT_MIN_SIDE = 5  # steady fixes at least at each end of that span (below / above the mean speed)
KWS_OFFSET_MPS = 0.5  # |o| beyond this (and beyond KWS_OFFSET_SIGMAS of its std) refutes the scale:
#                       a tyre's scale leaves no offset, GNSS speed noise (~0.1 m/s) averages well below it
KWS_OFFSET_SIGMAS = 4.0


class WheelScaleSeed:
    """The wheels' scale GNSS speed / raw wheel speed averaged over steady fixes: re-seeds the
    filter's wheel-scale state once when it lies beyond where that state may learn.

    Why: a wrong tyre size or rolling radius in ``[inputs.wheel_speed_*] scale`` (5-20 %, the
    commonest wheel error) is a tyre to :class:`WheelScaleCheck` (within ``WSC_AGREE_REL``: it
    confirms the wheels), but the filter's wheel scale is clamped to +-5 %
    (fault_detection.LEARNED_BOUNDS, so that a fault slipping through cannot drive it somewhere
    unphysical) and GNSS beyond the narrow GNSS/wheel gate is rejected as a glitch: vx followed
    four agreeing wheels 10 % off while published valid with a std of 0.1-0.3 m/s (dlc_dry with
    1.12x wheels: 5843 rows valid beyond 3 sigma). A glitch lasts seconds and is not steady; many
    fixes at a steady speed, straight or in a steady corner, that all give one ratio are the wheels'
    scale. Each steady fix (``KWS_MIN_SPEED``, ``KWS_MAX_AX``, ``KWS_MAX_LATERAL``) gives the ratio
    of the antenna's longitudinal speed over ground to the raw wheel speed; when the last
    ``KWS_WINDOW_S`` (at least ``KWS_FIXES`` over ``KWS_SPAN_S``) agree within ``KWS_MAX_SPREAD``,
    and the means of their older and newer half within ``KWS_HALVES_REL`` (a glitch is not steady),
    and their mean lies outside the current bounds, or ``KWS_FAR`` from the state,
    :meth:`observe` returns True once: the caller re-seeds the state to :attr:`scale` with
    :attr:`std` and re-centres the bounds (:func:`recentred_bounds`). The gate and the slow walk
    stay as they are for the glitches they protect against.

    A re-seeded scale is a hypothesis: at one speed a scale and an offset are the same thing (a
    wheel-speed signal whose DBC offset the mapping forgot reads v + o, which at a steady 30 m/s
    looks like a tyre 25 % off). A scale is one ratio at every speed, an offset is not: if the
    wheels read v + o and the seed learned m = v_s / (v_s + o) at the seed's speed v_s, vx at
    speed v is m (v + o) = v + (v_s - v)(1 - m). So until steady fixes at speeds
    ``KWS_FIT_SPAN_REL`` apart confirm the ratio, :meth:`offset_bound` (``|v - v_s| |1 - m|``)
    is published in the vx std; every steady fix (at any ratio) feeds a fit raw = s g + o over
    ``KWS_FIT_WINDOW_S``, and an offset beyond ``KWS_OFFSET_MPS`` and ``KWS_OFFSET_SIGMAS`` of its
    std refutes the scale (:attr:`offset_found`; :meth:`observe_offset` returns True once, for the
    log line :meth:`offset_message`): velocity and sideslip are not promised after that.

    Until then :attr:`gap` is the scale error the fixes show against the state (any fix above
    ``KWS_GAP_MIN_SPEED``, the one that confirms the wheels on, whose ratio a tyre can have,
    low-passed): the published vx std carries
    it, so wheels off by more than the bounds allow are not promised tighter than GNSS shows them.
    """

    def __init__(self) -> None:
        self.q: list[float] = []  # the window's ratios
        self.t: list[float] = []  # and their times
        self.scale = math.nan  # the mean of the last full window
        self.std = math.nan  # its uncertainty
        self.spread = math.nan  # its ratios' std
        self.seeded = False
        self.gap = 0.0  # |low-passed ratio - state|, relative (published vx std: gap x raw wheel speed)
        self.gap_t = -math.inf  # the time of validity of the last fix that set the gap
        self._q_lp = math.nan
        self.fit: list[tuple[float, float, float]] = []  # steady fixes (t, GNSS speed, raw wheel speed)
        self.v_seed = math.nan  # the mean GNSS speed of the window that seeded the scale
        self.ratio_checked = False  # steady fixes across speeds found the seeded ratio a scale
        self.offset_found = False  # ... or found an offset: the scale is refuted
        self.offset = math.nan  # the fit's offset o (m/s, in the raw wheel speed) and its std
        self.offset_std = math.nan
        self.offset_slope = math.nan

    def offset_bound(self, v: float) -> float:
        """What an offset of the size the seed absorbed would make vx wrong by at speed ``v``
        (m/s; 0 unless a re-seed's ratio is still unchecked across speeds): the seed's
        ``|1 - m|`` times how far ``v`` is from the speed it was seen at (class docstring)."""
        if self.ratio_checked or self.offset_found or self.v_seed != self.v_seed:
            return 0.0
        return abs(abs(v) - self.v_seed) * abs(1.0 - self.scale)

    def _fit_offset(self) -> None:
        """Least squares raw = s g + o over the fit window; judge o once the speeds span enough."""
        n = len(self.fit)
        if n < 2 * KWS_FIT_MIN_SIDE:
            return
        gm = sum(f[1] for f in self.fit) / n
        if gm <= 0.0 or max(f[1] for f in self.fit) - min(f[1] for f in self.fit) < KWS_FIT_SPAN_REL * gm:
            return
        below = sum(1 for f in self.fit if f[1] < gm)
        if below < KWS_FIT_MIN_SIDE or n - below < KWS_FIT_MIN_SIDE:
            return
        wm = sum(f[2] for f in self.fit) / n
        # raw - wm = slope (g - gm) + c, centred as the fit was before line_fit.py (speeds near
        # 30 m/s a few m/s apart: uncentred sums lose digits to cancellation); rebuilt from the
        # window each time (it forgets the fixes that leave it)
        fit = LineFit()
        for f in self.fit:
            fit.add(f[1] - gm, 1.0, f[2] - wm)
        if not fit.solve():
            return
        slope = fit.k
        o = wm + fit.c - slope * gm  # the offset at g = 0
        var = fit.residual_var()
        o_var = fit.c_var(var) + gm * gm * fit.k_var(var) - 2.0 * gm * fit.kc_cov(var)
        # fixes ~1 s apart are independent (as the seed's window): the std from that many
        n_ind = max(2.0, min(n, self.fit[-1][0] - self.fit[0][0]))
        # ... and what no averaging removes (KWS_STD_FLOOR of the ratio, at the mean speed)
        o_std = math.hypot(math.sqrt(max(o_var, 0.0) * n / n_ind), KWS_STD_FLOOR * gm)
        self.offset, self.offset_std, self.offset_slope = o, o_std, slope
        if abs(o) > max(KWS_OFFSET_MPS, KWS_OFFSET_SIGMAS * o_std):
            self.offset_found = True
        elif abs(o) + 2.0 * o_std <= KWS_OFFSET_MPS:
            self.ratio_checked = True

    def observe_offset(self, t: float, g_x: float, w: float) -> bool:
        """One steady fix (``g_x`` the antenna's longitudinal speed over ground, ``w`` the raw
        wheel speed) into the offset fit; True once, when a re-seeded scale is refuted."""
        self.fit.append((t, g_x, w))
        while t - self.fit[0][0] > KWS_FIT_WINDOW_S:
            del self.fit[0]
        if not self.seeded or self.offset_found or self.ratio_checked:
            return False
        self._fit_offset()
        return self.offset_found

    def offset_message(self) -> str:
        """The one log line of a refuted scale: which key, the offset seen."""
        return (f"[inputs.wheel_speed_fl/fr/rl/rr] offset: the wheel speeds read {self.offset_slope:.3f} x the "
                f"GNSS speed {self.offset:+.2f} m/s (+- {self.offset_std:.2f}, {len(self.fit)} steady fixes "
                f"across speeds): an offset of {self.offset:+.2f} m/s, not a wheel radius (a DBC offset missing "
                f"from the mapping?); velocity and sideslip are not promised; correct the offset in the config")

    def observe(self, t: float, raw: float, gnss: float, vy: float, r: float, ax: float, lever_x: float,
                lever_y: float, kw: float, kw_var: float, bounds: tuple[float, float]) -> bool:
        """One GNSS fix at its time of validity ``t``: ``raw`` the fused wheel speed before the
        learned scale, ``gnss`` its speed over ground, ``vy``, ``r``, ``ax`` the filter's lateral
        speed, yaw rate and longitudinal acceleration then, the receiver's lever arm, the state's
        wheel scale ``kw``, its variance and its current ``bounds``. True once: re-seed."""
        w = abs(raw)
        if not (w == w and gnss == gnss and w > 0.0):
            return False
        lat = vy + r * lever_x  # the antenna's lateral speed (ISO 8855: +y left, lever x ahead)
        g2 = gnss * gnss - lat * lat
        if g2 <= 0.0:
            return False
        g_x = math.sqrt(g2) + r * lever_y  # its longitudinal speed, taken back to the axis
        q = g_x / w
        if gnss >= KWS_MIN_SPEED and abs(ax) <= KWS_MAX_AX and abs(lat) <= KWS_MAX_LATERAL * gnss:
            self.observe_offset(t, g_x, w)  # at any ratio: an offset's ratio leaves KWS_TOTAL as speed falls
        lo, hi = KWS_TOTAL
        if not lo <= q <= hi:  # no tyre: a unit error (WheelScaleCheck) or a GNSS glitch
            return False
        if max(gnss, w * kw) >= KWS_GAP_MIN_SPEED:  # as WheelScaleCheck: the fix that confirms sets it
            ql = self._q_lp
            self._q_lp = q if ql != ql else ql + KWS_GAP_GAIN * (q - ql)
            self.gap = abs(self._q_lp - kw)
            self.gap_t = t
        if gnss < KWS_MIN_SPEED or abs(ax) > KWS_MAX_AX or abs(lat) > KWS_MAX_LATERAL * gnss:
            return False
        self.q.append(q)
        self.t.append(t)
        while t - self.t[0] > KWS_WINDOW_S:
            del self.q[0]
            del self.t[0]
        n = len(self.q)
        if n < KWS_FIXES or self.t[-1] - self.t[0] < KWS_SPAN_S:
            return False
        m = sum(self.q) / n
        sd = math.sqrt(sum((v - m) ** 2 for v in self.q) / (n - 1))
        self.scale, self.spread = m, sd
        t_mid = 0.5 * (self.t[0] + self.t[-1])
        old = [v for v, tv in zip(self.q, self.t) if tv < t_mid]
        new = [v for v, tv in zip(self.q, self.t) if tv >= t_mid]
        steady = (3 * len(old) >= KWS_FIXES and 3 * len(new) >= KWS_FIXES
                  and abs(sum(old) / len(old) - sum(new) / len(new)) <= KWS_HALVES_REL * m)
        # fixes ~1 s apart are independent; fewer fixes than seconds: each its own
        n_ind = max(1.0, min(n, self.t[-1] - self.t[0]))
        self.std = math.hypot(sd / math.sqrt(n_ind), KWS_STD_FLOOR)
        if self.seeded or sd > KWS_MAX_SPREAD or not steady:
            return False
        outside = not bounds[0] <= m <= bounds[1]
        far = abs(m - kw) > max(KWS_FAR, 4.0 * math.sqrt(max(kw_var, 0.0) + self.std ** 2))
        if outside or far:
            self.seeded = True
            self.v_seed = sum(f[1] for f in self.fit if f[0] >= self.t[0]) / max(
                1, sum(1 for f in self.fit if f[0] >= self.t[0]))
            return True
        return False

    @property
    def measured(self) -> bool:
        """A fix has measured the wheels' scale against GNSS (:attr:`gap` says by how much)."""
        return self._q_lp == self._q_lp

    def message(self) -> str:
        """The one log line of a re-seed: which mapping, the ratio, what was learned."""
        return (f"[inputs.wheel_speed_fl/fr/rl/rr]: the wheel speeds read {1.0 / self.scale:.3f}x the GNSS "
                f"speed over ground ({len(self.q)} steady fixes, spread {100.0 * self.spread:.1f} %): the "
                f"wheel radius / scale in the config is off by {100.0 * abs(1.0 / self.scale - 1.0):.0f} %, "
                f"learned (wheel scale {self.scale:.3f} +- {self.std:.3f}); correct the scale in the config")


def recentred_bounds(scale: float) -> tuple[float, float]:
    """The wheel-scale state's bounds around a learned ``scale``: +-``KWS_HALF_WIDTH``, within
    ``KWS_TOTAL``."""
    return (max(KWS_TOTAL[0], scale - KWS_HALF_WIDTH), min(KWS_TOTAL[1], scale + KWS_HALF_WIDTH))
