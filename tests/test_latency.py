"""The online GNSS latency identification (estimator/latency.py) on synthetic series whose latency
is known: it finds it, and it stays put when the series carries no timing information."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.fusion.wheel_speed import WheelSpeedFusion
from ecu_daemon.estimator.history import AUX_AX, AUX_AY, AUX_R, AUX_WHEEL, StepHistory
from ecu_daemon.estimator.kinematic import VX, VY
from ecu_daemon.estimator.latency import PRIOR_STD_S, LatencyEstimator, SpeedIntegral
from latency_feed import feed_wheels

DT = 0.006
FIX_EVERY = 33  # steps: GNSS at ~5 Hz


def run(speed, delay_s, prior_s=0.2, seconds=120.0, gnss_noise=0.0, wheel_scale=1.0, seed=1):
    """Feed a speed profile: wheels see speed(t) every step, GNSS reports speed(t - delay) at t.

    ``wheel_scale``: the wheels read scale * the true speed (a radius error must not bias timing).
    """
    return feed_wheels(LatencyEstimator(DT, prior_s, max_s=0.8), speed, delay_s, seconds, FIX_EVERY,
                       np.random.default_rng(seed), gnss_noise=gnss_noise, wheel_scale=wheel_scale)


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
                           accel_bias=0.1, gnss_noise=0.03, use_accel=True, seed=2,
                           accel_usable=lambda t: True, trace=None, accel_noise=0.05,
                           sideslip_unknown=lambda t: False):
    """As ``run``, and the accelerometer (bias ``accel_bias``, noisy) integrated as the
    estimator does (SpeedIntegral) and attached as the second timing reference. ``wheel(v, dv/dt)``:
    what the wheels read; ``wheel_lag_s``: their signal lags by that much (filtered ABS sensors;
    a function of the time: a lag that changes along the drive, as a biased clock in a corner).
    ``accel_usable(t)``: False breaks the integral off (as mid-corner while the sideslip is
    unknown); ``sideslip_unknown(t)``: True breaks it off on the integrand's own test (a yaw rate
    with vy's std too wide for the r vy share); ``trace``: a list that receives (delay, std) after
    every fix."""
    rng = np.random.default_rng(seed)
    est = LatencyEstimator(DT, prior_s, max_s=0.8)
    acc = LatencyEstimator(DT, prior_s, max_s=0.8, extra=1)
    if use_accel:
        est.attach(acc)
    integral = SpeedIntegral(DT, 0.8)
    hist = StepHistory(est.max_steps + 20)
    hist.reset(0)
    d_steps = round(delay_s / DT)
    lag_at = wheel_lag_s if callable(wheel_lag_s) else (lambda t: wheel_lag_s)

    def dvdt(t):
        return (speed(t + DT) - speed(t - DT)) / (2 * DT)

    for k in range(int(seconds / DT)):
        t = k * DT
        tw = (k - round(lag_at(t) / DT)) * DT
        i = hist.slot(k)
        hist.aux[i, AUX_WHEEL] = wheel(speed(tw), dvdt(tw))
        hist.X[i, VX], hist.aux[i, AUX_AX] = speed(t), dvdt(t)  # the filter's speed, the accelerometer
        hist.last = k
        r, vy_std = (0.5, 1.0) if sideslip_unknown(t) else (0.0, 0.0)
        integral.step(k, speed(t), 0.0, r, dvdt(t) + accel_bias + accel_noise * rng.normal(), 0.0, vy_std,
                      usable=accel_usable(t))
        if k % FIX_EVERY == 0 and k > d_steps:
            y = speed((k + 1 - d_steps) * DT) + gnss_noise * rng.normal()
            est.observe(k + 1, y, hist)
            integral.observe(0, k + 1, y, acc)
            if trace is not None:
                trace.append((est.delay_s, est.std_s))
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


def speed_steps(t):
    """22 m/s with a 3 m/s change every 20 s (up, then down), as the two-receiver drives have."""
    edge = math.tanh(((t % 20.0) - 10.0) / 1.5)
    return 22.0 + 1.5 * (edge if t % 40.0 < 20.0 else -edge)


def test_agreeing_clocks_take_the_delay_to_their_best_not_to_the_edge_of_what_they_reject():
    """From a prior 0.1 s short, with wheels and accelerometer agreeing: a delay that moved only
    until the data no longer rejected it (4 sigma) stopped 0.066 s short here (two_rx_slalom:
    -0.027 s); it goes on into their 1-sigma set."""
    trace = []
    est = run_with_accelerometer(speed_steps, 0.4, prior_s=0.3, seconds=60.0, gnss_noise=0.1, trace=trace)
    true = round(0.4 / DT) * DT  # the delay on the step grid
    assert est.delay_s == pytest.approx(true, abs=0.025)
    assert all(abs(d - true) <= 3.0 * s for d, s in trace)  # honest on the way


def test_steady_speed_with_the_accelerometer_the_prior_stands():
    est = run_with_accelerometer(lambda t: 22.0, 0.4, prior_s=0.2)
    assert est.delay_s == 0.2 and est.std_s == PRIOR_STD_S


def corner_clock(t):
    """The wheels' clock error: none for 30 s, then 0.08 s late (in a corner the wheels are a
    biased clock: the antenna-to-wheel ratio's errors, every wheel a different speed)."""
    return 0.0 if t < 30.0 else 0.08


