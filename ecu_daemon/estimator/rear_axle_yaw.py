"""The yaw rate the rear (unsteered) axle's two wheel speeds say, in either direction of travel.

Why one helper: two checks witness the gyro with the rear wheels (``gyro_scale_gate.py``: is the
gyro's scale right; ``wheel_yaw_check.py``: is the wheels' scale right), and each had its own
formula. One fitted ``v_rr - v_rl`` at any speed, which reads a right gyro as -1x while reversing
on wheel speeds that a DBC sends unsigned (most do: the ABS reports a magnitude, the direction is
the gear's); the other took ``sign(vx) (|v_rr| - |v_rl|)``. One formula, here, keeps them alike.

Physics (ISO 8855, left wheel at y = +T/2): each rear wheel rolls along the body's x axis, its
ground speed ``vx - r T/2`` (left) and ``vx + r T/2`` (right), whatever the sideslip. Signed
encodings send exactly that: ``v_rr - v_rl = r T`` forward and reversing. Unsigned ones send the
magnitudes: ``|v_rr| - |v_rl|`` is ``r T`` forward and ``-r T`` reversing (``|vx + rT/2| =
-vx - rT/2`` when ``vx < 0`` and ``|vx| > rT/2``, always at the speeds the checks use). So

    sign(vx) (|v_rr| - |v_rl|) = r T

for both encodings and both directions, and ``sign(vx) (|v_rl| + |v_rr|) / 2 = vx``: the wheels'
magnitudes carry the turn, the direction of travel (``vx``, the filter's: gear, GNSS, ax) its sign.
A mapping's scale ``s`` (a unit error) multiplies both alike, and a relative radius difference
``c`` of the two tyres adds ``-c vx`` to the difference (the right tyre larger reads slower).
"""
from __future__ import annotations


def direction(vx: float) -> float:
    """+1 forward (and at standstill), -1 reversing: the sign the wheels' magnitudes are given."""
    return 1.0 if vx >= 0.0 else -1.0


def rear_speed_difference(rl: float, rr: float, vx: float) -> float:
    """``r T`` (m/s) from the rear wheel speeds as mapped, signed or unsigned (module docstring);
    NaN in, NaN out."""
    return direction(vx) * (abs(rr) - abs(rl))


def rear_mean_speed(rl: float, rr: float, vx: float) -> float:
    """The rear axle's speed along x (m/s), signed by the direction of travel: the offset's
    regressor (``c vx``) of a fit of :func:`rear_speed_difference`."""
    return direction(vx) * 0.5 * (abs(rl) + abs(rr))
