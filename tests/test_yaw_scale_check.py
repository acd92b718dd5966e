"""The yaw-rate scale fit (estimator/yaw_scale_check.py) on synthetic course / gyro series."""
import math

import numpy as np
import pytest

from ecu_daemon.estimator.yaw_scale_check import BANK_TILT_SCALE, SCALE_PRIOR, YawScaleCheck

DT = 0.006
STEPS = 17  # ~0.1 s between fixes


def _drive(scale: float, r_of_t, duration: float, bias: float = 0.0, course_noise: float = 0.0, seed: int = 1):
    """A car at 10 m/s with zero sideslip turning at r_of_t(t); the gyro reads (1 + scale) r + bias and
    the filter's bias correction is exact up to ``bias`` (the residual the fit must not read as scale)."""
    rng = np.random.default_rng(seed)
    chk = YawScaleCheck(0.0)
    psi = 0.3
    k = 0
    t = 0.0
    while t < duration:
        rs = []
        for _ in range(STEPS):
            k += 1
            t = k * DT
            r_true = r_of_t(t)
            psi -= r_true * DT
            rs.append((1.0 + scale) * r_true + bias)
        course = psi + course_noise * rng.standard_normal()
        chk.observe(t, k, DT, np.array(rs), course, 0.05, 10.0, 10.0, 0.0, rs[-1], 0.0, 0.02,
                    math.radians(0.01))
    return chk


def _circle_with_speed_changes(t):
    return 0.2 + 0.15 * math.sin(2.0 * math.pi * t / 40.0)


@pytest.mark.parametrize("scale", [-0.03, -0.01, 0.0, 0.01, 0.03])
def test_scale_is_learned_within_its_std_on_a_circle(scale):
    chk = _drive(scale, _circle_with_speed_changes, 90.0, course_noise=math.radians(0.3))
    assert chk.scale_sd < 0.2 * SCALE_PRIOR  # the circle observes it well
    # the fit's scale is the heading's error per radian the gyro integrates: s / (1 + s)
    assert abs(chk.scale - scale / (1.0 + scale)) < 3.0 * chk.scale_sd
    # the published std covers the actual scale error
    assert chk.scale_std() >= abs(scale / (1.0 + scale))


def test_straight_driving_keeps_the_prior():
    chk = _drive(0.03, lambda t: 0.0, 60.0)
    assert chk.scale_std() == pytest.approx(SCALE_PRIOR, rel=1e-3)


def test_a_residual_bias_within_the_filter_std_is_not_read_as_a_scale():
    # 0.01 deg/s residual bias on a steady circle at 0.3 rad/s: would be 0.06 % of scale, inside the std
    chk = _drive(0.0, lambda t: 0.3, 120.0, bias=math.radians(0.01))
    assert abs(chk.scale) < 3.0 * chk.scale_sd
    assert chk.scale_sd < SCALE_PRIOR


def test_floor_is_the_bank_tilt():
    chk = _drive(0.0, _circle_with_speed_changes, 90.0)
    assert chk.scale_std() == pytest.approx(BANK_TILT_SCALE)
    assert 0.0017 < BANK_TILT_SCALE < 0.0019


def test_many_laps_with_a_large_scale_error_do_not_wrap():
    # 3 % over ~30 laps: the gyro's heading is > pi off the course
    chk = _drive(0.03, lambda t: 0.6, 330.0)
    assert abs(chk.scale - 0.03 / 1.03) < 3.0 * chk.scale_sd
