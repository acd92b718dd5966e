"""A slow turn the rear wheels counted alike withholds the sideslip for its memory, not for good.

Why: ``gyro_scale_gate.py`` promises a sideslip on an unconfirmed gyro only while it was never
exercised (every sample within ``GSC_QUIET`` of 0 or of a witness), because a wrong scale is ruinous
the moment the gyro reads a turn wrong. Below ``GSC_MIN_SPEED`` neither witness judges a sample,
so any slow turn counts as exercise, and a drive that reverses through a curve and then drives
straight never turns at speed for a witness to confirm the gyro: sideslip (and heading) withheld
for the rest of the drive while right (random drives 1203, 1209, 1301, 1362, 1386, 1414, 1423 on
main 88d1c19: sideslip valid on 0.50 of the rows above 5 m/s; 1362 reverses at -2.5 m/s through a
22 deg curve at 1228-1242 s, then drives straight at 10 m/s: invalid at a 0.21 deg std, 0.10-0.16
deg off).

Physics: no sideslip is promised below ``MIN_SPEED_SIDESLIP`` (= ``GSC_MIN_SPEED``) nor reversing
(core promises it at ``vx > MIN_SPEED_SIDESLIP`` only), so a turn there can spoil a later promise
only through what the filter remembers of it (reversing at speed counts as slow: 1209 reversed
through its curve at 2.8-3.0 m/s, where ay / vx on a bank put a right gyro's samples beyond
``GSC_QUIET`` of the witness):

* the heading, which the gyro turned by its scale times the rotation: with P's heading std small,
  each fix's course (heading + sideslip) splits that error into the sideslip. Sample by sample the
  rear wheels are too coarse below 3 m/s (one 0.03 m/s quantum over the track is 0.02 rad/s), but
  summed over the slow turns they count its rotation (``GyroScaleGate.slow_turn`` already sums
  their disagreement for the heading's std). A slow turn is forgiven only where that disagreement
  is within ``GSC_AGREE`` of the wheels' rotation (+ ``SLOW_TURN_TOL`` of quanta): a right gyro
  (1362: 1.6 deg over 22 deg), not a flip (twice the rotation: 46 deg on 1362 flipped) nor a gyro
  read 1/57x (the whole rotation);
* the filter's vy, which integrated ``ay - r vx``: the model and the wheels pull it back within
  seconds, so the turn is forgotten only after ``SLOW_FORGET_S`` of samples at the witnesses' speed
  on which the gyro read what a witness read (or nothing), where a wrong scale would have shown.

Exercise at speed (a 57x gyro's bias, a flipped gyro in any turn at speed) still withholds the
sideslip until a witness confirms, as before; the heading keeps the gate's rule
(``GyroScaleGate.heading_ok``). Used under core.SLOW_TURN_FORGOTTEN.
"""
from __future__ import annotations

import math

SLOW_FORGET_S = 2.0  # s of quiet, witnessed samples at speed after the last slow exercise
SLOW_AGREE = 0.3  # the gyro's slow rotation within this share of the wheels' (gyro_scale_gate.GSC_AGREE)
SLOW_TURN_TOL = math.radians(1.0)  # rad: the wheels' quanta and radius difference over a slow turn


class SlowExercise:
    """Exercise of an unconfirmed gyro, split by where it happened (module docstring)."""

    def __init__(self, sample_dt: float):
        self.sample_dt = sample_dt
        self.at_speed = False  # exercised where a witness could judge it: withheld until confirmed
        self.slow = False  # exercised below the witnesses' speed and not yet forgotten
        self.quiet_s = 0.0  # witnessed quiet samples at speed since the last slow exercise (s)
        self.disagree = 0.0  # rad: the gyro's rotation less the rear wheels', below the fits' speed
        self.wheels_turn = 0.0  # rad: the rear wheels' rotation there (absolute, summed)
        self.wheels_net = 0.0  # rad: ... signed, the net rotation (slow_turn_heading.py)
        self.uncounted = False  # a slow exercise the rear wheels did not count (stale, isolated, at 0)
        self.forgiven = False  # a slow exercise was forgotten (the wheels counted it alike): slow_turn_heading.py

    def turn(self, diff: float, ww: float) -> None:
        """A slow (or reversing) sample both rear wheels count: the gyro less the wheels' yaw rate (``diff``,
        the radius difference taken out) and the wheels' yaw rate ``ww`` (rad/s)."""
        self.disagree += diff * self.sample_dt
        self.wheels_turn += abs(ww) * self.sample_dt
        self.wheels_net += ww * self.sample_dt

    def sample(self, exercised: bool, slow: bool, witnessed: bool, counted: bool = True) -> None:
        """One gate sample: ``exercised`` beyond GSC_QUIET of 0 and of the witnesses, ``slow``
        below GSC_MIN_SPEED or reversing (no sideslip promised), ``witnessed`` at least one witness
        read the yaw rate, ``counted`` both rear wheels moving and read (:meth:`turn` follows):
        a slow exercise they did not count is never forgiven (no witness of its rotation at all)."""
        if slow:
            if exercised:
                self.slow = True
                self.quiet_s = 0.0
                if not counted:
                    self.uncounted = True
            return
        if exercised:
            self.at_speed = True
        elif witnessed:
            self.quiet_s += self.sample_dt
            if (self.slow and self.quiet_s >= SLOW_FORGET_S and not self.uncounted
                    and abs(self.disagree) <= SLOW_AGREE * self.wheels_turn + SLOW_TURN_TOL):
                self.slow = False
                self.forgiven = True
