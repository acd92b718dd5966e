"""The gyro's vote: it is blamed only when its two witnesses agree with each other and not with it.

Why. The fault detector (fault_detection.py) judges the gyro against two witnesses of the same yaw
rate, the witness pair's wheel difference and ay / vx, each with its own, unrelated, error: the
wheels' from tyre slip (on all-wheel drive every wheel is driven and the inner one, unloaded in a
corner, slips more; a flying start at 40 m/s under full drive), ay / vx from the sideslip's rate
(ay / vx = r + d(beta)/dt at the CG). A faulty gyro puts *its* error into both disagreements alike:
an offset the same offset, a scale error the same slope against the yaw rate. So the witnesses
agree with each other and not with the gyro. Where the two disagreements differ by more than either
witness's own tolerance, at least one witness is off by its own error, and two witnesses that
contradict each other cannot outvote the third source: the verdict is "cannot tell" (the gyro stays
suspect, sideslip is not promised and the heading's std grows by the disagreement, as for any
unresolved vote), not "isolate the gyro", which replaced a right yaw rate by the slipping wheels'
and repaired the heading by their error.

Found on main 88d1c19, random drives 1201-1440 (no sensor fault in any): the gyro was isolated for
>= 1 s in 21 of them (1207 1210 1226 1230 1239 1244 1250 1253 1270 1279 1291 1298 1317 1336 1361
1372 1376 1394 1397 1413 1429; 16 all-wheel drive). At the isolating step the level tests had not
both failed in most: the scale test (a slope of the disagreement against the yaw rate that both
witnesses show) forced the verdict, with slopes far apart, each a witness's own transient error:
1207 wheels 0.44 / ay 1.07, 1226 0.16 / 0.45, 1230 0.15 / 0.59, 1239 0.24 / 0.93 and 0.18 / 0.90,
1253 0.68 / 1.39, 1291 0.18 / 0.90, 1317 -1.27 / -0.18 and -2.98 / -0.68 (a scaled gyro, x1.3, gives
both ~0.23). Where both level tests failed, the residuals had opposite signs: 1291 at 15.9 s, wheels
-0.32 rad/s (slow), ay / vx +0.35 (a 40 m/s all-wheel-drive car, its wheels slipping).

The rule, for the *onset* of an isolation only (a gyro already isolated returns by today's tests):

* the scale test blames the gyro only when the two witnesses' slopes agree within SCALE_AGREE_TOL
  (:func:`slopes_agree`), the scale test's own tolerance for one witness's slope error (track,
  radius, roll gravity: a few %);
* the level tests blame it only when the two residuals agree within ay / vx's tolerances (the
  detector's ``witnesses_agree``), unless a test no witness error explains already fired (a jump no
  car makes, a stuck value: :func:`onset_verdict`'s ``forced``). A scale failure with agreeing
  slopes is not among those: at its onset the level residuals must agree too (the suite's
  ``fault_yaw_rate_scaled``: first isolated at the same step as before, re-isolated 0.5 s later).

Without ay / vx as a witness (below 6 m/s, ay itself isolated) nothing changes: the wheels judge
alone, as before. ``core.GYRO_WITNESSES_AGREE`` False: main's vote bit for bit.
"""
from __future__ import annotations

#: the two witnesses' slopes of (gyro - witness) against the yaw rate must be this close for the
#: scale test to blame the gyro (fault_detection.SCALE_TOL, one witness's slope allowance)
SCALE_AGREE_TOL = 0.15
#: s: the largest |beta / r| of a car in its linear range the fit may take for ay / vx's transient
#: (|lr / vx - m lf vx / (L C_r)|: ~0.15 s for a 1.5 t car at 22 m/s, ~0.5 s for 2.3 t at 45 m/s)
SIDESLIP_GAIN_MAX_S = 0.5


def slopes_agree(s_w: float, s_a: float) -> bool:
    """Do the wheels' and ay / vx's slopes against the yaw rate say the same scale error?"""
    return abs(s_w - s_a) <= SCALE_AGREE_TOL


def ay_slope(s_a: float, var_r: float, var_q: float, cov_rq: float, det: float, cov_qe: float,
             cov_re: float) -> float:
    """ay / vx's slope against the yaw rate with its transient taken out: ay / vx = r + d(beta)/dt,
    and a car in its linear range has beta ~ G r (G = lr / vx - m lf vx / (L C_r), the steady-state
    sideslip gain), so in a turn-in d(beta)/dt ~ G rdot and ay / vx reads like a gyro lagging by G.
    Fitted as the wheels' timing term is (e_a = c + s r + G rdot, the weighted covariances of the
    scale test, rdot the gyro's low-passed), G within +-SIDESLIP_GAIN_MAX_S; like the wheels' lag it
    may explain a slope away, never make one (the smaller slope counts)."""
    g = (var_r * cov_qe - cov_rq * cov_re) / det
    g = min(max(g, -SIDESLIP_GAIN_MAX_S), SIDESLIP_GAIN_MAX_S)
    s_t = (cov_re - g * cov_rq) / var_r
    return s_t if abs(s_t) < abs(s_a) else s_a


def onset_verdict(verdict, witnesses_agree: bool, a_witness: bool, forced: bool):
    """The gyro latch's verdict at a step it is not isolated: a failing vote in which ay / vx
    votes but contradicts the wheels is "cannot tell" (None), unless ``forced`` (jump, stuck,
    a shared scale)."""
    if verdict and a_witness and not forced and not witnesses_agree:
        return None
    return verdict
