"""The heading after a slow turn the rear wheels counted alike: its std carries the scale they measured, not a flip.

Why: an unconfirmed gyro's heading std carries ``GyroScaleGate.heading_scale_sd`` (a flipped sign's
scale error, 1.0 as a std) times the rotation the heading still owes to the gyro's scale
(``scale_sensitivity.py``), and the heading is promised only where the gate's ``heading_ok`` holds
(scale confirmed or never exercised). A drive that reverses through a curve below the witnesses'
3 m/s and then drives straight never confirms the gyro: the heading stayed withheld while right
(random drives 1487, 1532, 1547, 1584, 1653, 1667 on main 81ac01f, heading valid on 0.49-0.50 of the
rows above 5 m/s; 1487: 0.0-0.13 deg off through and after a 24 deg reverse curve, at a published std
of 24 deg that the fixes took back to 1.5 deg only ~10 s after the reverse, and invalid to the end by
the gate even then), although ``slow_exercise.py`` already forgave that turn for the sideslip.

Physics: the heading integrates ``k r``; with ``k`` the gyro's scale, the slow turns put
``(k - 1) x W`` into it, ``W`` their net rotation. Below 3 m/s the rear wheels still count that
rotation, summed over the slow turns (``SlowExercise.wheels_net``), and the gyro's rotation less
theirs (``SlowExercise.disagree``) is ``(k - 1) W`` itself, within the wheels' quanta
(``SLOW_TURN_TOL``). So once such a turn is forgiven (the summed disagreement within
``SLOW_AGREE`` of the wheels' rotation, then quiet witnessed seconds at speed), the scale error is
measured: ``(|disagree| + SLOW_TURN_TOL) / |wheels_net|``, used as one std (a bound taken as a std:
conservative; the net rotation, not the summed absolute one, whose wheel noise and S-bends would
make it small), in place of the flip's 1.0 -- and the gate's forgetting rule
(``sideslip_ok_forgetting``) in place of "never exercised" for the heading too. Times the rotation
the heading still owes to the scale (about ``W`` at the reverse's end), that is the measured
disagreement plus the quanta (1487: 1.1 deg + 1 deg over a 25.5 deg net turn: 0.082, against 1.0).
A flip reads the rotation the other way (disagreement twice the rotation) and a gyro read 1/57x
not at all: neither is forgiven, both keep the flip's std and the old rule (the heading unpromised
until the gyro is confirmed). Exercise at speed, a slow turn the wheels did not count, a
contradiction, or a net rotation within the quanta keep the old std. Used under core.HEADING_SLOW_TURN_FORGOTTEN.
"""
from __future__ import annotations

from .slow_exercise import SlowExercise, SLOW_TURN_TOL


def scale_sd(ex: SlowExercise, unconfirmed_sd: float) -> float:
    """The scale error's std an unconfirmed gyro's heading must carry: the wheels' measure of it
    once a slow turn was forgiven (module docstring), else ``unconfirmed_sd`` (a flip's)."""
    if (not ex.forgiven or ex.slow or ex.at_speed or ex.uncounted
            or abs(ex.wheels_net) <= SLOW_TURN_TOL):
        return unconfirmed_sd
    return min(unconfirmed_sd, (abs(ex.disagree) + SLOW_TURN_TOL) / abs(ex.wheels_net))
