"""The car's sideslip rate against the single-track model's: a slide the steering cannot see.

Why (issue 7, never-seen random drive 2254): the single-track pseudo-measurement asserts the rear tyre
law, and the steering's misfit (``SingleTrackFusion.law_excess_var``, ``core.LAW_EXCESS``) widens it
only by the *difference* of the two axles' slips beyond their laws. A car sliding with both axles at
their limit (2254: all-wheel drive, double lane change on mu 0.208 dropping to 0.099; front and rear
slip both ~15 deg at 1243.3 s) shows no misfit once the steering passes through L r / vx: there the
excess fell to 0, the pseudo-measurement came back at full weight and moved vy from -2.1 to -0.6 m/s
within 36 ms (true -2.9), the sideslip from -9.9 to -0.4 deg at a 0.8 deg std, and at 1244.30-1244.52 s
it was published valid at -0.2..+0.4 deg +- 0.6 for a true -17.6 (main 7f4496e). The only documented
blind spot of the misfit ("both axles leaving the law alike", ``law_holds``).

The physics: on ice at the friction limit the tyres' lateral force is saturated (mu g = 0.97 m/s^2 on
2254's 0.099), so the model, which reads vy from the forces as a gripping car would, says nothing about
vy. The kinematics do, without tyres, steering or GNSS: vy changes at ay - r vx. Where the model holds,
its vy follows the car's, so its own change (``vy_model(t) - vy_model(t0)``) matches the integral of
ay - r vx; a car sliding sideways at 0.8 m/s^2 (2254: ay 0.87, r vx 1.68) with r and ay steady (the
model's vy steady) leaves the model behind by that much every second. The model's error changes by
exactly that mismatch: e(t) = e(t0) + int (dvy_model / dt - (ay - r vx)) dt. So the mismatch,
integrated with the model's correlation time (``single_track.CORNER_STEPS`` x 6 ms, ~2 s: the same
memory the filter gives the model's errors), beyond what the accelerometer's and gyro's residual
offsets integrate to over that time and the model's own error, is what the model's vy may be off by
now: it joins the law excess (``core.SLIDE_RATE``). It needs the IMU's inputs (not substituted) and
forward speed; it restarts with the filter. When the tyres regain grip the car's vy comes back to the
law and the integral comes back with it.

What it cannot tell from a slide: an accelerometer offset that steps faster than the filter's b_ay
follows, which is what a road's bank changing does (g sin(bank) in ay; suite road_handling: a 2.9 deg
step of bank put -0.6 m/s^2 into ay - r vx for 4 s on a gripping car, the model right). So core applies
it only while the steering has shown the road's friction at the present |ay|
(``fusion/friction_limit.py``'s hold): at the limit, where the model has nothing to say about vy.
The residual offsets' 0.1 m/s^2 (``ACC_STD``) make it slow for a slow slide: a sideslip growing at
1 deg/s at 14 m/s (0.25 m/s^2, random drive 2318) stays inside its 3 sigma.
"""
from __future__ import annotations

import math

from .single_track import CORNER_STEPS

# m/s^2: what ay - r vx is off by that the filter's bias states do not take out, as a bias over the
# memory: the accelerometer's residual offset and the road's bank split (~0.05), the gyro's residual
# bias times the speed (0.002 rad/s at 20 m/s: 0.04), the yaw-scale error times r vx (0.5 % of
# 8 m/s^2: 0.04), the IMU's lever arm times the yaw acceleration in a transient (core.IMU_LEVER_STD_M)
ACC_STD = 0.1
SIGMA = 3.0  # the mismatch beyond this many sigmas of the above is the model's error
MIN_SPEED = 3.0  # m/s: below it no sideslip is promised (core.MIN_SPEED_SIDESLIP)


class SlideRate:
    """Leaky integral of the kinematic vy change less the model's vy change (m/s)."""

    def __init__(self, dt: float):
        self.dt = dt
        self.tau = CORNER_STEPS * dt  # the model's error correlation time (s)
        self._keep = 1.0 - dt / self.tau
        # 3 sigma of the residual offsets integrated over the memory (their steady-state level)
        self._lim_acc = (SIGMA * ACC_STD * self.tau) ** 2
        self.reset()

    def reset(self) -> None:
        self.e = 0.0
        self.vy_model = math.nan  # the model's vy at the step before (NaN: start over)

    def step(self, vx: float, r: float, ay: float, vy_model: float, model_std: float) -> float:
        """One step: ``r`` and ``ay`` bias-corrected as the filter integrates them, ``vx`` the filter's,
        ``vy_model`` the model's vy for this instant (the lag shift in) and ``model_std`` its own
        error's std (``SingleTrackFusion.model_error``). Returns the variance (m/s)^2 the model's vy
        may be off by beyond its own uncertainty (0 while the kinematics follow it)."""
        if not vx >= MIN_SPEED or not math.isfinite(vy_model):
            self.reset()
            return 0.0
        prev = self.vy_model
        self.vy_model = vy_model
        if prev != prev:  # NaN: the first step of a run
            return 0.0
        e = self.e = self._keep * self.e + (ay - r * vx) * self.dt - (vy_model - prev)
        lim = math.sqrt(self._lim_acc + (SIGMA * model_std) ** 2)
        e = abs(e)
        return (e - lim) ** 2 if e > lim else 0.0
