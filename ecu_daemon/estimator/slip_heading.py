"""Heading std while wheel slip biases vx: one antenna's heading is no better than the sideslip.

Why (issue 7, random drive 1006): a single GNSS antenna measures the velocity vector, its speed and
its course; the heading is that course less the sideslip (heading clockwise from north, sideslip
positive to the left, ISO 8855: course = heading - sideslip). The wheels measure vx, and under
braking (or traction) at a tyre's limit their longitudinal slip makes that vx wrong by a bias over
the whole manoeuvre (the wheel-slip bound ``Estimator.slip_hold``: published on vx's std, not grown
in P, so P still holds vx to the wheels' noise). Each fix then asks the filter to split a speed it
cannot reach with that vx: the rest goes into vy, so the sideslip turns by the fix's share of the
bias, and the heading turns the other way by the same angle to keep the fix's course (1006: a steady
circle on a friction drop from 0.90 to 0.55, the driver braking at -3 m/s^2 at 4.3 m/s^2 lateral;
the wheels 1.8 m/s slow, the sideslip 3.4 deg off at its own 2.1 deg std -- not valid, rightly --
and the heading 5.0 deg off at 1.45 deg, valid: 93 rows beyond 3 sigma, the car sliding from -2.4 to
-10 deg of sideslip).

The heading's own covariance cannot see it (the bias is not a state) and the sideslip's std can:
where the fixes have been splitting a biased vx, the heading error is the sideslip error (course
intact, 1006: -1.3 deg of course against -5.0 of heading). So while the wheel-slip bias exceeds what
P already grants vx (it is then the larger part of vx's error) and the heading rests on courses (no
fresh dual-antenna heading), the published heading std is at least the sideslip's. A car braking
with the sideslip known (valid: its std below 0.67 deg) keeps its heading valid; one braking with
the sideslip unknown does not promise the heading the same fixes have split.

The fixes move the heading only as far as P lets them: a course residual is split between heading
and sideslip by their variances. A heading the gyro carries from before (P's heading std a small
part of the sideslip's) is not the one the fixes set, and the bias has not reached it (random drive
499: a spin to a stop on mu 0.35, heading P std 0.47 deg against a sideslip std of 3.7-4.5 deg at
1 Hz fixes, the slip witness at 0.5-1.0 m/s: the heading 0.35 deg off, right; without this the floor
cost it 9 points of heading validity). So the floor applies while P's heading std is at least
``HELD_SHARE`` of the sideslip's (1006: 1.4-7.7 deg against 2.0-4 deg).
"""
from __future__ import annotations

import math

#: P's heading std, as a share of the sideslip's, from which the fixes' split moves the heading
#: materially (a residual's share for the heading is r^2 / (1 + r^2): 10 % at r = 1/3)
HELD_SHARE = 1.0 / 3.0


def heading_floor(slip_std: float, vx_std_filter: float, sideslip_std: float,
                  heading_std_filter: float) -> float:
    """The heading std (rad) a wheel-slip bias leaves at least, given that bias as the std published
    on vx (``slip_std``, m/s: ``core.Estimator.slip_hold`` / sqrt 3, a bias uniform up to its bound),
    the filter's own vx and heading stds (m/s, rad) and the sideslip's published std (rad): that
    std while the bias is the larger part of vx's error and the fixes hold the heading, else 0."""
    if slip_std > vx_std_filter and heading_std_filter >= HELD_SHARE * sideslip_std:
        return sideslip_std
    return 0.0


def split_sideslip_error(brake_slip: float, vx: float, vy: float, room: float = math.inf) -> float:
    """How much larger (rad) the sideslip's magnitude may be than the truth because the fixes have
    split a GNSS speed the braking wheels' vx cannot reach into vy (``core.SLIP_SPLIT``), given the
    wheels' held braking-slip bound ``brake_slip`` (m/s: the wheels, so vx, slow by at most that).

    Why (issue 7, random drive 4085: a FWD ploughing at the limit of a 0.187 road on a circle, the
    driver braking at -0.6 m/s^2): the wheels read vx 0.65 m/s slow and the single-track law no
    longer held vy (the front 12-20 deg past its law), so each fix matched its speed S with vy:
    vy^2 = S^2 - vx^2 grew from the true 1.3 to 3.9 m/s (sideslip 15-17 deg against the true 3-5),
    and the heading turned by the same 12 deg to keep the course, at a 0.9 deg std, valid.
    The split is geometry: with the filter's speed S matched and vx slow by up to b, the true
    vx is at most vx + b, so the true vy^2 is at least vy^2 - 2 |vx| b - b^2. A small vy cannot be
    told from a slow vx at all (the speed is vx + vy^2 / 2 vx): vy below sqrt(2 |vx| b) is all in
    doubt. One-sided: a speed the wheels overshoot (traction) cannot be matched by a larger vy,
    so this applies to braking slip only. A bias uniform up to this angle, as ``slip_hold``'s on vx
    (std = angle / sqrt 3, by the caller).

    ``room`` (m/s): how far the fixes have taken |vy| from the single-track model's vy. The split
    works against the model's pseudo-measurement, so the part of vy it made is at most that
    departure (the rest is the model's own error, which its std carries): random drive 3847 (a
    circle braked at the limit of its law, vy -0.22 m/s on the model's) lost 2.4 points of sideslip
    validity to the geometric bound alone, with vy where the model held it."""
    avx = abs(vx)
    avy = abs(vy)
    if not (brake_slip > 0.0 and avx > 0.0):
        return 0.0
    lo2 = avy * avy - 2.0 * avx * brake_slip - brake_slip * brake_slip
    vy_lo = max(math.sqrt(lo2) if lo2 > 0.0 else 0.0, avy - room)
    beta_lo = math.atan2(vy_lo, avx + brake_slip)
    return max(math.atan2(avy, avx) - beta_lo, 0.0)
