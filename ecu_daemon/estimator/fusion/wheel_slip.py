"""The wheels' speed lost (or gained) beyond what the accelerometer says the car lost: slip.

Why: ``WheelSpeedFusion.slip_bound`` is the linear slip law (slip ratio = |ax| / (g C_x)), right
for a tyre well inside its grip. At the friction limit it is not: an ABS (or traction control)
holds the slip ratio near its threshold, 10-20 % whatever the deceleration, and on a wet or snowy
road that deceleration is small, so the law says 0.3 m/s where the wheels run 1.5-2 m/s below the
car (random drives 12, 64, 83, 159, 193, 210 of tools/random_drives.py; vx valid 1.5-2 m/s off at
a 0.25-0.5 m/s std). The grip is unknown, so the limit is not predicted: it is measured. A wheel
speed can only fall behind the car's by slipping, and slip builds while the wheels decelerate
faster than the car: from the last moment the tyres carried no longitudinal force (|ax| small: no
slip then) the accelerometer, integrated, says where the car's speed went; what the wheels lost
beyond that is slip, less what the accelerometer's bias (as well as the filter knew it then) and
the wheels' noise could make of it. Once built up, a held slip is invisible to this comparison (the
wheels then decelerate with the car), so the slip *ratio* seen is kept for the rest of the
manoeuvre: an ABS keeps it while it keeps braking. Only the direction slip takes counts (braking:
wheels slower; traction: the driven wheels faster): a wheel-speed lag reads the other way and is
not slip. The bound goes into the published vx std (core.py, beside the linear law's); the slip seen
beyond the comparison's errors (``excess``) also widens the wheel update, so vx leans on ax and GNSS
while it lasts.

"No longitudinal force" is the tyres' force, not the car's acceleration (issue 7, "mode B on
snow"): two things made a small |ax - b_ax| a false anchor. (1) ``b_ax`` holds the grade as well as
the sensor's offset, so ax - b_ax is the kinematic acceleration; on a 7 % downhill the tyres brake
at 0.7 m/s^2 to hold the speed (random drive 83: ax -0.6 m/s^2 while they carried -1.3 m/s^2 on
snow, mu 0.23). The tyres' force per mass is the specific force less the sensor's own offset
(road.py splits ``b_ax`` into the two). (2) A tyre's grip is shared by both directions (the friction
ellipse): near its lateral limit a small longitudinal force takes a large slip ratio (at
saturation the slip vector points along the force, kappa / tan(alpha) = Fx / Fy), so a car sliding
through a snowy corner slips its wheels at |ax| < 1 m/s^2 (drives 193, 239: 0.3-1 m/s at ay
0.9-1.0 of mu g). So two comparisons run side by side, each a lower bound on the slip, and the larger counts:

* one anchored where the tyres carry (almost) no force at all, |(fx, fy)| below the threshold: it
  runs through a corner from its entry, so it sees slip that builds near the lateral limit at any
  |fx|; but its bias x time allowance grows with the corner (3 sigma of a 0.015 m/s^2 bias is 0.5
  m/s after 12 s), so a late, quick slip can drown in it (drive 193: 0.4 m/s lost 12 s into a
  corner, not seen);
* one anchored where |fx| alone is below it (the abs33 rule, with the tyres' force for the car's
  acceleration): short, so sensitive to the slip an ABS or a brake in a corner builds within
  0.3 s. Anchored on a slipping tyre it sees only the slip added since: less, never more.

Both are anchored by a force threshold, and on ice that threshold is the grip itself (random drive
83 after its patch of mu 0.11: mu g = 1.06 m/s^2, the tyres at |f| 0.95-1.07 for 12 s). There the
free comparison restarts whenever |f| dips below 1 m/s^2, and a slip of 0.34 m/s built within 0.3 s
(a brake on ice) is never seen; or, anchored 8 s before, its reference has drifted 0.12 m/s and its
bias x time allowance hides the rest. Which of the two happened turned on fy, i.e. on the filter's
b_ay: the tyre-law excess (core.LAW_EXCESS) moved it (0.45 against 0.35 m/s^2 without, at 1241 s),
and fy by up to 0.4 m/s^2 with it, which no threshold should hinge on. So two more comparisons need
no anchor at all: windows of WINDOW_S, restarted from the smoothed wheels, staggered by half of it.
Slip builds while the wheels decelerate faster than the car, and a window's loss is what built within
it: a lower bound on the slip (it was >= 0 at the window's start), with the allowance of a 1 s
comparison. A held slip does not build any further, so a window keeps the largest ratio it has seen
until the tyres are force-free and inside their law (``at_limit`` False): then it starts over at 0.
"""
from __future__ import annotations

import math

