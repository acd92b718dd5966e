"""The 6 ms tick thread: absolute deadlines, catch-up accounting, statistics."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from ecu_daemon.io.tick import ScaledClock, TickStats, TickThread, WakeLead

PERIOD = 0.006


def run_ticks(n, on_tick=None, **kw):
    calls = []
    done = threading.Event()

    def cb(k, now):
        calls.append((k, now))
        if len(calls) >= n:
            done.set()
        if on_tick is not None:
            on_tick(k, now)

    t = TickThread(PERIOD, cb, **kw)
    t.start()
    assert done.wait(10.0), "tick thread did not reach the expected number of ticks"
    t.stop()
    assert not t.is_alive()
    return t, calls


def test_ticks_never_fire_before_their_deadline_and_indices_increase():
    t, calls = run_ticks(40, offset_s=0.001)
    ks = [k for k, _ in calls]
    assert all(b > a for a, b in zip(ks, ks[1:]))
    for k, now in calls:
        assert now >= k * PERIOD + 0.001  # the callback sees its own deadline has passed
        # k is the newest due index: the next deadline has not passed yet when it was computed
        assert now < (k + 1) * PERIOD + 0.001
    assert t.stats.ticks == len(calls)


def test_a_stalled_callback_is_caught_up_and_counted():
    stalled = []

    def stall(k, now):
        if not stalled:
            stalled.append(k)
            time.sleep(4 * PERIOD)

    t, calls = run_ticks(10, on_tick=stall)
    ks = [k for k, _ in calls]
    assert ks[1] - ks[0] >= 4  # the missed deadlines were skipped, not replayed one by one
    assert t.stats.skipped >= 3
    assert t.stats.overruns >= 1
    assert t.stats.snapshot().late_max_s >= 3 * PERIOD


def test_callback_exceptions_are_counted_and_ticking_continues():
    def boom(k, now):
        raise RuntimeError("estimator blew up")

    t, calls = run_ticks(5, on_tick=boom)
    assert t.errors >= 5


def test_stats_percentiles_and_histogram():
    s = TickStats(window=100)
    for i in range(100):
        s.record(i * 1e-5, 1e-5, 0, False)  # 0 .. 0.99 ms
    s.record(0.5, 0.0, 2, True)  # one very late tick
    snap = s.snapshot()
    assert snap.ticks == 101
    assert snap.overruns == 1 and snap.skipped == 2
    assert snap.late_max_s == pytest.approx(0.5)
    assert snap.late_max_total_s == pytest.approx(0.5)
    assert 0.4e-3 < snap.late_p50_s < 0.6e-3
    # whole-run histogram: 50th percentile within one bin, the 0.5 s tick lands in the overflow bin
    assert s.total_percentile(50) == pytest.approx(0.5e-3, abs=2e-5)
    assert s.hist[-1] == 1


def test_scaled_clock_runs_faster():
    c = ScaledClock(10.0)
    # bracket each reading between two of time.monotonic (non-decreasing): exact bounds, whatever the
    # load delays between the calls (the old "c() - a >= 9 x elapsed" read the clock after c())
    before_a = time.monotonic()
    a = c()
    after_a = time.monotonic()
    time.sleep(0.02)
    before_b = time.monotonic()
    b = c()
    after_b = time.monotonic()
    assert 10 * (before_b - after_a) - 1e-9 <= b - a <= 10 * (after_b - before_a) + 1e-9
    assert b - a >= 10 * 0.02 - 1e-9
    with pytest.raises(ValueError):
        ScaledClock(0.0)


def test_snapshot_percentiles_are_numpys():
    """The snapshot's own percentile of a sorted window gives np.percentile's numbers (linear)."""
    from ecu_daemon.io.tick import _percentile

    rng = np.random.default_rng(7)
    for n in (1, 2, 3, 10, 777, 2048):
        x = rng.exponential(1e-3, size=n)
        for q in (0, 50, 99, 100):
            assert _percentile(np.sort(x), q) == pytest.approx(float(np.percentile(x, q)), rel=1e-12, abs=0)


def test_wake_lead_follows_the_median_wake_up_delay_within_its_cap():
    """The tick is woken a typical wake-up delay before its deadline, not a fixed worst case:
    the spin after the wake-up is CPU burned on every tick."""
    lead = WakeLead(max_s=200e-6, window=8)
    assert lead.lead_s == 200e-6  # no wake-ups seen yet: the longest spin
    for d in (30e-6, 40e-6, 20e-6, 35e-6, 5e-3, 25e-6, 45e-6, 33e-6)[:-1]:
        lead.observe(d)
    assert lead.lead_s == 200e-6  # changes once per window, not per tick
    lead.observe(33e-6)
    assert lead.lead_s == pytest.approx(33e-6)  # the 5 ms outlier (a busy core) does not drag it up
    for d in [3e-3] * 8:  # a host that wakes everything late: a spin of at most the cap
        lead.observe(d)
    assert lead.lead_s == 200e-6
    for d in [-1e-6] * 8:  # woken early (a timer that fires ahead): no negative lead
        lead.observe(d)
    assert lead.lead_s == 0.0


def test_the_spin_accounting_counts_the_spin_not_the_sleep():
    """The learned lead stays within spin_s, and ``spun_s`` holds the spins (not the 6 ms sleeps)."""
    t, calls = run_ticks(80, spin_s=0.0002)
    assert 0.0 <= t.lead.lead_s <= 0.0002
    assert 0.0 <= t.spun_s <= len(calls) * 0.0002 + 0.05  # bounded by the spin it may do
