"""SlipWitness (fusion/wheel_slip.py): the wheels' loss beyond the integrated accelerometer is slip.

Synthetic wheel and ax samples at the estimator's 6 ms step; the replay of the drive that found
it is tests/test_abs_slip.py.
"""
from __future__ import annotations

import math

from ecu_daemon.estimator.fusion.wheel_slip import SlipWitness

DT = 0.006


def _brake(w: SlipWitness, v0: float, decel: float, slip_rate: float, seconds: float,
           bax_var: float = 1e-4) -> tuple[float, float]:
    """Brake at ``decel`` from ``v0``; the wheels fall behind the car at ``slip_rate`` (m/s per s).
    Returns (car speed, the witness's bound) at the end."""
    w.step(v0, 0.0, 0.0, bax_var, 0.0)  # force-free: the anchor
    v = v0
    lost = 0.0
    bound = 0.0
    for _ in range(round(seconds / DT)):
        v -= decel * DT
        lost += slip_rate * DT
        bound = w.step(v - lost, -decel, 0.0, bax_var, 0.0)
    return v, bound


def test_wheels_falling_behind_the_integrated_ax_are_slip_and_the_ratio_is_held():
    w = SlipWitness(DT, 0.02 ** 2, driven_fused=False)
    # 4 m/s^2 from 15 m/s, the wheels losing 1.6 m/s over 0.8 s (an ABS settling at its threshold)
    v, bound = _brake(w, 15.0, 4.0, 2.0, 0.8)
    assert bound > 1.3  # the loss, less the comparison's error: far above the linear law's 0.3 m/s
    ratio = w.ratio
    # the slip then held: the wheels decelerate with the car, the ratio stays (the ABS keeps it)
    for _ in range(round(1.0 / DT)):
        v -= 4.0 * DT
        bound = w.step(v - 1.6, -4.0, 0.0, 1e-4, 0.0)
    assert w.ratio >= ratio
    assert bound == w.ratio * (v - 1.6)
    # released: no longitudinal force, no slip, the comparison starts again
    assert w.step(v, 0.0, 0.0, 1e-4, 0.0) == 0.0 and w.ratio == 0.0


def test_wheels_that_follow_the_accelerometer_are_not_slip():
    # dry-road braking, the wheels' small slip built at once (linear law): nothing beyond noise
    _, bound = _brake(SlipWitness(DT, 0.02 ** 2, driven_fused=False), 25.0, 7.0, 0.0, 3.0)
    assert bound == 0.0
    # an ax bias the filter knew poorly grows the comparison's error with time, not the bound
    _, bound = _brake(SlipWitness(DT, 0.02 ** 2, driven_fused=False), 25.0, 5.0, 0.1, 3.0, bax_var=0.1 ** 2)
    assert bound == 0.0


def test_lagging_wheels_and_undriven_wheels_under_traction_are_not_slip():
    # a wheel-speed lag reads the wheels *faster* than the car while braking: the other way to slip
    _, bound = _brake(SlipWitness(DT, 0.02 ** 2, driven_fused=False), 20.0, 6.0, -1.0, 1.0)
    assert bound == 0.0
    # accelerating: undriven wheels cannot slip forwards; driven ones (all-wheel drive) can
    for driven, expect in ((False, 0.0), (True, 0.5)):
        w = SlipWitness(DT, 0.02 ** 2, driven_fused=driven)
        w.step(5.0, 0.0, 0.0, 1e-4, 0.0)
        v = 5.0
        for i in range(round(1.0 / DT)):  # the wheels gain 1 m/s on the car over the second
            v += 3.0 * DT
            bound = w.step(v + (i + 1) * DT, 3.0, 0.0, 1e-4, 0.0)
        assert (bound > expect) if expect else bound == 0.0
        assert math.isfinite(bound)


def _corner(w: SlipWitness, v: float, fx: float, fy: float, bax: float, slip_after: float,
            slip: float, seconds: float) -> float:
    """Constant speed (ax - bax = 0) with the tyres carrying ``(fx, fy)`` per mass; after
    ``slip_after`` s the wheels fall ``slip`` m/s behind over 0.3 s. Returns the last bound."""
    w.step(v, bax, bax, 1e-4, 0.0, 0.0, 0.0)  # force-free: the anchor (a straight, no braking)
    bound = 0.0
    for i in range(round(seconds / DT)):
        t = i * DT
        lost = slip * min(max(t - slip_after, 0.0) / 0.3, 1.0)
        bound = w.step(v - lost, bax, bax, 1e-4, 0.0, fx, fy)
    return bound