#: the tyres' force per mass (m/s^2, longitudinal and lateral together: they share one grip) below
#: which they carry (almost) none: the linear law's slip there (0.7 % at 1 m/s^2) is below what this
#: witness can tell, and no grip is near its limit, so the comparison starts again.
#: Tested on the sample itself, not low-passed: an ABS application builds ~1 m/s of slip within
#: 0.3 s of the brake's onset (the reduction in tests/test_abs_slip.py), and a low-pass that quiets
#: ax's noise (0.2 s) starts the comparison after most of it; a noise dip below the threshold
#: mid-braking can restart it only where the braking is near 1 m/s^2 (little slip to lose).
#: Not lower (0.5, low-passed): a corner's mild drag then starts a comparison seconds before the
#: braking (random drives 12, 159 broke again).
ANCHOR_AX_MPS2 = 1.0
#: sigmas of the comparison's own error (ax bias x time, wheel noise) a loss must exceed to be slip
SLIP_SIGMAS = 3.0
#: m/s: what neither bias nor noise explains but the comparison still carries: a grade changing
#: under the car (the bias state holds the grade at the start), ax's unmodelled pitch; with
#: SLIP_SCALE_MARGIN, the wheel-radius scale's error x the speed change. 0.2 m/s flat (abs33) hid
#: the 0.3-0.45 m/s a snowy corner's slip takes at a small speed change (drives 83, 193); a false
#: reading costs the published std the loss itself (/ sqrt 3), never the flag (that takes 2.2 m/s)
SLIP_MARGIN_MPS = 0.1
#: the wheel-radius scale's error the margin allows for, x the speed change since the anchor
SLIP_SCALE_MARGIN = 0.02
#: s: the wheels are compared low-passed (noise 0.08 m/s a sample: 3 sigma of two samples is 0.34
#: m/s, beyond a snowy corner's slip). The anchor follows them complementarily (the accelerometer
#: carries the speed, the wheels only pull it: no lag) and the loss is smoothed over the same time:
#: a slip shows 0.1 s later, and stays (the ratio is held)
WHEEL_SMOOTH_S = 0.1
#: lowest speed (m/s) a slip ratio is taken at (wheels read 0 below ~0.3 m/s)
MIN_SPEED_MPS = 2.0
#: s: the windowed comparisons' length; two run staggered by half of it, so a slip built within
#: WINDOW_S / 2 (an ABS, a brake on ice: ~0.3 s) lies whole inside one of them. Short, so the bias x
#: time allowance stays below the wheels' noise (3 sigma of a 0.015 m/s^2 bias is 0.05 m/s after
#: 1 s) and the r vy term cannot drift them (0.1 rad/s x 0.4 m/s of vy std: 0.04 m/s after 1 s)
WINDOW_S = 1.0


class _Comparison:
    """The accelerometer integrated from one anchor against the wheels (see the module doc)."""

    def __init__(self, hold: bool):
        self.hold = hold  # keep the largest ratio seen until the next anchor (see SlipWitness)
        self.v_ref = math.nan  # the car's speed as the accelerometer carries it from the anchor
        self.bax = 0.0  # the filter's ax bias at the anchor (later it takes up the slip itself)
        self.bax_var = 0.0
        self.t = 0.0  # s since the anchor
        self.ratio = 0.0  # the largest slip ratio seen since the anchor
        self.excess = 0.0  # m/s: slip seen now beyond what the comparison's errors explain
        self.v0 = math.nan  # the speed at the anchor
        self.diff = 0.0  # (v_ref - wheels), low-passed
        self.anchored = False  # the last step was an anchor: v_ref follows the wheels

    def anchor(self, w: "SlipWitness", v_wheels: float, ax_m: float, bax: float, bax_var: float,
               r_vy: float) -> None:
        if self.anchored and math.isfinite(self.v_ref) and math.isfinite(v_wheels):
            self.v_ref += (ax_m - bax + r_vy) * w.dt
            self.v_ref += w.pull * (v_wheels - self.v_ref)
        else:
            self.v_ref = v_wheels
        self.anchored = math.isfinite(v_wheels)
        self.ratio = 0.0
        self._restart(bax, bax_var)

    def rewindow(self, bax: float, bax_var: float) -> None:
        """Start a new window from the smoothed wheels, the ratio seen so far kept (see SlipWitness)."""
        self.v_ref -= self.diff  # the wheels, low-passed (diff is v_ref - wheels, low-passed)
        self._restart(bax, bax_var)

    def _restart(self, bax: float, bax_var: float) -> None:
        """The comparison starts over from v_ref with the filter's ax bias now (anchor, rewindow)."""
        self.v0 = self.v_ref
        self.bax = bax
        self.bax_var = bax_var
        self.t = 0.0
        self.excess = 0.0
        self.diff = 0.0

    def step(self, w: "SlipWitness", v_wheels: float, ax_m: float, r_vy: float, fx: float) -> None:
        self.anchored = False
        self.t += w.dt
        self.v_ref += (ax_m - self.bax + r_vy) * w.dt
        self.diff += w.pull * (self.v_ref - v_wheels - self.diff)
        lost = self.diff  # > 0: the wheels are slower than the car
        if self.v_ref < 0.0:
            lost = -lost
        braking = fx * self.v_ref < 0.0  # the tyres' force against the motion (downhill: at ax 0)
        if not braking:
            lost = -lost if w.driven_fused else 0.0  # traction speeds up driven wheels only
        # the wheels' noise, smoothed at the anchor and now (counted as if every 2nd sample were new)
        sigma2 = self.bax_var * self.t * self.t + 2.0 * w.wheel_noise2 * w.pull
        margin = SLIP_MARGIN_MPS + SLIP_SCALE_MARGIN * abs(self.v_ref - self.v0)
        self.excess = max(0.0, lost - SLIP_SIGMAS * math.sqrt(sigma2) - margin)
        speed = abs(v_wheels)
        if not self.hold:  # anchored slip-free: the loss is the slip now, a recovered wheel shows 0
            self.ratio = 0.0
        if speed > MIN_SPEED_MPS and self.excess > 0.0:  # slip, measured: the loss itself
            self.ratio = max(self.ratio, lost / speed)


