"""The latency sensitivity S (estimator/latency_sensitivity.py) carried through a rewind, against the
step-by-step product it stands for."""
import numpy as np
import pytest

from ecu_daemon.estimator import backend
from ecu_daemon.estimator.history import StepHistory
from ecu_daemon.estimator.kinematic import NX
from ecu_daemon.estimator.latency_sensitivity import LatencySensitivity


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
