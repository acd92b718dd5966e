"""The latency sensitivity S (estimator/latency_sensitivity.py) carried through a rewind, against the
step-by-step product it stands for."""
import numpy as np

from ecu_daemon.estimator.history import StepHistory
from ecu_daemon.estimator.kinematic import NX
from ecu_daemon.estimator.latency_sensitivity import LatencySensitivity


def test_a_fix_is_carried_to_the_present_as_the_steps_transitions_would():
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
    sens._carry(h, s)
    ref = S0.copy()
    for j in range(s + 1, last + 1):
        ref = h.Ar[j % h.n] @ ref
        np.testing.assert_allclose(sens.Sr[j % h.n], ref, rtol=1e-12, atol=1e-12)
    before = sens.S.copy()
    sens._carry(h, last)  # nothing after the newest step: nothing moves
    np.testing.assert_array_equal(sens.S, before)
