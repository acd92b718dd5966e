"""The identified latency's std is what the timing information supports (latency.INFORMATION_STD, issue 7).

The std was the half-width of the cost profile's 4-sigma set. Where the speed hardly changes its
acceleration, the profile is the wheels' per-candidate sample noise (each candidate reads its own
stored sample): ragged, its set narrower than the information in it. Random drive 3991 (dev: AWD,
low-speed growing circle, prior 0.321 s for a true 0.078): the delay held at 0.024 s with a std of
0.008-0.015 s (3.7-4.3 sigma) while 1 / sqrt(info) was 0.016-0.024 s. Synthetic here: wheels the only
reference (0.02 m/s sample noise), GNSS speed at ~10 Hz with 0.05 m/s noise, prior = truth, 30 s."""
from __future__ import annotations

import numpy as np
import pytest

import ecu_daemon.estimator.latency as L
from ecu_daemon.estimator.latency import LatencyEstimator
from latency_feed import feed_wheels

DT = 0.006
TRUE_S = 0.1
SEEDS = range(1, 13)


def weak_launch(t: float) -> float:
    """3 m/s, the acceleration rising 0 -> 0.3 m/s^2 over 6 s, then steady: only the first 6 s time the GNSS."""
    if t < 6.0:
        return 3.0 + 0.5 * 0.3 * t * t / 6.0
    return 3.0 + 0.5 * 0.3 * 6.0 + 0.3 * (t - 6.0)


def town(t: float) -> float:
    """+-3 m/s speed changes: timed to a few ms (test_latency.py's town driving)."""
    return 15.0 + 3.0 * np.sin(2 * np.pi * t / 7.0) + 1.5 * np.sin(2 * np.pi * t / 2.9)


def identify(speed, seed: int) -> LatencyEstimator:
    return feed_wheels(LatencyEstimator(DT, TRUE_S, max_s=0.8), speed, TRUE_S, 30.0, 17,
                       np.random.default_rng(seed), gnss_noise=0.05, wheel_noise=0.02)


def data_best(est: LatencyEstimator) -> float:
    p = est._profile()
    return (int(p[0].argmin()) + 1) * DT


def test_a_delay_the_data_cannot_time_keeps_a_wide_std(monkeypatch):
    """The profile's best scatters by ~0.19 s rms over the seeds (1 / sqrt(info) ~0.13 s); the std,
    the prior's 0.15 s and the information's together, stays >= 0.09 s on every seed (flag off: 0.058)."""
    monkeypatch.setattr(L, "INFORMATION_STD", True)
    ests = [identify(weak_launch, s) for s in SEEDS]
    scatter = float(np.sqrt(np.mean([(data_best(e) - TRUE_S) ** 2 for e in ests])))
    assert scatter > 0.1, scatter  # the premise: these data do not time the delay
    stds = [e.std_s for e in ests]
    assert min(stds) >= 0.09, stds
    for e in ests:
        p = e._profile()
        assert e.std_s >= min(L.PRIOR_STD_S, 1.0 / np.sqrt(e.information(p[2]))) * 0.66, e.std_s


def test_without_it_the_ragged_profile_claims_more(monkeypatch):
    """The mechanism, flag off: the profile's narrow 4-sigma set is read as the std."""
    monkeypatch.setattr(L, "INFORMATION_STD", False)
    stds = [identify(weak_launch, s).std_s for s in SEEDS]
    assert min(stds) < 0.07, stds


@pytest.mark.parametrize("flag", [True, False])
def test_a_delay_the_data_do_time_shrinks(monkeypatch, flag):
    """Speed changes that time the GNSS: the std falls to its floor, the estimate within a few ms."""
    monkeypatch.setattr(L, "INFORMATION_STD", flag)
    for s in SEEDS[:4]:
        est = identify(town, s)
        assert est.std_s <= 0.01, est.std_s
        assert abs(est.delay_s - TRUE_S) <= 0.005, est.delay_s
