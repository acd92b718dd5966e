"""The road filter's walks where the road changes (estimator/road.py): the grade moves per metre
travelled (vertical curves), not per second, also while the accelerometers are not heard; and the
bank change the main filter's b_ay walk charges is counted in the roll's std (the gain state takes
part of it as roll) where the lateral force makes it show."""
from __future__ import annotations

import math

import pytest

from ecu_daemon.estimator.road import (ANGLE_WALK, BANK_SWING, GRADE_WALK_M, ROLL_DOUBT_FORCE, UPDATE_EVERY,
                                       RoadAttitude)

DT = 0.006


def _grade_var_after(vx: float, steps: int, update: bool) -> float:
    road = RoadAttitude(DT, 0.1, {})
    p0 = road.grade.P[0, 0]
    for k in range(1, steps + 1):
        road.step(k, 0.0, 1e-4, 0.0, 1e-4, 0.0, vx, 0.0, 1e-4, update)
    return road.grade.P[0, 0] - p0


def test_grade_walks_per_metre_travelled_even_unheard():
    steps = 100 * UPDATE_EVERY
    t = steps * DT
    standing = _grade_var_after(0.0, steps, False)
    driving = _grade_var_after(20.0, steps, False)
    assert standing == pytest.approx(ANGLE_WALK ** 2 * t, rel=1e-9)
    assert driving - standing == pytest.approx(GRADE_WALK_M ** 2 * 20.0 * t, rel=0.01)


def test_bax_lags_a_changing_grade_so_it_pulls_less_at_speed():
    """The same b_ax (1 deg of grade) moves the grade less at 20 m/s than standing: it averages
    the last CORRELATION_S of road, which may have climbed since."""
    moved = {}
    for vx in (0.0, 20.0):
        road = RoadAttitude(DT, 0.1, {})
        road.grade.P[0, 0] = math.radians(1.0) ** 2
        road.grade.P[1, 1] = 0.001 ** 2
        road.step(UPDATE_EVERY - 1, 0.0, 1e-6, 0.0, 1e-6, 0.0, vx, 0.0, 1e-4, True)
        road.step(UPDATE_EVERY, 9.80665 * math.sin(math.radians(1.0)), 1e-6, 0.0, 1e-6, 0.0, vx, 0.0, 1e-4, True)
        moved[vx] = road.grade.x[0]
    assert moved[0.0] > 2.0 * moved[20.0] > 0.0


def _roll_std(walk: float, ay: float) -> float:
    road = RoadAttitude(DT, 0.02, {})
    road.step(1, 0.0, 1e-4, 0.0, 1e-4, 0.0, 20.0, walk, 1e-4, True)
    for _ in range(200):  # the lagged lateral force settles
        road.set_roll(ay, 0.02, 1e-4)
    return road.roll_std


def test_bank_walk_counts_in_the_roll_where_the_force_shows_it():
    walk = (9.80665 * math.radians(1.0)) ** 2  # the main filter's b_ay walk: one degree of bank
    corner, corner0 = _roll_std(walk, 4.0), _roll_std(0.0, 4.0)
    assert corner ** 2 - corner0 ** 2 == pytest.approx(math.radians(1.0) ** 2, rel=0.01)
    straight, straight0 = _roll_std(walk, 0.1 * ROLL_DOUBT_FORCE), _roll_std(0.0, 0.1 * ROLL_DOUBT_FORCE)
    assert straight ** 2 - straight0 ** 2 == pytest.approx(0.01 * math.radians(1.0) ** 2, rel=0.05)
    capped = _roll_std(1e3, 4.0)
    assert capped ** 2 - corner0 ** 2 == pytest.approx(BANK_SWING ** 2, rel=0.01)
