"""How much of the ay-vs-gyro test's slow residual a road's changing bank may explain (issue 7).

Why: ``FaultDetector._yaw`` judges the lateral accelerometer by the low-passed disagreement
``r - (ay - b_ay - lr rdot) / vx`` (``YAW_SLOW_TAU_S``) against a flat road's tolerance
(``YAW_SLOW_TOL + YAW_SLOW_TOL_REL |r|``). The road's bank puts ``g sin(bank)`` into ay; the main
filter's ``b_ay`` holds a constant bank (road.py: a constant bank and a constant offset read the same),
but not a bank that changes faster than its walk follows. On fault-free road courses and banked
drives that isolated a healthy ay and withheld right sideslip (avail42's census of main b26daff on
random drives 1681-1920: 34,949 right rows withheld with an IMU signal isolated; drives 1710, 1729,
1796, 1892, 1748, 1757; 1729 at t+22.6 s: bank -0.022 rad at 6.5 m/s, 0.034 rad/s against a
0.029 rad/s tolerance).

The physics: a road's bank changes with the distance travelled, at most ``BANK_RATE_M`` per metre
(superelevation runoff: a handling course reverses 8 % into -6 % over 15-20 m transitions, ~0.009
rad/m; public roads' runoff is slower, ~0.002 rad/m), and by at most ``BANK_CHANGE_MAX`` in all
(2.5 % crossfall to 8 % superelevation the other way, road.py's ``BANK_SWING`` twice). Within the
test's low-pass window (``YAW_SLOW_TAU_S``) at speed vx the bank may change by
``min(BANK_RATE_M vx tau, BANK_CHANGE_MAX)``, so gravity may move ay by g times that, and the slow
test's residual (ay divided by vx) by ``g min(BANK_RATE_M vx tau, BANK_CHANGE_MAX) / vx``. An ay
offset that changes no faster is followed by ``b_ay`` exactly as such a bank is; it need not be
isolated. Only ay's isolation verdict widens (``fault_detection.AY_BANK_RATE_ALLOWANCE``): while the
residual is beyond the flat road's tolerance b_ay is lagging the bank and the yaw witnesses stay
suspect (sideslip not promised), as on main; and not while ay is isolated (b_ay frozen follows
nothing). Known cost (bankay42's report): b_ay's lag behind a bank ramp is not in the sideslip std; on 1796
(t+118 s) main is 2.5 sigma off there, and with this allowance's different history 31 rows went beyond
3 sigma (0.9 deg at 0.29 deg). A step fault (offset, zero, stuck: the suite's ``fault_accel_y_*``, 2 m/s^2 at 22 m/s
where the allowance is 1.0 m/s^2) still exceeds it, and the fast test (``YAW_TAU_S``) and the
stuck test are unchanged.
"""
from __future__ import annotations

import math

from ..gravity import G

#: rad per metre travelled: the fastest a road's bank changes (a handling course's superelevation reversal)
BANK_RATE_M = 0.01
#: rad: the most a road's bank changes from one curve to the next (road.py BANK_SWING is its 1-sigma, 3 deg)
BANK_CHANGE_MAX = 2.0 * math.radians(3.0)


def ay_change_bound(vx: float, window_s: float) -> float:
    """m/s^2: the most gravity's share of ay moves while a bank changes at the road's bound for
    ``window_s`` at ``vx`` (and by no more than BANK_CHANGE_MAX in all)."""
    return G * min(BANK_RATE_M * vx * window_s, BANK_CHANGE_MAX)


def slow_ay_allowance(vx: float, window_s: float) -> float:
    """rad/s: what a bank changing at the road's bound within ``window_s`` at ``vx`` puts into the
    ay test's residual ``(ay - b_ay) / vx`` (vx > 0)."""
    return ay_change_bound(vx, window_s) / vx
