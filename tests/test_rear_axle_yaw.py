"""The rear axle's yaw rate (estimator/rear_axle_yaw.py): ``r T`` and vx from the two rear wheel
speeds in both directions of travel, whether the DBC sends them signed or as magnitudes."""
from __future__ import annotations

import math

import pytest

from ecu_daemon.estimator.rear_axle_yaw import rear_mean_speed, rear_speed_difference

T = 1.6


@pytest.mark.parametrize("vx", [12.0, 3.5, -3.5, -6.0])
@pytest.mark.parametrize("r", [0.4, -0.25, 0.0])
@pytest.mark.parametrize("unsigned", [False, True])
def test_difference_is_r_times_track_and_mean_is_vx_in_both_directions(vx, r, unsigned):
    rl, rr = vx - r * T / 2, vx + r * T / 2  # ISO 8855: left wheel at y = +T/2
    if unsigned:
        rl, rr = abs(rl), abs(rr)
    assert rear_speed_difference(rl, rr, vx) == pytest.approx(r * T, abs=1e-12)
    assert rear_mean_speed(rl, rr, vx) == pytest.approx(vx, abs=1e-12)


def test_a_missing_wheel_is_nan():
    assert math.isnan(rear_speed_difference(math.nan, 3.0, 3.0))
    assert math.isnan(rear_mean_speed(3.0, math.nan, -3.0))