def breaking_off(t):
    """The accelerometer's integral breaks off (the sideslip unknown) for 0.1 s every 3 s after 30 s."""
    return t >= 30.0 and (t % 3.0) < 0.1


def test_the_accelerometer_judges_the_wheels_across_its_break_offs():
    """Each break-off of the integral starts a run with a new constant, and a run needs 30 fixes
    for a profile of its own: with the earlier runs' timing dropped, the corner-biased wheels timed
    the GNSS alone between them (circle_dry: +0.036 s; here 0.059 s off). The earlier runs'
    cost profiles add to the current one's, and the accelerometer goes on judging."""
    trace = []
    est = run_with_accelerometer(accelerating, 0.3, prior_s=0.3, seconds=90.0, wheel_lag_s=corner_clock,
                                 sideslip_unknown=breaking_off, trace=trace)
    assert max(abs(d - 0.3) for d, _ in trace) <= 0.01  # the delay stayed ...
    assert est.delay_s == pytest.approx(0.3, abs=0.01)
    assert est.references[-1].updates < 30  # ... though the integral did break off


def test_a_run_ended_unusable_is_not_kept_one_ended_on_the_sideslip_test_is():
    """A run ends unusable when it is no longer a clean reference (core.py: the grade changed along
    it by 3 %, bending its fit; the IMU; reversing): its timing is dropped with its constant
    (road_country: +0.144 s with such runs kept). One broken off on the integrand's sideslip test
    was within its error budget until then: its timing is kept, until the new run has a profile of
    its own (30 fixes; here 20 after the break-off)."""
    kept = {}
    for reason in ("sideslip", "unusable"):
        lat = LatencyEstimator(DT, 0.3, 0.8, extra=1)
        integral = SpeedIntegral(DT, 0.8)
        for k in range(int(24.0 / DT)):
            t = k * DT
            stop = reason == "sideslip" and 20.0 <= t < 20.1
            integral.step(k, accelerating(t), 0.0, 0.5 if stop else 0.0, (accelerating(t + DT) - accelerating(t)) / DT,
                          0.0, 1.0 if stop else 0.0, usable=not (reason == "unusable" and 20.0 <= t < 20.1))
            if k % FIX_EVERY == 0 and k > 60:
                integral.observe(0, k + 1, accelerating((k + 1 - 50) * DT), lat)
        kept[reason] = lat.past_cost is not None
    assert kept == {"sideslip": True, "unusable": False}


# --- the wheels as they are fed from the filter's history (observe): geometry and slip ---------

LEVER = (0.7, 0.3)  # antenna ahead of and left of the CG, m