class SlipWitness:
    """Integrates the accelerometer from the last force-free moments against the wheel speed."""

    def __init__(self, dt: float, wheel_noise2: float, driven_fused: bool):
        self.dt = dt
        self.wheel_noise2 = wheel_noise2
        self.driven_fused = driven_fused  # the fused wheels include driven ones: traction slips them
        self.free = _Comparison(False)  # from the last step with no tyre force at all
        self.straight = _Comparison(True)  # from the last step with no longitudinal tyre force
        # windows restarted every WINDOW_S, their ratios held until the tyres are force-free
        self.windows = (_Comparison(True), _Comparison(True))
        self.pull = min(1.0, dt / WHEEL_SMOOTH_S)  # the wheels' weight per step in the smoothing
        self.ratio = 0.0  # the larger comparison's slip ratio
        self.excess = 0.0  # m/s: slip seen now beyond what the comparisons' errors explain

    def step(self, v_wheels: float, ax_m: float, bax: float, bax_var: float, r_vy: float,
             fx: float = math.nan, fy: float = 0.0, at_limit: bool = False) -> float:
        """One step; returns the slip bound (m/s) the evidence so far puts on the fused wheels.

        ``v_wheels``: the fused wheels' speed as the car's vx (scale and kinematics applied), nan
        when not fused; ``ax_m``: the accelerometer as the filter integrates it (bias not removed);
        ``bax``, ``bax_var``: the filter's ax bias and its variance now; ``r_vy``: r vy, vx's other
        rate in the body frame. ``fx``, ``fy``: the force the tyres carry per mass (the specific
        force less the sensor's own offsets, grade and bank left in: the tyres hold the car on
        them); nan ``fx``: ``ax_m - bax`` (no split of the bias known), ``fy`` 0. ``at_limit``: the
        steering says a tyre has left its linear law (``SingleTrackFusion.law_excess_var`` > 0): a
        small force is then no sign of a slip-free tyre, so the windows' held slip is kept."""
        if not math.isfinite(fx):
            fx = ax_m - bax
        known = math.isfinite(v_wheels)
        free = math.hypot(fx, fy) < ANCHOR_AX_MPS2
        for c, anchor in ((self.free, free), (self.straight, abs(fx) < ANCHOR_AX_MPS2)):
            if not known or anchor or not math.isfinite(c.v_ref):
                c.anchor(self, v_wheels, ax_m, bax, bax_var, r_vy)
            else:
                c.step(self, v_wheels, ax_m, r_vy, fx)
        # the windows' held slip ends only where the tyres are force-free *and* inside their law: at
        # the limit (the steering's misfit of the understeer law, core.LAW_EXCESS) the grip itself
        # may be ~1 m/s^2 (ice, mu 0.11), and |f| flickering about the threshold there is no release
        slip_free = free and not at_limit
        for i, c in enumerate(self.windows):
            if not known or slip_free or not math.isfinite(c.v_ref):
                c.anchor(self, v_wheels, ax_m, bax, bax_var, r_vy)
                c.t = -0.5 * WINDOW_S * i  # the stagger: the second window's first one is half as long
            elif c.t >= WINDOW_S:
                c.rewindow(bax, bax_var)
                c.step(self, v_wheels, ax_m, r_vy, fx)
            else:
                c.step(self, v_wheels, ax_m, r_vy, fx)
        w0, w1 = self.windows
        self.ratio = max(self.free.ratio, self.straight.ratio, w0.ratio, w1.ratio)
        self.excess = max(self.free.excess, self.straight.excess, w0.excess, w1.excess)
        return self.ratio * abs(v_wheels) if known else 0.0