def test_on_a_downhill_the_tyres_brake_at_zero_ax_and_slip():
    # 7 % downhill at constant speed: ax - b_ax = 0 (b_ax holds the grade), but the tyres brake at
    # 0.7 m/s^2 and, near a snowy corner's limit, slip 0.35 m/s (random drive 83)
    bax = -0.7 - 0.1  # the grade's share of b_ax and the sensor's own offset
    bound = _corner(SlipWitness(DT, 0.08 ** 2, driven_fused=False), 10.0, -1.3, 1.2, bax, 0.5, 0.35, 1.5)
    assert bound > 0.25
    # without the split (fx unknown: ax - b_ax = 0 taken for the tyres' force) it re-anchors on the
    # slipping wheels every step: abs33's blind spot
    w = SlipWitness(DT, 0.08 ** 2, driven_fused=False)
    w.step(10.0, bax, bax, 1e-4, 0.0)
    assert all(w.step(10.0 - 0.35 * min(i * DT / 0.3, 1.0), bax, bax, 1e-4, 0.0) == 0.0 for i in range(250))


def test_near_the_lateral_limit_a_small_longitudinal_force_slips_the_wheels():
    # all-wheel drive through a snowy corner at 2.4 m/s^2 (mu g 2.4), fx ~ 0: the driven wheels run
    # 0.5 m/s ahead (random drive 239: the slip vector points along the force at saturation)
    w = SlipWitness(DT, 0.08 ** 2, driven_fused=True)
    bound = _corner(w, 14.0, 0.3, 2.4, 0.0, 1.0, -0.5, 2.5)
    assert bound > 0.35
    # the same wheels on a straight (no lateral force): |(fx, fy)| small, the comparison restarts
    # each step, nothing is read into them
    assert _corner(SlipWitness(DT, 0.08 ** 2, driven_fused=True), 14.0, 0.3, 0.0, 0.0, 1.0, -0.5, 2.5) == 0.0


def test_a_corner_without_slip_reads_none():
    # 20 s at 6 m/s^2 lateral on a dry road, the wheels following the car: the long comparison's
    # allowance (bias x time, noise, margin) holds
    assert _corner(SlipWitness(DT, 0.08 ** 2, driven_fused=True), 20.0, 0.2, 6.0, 0.05, 0.0, 0.0, 20.0) == 0.0


def _ice(w: SlipWitness, at_limit: bool, slip: float, seconds: float = 10.0, slip_after: float = 8.0,
         bax_var: float = 0.015 ** 2) -> float:
    """Braking through a corner on ice at the grip (mu 0.11: mu g 1.06 m/s^2), the tyres' force
    flickering about the 1 m/s^2 threshold (|(fx, fy)| 0.96 every 7th step, 1.08 otherwise), the
    car at constant speed (downhill); after ``slip_after`` s the wheels fall ``slip`` m/s behind
    within 0.3 s (a brake on ice, random drive 83 at 1242 s). Returns the largest bound."""
    v, bax = 12.0, -0.6
    w.step(v, bax, bax, bax_var, 0.0, 0.0, 0.0)  # force-free before the corner: the anchor
    best = 0.0
    for i in range(round(seconds / DT)):
        lost = slip * min(max(i * DT - slip_after, 0.0) / 0.3, 1.0)
        fy = 0.75 if i % 7 == 0 else 0.9
        best = max(best, w.step(v - lost, bax, bax, bax_var, 0.0, -0.6, fy, at_limit))
    return best


def test_a_slip_built_at_the_grip_on_ice_is_seen_whatever_the_force_threshold_says():
    # 0.34 m/s within 0.3 s, 8 s into the corner: the free comparison either restarts on the dips
    # below 1 m/s^2 or, run from the corner's entry, hides it in its 8 s bias x time allowance; a
    # 1 s window sees it whole, and holds it while the steering says the tyres are beyond their law
    assert _ice(SlipWitness(DT, 0.046 ** 2, driven_fused=False), True, 0.34) > 0.2
    # the same wheels without slip: nothing read into them, however long the corner
    assert _ice(SlipWitness(DT, 0.046 ** 2, driven_fused=False), True, 0.0, seconds=20.0) == 0.0


def test_the_held_window_slip_ends_only_where_the_tyres_are_force_free_and_inside_their_law():
    w = SlipWitness(DT, 0.046 ** 2, driven_fused=False)
    _ice(w, True, 0.34)
    v = 12.0 - 0.34
    held = w.ratio
    assert held > 0.0
    # the slip held (wheels decelerating with the car): a dip below 1 m/s^2 at the limit keeps it
    assert w.step(v, -0.6, -0.6, 0.015 ** 2, 0.0, -0.6, 0.7, True) > 0.2 and w.ratio >= held
    # force-free inside the law: released
    assert w.step(12.0, -0.6, -0.6, 0.015 ** 2, 0.0, 0.0, 0.0, False) == 0.0 and w.ratio == 0.0