def run_history(speed, yaw_rate, delay_s, slip=0.0, prior_s=0.4, seconds=45.0, gnss_noise=0.02, seed=3,
                vy_error=lambda t: (0.0, 0.01), driven_axle="front"):
    """Wheels only (no accelerometer reference: it breaks off mid-corner and after an outage), fed
    through ``observe`` from a history as the estimator keeps it. ``speed(t)``, ``yaw_rate(t)``:
    the car's motion (speed at the CG); the sideslip is the kinematic one of a car whose rear axle
    is 1.5 m behind the CG (vy = -1.5 r: 9.5 deg at 6 m/s on a 9 m circle); GNSS reads the
    antenna's speed |v + r x lever| ``delay_s`` late; the rear wheels read vx, less
    ``slip`` * vx * the deceleration. ``vy_error(t)``: the filter's vy error and its std.
    ``driven_axle = "all"``: all four wheels are fused and driven, so they slip in traction too."""
    rng = np.random.default_rng(seed)
    est = LatencyEstimator(DT, prior_s, max_s=0.8)
    hist = StepHistory(est.max_steps + 20)
    hist.reset(0)
    wheels = WheelSpeedFusion(driven_axle, 1.2, 0.05)
    traction = driven_axle == "all"

    def motion(t):
        r = yaw_rate(t)
        vy = -1.5 * r
        return math.sqrt(speed(t) ** 2 - vy * vy), vy, r

    d_steps = round(delay_s / DT)
    for k in range(int(seconds / DT)):
        t = k * DT
        vx, vy, r = motion(t)
        dvx = (motion(t + DT)[0] - motion(t - DT)[0]) / (2 * DT)
        i = hist.slot(k)
        e, e_std = vy_error(t)
        hist.X[i, VX], hist.X[i, VY] = vx, vy + e
        hist.P[i, VY, VY] = e_std * e_std
        # what the accelerometer reads: dvx/dt - r vy, and r vx (vy steady)
        hist.aux[i, AUX_R], hist.aux[i, AUX_AX], hist.aux[i, AUX_AY] = r, dvx - r * vy, r * vx
        hist.aux[i, AUX_WHEEL] = vx * (1.0 + slip * (dvx if traction else min(dvx, 0.0)))
        hist.last = k
        if k % FIX_EVERY == 0 and k > d_steps:
            vs, vys, rs = motion((k + 1 - d_steps) * DT)
            y = math.hypot(vs - rs * LEVER[1], vys + rs * LEVER[0]) + gnss_noise * rng.normal()
            est.observe(k + 1, y, hist, LEVER, wheels)
    return est


def corner_then_straight(t):
    """A 9 m circle at 6 m/s (40 deg/s) for 12 s, left within a second (flying_6_r9r)."""
    return -6.0 / 9.0 * min(max(13.0 - t, 0.0), 1.0)


def speed_6(t):
    """6 m/s, -20 % from 15 to 20 s and back from 26 to 31 s (the flying starts' speed changes)."""
    return 6.0 - 1.2 * min(max(t - 15.0, 0.0), 5.0) / 5.0 + 1.2 * min(max(t - 26.0, 0.0), 5.0) / 5.0


def test_a_corner_exit_is_not_read_as_timing():
    """In a 9 m circle the antenna moves 4 % faster than the rear wheels turn (lever arm and
    sideslip); at the exit the ratio steps, and vx rises at the same |v|: a plain wheel
    regression read that as a 0.13 s shorter latency (flying_6_r9r). The GNSS speed is taken
    back to the wheels through the filter's ratio at the current delay."""
    est = run_history(speed_6, corner_then_straight, 0.4)
    assert est.delay_s == pytest.approx(0.4, abs=0.015)


def test_mid_corner_fixes_wait_while_the_sideslip_is_unknown():
    """Started mid-corner, the filter's sideslip is the model's guess until GNSS has corrected it;
    the antenna-to-wheel ratio carries its error (|vy_ant| / |v_ant| of it) and its convergence
    would read as timing (flying_6_r9r: the wheels said 0.31 s for 0.4). Those fixes wait; on
    the straight (no lateral antenna speed) vy's uncertainty does not matter."""
    known = run_history(speed_6, corner_then_straight, 0.4, seconds=20.0)
    unknown = run_history(speed_6, corner_then_straight, 0.4, seconds=20.0,
                          vy_error=lambda t: (0.0, 0.8 if t < 16.0 else 0.01))
    assert unknown.updates <= known.updates - 55  # the 12 s of the corner at 5 Hz, less its first
    assert unknown.updates >= known.updates - 70  # ... and only those


