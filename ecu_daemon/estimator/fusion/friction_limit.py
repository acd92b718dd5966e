"""The road's friction, once an axle has been seen at its limit: the other axle is near it too.

Why (issue 7, random drive 683): the single-track pseudo-measurement asserts the rear tyre law, and
the steering's misfit (``SingleTrackFusion.law_excess_var``, ``core.LAW_EXCESS``) widens it only by
what the understeer relation misses: the *difference* of the two axles' slips beyond their laws. In
a steady corner both axles carry the same share of their load, F_y / F_z = ay / g (front
m ay lr / L on m g lr / L, rear likewise), so both use the same fraction of the road's friction. A
front seen beyond its law (a plough) says the road's friction is near |ay| / g; at that |ay| the
rear is at its limit as well, and when it lets go too the misfit *shrinks* (both axles leave their
law alike) while the rear's slip grows. Drive 683 (all-wheel drive, steady circle, mu 0.21 -> 0.127):
the front ploughed at |ay| 1.0-1.1 m/s^2 (steering misfit up to 29 deg), then the rear let go at the
same |ay|: rear slip 0.6 -> 22 deg over 12 s while the misfit fell from 29 to 3.6 deg, its excess
from 4.0 to 0.2 m/s. The model held vy near 0 against a true sideslip of 17.7 deg, and the gyro's
scale fit (``yaw_scale_check.py``), reading courses against that model, took the sideslip's growth
for a 3.8-6.5 % scale: applied, the heading moved 8.5 deg at once and was published valid 14.5 deg off.

So the largest slip the steering has shown beyond the law (as an angle, the misfit's excess over
vx) is kept as what the rear may be off by for as long as the car stays at the lateral acceleration
it was seen at (|ay| >= HOLD_SHARE of it): the same utilisation, the same possible excess. It ends
when |ay| has stayed below that for RELEASE_S (the car has left the limit: a straight, a gentler
corner), or at once when the car corners harder than the limit it was seen at with the law holding
(the road grips better than that: a friction rise). An upper bound, like the excess itself.

Who uses it: the gyro's scale fit (``core.Estimator._check_lever_arm``, ``core.FRICTION_MEMORY``),
which reads courses against the model over a whole corner and applies what it finds to the state.
Not the pseudo-measurement, which keeps the present misfit: the filter's sideslip std already
grows while it is nonzero, and held through a whole limit stretch it made slaloms and lane changes
on snow invalid where they were right (random drive 636: sideslip valid above 5 m/s 91 -> 33 %,
worst error 0.5 deg; 563, 505, 515: 4-12 points).
"""
from __future__ import annotations

import math

from .single_track import LAW_HOLDS_SIGMA

#: share of the |ay| the limit was seen at above which the axles are taken to be at it still: a
#: tyre's force near its peak is flat in slip (Magic Formula curvature), so 80 % of the peak force
#: is already well beyond the linear law's slip
HOLD_SHARE = 0.8
#: s: |ay| below the hold this long ends it (a yaw-rate reversal crosses zero in a fraction of it)
RELEASE_S = 1.0
#: m/s: below this the misfit's angle is noise (as single_track.MIN_SPEED)
MIN_SPEED_MPS = 3.0
#: sigmas of the steering's misfit on the oversteer side that, after a plough in the same corner at
#: the same |ay|, say the rear has let go too (:attr:`FrictionLimit.rear_var`): the front's excess
#: cannot be negative at the limit, so oversteer there is the rear's own excess, and a swing from
#: beyond 3 sigma understeer to 1 sigma oversteer is 4 sigma of the misfit's noise
REAR_OVERSTEER_SIGMA = 1.0


class FrictionLimit:
    """Holds the largest steering-seen slip beyond the tyre law while |ay| stays at its limit."""

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        self.a_lim = math.inf  # |ay| (m/s^2) an axle was last seen beyond its law at; inf: none
        self.angle = 0.0  # the largest excess seen there (rad of slip)
        self.below_t = math.inf  # when |ay| fell below the hold (inf: not below)
        self.plough_side = 0  # the side (sign of ay) of the corner the front was last seen ploughing in
        self.rear = False  # the rear seen letting go at that limit, in that corner
        self.rear_var = 0.0  # the held excess while it is ((m/s)^2; 0 otherwise)

    def step(self, t: float, vx: float, ay: float, law_var: float, oversteer: float = math.nan) -> float:
        """One step: the steering's law excess variance of this step ((m/s)^2, 0 inside the law) and
        its misfit on the oversteer side in sigmas (``SingleTrackFusion.oversteer_sigmas``; NaN: not
        measured); returns the law excess, or the held excess at this vx when that is larger, and
        sets :attr:`rear_var`.

        The rear's own witness (core.FRICTION_REAR): the held excess says what the rear *may* be off
        by anywhere at the limit; a plough alone leaves the rear on its law, and held on the
        pseudo-measurement through every limit stretch it cost slaloms on snow their validity. But
        once the front has ploughed in this corner (the misfit beyond its law on the understeer side)
        and, with |ay| still at that limit, the misfit swings to the oversteer side, the rear has
        left its law as well: the front's excess cannot be negative at the limit, so oversteer there
        is the rear's, and the misfit *shrinks* while both are off (random drive 3791: front slip
        -6 deg at |ay| 2.8 m/s^2, misfit +3.4 deg; the driver unwinds, the rear goes -3 -> -4 deg at
        the same |ay|, the misfit swings to -1.2 then -3.2 deg, while the law pulled vy from 0.54 to
        0.22 m/s). Then the held excess is :attr:`rear_var` until |ay| falls below HOLD_SHARE of the
        limit (the axles off their limit: the law's own misfit speaks again) or ay changes side (a
        slalom's next corner has shown no plough yet: per side, not per |ay|)."""
        a = abs(ay)
        side = 1 if ay > 0.0 else (-1 if ay < 0.0 else 0)  # not bool - bool: ay may be a numpy scalar
        if side != self.plough_side:  # the corner the plough was seen in is over
            self.plough_side = 0
            self.rear = False
        if law_var > 0.0 and vx >= MIN_SPEED_MPS:
            ang = math.sqrt(law_var) / vx
            if ang > self.angle:
                self.angle = ang
            self.a_lim = a  # the limit as last seen
            self.below_t = math.inf
            if oversteer < -LAW_HOLDS_SIGMA:  # the front beyond its law: a plough in this corner
                self.plough_side = side
            held = self.angle * vx
            self._rear(a, vx, oversteer, held)
            return max(law_var, held * held)
        if self.a_lim == math.inf:
            return law_var
        if a > self.a_lim / HOLD_SHARE:  # beyond the limit with the law holding: the road grips better
            self.reset()
            return law_var
        if a < HOLD_SHARE * self.a_lim:
            if self.below_t == math.inf:
                self.below_t = t
            if t - self.below_t >= RELEASE_S:
                self.reset()
                return law_var
        else:
            self.below_t = math.inf
        held = self.angle * vx
        self._rear(a, vx, oversteer, held)
        return max(law_var, held * held)

    def _rear(self, a: float, vx: float, oversteer: float, held: float) -> None:
        """The rear's witness (:meth:`step`), with |ay| = ``a`` and the held excess ``held`` (m/s)."""
        if a < HOLD_SHARE * self.a_lim:
            self.rear = False
        elif self.plough_side != 0 and oversteer > REAR_OVERSTEER_SIGMA and vx >= MIN_SPEED_MPS:
            self.rear = True
        self.rear_var = held * held if self.rear else 0.0
