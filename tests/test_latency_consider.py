"""The GNSS latency error as one unknown shared by every fix (estimator/latency_consider.py).

A synthetic steady circle on the real history and update code: each fix sees the same latency
error d, as the course (and a dual-antenna heading) turned by r d. Monte Carlo over d and the
receiver noise checks what the published std promises, against the white-noise treatment the
estimator used before (``R += (r std)^2`` on every fix).
"""
from __future__ import annotations

import math

import numpy as np

from ecu_daemon.estimator.history import StepHistory
from ecu_daemon.estimator.kinematic import NX, PSI, VY
from ecu_daemon.estimator.latency_consider import LatencyConsider, antenna_acceleration_ned

R_TURN = 0.6  # rad/s, a 10 m circle at 6 m/s
LAT_STD = 0.05  # s, the latency's std as latency.py reports it in a steady circle
SIG_COURSE = math.radians(0.3)  # per fix
SIG_HEADING = math.radians(0.15)  # per fix (dual antenna)
FIXES = 40  # 8 s at 5 Hz
TRIALS = 400
PSI0 = 1.0
# the toy state: psi = heading (rad), vy = sideslip (rad); the other states are spectators
P0 = np.diag([1.0, math.radians(2.0) ** 2, math.radians(0.5) ** 2, 1.0, 1.0, 1.0, 1.0, 1.0])


def _fresh(n: int = 4) -> StepHistory:
    h = StepHistory(n)
    h.reset(0)
    for k in range(n):
        h.X[k] = 0.0
        h.X[k, PSI] = PSI0  # away from the wrap at 0 / 2 pi the history keeps
        h.P[k] = P0
        h.A[k] = np.eye(NX)
    h.last = n - 1
    return h


def _fuse(h: StepHistory, cons: LatencyConsider | None, z: float, H: np.ndarray, hd: float, var: float) -> None:
    """One scalar fix at the newest stored step: augmented (cons) or white (R += (hd std)^2)."""
    s = h.last
    i = h.slot(s)
    y = np.array([z - float(H @ h.X[i])])
    dx, M = np.zeros(NX), np.zeros((NX, NX))
    Hm = H[None, :]
    if cons is None:
        Rm = np.array([[var + (hd * LAT_STD) ** 2]])
        S = Hm @ h.P[i] @ Hm.T + Rm
        K = h.P[i] @ Hm.T / S[0, 0]
        dx[:] = (K @ y).ravel()
        M[:] = K @ Hm @ h.P[i]
        M[:] = 0.5 * (M + M.T)
        assert h.correct(s, dx, M)
        return
    nis, upd = cons.late_update(h.P[i], cons.Cr[i], Hm, np.array([hd]), np.array([[var]]), y, dx, M)
    assert math.isfinite(nis)
    assert h.correct(s, dx, M)
    cons.commit(h, s, upd)


