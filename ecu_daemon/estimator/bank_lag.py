"""The vy (so sideslip) error while ``b_ay`` lags a bank that is changing, as a variance (issue 7).

Why: the main filter's ``b_ay`` holds gravity's share of the road bank, ``g sin(bank)``
(road.py). A bank that ramps (a superelevation transition) runs ahead of it: ``b_ay`` follows with
the filter's time constant (seconds), and until it has, the filter integrates the difference as a
lateral acceleration into vy. The filter does not know it: its ``P[b_ay]`` grows only by the bank
walk (bank_walk.py), which a ramp outruns. Random drive 1796 (road course, mu 0.33, 14.5 m/s): the
bank ramps from +0.025 to -0.060 rad in 3 s (t+115-118 s), ``b_ay`` is 0.65 m/s^2 behind at the
ramp's end against a ``b_ay`` std of 0.083, the vy error is -0.22 m/s and the sideslip -0.86 to
-0.95 deg against a published std of 0.29-0.31 deg: 31 valid rows beyond 3 sigma (they appeared
with bankay42's ay allowance, which changed b_ay's history; main's same moment was 2.4-2.5 sigma).

The physics: a lag ``l`` of ``b_ay`` is an error of the filter's bias state, and the filter's own
covariance says how a bias error carries into vy: the regression ``P[vy, b_ay] / P[b_ay]`` (the
vy correction per unit of b_ay correction its measurements have been making; on 1796 -0.31 at
t+118.1 s where the true vy error / lag was -0.33, -0.42 against -0.54 at t+120 s). The part of
the lag beyond what ``P[b_ay]`` already holds is added to vy's variance: ``c^2 (l^2 - P[b_ay])``.
The lag itself is what the ay-vs-gyro test sees and b_ay has not taken up: its slow residual
``e_as`` (rad/s) is ``(l - dvy/dt) / vx`` (fault_detection.py), so ``l = |e_as| vx``, less what
the ay test itself allows a transient's dvy/dt (``YAW_TOL_RDOT`` times its decaying peak of |yaw
acceleration|): a slalom's or a lane change's residual is its vy changing, not a bank (the first
version without it withheld right sideslip on flat slaloms, sines and lane changes: random drives
1971 0.924 -> 0.780 valid above 5 m/s, 1925 0.997 -> 0.942, 1934 0.982 -> 0.940). A bank moves ay by at most ``g`` times its whole possible
change (``bank_rate.BANK_CHANGE_MAX``), or its rate bound times the distance b_ay takes to
follow (``bank_rate.BANK_RATE_M`` x vx x ``road.CORRELATION_S``): a larger residual is no bank
(a sensor fault: the ay test's own business), and the lag counted is capped there. A constant
bank, once b_ay has it, leaves no residual and costs nothing; nor does a residual inside b_ay's
own std (the usual noise and transients): the term is zero, bit for bit, there.

Measured (bankss43, 46 random drives of 241-2160): valid sideslip rows beyond 3 sigma 98 -> 0
(1796's 31, and main's 51 on 527 and 16 on 2052); the cost is 5516 valid rows on road courses, the
ramps' transients, 91 % of them 0.5 deg or more off; the 23 non-road drives, banked and flat, unchanged.
"""
from __future__ import annotations

from .bank_rate import ay_change_bound
from .fault_detection import YAW_TOL_RDOT
from .road import CORRELATION_S

#: m/s: below this the ay test's residual is not formed (fault_detection: 2 x YAW_MIN_SPEED)
MIN_SPEED = 6.0


def vy_var(e_as: float, rdot_abs: float, vx: float, p_vy_bay: float, p_bay: float) -> float:
    """(m/s)^2: the vy variance of b_ay's lag behind a changing bank (0 where there is none to add);
    ``rdot_abs``: the ay test's decaying peak of |yaw acceleration| (its transient allowance)."""
    if vx <= MIN_SPEED or p_bay <= 0.0:
        return 0.0
    seen = abs(e_as) - YAW_TOL_RDOT * rdot_abs
    if seen <= 0.0:
        return 0.0
    lag = min(seen * vx, ay_change_bound(vx, CORRELATION_S))
    excess = lag * lag - p_bay
    if excess <= 0.0:
        return 0.0
    c = p_vy_bay / p_bay
    return c * c * excess
