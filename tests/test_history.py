"""The late-measurement rewind (``StepHistory.correct``) against a brute-force re-filter from the
stored step, on a linear problem built from the production update functions (both kernels)."""
from __future__ import annotations

import numpy as np
import pytest

from ecu_daemon.estimator import backend, kalman
from ecu_daemon.estimator.history import StepHistory
from ecu_daemon.estimator.kinematic import NX

STEPS = 60  # steps between the late measurement's time of validity and the present


def problem(seed=3):
    """A linear system driven by noise and its measurements: transitions, process noise, per
    step one scalar measurement (h, z, R), the prior, and the late 2-D measurement (at step 10)
    of the true state."""
    rng = np.random.default_rng(seed)
    F = [np.eye(NX) + 0.01 * rng.normal(size=(NX, NX)) for _ in range(STEPS + 1)]
    q = rng.uniform(1e-4, 1e-3, NX)
    a = rng.normal(size=(NX, NX))
    P0 = a @ a.T + np.eye(NX)
    truth = [rng.multivariate_normal(np.zeros(NX), P0)]
    for k in range(1, STEPS + 1):
        truth.append(F[k] @ truth[-1] + rng.normal(size=NX) * np.sqrt(q))
    meas = [None]
    for k in range(1, STEPS + 1):
        h, R = rng.normal(size=NX), float(rng.uniform(0.05, 0.2))
        meas.append((h, float(h @ truth[k] + rng.normal() * np.sqrt(R)), R))
    H, R2 = rng.normal(size=(2, NX)), np.diag([0.05, 0.08])
    z2 = H @ truth[10] + rng.normal(size=2) * np.sqrt(np.diag(R2))
    return F, np.diag(q), meas, np.zeros(NX), P0, H, z2, R2


def wrapped(x):
    """State index 2 is the heading: the history keeps it in [0, 2 pi)."""
    x = x.copy()
    x[2] %= 2 * np.pi
    return x


def step(x, P, F, Q, m, gains=None):
    """One filter step as the core runs it: predict, fuse, A = (I - K h') F. ``gains``: hold K."""
    x[:] = F @ x
    P[:] = F @ P @ F.T + Q
    A = F.copy()
    h, z, R = m
    if gains is None:
        kalman.scalar_update(x, P, z - h @ x, h, R, 0.0, A)
    else:  # the same step with a fixed gain, Joseph form (exact for any gain)
        K = gains
        x += K * (z - h @ x)
        P[:] = kalman.joseph(P, K[:, None], h[None, :], np.array([[R]]))
        A -= np.outer(K, h @ A)
    kalman.symmetrize(P)
    return A


def fuse_2d(x, P, H, z, R):
    """The late measurement at its stored step (as fusion/gnss_velocity.py): dx and M."""
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return K @ (z - H @ x), P - kalman.joseph(P, K, H, R)


def run_history(prob):
    F, Q, meas, x0, P0, *_ = prob
    hist = StepHistory(STEPS + 5)
    hist.reset(0)
    x, P = x0.copy(), P0.copy()
    hist.X[0], hist.P[0], hist.A[0] = x, P, np.eye(NX)
    hist.last = 0
    gains = []
    for k in range(1, STEPS + 1):
        P_prior = F[k] @ P @ F[k].T + Q
        h, _, R = meas[k]
        gains.append(P_prior @ h / (h @ P_prior @ h + R))
        hist.A[k] = step(x, P, F[k], Q, meas[k])
        hist.X[k], hist.P[k] = x, P
        hist.last = k
    return hist, gains


@pytest.mark.parametrize("compiled", [False, True])
def test_rewind_is_the_refilter_with_the_stored_gains(compiled):
    """Exact for the linearised system: the shifted history equals re-running every later step
    from the corrected stored step with the gains it used (the covariance too: Joseph form is
    linear in P for a fixed gain, which is what lets the shift carry M as A M A')."""
    prob = problem()
    F, Q, meas, _, _, H, z, R = prob
    with backend.selected(compiled):
        hist, gains = run_history(prob)
        s = 10
        xs, Ps = hist.X[s].copy(), hist.P[s].copy()
        dx, M = fuse_2d(xs, Ps, H, z, R)
        assert hist.correct(s, dx, M)
        x, P = xs + dx, Ps - M
        for k in range(s + 1, STEPS + 1):
            step(x, P, F[k], Q, meas[k], gains=gains[k - 1])
            np.testing.assert_allclose(hist.X[k], wrapped(x), rtol=1e-10, atol=1e-10)
            np.testing.assert_allclose(hist.P[k], P, rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("compiled", [False, True])
def test_rewind_is_close_to_the_optimal_refilter_and_never_more_confident(compiled):
    """Re-filtering with gains recomputed from the corrected covariances is the optimum the shift
    approximates: the present state within a tenth of a standard deviation of it, the stds within
    1 %, and the shift's covariance at least the optimum's (it never claims information it does
    not have)."""
    prob = problem(seed=11)
    F, Q, meas, _, _, H, z, R = prob
    with backend.selected(compiled):
        hist, _ = run_history(prob)
        s = 10
        xs, Ps = hist.X[s].copy(), hist.P[s].copy()
        dx, M = fuse_2d(xs, Ps, H, z, R)
        x_before = hist.X[STEPS].copy()
        assert hist.correct(s, dx, M)
        x, P = xs + dx, Ps - M
        for k in range(s + 1, STEPS + 1):
            step(x, P, F[k], Q, meas[k])
    sd = np.sqrt(np.diag(P))
    assert np.abs(hist.X[STEPS] - x_before).max() > 0.01 * sd.min()  # the late fix moved the present
    assert np.all(np.abs(hist.X[STEPS] - wrapped(x)) < 0.1 * sd)
    ratio = np.sqrt(np.diag(hist.P[STEPS])) / sd
    assert ratio.min() >= 1.0 - 1e-12 and ratio.max() < 1.01
    assert np.linalg.eigvalsh(hist.P[STEPS] - P).min() > -1e-12


def test_rewind_at_the_present_step_and_psi_wraps():
    with backend.selected(True):
        hist, _ = run_history(problem())
        s = hist.last
        hist.X[s, 2] = 6.2
        dx = np.zeros(NX)
        dx[2] = 0.2
        assert hist.correct(s, dx, np.zeros((NX, NX)))
        assert hist.X[s, 2] == pytest.approx(0.2 - (2 * np.pi - 6.2))