def _circle(dual: bool, augmented: bool, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """Sideslip errors and published stds after FIXES fixes, over TRIALS drives."""
    rng = np.random.default_rng(seed)
    Hc = np.zeros(NX)
    Hc[PSI] = Hc[VY] = 1.0  # course = heading + sideslip
    Hh = np.zeros(NX)
    Hh[PSI] = 1.0
    err, std = np.empty(TRIALS), np.empty(TRIALS)
    for t in range(TRIALS):
        psi, beta = PSI0 + rng.normal(0.0, math.sqrt(P0[PSI, PSI])), rng.normal(0.0, math.sqrt(P0[VY, VY]))
        d = rng.normal(0.0, LAT_STD)
        h = _fresh()
        cons = None
        if augmented:
            cons = LatencyConsider(h.n)
            cons.sync(h, 0.4, LAT_STD)
        for _ in range(FIXES):
            if dual:
                _fuse(h, cons, psi + R_TURN * d + rng.normal(0.0, SIG_HEADING), Hh, R_TURN, SIG_HEADING ** 2)
            _fuse(h, cons, psi + beta + R_TURN * d + rng.normal(0.0, SIG_COURSE), Hc, R_TURN, SIG_COURSE ** 2)
        i = h.slot(h.last)
        err[t] = h.X[i, VY] - beta
        std[t] = math.sqrt(h.P[i][VY, VY])
    return err, std


def test_a_shared_latency_error_is_not_averaged_away_as_white_noise_would_be():
    """Single antenna in a steady circle: every course is off by the same r d. White noise
    promises an average over the fixes that does not happen (outside 3 sigma far more often than
    the 0.3 % of a calibrated filter); the augmented state keeps the promise."""
    err_w, std_w = _circle(dual=False, augmented=False)
    err_a, std_a = _circle(dual=False, augmented=True)
    assert np.mean(np.abs(err_w) <= 3 * std_w) < 0.8  # measured: 68 %
    assert np.mean(np.abs(err_a) <= 3 * std_a) >= 0.99
    assert 0.8 < np.std(err_a) / np.mean(std_a) < 1.25  # the std is the error's, not a bound


def test_velocity_and_heading_of_one_receiver_share_the_error_and_it_cancels_in_the_sideslip():
    """Dual antenna: course - heading = sideslip at any latency. Sharing d, the filter finds the
    sideslip to the receivers' noise (and says so); as independent white noise each fix carries
    r std = 1.7 deg, and both the error and the published std stay several times larger."""
    err_w, std_w = _circle(dual=True, augmented=False)
    err_a, std_a = _circle(dual=True, augmented=True)
    assert np.mean(np.abs(err_a) <= 3 * std_a) >= 0.99
    assert 0.8 < np.std(err_a) / np.mean(std_a) < 1.25
    assert np.mean(std_a) < np.mean(std_w) / 4.0  # measured: 0.05 deg against 0.36 (errors 0.05 / 0.39)
    assert np.std(err_a) < np.std(err_w) / 4.0


def test_a_tighter_latency_std_conditions_the_whole_augmented_covariance_consistently():
    """latency.py's std falling from 0.05 to 0.02 s: d's variance, its cross-covariance and the
    state's covariance shrink together (the augmented covariance stays positive definite); a
    wider one widens d alone; its delay moving by D moves d by -D."""
    h = _fresh()
    cons = LatencyConsider(h.n)
    cons.sync(h, 0.4, LAT_STD)
    Hc = np.zeros(NX)
    Hc[PSI] = Hc[VY] = 1.0
    for _ in range(5):
        _fuse(h, cons, PSI0 + 0.01, Hc, R_TURN, SIG_COURSE ** 2)
    i = h.slot(h.last)
    p_vy, c_vy = h.P[i][VY, VY], cons.C[i, VY]
    assert abs(c_vy) > 0.0
    cons.sync(h, 0.4, 0.02)
    assert cons.var < 0.02 ** 2 and abs(cons.C[i, VY]) < abs(c_vy) and h.P[i][VY, VY] < p_vy
    aug = np.block([[h.P[i], cons.C[i][:, None]], [cons.C[i][None, :], np.array([[cons.var]])]])
    assert np.all(np.linalg.eigvalsh(aug) > 0.0)
    var, d = cons.var, cons.d
    cons.sync(h, 0.41, 0.04)
    assert cons.var > var and math.isclose(cons.d, max(d - 0.01, -0.12))


def test_antenna_acceleration_is_the_derivative_of_the_antenna_velocity():
    """Against a finite difference of generated.gnss_velocity along a yawing, accelerating body."""
    from ecu_daemon.estimator import generated as gen

    lx, ly = 0.7, 0.3
    dt = 1e-5

    def state(t):
        r = 0.5 + 0.2 * t  # rdot = 0.2
        psi = 1.0 - (0.5 * t + 0.1 * t * t)  # d psi / dt = -r
        vx, vy = 8.0 + 1.5 * t, 0.4 - 0.3 * t
        return vx, vy, psi, r

    vx, vy, psi, r = state(0.0)
    ax = 1.5 - r * vy  # specific force = dv/dt + omega x v
    ay = -0.3 + r * vx
    a = antenna_acceleration_ned(psi, ax, ay, r, 0.2, lx, ly)
    v = [gen.gnss_velocity(*state(t)[:3], 0, 0, 0, 0, 0, state(t)[3], lx, ly) for t in (-dt, dt)]
    fd = [(v[1][j] - v[0][j]) / (2 * dt) for j in (0, 1)]
    assert np.allclose(a, fd, atol=1e-5)
