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
