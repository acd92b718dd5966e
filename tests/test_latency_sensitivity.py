"""The latency sensitivity S (estimator/latency_sensitivity.py) carried through a rewind, against the
step-by-step product it stands for."""
import numpy as np
import pytest

from ecu_daemon.estimator import backend
from ecu_daemon.estimator.history import StepHistory
from ecu_daemon.estimator.kinematic import NX
from ecu_daemon.estimator.latency_sensitivity import LatencySensitivity, timing_secant


@pytest.mark.parametrize("compiled", [False, True])
def test_a_fix_is_carried_to_the_present_as_the_steps_transitions_would(compiled):
    rng = np.random.default_rng(7)
    h = StepHistory(100)
    sens = LatencySensitivity(h.n)
    first, last = 40, 170  # wraps around the ring
    h.first, h.last = first, last
    for k in range(first, last + 1):
        h.Ar[k % h.n][:] = np.eye(NX) + 0.05 * rng.standard_normal((NX, NX))
    S0 = rng.standard_normal(NX)
    s = 95
    sens.Sr[h.slot(s)][:] = S0
    H, R, P = np.zeros((1, NX)), np.ones((1, 1)), np.eye(NX)  # a fix that reads nothing: S_s stays S0
    with backend.selected(compiled):
        sens.fused(h, s, P, H, R, np.zeros(1))
    np.testing.assert_array_equal(sens.Sr[h.slot(s)], S0)
    ref = S0.copy()
    for j in range(s + 1, last + 1):
        ref = h.Ar[j % h.n] @ ref
        np.testing.assert_allclose(sens.Sr[j % h.n], ref, rtol=1e-12, atol=1e-12)
    before = sens.S.copy()
    with backend.selected(compiled):
        sens.fused(h, last, P, H, R, np.zeros(1))  # nothing after the newest step: nothing moves
    np.testing.assert_array_equal(sens.S, before)


def test_timing_secant_is_the_tangent_in_a_steady_turn_and_covers_a_turn_in():
    """A heading turning at a constant rate is off by r d at any latency error d (the tangent is
    exact); at a turn-in the fix's assumed step is still on the straight (tangent 0) while its true
    instant is in the corner: 3 published sigmas (secant x the lag, at most x span) must reach its turn."""
    dt, span = 0.01, 0.45
    steady = np.cumsum(np.full(81, 0.3)) * dt  # 0.3 rad/s from 0.4 s before to 0.4 s after step 40
    assert timing_secant(steady, 40, dt, span, 0.3) == pytest.approx(0.3)
    r = np.where(np.arange(81) * dt > 0.5, 0.34, 0.0)  # the turn-in 0.5 s after the assumed step
    turned = np.cumsum(r) * dt
    slope = timing_secant(turned, 0, dt, span, 0.0)
    for j in range(1, 81):  # whatever the true instant
        assert abs(slope) * min(j * dt, span) >= abs(turned[j] - turned[0]) - 1e-12
    assert slope > 0.1  # the tangent (0) published nothing of it
