"""Each aiding source alone (fusion/*.py): what it measures, that it pulls the state the right way
by the right amount, and what it refuses."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator import generated as gen
from ecu_daemon.estimator.fusion.gnss_velocity import GnssVelocityFusion
from ecu_daemon.estimator.fusion.single_track import LaggedModelInputs, SingleTrackFusion
from ecu_daemon.estimator.fusion.standstill import StandstillFusion
from ecu_daemon.estimator.fusion.wheel_speed import WheelSpeedFusion
from ecu_daemon.estimator.history import AUX_R, StepHistory
from ecu_daemon.estimator.kinematic import BAX, BAY, BR, KW, NX, PSI, VX, VY
from ecu_daemon.samples import GnssSample


def state(vx=20.0, vy=0.3, psi=1.0, kw=1.0):
    x = np.zeros(NX)
    x[[VX, VY, PSI, KW]] = vx, vy, psi, kw
    P = np.diag([0.5, 0.2, 0.01, 1e-6, 0.01, 0.01, 1e-4, 1e-4])
    return x, P, np.eye(NX)


# ---- wheel speed -------------------------------------------------------------------------------

def test_wheel_speed_pulls_vx_towards_the_wheels_by_the_kalman_weight():
    w = WheelSpeedFusion("front", 1.2, 0.05)  # rear (undriven) pair: measures vx / k_w
    x, P, A = state()
    p0 = P[VX, VX]
    assert w.fuse(x, P, 21.0, 0.0, 0.0, 0.0, A)
    R = 0.05 ** 2 + (0.002 * 20.0) ** 2
    # h = [1/kw, ..., -vx/kw^2 at KW]: the k_w prior is tight, so vx takes almost all of it
    assert x[VX] - 20.0 == pytest.approx(p0 / (p0 + 20.0 ** 2 * 1e-4 + R), rel=1e-6)
    assert P[VX, VX] < 0.1 * p0 and A[VX, VX] < 0.1  # A carries (I - K h') for the rewind
    assert w.consecutive_rejects == 0


def test_wheel_speed_gates_a_locked_wheel_out_and_counts_the_run():
    w = WheelSpeedFusion("front", 1.2, 0.05)
    x, P, A = state(vx=20.0)
    x0, P0 = x.copy(), P.copy()
    for n in (1, 2):
        assert not w.fuse(x, P, 0.0, 0.0, 0.0, 0.0, A)
        assert w.consecutive_rejects == n
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(P, P0)
    assert w.fuse(x, P, 20.1, 0.0, 0.0, 0.0, A) and w.consecutive_rejects == 0


def test_front_wheels_of_a_rear_driven_car_see_the_steered_velocity():
    """The front pair measures vx cos(delta) + (vy + lf r) sin(delta): fed exactly that, nothing
    moves (a zero innovation), fed vx alone while steering, vy is corrected too."""
    w = WheelSpeedFusion("rear", 1.3, 0.05)
    x, P, A = state(vx=15.0, vy=0.4)
    delta, r = 0.2, 0.3
    z = 15.0 * math.cos(delta) + (0.4 + 1.3 * r) * math.sin(delta)
    assert w.fuse(x, P, z, delta, r, 0.0, A)
    np.testing.assert_allclose(x[[VX, VY]], [15.0, 0.4], atol=1e-12)
    assert w.h[VY] == pytest.approx(math.sin(delta)) and w.h[BR] == pytest.approx(-1.3 * math.sin(delta))


# ---- single track ------------------------------------------------------------------------------

def single_track():
    return SingleTrackFusion(1500.0, 2500.0, 1.2, 1.5, 80000.0, 90000.0, adapt=True)


def test_single_track_on_a_straight_is_the_kinematic_vy():
    st = single_track()
    vy, var = st.pseudo_measurement(20.0, 0.1, 0.0, 0.0)
    assert vy == pytest.approx(1.5 * 0.1)  # lr r: no lateral force, no rear slip
    assert var > 0.0


def test_single_track_in_a_corner_is_the_rear_slip_of_the_lateral_force():
    """vy = lr r - vx (m / C_r) (lf ay - Iz/m r_dot) / L at small ay (the cubic term is negligible)."""
    st = single_track()
    vx, r, ay = 20.0, 0.05, 1.0
    vy, _ = st.pseudo_measurement(vx, r, ay, 0.0)
    k3 = st.rear.k[1] * (ay / 9.81) ** 2
    want = 1.5 * r - vx * (1500.0 / 90000.0 + k3) * (1.2 * ay) / 2.7
    assert vy == pytest.approx(want, rel=1e-9)
    assert vy < 1.5 * r  # the rear axle slips outwards


def test_single_track_fuses_vy_only_and_not_at_a_crawl():
    st = single_track()
    x, P, A = state(vx=20.0, vy=0.0)
    assert st.fuse(x, P, 0.1, 0.0, 0.0, A)
    assert 0.0 < x[VY] < 0.15 and x[VX] == pytest.approx(20.0, abs=1e-12)  # P is diagonal
    x, P, A = state(vx=0.3)
    x0 = x.copy()
    assert not st.fuse(x, P, 0.1, 0.0, 0.0, A)
    np.testing.assert_array_equal(x, x0)



def _linear_turn_in(steps: int, dt: float, vx: float):
    """A linear single-track car (the model's own law, exact: m 1500, Iz 2500, lf 1.2, lr 1.5,
    C_f 80 kN/rad, C_r 90 kN/rad) at vx, steered to 0.04 rad over 0.15 s from t = 0.2 s:
    per step (r, ay, vy) as the IMU reads r and ay and the truth has vy (0.25 g, rdot ~1 rad/s^2)."""
    m, iz, lf, lr, cf, cr = 1500.0, 2500.0, 1.2, 1.5, 80000.0, 90000.0
    vy = r = 0.0
    for k in range(steps):
        delta = 0.04 * min(max((k * dt - 0.2) / 0.15, 0.0), 1.0)
        fyf = -cf * ((vy + lf * r) / vx - delta)
        fyr = -cr * (vy - lr * r) / vx
        ay = (fyf + fyr) / m
        vy += (ay - r * vx) * dt
        r += (lf * fyf - lr * fyr) / iz * dt
        yield r, ay, vy


def test_single_track_inputs_at_one_lag_follow_a_turn_in():
    """Timing of the samples (issue 7): the model's yaw acceleration is the slope of a twice
    low-passed yaw rate (0.08 s late); fed with r and ay as they come, the model's vy led its
    yaw-inertia term by that lag and missed a turn-in by 0.2 deg. With r and ay through the same
    low-passes and the IMU's vy change over the lag added (LaggedModelInputs), it follows the
    turn-in to a twentieth of that, and both are exact in the steady corner."""
    dt, vx = 0.006, 16.0
    st = single_track()
    st.rear.k[1] = 0.0  # the linear car: no saturation term
    a1, a2 = dt / (0.03 + dt), dt / (0.05 + dt)  # the estimator's r_lp and rdot low-passes
    lag = LaggedModelInputs(a1, a2, dt)
    r_lp = rdot = 0.0
    before, after = [], []
    for r, ay, vy in _linear_turn_in(int(1.5 / dt), dt, vx):
        r_prev, r_lp = r_lp, r_lp + a1 * (r - r_lp)
        rdot += a2 * ((r_lp - r_prev) / dt - rdot)
        before.append(st.model_vy(vx, r, ay, rdot) - vy)
        r_c, ay_c, shift = lag.step(r_lp, r, ay, vx)
        after.append(st.model_vy(vx, r_c, ay_c, rdot) + shift - vy)
    before, after = (np.degrees(np.abs(np.array(e)) / vx) for e in (before, after))
    assert before.max() > 0.15  # the old inputs: 0.2 deg at the turn-in
    assert after.max() < 0.02 and after.max() < before.max() / 10.0
    assert after[-1] < 1e-3 and before[-1] < 1e-3  # steady corner: both the law itself

# ---- standstill --------------------------------------------------------------------------------

def test_single_track_model_vy_is_the_pseudo_measurements_vy_to_the_bit():
    """The fault detector's per-step shortcut (vy without the variance) must be the same number
    the filter fuses, also after the RLS has moved both parameters."""
    rng = np.random.default_rng(3)
    st = SingleTrackFusion(1500.0, 2500.0, 1.2, 1.5, 100000.0, 120000.0, True)
    for n in range(3000):
        vx, r, ay, rdot = rng.uniform(-5, 60), rng.normal(0, 0.5), rng.normal(0, 6), rng.normal(0, 2)
        assert st.model_vy(vx, r, ay, rdot) == st.pseudo_measurement(vx, r, ay, rdot)[0]
        if n % 10 == 0:
            st.adapt_from(max(vx, 9.0), rng.normal(0, 0.5), 1e-4, r, ay, rdot, rng.normal(0, 0.05))
    assert st.rear.updates > 0


def test_single_track_law_holds_while_the_steering_agrees_with_both_axles():
    """In a GNSS outage the model's bound on the sideslip std needs the tyre law confirmed without vy:
    L r - vx delta = front slip - rear slip (core.MODEL_BOUND). A steady 0.41 g corner steered as the
    law says, or 30 % of the front slip off (inside the 40 % prior), holds; 5 deg more front slip (a
    front axle at its friction limit: mu 0.5 gave 22 deg) or 5 deg less (the rear at its limit) does
    not; nor does a missing steering angle."""
    st = single_track()
    vx, ay = 20.0, 4.0
    r = ay / vx
    n2 = (ay / 9.81) ** 2
    y_f, _ = st.front.predict(st.regressor_front(vx, ay, 0.0), n2, True)
    y_r, _ = st.rear.predict(st.regressor_rear(vx, ay, 0.0), n2, True)
    delta = (st.L * r - (y_f - y_r)) / vx  # the law's steady-state road-wheel angle
    assert st.law_holds(vx, r, ay, 0.0, delta)
    assert st.law_holds(vx, r, ay, 0.0, delta + 0.3 * y_f / vx)
    assert not st.law_holds(vx, r, ay, 0.0, delta + math.radians(5.0))
    assert not st.law_holds(vx, r, ay, 0.0, delta - math.radians(5.0))
    assert not st.law_holds(vx, r, ay, 0.0, math.nan)
    assert not st.law_holds(0.3, 0.0, 0.0, 0.0, 0.0)


def test_single_track_law_excess_is_the_misfit_beyond_the_laws_own_3_sigma():
    """core.LAW_EXCESS: the steering's misfit of the understeer relation beyond 3 sigma of both laws
    and the steering is what the rear law's vy may be off by (an axle at its combined-slip limit on a
    low-friction road). Zero wherever law_holds is true (no widening on a dry corner steered as the
    law says), the excess squared beyond it, either sign, and zero without a steering angle."""
    st = single_track()
    vx, ay = 20.0, 4.0
    r = ay / vx
    n2 = (ay / 9.81) ** 2
    y_f, var_f = st.front.predict(st.regressor_front(vx, ay, 0.0), n2, True)
    y_r, var_r = st.rear.predict(st.regressor_rear(vx, ay, 0.0), n2, True)
    delta = (st.L * r - (y_f - y_r)) / vx
    lim = 3.0 * math.sqrt(var_f + var_r + (math.radians(0.3) * vx) ** 2)
    assert st.law_excess_var(vx, r, ay, 0.0, delta) == 0.0
    assert st.law_excess_var(vx, r, ay, 0.0, delta + 0.3 * y_f / vx) == 0.0
    for sign in (1.0, -1.0):
        d = sign * math.radians(5.0)
        assert not st.law_holds(vx, r, ay, 0.0, delta + d)
        assert st.law_excess_var(vx, r, ay, 0.0, delta + d) == pytest.approx((abs(d) * vx - lim) ** 2, rel=1e-9)
    assert st.law_excess_var(vx, r, ay, 0.0, math.nan) == 0.0
    assert st.law_excess_var(0.3, 0.0, 0.0, 0.0, 0.0) == 0.0


def test_single_track_law_excess_and_oversteer_is_the_two_methods_bit_for_bit():
    """core's step asks law_excess_and_oversteer for both when FRICTION_REAR is on (one misfit
    computed, not two: perf50): each value the bits of its own method, at and beyond the law, both
    signs of ay, ay = 0, no steering angle and below MIN_SPEED (0 / NaN as the methods give)."""
    st = single_track()
    cases = [(20.0, 0.2, 4.0, 0.0, 0.02), (20.0, 0.2, 4.0, 0.0, 0.02 + math.radians(5.0)),
             (20.0, -0.2, -4.0, 0.1, -0.02 - math.radians(5.0)), (20.0, -0.2, -4.0, 0.1, -0.02 + math.radians(5.0)),
             (15.0, 0.1, 0.0, 0.0, 0.05), (15.0, 0.1, 2.0, 0.0, math.nan), (0.3, 0.0, 1.0, 0.0, 0.0)]
    for vx, r, ay, rdot, delta in cases:
        excess, over = st.law_excess_and_oversteer(vx, r, ay, rdot, delta)
        want_excess, want_over = st.law_excess_var(vx, r, ay, rdot, delta), st.oversteer_sigmas(vx, r, ay, rdot, delta)
        assert excess.hex() == want_excess.hex()
        assert over.hex() == want_over.hex() or (math.isnan(over) and math.isnan(want_over))
    assert st.law_excess_and_oversteer(*cases[1])[0] > 0.0 and abs(st.law_excess_and_oversteer(*cases[2])[1]) > 1.0


def test_single_track_fuse_widened_by_the_law_excess_moves_vy_less():
    """The excess widens the pseudo-measurement by its ~2 s correlation (CORNER_STEPS), a bias for
    the corner: the same model innovation moves vy less and leaves more vy variance."""
    st = single_track()
    out = []
    for law_var in (0.0, 0.5 ** 2):
        x = np.zeros(NX)
        x[VX] = 15.0
        x[VY] = 0.8
        P = np.eye(NX) * 0.01
        assert st.fuse(x, P, 0.25, 3.5, 0.0, None, 1, 1.0, 0.0, law_var)
        out.append((abs(x[VY] - 0.8), P[VY, VY]))
    assert out[1][0] < out[0][0]
    assert out[1][1] > out[0][1]


def test_standstill_needs_the_hold_time():
    s = StandstillFusion(0.006, 0.01)
    assert not any(s.detect(0.0) for _ in range(s.hold_steps - 1))
    assert s.detect(0.0)
    assert not s.detect(0.5)  # one moving wheel restarts the count
    assert not s.detect(0.0)


def test_standstill_zeroes_velocity_and_reads_the_gyro_bias():
    s = StandstillFusion(0.006, 0.01)
    x, P, A = state(vx=0.2, vy=0.05)
    P[BR, BR] = 1e-4
    for _ in range(50):
        s.fuse(x, P, 0.004, 0.1, -0.05, A)
    assert abs(x[VX]) < 1e-3 and abs(x[VY]) < 1e-3
    # a constant observed 50 times: the Bayesian mean of the prior (0) and the readings
    assert x[BR] == pytest.approx(0.004 * (50 / s.gyro_R) / (1 / 1e-4 + 50 / s.gyro_R), rel=1e-9)
    assert x[BAX] == pytest.approx(0.1 * (50 / s.accel_R) / (1 / 0.01 + 50 / s.accel_R), rel=1e-9)
    assert x[BAY] == pytest.approx(-0.05 * (50 / s.accel_R) / (1 / 0.01 + 50 / s.accel_R), rel=1e-9)


# ---- GNSS velocity -----------------------------------------------------------------------------

def gnss(vn, ve, acc=0.1, fix=3):
    return GnssSample(t=0.0, vel_n_mps=vn, vel_e_mps=ve, speed_acc_mps=acc, fix_type=fix, fix_ok=True)


def history(x, P, steps=20):
    h = StepHistory(steps + 5)
    h.reset(0)
    for k in range(steps):
        h.X[k], h.P[k], h.A[k] = x, P, np.eye(NX)
        h.aux[k, AUX_R] = 0.0
    h.last = steps - 1
    return h


def test_gnss_velocity_corrects_heading_and_carries_it_to_the_present():
    g = GnssVelocityFusion(1.0, 0.0, 3, 1.0, 0.3, 5.0)
    x, P, _ = state(vx=20.0, vy=0.0, psi=1.0)
    P[PSI, PSI] = math.radians(3.0) ** 2
    P[VY, VY] = 0.01  # else part of the cross-track error is (rightly) read as sideslip
    h = history(x, P)
    course = 1.0 + math.radians(2.0)  # the car really points 2 deg further clockwise
    assert g.fuse(h, 5, gnss(20.0 * math.cos(course), 20.0 * math.sin(course)))
    for k in range(5, h.last + 1):
        assert h.X[k, PSI] == pytest.approx(course, abs=math.radians(0.3))
        assert h.P[k][PSI, PSI] < P[PSI, PSI]
    assert h.X[4, PSI] == 1.0  # before the time of validity: untouched
    assert g.fused == 1


def test_gnss_velocity_gates_a_glitch_and_leaves_the_history_alone():
    g = GnssVelocityFusion(0.0, 0.0, 3, 1.0, 0.3, 5.0)
    x, P, _ = state(vx=20.0, vy=0.0, psi=0.0)
    h = history(x, P)
    X0, P0 = h.X.copy(), h.P.copy()
    assert not g.fuse(h, 5, gnss(60.0, 0.0))
    assert g.consecutive_rejects == 1 and "innovation gate" in g.last_reason
    np.testing.assert_array_equal(h.X, X0)
    np.testing.assert_array_equal(h.P, P0)


def test_gnss_speed_only_moves_the_speed_not_the_heading():
    g = GnssVelocityFusion(0.0, 0.0, 3, 1.0, 0.3, 5.0)
    x, P, _ = state(vx=20.0, vy=0.0, psi=2.0)
    P[PSI, PSI] = math.pi ** 2
    h = history(x, P)
    assert g.fuse_speed(h, 5, gnss(0.0, 21.0))
    assert 20.0 < h.X[h.last, VX] <= 21.0
    assert h.X[h.last, PSI] == pytest.approx(2.0, abs=1e-9)


def test_gnss_uses_the_derived_antenna_velocity():
    """At the antenna, a lever arm adds r x lever: the fusion predicts what generated.py says."""
    g = GnssVelocityFusion(1.5, 0.4, 3, 1.0, 0.3, 5.0)
    x, P, _ = state(vx=20.0, vy=0.5, psi=0.7)
    h = history(x, P)
    h.aux[:, AUX_R] = 0.2
    vn, ve = gen.gnss_velocity(*x, 0.2, 1.5, 0.4)
    assert g.fuse(h, 5, gnss(vn, ve, acc=0.05))  # exactly the prediction: nothing moves
    np.testing.assert_allclose(h.X[h.last], x, atol=1e-12)


def test_gnss_quality_checks():
    g = GnssVelocityFusion(0.0, 0.0, 3, 1.0, 0.3, 5.0)
    assert g.usable(gnss(10.0, 0.0))
    assert not g.usable(gnss(10.0, 0.0, fix=2))
    assert not g.usable(gnss(10.0, 0.0, acc=2.0))
    assert not g.usable(gnss(200.0, 0.0))