def test_wheel_fixes_in_a_tight_corner_are_not_clean():
    """The unbraked wheel fixes may refute the delay while the accelerometer's integral has broken
    off (on Revs it reads the car's pitch under hard braking, and the wheels bring the delay back),
    so they must be clean: in a corner the antenna reads several per cent off the wheels and the
    filter's error in that ratio drifts with the speed and steps at the exit (lowspeed_r10: the
    wheels said 0.56 s for 0.4). Fixes whose window is in the corner or across its exit are left out."""
    straight = run_history(speed_6, lambda t: 0.0, 0.4, seconds=20.0)
    corner = run_history(speed_6, corner_then_straight, 0.4, seconds=20.0)
    assert corner.updates == straight.updates  # every fix seen ...
    assert 55 <= straight.slip_free.updates - corner.slip_free.updates <= 70  # ... the 13 s of corner not clean


def test_a_sideslipping_circle_with_speed_changes_still_times_the_gnss():
    """ax reads a share of the centripetal acceleration in a sideslipping circle (-r vy, here
    -0.4 m/s^2 while the speed rises): that is not braking, and the fixes still time the GNSS (the
    wheels alone here; none of them is clean enough to refute a delay the accelerometer judges)."""
    est = run_history(lambda t: 8.0 + 0.2 * t + 0.3 * math.sin(2 * math.pi * t / 7.0), lambda t: 0.5, 0.3)
    assert est.slip_free is None  # the antenna reads 2 % off the wheels: no fix is clean ...
    assert est.delay_s == pytest.approx(0.3, abs=0.03)  # ... and together they find the delay


def smooth_braking_drive(t):
    """Speeding up smoothly (an S-curve, 25 -> 31.4 m/s in 8 s), then braking at 1.6 m/s^2 for 4 s."""
    phase = t % 12.0
    if phase < 8.0:
        return 25.0 + 3.2 * (1.0 - math.cos(math.pi * phase / 8.0))
    return 31.4 - 1.6 * (phase - 8.0)


def test_braked_wheels_alone_do_not_lengthen_the_latency():
    """Braked wheels turn slower than the car by v * kappa: as timing that is v m / C_x later
    however hard the braking (+0.04 s after the 30 s outage of the demo drive, where the
    accelerometer reference had broken off). The wheels time only the phases without braking."""
    est = run_history(smooth_braking_drive, lambda t: 0.0, 0.3, slip=0.01, seconds=90.0)
    assert est.delay_s == pytest.approx(0.3, abs=0.015)


def test_all_wheel_drive_wheels_slipping_in_traction_do_not_lengthen_the_latency():
    """Four driven wheels slip whenever the speed changes (kappa = a / (C_x g), here a tyre stiffer
    than the fusion's model: C_x = 18): the wheel speed leads the car by v / (C_x g), 0.085 s at
    15 m/s, and there are no unbraked, undriven fixes to time the GNSS instead. With no accelerometer
    (random drive 217: a grade that changes along the road broke it off every few fixes) the slip
    read as latency kept a 0.80 s prior at 0.78 for a true 0.639 and put 2.1 deg into a valid
    sideslip. The wheels' expected slip comes out of the regressor."""
    est = run_history(accelerating, lambda t: 0.0, 0.3, slip=1.0 / (18.0 * 9.81), seconds=90.0,
                      driven_axle="all")
    assert est.delay_s == pytest.approx(0.3, abs=0.025)


def test_a_slalom_at_constant_speed_leaves_the_prior_alone():
    """A slalom at a steady 8 m/s: the wheels' speed hardly changes, the antenna's does (lever arm
    and sideslip swing with the yaw rate). That is geometry, not timing; the delay stays put
    (lowspeed_r25 moved 0.07 s on it)."""
    est = run_history(lambda t: 8.0, lambda t: 0.3 * math.sin(2 * math.pi * 0.4 * t), 0.3, prior_s=0.4,
                      seconds=60.0, vy_error=lambda t: (0.05 * math.sin(2 * math.pi * 0.4 * t - 0.5), 0.05))
    assert est.updates > 200
    assert est.delay_s == 0.4


# --- references that share the GNSS fixes ------------------------------------------------------

