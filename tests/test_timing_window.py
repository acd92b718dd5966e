"""timing_window.py (the instants a fix may be from) and timing_trust's two latency predicates.

The window was written twice in core.py (the course's and the speed fix's); these pin the one rule
to what each wrote, and the two predicates to the questions their docstrings say they answer."""
import numpy as np
from hypothesis import given, settings, strategies as st

from ecu_daemon.estimator import timing_window
from ecu_daemon.estimator.latency import PRIOR_STD_S, LatencyEstimator
from ecu_daemon.estimator.latency_sensitivity import timing_secant
from ecu_daemon.estimator.timing_trust import IDENTIFIED_STD_S, at_prior, identified

DT = 0.006


@st.composite
def _history(draw):
    """(oldest, last, s, k_rx): a stored step s in oldest..last, received at k_rx >= s."""
    oldest = draw(st.integers(0, 5000))
    last = draw(st.integers(oldest, oldest + 400))
    s = draw(st.integers(oldest, last))
    k_rx = draw(st.integers(s, last + 3))
    return oldest, last, s, k_rx


@settings(max_examples=300, deadline=None)
@given(hist=_history(), max_steps=st.integers(2, 300))
def test_the_receivers_range_is_the_speed_fixs_window(hist, max_steps):
    """n = 0 with the range: what the along-track term wrote on its own before."""
    oldest, last, s, k_rx = hist
    lo, hi = timing_window.steps(oldest, last, s, k_rx, 0, max_steps)
    assert (lo, hi) == (min(max(k_rx - max_steps, oldest), s), max(min(k_rx, last), s))
    assert lo <= s <= hi and oldest <= lo and hi <= max(last, s)


@settings(max_examples=300, deadline=None)
@given(hist=_history(), n=st.integers(0, 200), max_steps=st.integers(2, 300), whole=st.booleans())
def test_the_window_holds_s_and_stays_in_the_history(hist, n, max_steps, whole):
    oldest, last, s, k_rx = hist
    lo, hi = timing_window.steps(oldest, last, s, k_rx, n, max_steps if whole else None)
    assert oldest <= lo <= s <= hi <= last
    assert hi <= max(k_rx, s)  # never after the reception
    assert lo == max(s - n if not whole else min(s - n, k_rx - max_steps), oldest)


def test_the_secant_integrates_the_ring_across_its_wrap():
    """The stored rate over lo..hi read from the ring (slots wrap), integrated and ``timing_secant``ed."""
    rng = np.random.default_rng(3)
    n_slots = 50
    aux = rng.normal(size=(n_slots, 4))
    lo, hi, s = 40, 70, 55  # slots 40..49 then 0..20
    got = timing_window.secant(aux, n_slots, 2, lo, hi, s, DT, 0.1, 0.5)
    rows = [k % n_slots for k in range(lo, hi + 1)]
    want = timing_secant(np.cumsum(aux[rows, 2]) * DT, s - lo, DT, 0.1, 0.5)
    assert got == want


def test_at_prior_and_identified_answer_different_questions():
    est = LatencyEstimator(DT, 0.3, 1.0)
    assert at_prior(est) and not identified(est)  # nothing learned yet
    est.std_s = 0.1  # narrowed, not yet identified: the window is 3 sigma, the along-track term wide
    assert not at_prior(est) and not identified(est)
    est.std_s = IDENTIFIED_STD_S
    assert not at_prior(est) and identified(est)
    fixed = LatencyEstimator(DT, 0.3, 1.0, fixed=True)
    fixed.std_s = PRIOR_STD_S  # widened by its monitor: still never identified, never "at the prior"
    assert not at_prior(fixed) and not identified(fixed)
    off = LatencyEstimator(DT, 0.3, 1.0, enabled=False)
    assert not at_prior(off) and identified(off)  # never any evidence: its own std
    tight = LatencyEstimator(DT, 0.3, 1.0, prior_std_s=0.05)  # a configured prior tighter than the default
    assert not at_prior(tight) and identified(tight)
