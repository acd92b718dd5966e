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
"""
from __future__ import annotations

import math

#: |ax| (m/s^2) below which the tyres carry (almost) no longitudinal force: the linear law's slip
#: there (0.7 % at 1 m/s^2) is below what this witness can tell, so the comparison starts again.
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
#: under the car (the bias state holds the grade at the start), the wheel-radius scale's error x the
#: speed change, ax's unmodelled pitch; 0.2 m/s is 2 % of the speed change of a typical stop
SLIP_MARGIN_MPS = 0.2
#: lowest speed (m/s) a slip ratio is taken at (wheels read 0 below ~0.3 m/s)
MIN_SPEED_MPS = 2.0


class SlipWitness:
    """Integrates the accelerometer from the last force-free moment against the wheel speed."""

    def __init__(self, dt: float, wheel_noise2: float, driven_fused: bool):
        self.dt = dt
        self.wheel_noise2 = wheel_noise2
        self.driven_fused = driven_fused  # the fused wheels include driven ones: traction slips them
        self.v_ref = math.nan  # the car's speed as the accelerometer carries it from the anchor
        self.bax = 0.0  # the filter's ax bias at the anchor (later it takes up the slip itself)
        self.bax_var = 0.0
        self.t = 0.0  # s since the anchor
        self.ratio = 0.0  # the largest slip ratio seen since the anchor
        self.excess = 0.0  # m/s: slip seen now beyond what the comparison's errors explain

    def step(self, v_wheels: float, ax_m: float, bax: float, bax_var: float, r_vy: float) -> float:
        """One step; returns the slip bound (m/s) the evidence so far puts on the fused wheels.

        ``v_wheels``: the fused wheels' speed as the car's vx (scale and kinematics applied), nan
        when not fused; ``ax_m``: the accelerometer as the filter integrates it (bias not removed);
        ``bax``, ``bax_var``: the filter's ax bias and its variance now; ``r_vy``: r vy, vx's other
        rate in the body frame."""
        ax = ax_m - bax
        if not math.isfinite(v_wheels) or abs(ax) < ANCHOR_AX_MPS2 or not math.isfinite(self.v_ref):
            self.v_ref = v_wheels
            self.bax = bax
            self.bax_var = bax_var
            self.t = 0.0
            self.ratio = 0.0
            self.excess = 0.0
            return 0.0
        self.t += self.dt
        self.v_ref += (ax_m - self.bax + r_vy) * self.dt
        lost = self.v_ref - v_wheels  # > 0: the wheels are slower than the car
        if self.v_ref < 0.0:
            lost = -lost
        braking = ax * self.v_ref < 0.0
        if not braking:
            lost = -lost if self.driven_fused else 0.0  # traction speeds up driven wheels only
        sigma2 = self.bax_var * self.t * self.t + 2.0 * self.wheel_noise2
        self.excess = max(0.0, lost - SLIP_SIGMAS * math.sqrt(sigma2) - SLIP_MARGIN_MPS)
        speed = abs(v_wheels)
        if speed > MIN_SPEED_MPS and self.excess > 0.0:  # slip, measured: the loss itself
            self.ratio = max(self.ratio, lost / speed)
        return self.ratio * speed