def test_two_references_whose_residuals_are_the_same_gnss_noise_count_once():
    """Wheels and accelerometer are both regressed against the same GNSS speeds, so the fixes'
    own noise is in both residuals. Where it is all of them (the simulator's drives, random drive
    20: residual 0.10 m/s per fix, receiver noise 0.10-0.15 m/s) the two profiles carry one
    reference's information, not two (the plain sum made drive 20's latency std 0.05 s with the
    delay 0.2 s off, and its circle's heading valid 3 deg off beyond 3 sigma)."""
    from ecu_daemon.estimator.latency import combined_profile, information_share
    lr = np.array([9.0, 1.0, 0.0, 4.0, 25.0])
    both = [(lr, False, 0.01), (lr, False, 0.01)]
    assert combined_profile(both, 0.15 ** 2) == pytest.approx(lr)  # noise above both residuals: all shared
    assert combined_profile(both, 0.1 ** 2) == pytest.approx(lr)
    assert information_share(both, math.nan) == pytest.approx(0.5)  # unknown noise: the bound
    assert combined_profile([(lr, False, 0.01)], 0.01) == pytest.approx(lr)  # one reference: itself


def test_references_noisier_than_the_gnss_fixes_add_as_independent_evidence():
    """What two residuals share is the fixes' own noise and no more: references whose own errors
    dominate (a real car's filtered wheels, an accelerometer on a rough road) are nearly
    independent, and their information adds. The bound sqrt(min / max) alone (lat34) would have
    halved it."""
    from ecu_daemon.estimator.latency import combined_profile, shared_correlation
    lr = np.array([9.0, 1.0, 0.0, 4.0, 25.0])
    # GNSS 0.05 m/s, both residuals 0.2 m/s: rho = 0.0025 / 0.04
    assert shared_correlation([0.04, 0.04], 0.05 ** 2) == pytest.approx(0.0625)
    assert combined_profile([(lr, False, 0.04), (lr, False, 0.04)], 0.05 ** 2) == pytest.approx(2 * lr / 1.0625)
    assert shared_correlation([0.04, 0.04]) == pytest.approx(1.0)  # the bound, were the noise unknown


def test_the_shared_correlation_never_exceeds_what_the_smaller_residual_allows():
    from ecu_daemon.estimator.latency import shared_correlation
    # the shared variance is at most the smaller residual's: rho <= sqrt(min / max)
    assert shared_correlation([0.01, 0.04], 1.0) == pytest.approx(0.5)
    assert shared_correlation([0.01, 0.04], math.nan) == pytest.approx(0.5)
    assert shared_correlation([0.01, 0.04], 0.004) == pytest.approx(0.2)  # 0.004 / sqrt(0.01 * 0.04)
    assert shared_correlation([0.0, 0.04], 0.01) == 0.0  # a reference without residual shares nothing
    assert shared_correlation([0.0, 0.0], 0.01) == 1.0  # both fit exactly: nothing but the shared part
    assert shared_correlation([0.04], 0.01) == 0.0


def test_the_std_counts_the_shared_noise_once_while_the_decision_keeps_the_sum():
    """Two references with the same statistics (both residuals the fixes' own noise): the delay
    is decided on the summed profile (the identification's speed, which the stiffness regression
    learns on, stays as it was: slalom_dry's k_r went 30 % off when the decision used the
    shared-out profile, lat34), but the std is as wide as one reference's, not narrowed as
    independent evidence would narrow it (by up to sqrt 2)."""
    def drive(attach: bool, gnss_var: float, seed: int):
        est = LatencyEstimator(0.01, 0.3, 0.6)
        if attach:
            twin = LatencyEstimator(0.01, 0.3, 0.6)
            est.attach(twin)
        est.gnss_var = gnss_var
        rng = np.random.default_rng(seed)
        n = est.max_steps + 1
        for j in range(400):
            t = j * 0.2
            x = 10.0 + 2.0 * np.sin(0.5 * (t - 0.01 * (np.arange(n) + 1)))
            y = 10.0 + 2.0 * math.sin(0.5 * (t - 0.3)) + rng.normal(0.0, 0.1)
            if attach:
                twin._accumulate(x, y)
            est.observe_series(x, y)
        return est
    ratios = []
    for seed in (1, 2, 3, 4):
        alone, shared, summed = drive(False, 0.01, seed), drive(True, 0.01, seed), drive(True, 0.0, seed)
        assert shared.delay_s == summed.delay_s == alone.delay_s == 0.3  # a right prior stays
        assert shared.std_s == pytest.approx(alone.std_s)  # one reference's width ...
        assert shared.std_s >= summed.std_s  # ... never narrower than the sum's
        ratios.append(shared.std_s / summed.std_s)
    print(ratios)
    assert max(ratios) > 1.2  # where the profile's width sets the std, the sum would have narrowed it
