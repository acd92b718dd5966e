"""The tyre-law excess widens the single-track model's vy bound instead of switching it off
(issue 7, "the estimate is right, or it says it is not"; ``core.LAW_EXCESS_BOUND``).

Why: the law excess (``law_var`` in ``core.Estimator._step``: the steering's misfit beyond 3 sigma,
``SingleTrackFusion.law_excess_var``; the driven rear on its limit, ``drive_excess_var``; braking in
a corner and the wheels' slip ratio, ``brake_excess_var``) is a variance, (m/s)^2, of how far the
rear law's vy may be off beyond the law's own uncertainty. It already widens the pseudo-measurement
by itself. But it also switched the model's bound (``core.MODEL_BOUND``) off outright whenever it
was above 0, however small, and with the bound off a steady circle's sideslip is valid only on the
filter's own P, which sits above the 0.667 deg limit there. On main's random drives 1708 (a dry
circle, mu 1.03, 4 % downhill, cf +1.3 %: ay/(mu g) p50 0.41) and 2008 the steering's misfit was 0
on all but 7 and 8 steps; what fired was the brake rule (the brakes hold the car on the downhill
grade in the corner, ``brake_grip.py``): a ratio p50 1.26 (1708) and 1.49 (2008), i.e. an excess
std p50 0.033 m/s (0.16 deg of sideslip at 11.8 m/s) on 1708 and 0.11 m/s on 2008, against the
model's own std. 6,054 (1708) and 3,385 (2008) right rows were withheld for it.

The physics: the excess is stated as a variance of the law's error, the same kind of quantity as
the law's own (``SingleTrackFusion.model_error``). When it is small against the law's std, the law
is still right to within what it says plus the excess: that is the law's honest scatter, a little
wider. When it is large (seeds 12 and 159: mu 0.21, rear slip 5.8 deg against the law's ~1, the
misfit m/s), the law is wrong here, and the same sum says so: the bound then exceeds the filter's
own vy std and has no effect, exactly as switching it off did. So the bound becomes
``s_model + sqrt(excess) + |vy - vy_model| / 3`` (sqrt of a variance added as a std, not in
quadrature: a bias for the corner, counted at its full size), with the excess the *largest* of the
last HOLD_S (2 s, ``core.MODEL_STEADY_S``: the correlation time of the model's errors, the wait the
switch-off imposed) and never from before the model was last unsteady (``reset``: a transient, an
isolation, a stale input switch the bound off and start the 2 s wait, as before). The excess
rules' own inputs are present-state (the brake and slip-ratio rules' forces, the steering's misfit
with its own hold through transients, ``core.LAW_EXCESS_HOLD``), so their peak over 2 s bounds an
error that follows the forces within a tyre's relaxation time (0.5 m / 10 m/s).
"""
from __future__ import annotations

import collections
import math

#: s: the excess is held at its largest over this window (core.MODEL_STEADY_S)
HOLD_S = 2.0


class LawExcessBound:
    """The largest tyre-law excess variance of the last HOLD_S, since the bound last became unsteady."""

    def __init__(self) -> None:
        self.q: collections.deque = collections.deque()  # (t, var), var decreasing: a sliding maximum

    def step(self, t: float, law_var: float) -> None:
        """Take this step's law excess variance (m/s)^2 (0 while the law holds) at time ``t``."""
        q = self.q
        while q and q[-1][1] <= law_var:
            q.pop()
        if law_var > 0.0:
            q.append((t, law_var))
        while q and t - q[0][0] > HOLD_S:
            q.popleft()

    def reset(self, t: float, law_var: float) -> None:
        """The model's bound went unsteady at this step: what it holds begins again from here."""
        self.q.clear()
        if law_var > 0.0:
            self.q.append((t, law_var))

    def std(self) -> float:
        """m/s the model's vy bound is widened by."""
        return math.sqrt(self.q[0][1]) if self.q else 0.0
