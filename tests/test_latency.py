"""The online GNSS latency identification (estimator/latency.py) on synthetic series whose latency
is known: it finds it, and it stays put when the series carries no timing information."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.history import AUX_WHEEL, StepHistory
from ecu_daemon.estimator.latency import PRIOR_STD_S, LatencyEstimator, SpeedIntegral

DT = 0.006
FIX_EVERY = 33  # steps: GNSS at ~5 Hz


def run(speed, delay_s, prior_s=0.2, seconds=120.0, gnss_noise=0.0, wheel_scale=1.0, seed=1):
    """Feed a speed profile: wheels see speed(t) every step, GNSS reports speed(t - delay) at t.

    ``wheel_scale``: the wheels read scale * the true speed (a radius error must not bias timing).
    """
    rng = np.random.default_rng(seed)
    est = LatencyEstimator(DT, prior_s, max_s=0.8)
    hist = StepHistory(est.max_steps + 20)
    hist.reset(0)
    d_steps = round(delay_s / DT)
    for k in range(int(seconds / DT)):
        hist.aux[hist.slot(k), AUX_WHEEL] = wheel_scale * speed(k * DT)
        hist.last = k
        if k % FIX_EVERY == 0 and k > d_steps:
            # received just before step k + 1, valid at step k + 1 - d_steps (delay of d_steps)
            est.observe(k + 1, speed((k + 1 - d_steps) * DT) + gnss_noise * rng.normal(), hist)
    return est


def accelerating(t):
    """Speed changes of +-3 m/s over a few seconds, as in town: timing shows in the slopes."""
    return 15.0 + 3.0 * math.sin(2 * math.pi * t / 7.0) + 1.5 * math.sin(2 * math.pi * t / 2.9)


@pytest.mark.parametrize("delay_s", [0.12, 0.3, 0.48])
def test_finds_a_known_latency(delay_s):
    est = run(accelerating, delay_s, gnss_noise=0.03)
    assert est.delay_s == pytest.approx(delay_s, abs=0.012)  # two 6 ms steps
    assert est.std_s < 0.03


def test_a_wheel_radius_error_does_not_bias_the_timing():
    est = run(accelerating, 0.3, wheel_scale=1.04, gnss_noise=0.03)
    assert est.delay_s == pytest.approx(0.3, abs=0.012)


def test_steady_speed_carries_no_timing_information_and_the_prior_stands():
    est = run(lambda t: 22.0, 0.4, prior_s=0.2, gnss_noise=0.03)
    assert est.updates > 100  # the fixes were seen ...
    assert est.delay_s == 0.2  # ... and changed nothing
    assert est.std_s == PRIOR_STD_S


def test_below_walking_pace_nothing_is_learned():
    est = run(lambda t: 1.0 + 0.5 * math.sin(t), 0.4)
    assert est.updates == 0 and est.delay_s == 0.2


def test_disabled_keeps_the_configured_latency():
    est = LatencyEstimator(DT, 0.25, 0.8, enabled=False)
    hist = StepHistory(est.max_steps + 20)
    hist.reset(0)
    hist.last = est.max_steps + 10
    hist.aux[:, AUX_WHEEL] = 10.0
    est.observe(hist.last + 1, 12.0, hist)
    assert est.delay_s == 0.25 and est.updates == 0


# --- the accelerometer as a second timing reference (SpeedIntegral) ---------------------------

def braking_slip(v, dvdt):
    """A braked wheel turns slower than the car: v * kappa, kappa ~ decel * m / C_x (~1 %/(m/s^2))."""
    return v * (1.0 + 0.01 * min(dvdt, 0.0))


def run_with_accelerometer(speed, delay_s, wheel=lambda v, a: v, wheel_lag_s=0.0, prior_s=0.2, seconds=120.0,
                           accel_bias=0.1, gnss_noise=0.03, use_accel=True, seed=2):
    """As ``run``, and the accelerometer (bias ``accel_bias``, noisy) integrated as the
    estimator does (SpeedIntegral) and attached as the second timing reference. ``wheel(v, dv/dt)``:
    what the wheels read; ``wheel_lag_s``: their signal lags by that much (filtered ABS sensors)."""
    rng = np.random.default_rng(seed)
    est = LatencyEstimator(DT, prior_s, max_s=0.8)
    acc = LatencyEstimator(DT, prior_s, max_s=0.8, extra=1)
    if use_accel:
        est.attach(acc)
    integral = SpeedIntegral(DT, 0.8)
    hist = StepHistory(est.max_steps + 20)
    hist.reset(0)
    d_steps, lag = round(delay_s / DT), round(wheel_lag_s / DT)

    def dvdt(t):
        return (speed(t + DT) - speed(t - DT)) / (2 * DT)

    for k in range(int(seconds / DT)):
        t, tw = k * DT, (k - lag) * DT
        hist.aux[hist.slot(k), AUX_WHEEL] = wheel(speed(tw), dvdt(tw))
        hist.last = k
        integral.step(k, speed(t), 0.0, 0.0, dvdt(t) + accel_bias + 0.05 * rng.normal(), 0.0)
        if k % FIX_EVERY == 0 and k > d_steps:
            y = speed((k + 1 - d_steps) * DT) + gnss_noise * rng.normal()
            est.observe(k + 1, y, hist)
            integral.observe(0, k + 1, y, acc)
    return est


def braking_drive(t):
    """Speeding up gently, braking hard: the wheels slip only in the braking phases."""
    phase = t % 12.0
    return 25.0 + (0.8 * phase if phase < 8.0 else 6.4 - 1.6 * (phase - 8.0))


def test_braking_slip_biases_the_wheels_but_not_the_accelerometer():
    wheels_only = run_with_accelerometer(braking_drive, 0.3, wheel=braking_slip, use_accel=False)
    assert abs(wheels_only.delay_s - 0.3) > 0.03  # the bias the accelerometer is there for
    est = run_with_accelerometer(braking_drive, 0.3, wheel=braking_slip)
    assert est.delay_s == pytest.approx(0.3, abs=0.015)


def test_lagging_wheel_signals_do_not_shorten_the_latency():
    est = run_with_accelerometer(accelerating, 0.3, wheel_lag_s=0.06)
    assert est.delay_s == pytest.approx(0.3, abs=0.015)


@pytest.mark.parametrize("delay_s", [0.1, 0.6])
def test_accelerometer_alone_finds_the_latency_despite_its_bias(delay_s):
    """Wheels reading nothing useful (a constant): the accelerometer's integral, bias and all, times it."""
    est = run_with_accelerometer(accelerating, delay_s, wheel=lambda v, a: 20.0, prior_s=0.4, accel_bias=0.3)
    assert est.delay_s == pytest.approx(delay_s, abs=0.015)


def test_steady_speed_with_the_accelerometer_the_prior_stands():
    est = run_with_accelerometer(lambda t: 22.0, 0.4, prior_s=0.2)
    assert est.delay_s == 0.2 and est.std_s == PRIOR_STD_S
