"""A refutation needs the information to make it (latency.TIMING_INFORMATION, issue 7).

Random drive 3358 (dev): a straight launch at a steady 1.19 m/s^2 (1208-1219 s, yaw rate 0), the
configured latency the truth (0.066 s). A speed that is an affine function of time has no timing in
it: y = a x(t - d) + b fits every d, the shift going into b. The wheels' cost profile was their
per-candidate sample noise (ragged, 3.6-16.8 over the candidates, best at 0.324 s), the
accelerometer's flat (0.2-1.0); at 1216.27 s the prior's 16.5 > LR_REJECT read as a refutation and
the delay was chased to 0.3215 s, which the corner after it fused as a sideslip 2.3 deg off while
valid. Synthetic here: the same launch (the acceleration rising 0.6 -> 1.2 m/s^2 over 4 s, then
steady), wheels the only reference, each stored sample with its own noise, GNSS at 10 Hz."""
from __future__ import annotations

import numpy as np
import pytest

import ecu_daemon.estimator.latency as L
from ecu_daemon.estimator.latency import LatencyEstimator
from latency_feed import feed_wheels

DT = 0.006
TRUE_S = 0.066
SEEDS = range(1, 13)


def launch(t: float) -> float:
    """3 m/s, the acceleration rising 0.6 -> 1.2 m/s^2 over 4 s, then steady (speed linear in time)."""
    a0, a1, ramp = 0.6, 1.2, 4.0
    if t < ramp:
        return 3.0 + a0 * t + 0.5 * (a1 - a0) * t * t / ramp
    return 3.0 + a0 * ramp + 0.5 * (a1 - a0) * ramp + a1 * (t - ramp)


def drive(seed: int, prior_s: float = TRUE_S, wheel_noise: float = 0.03) -> LatencyEstimator:
    return feed_wheels(LatencyEstimator(DT, prior_s, max_s=0.8), launch, TRUE_S, 20.0, 17,
                       np.random.default_rng(seed), gnss_noise=0.07, wheel_noise=wheel_noise)


def test_a_steady_launch_leaves_a_right_prior_alone(monkeypatch):
    monkeypatch.setattr(L, "TIMING_INFORMATION", True)
    errors = [drive(s).delay_s - TRUE_S for s in SEEDS]
    assert max(abs(e) for e in errors) <= 0.006, errors


def test_without_the_information_the_wheels_sample_noise_moves_it(monkeypatch):
    """The mechanism, flag off (main before it): the noise's likelihood ratio alone moves the delay."""
    monkeypatch.setattr(L, "TIMING_INFORMATION", False)
    errors = [drive(s).delay_s - TRUE_S for s in SEEDS]
    assert max(abs(e) for e in errors) > 0.03, errors


def test_a_constant_acceleration_carries_no_timing_information(monkeypatch):
    """The information is the regressor's slope less what scale and offset explain: a speed linear
    in time has none (a noise-free ramp: ~0 of what the launch's first 4 s give)."""
    monkeypatch.setattr(L, "TIMING_INFORMATION", True)
    ramp = feed_wheels(LatencyEstimator(DT, TRUE_S, max_s=0.8), lambda t: 5.0 + 1.2 * t, TRUE_S, 14.0, 17,
                       np.random.default_rng(1))
    bent = feed_wheels(LatencyEstimator(DT, TRUE_S, max_s=0.8), launch, TRUE_S, 14.0, 17,
                       np.random.default_rng(1))
    assert ramp._run_information() < 1e-6 * bent._run_information()
    assert bent._run_information() > 0.0


@pytest.mark.parametrize("delay_s", [0.12, 0.3])
def test_informative_speed_changes_still_find_a_wrong_prior(monkeypatch, delay_s):
    """The gate does not hold a delay the data do refute (town driving, +-3 m/s: test_latency.py)."""
    monkeypatch.setattr(L, "TIMING_INFORMATION", True)

    def accelerating(t):
        return 15.0 + 3.0 * np.sin(2 * np.pi * t / 7.0) + 1.5 * np.sin(2 * np.pi * t / 2.9)

    est = feed_wheels(LatencyEstimator(DT, 0.2, max_s=0.8), accelerating, delay_s, 120.0, 33,
                      np.random.default_rng(1), gnss_noise=0.03, wheel_noise=0.03)
    assert est.delay_s == pytest.approx(delay_s, abs=0.012)


def test_drive_3358_keeps_its_right_prior_and_its_promise(tmp_path, monkeypatch):
    """The drive itself (written out in test_sideslip_latency_sens.py): main walked the delay to
    0.32 s and published the corner's sideslip 2.31 deg off as valid (74 rows beyond 3 sigma)."""
    import math

    from ecu_daemon.sim.suite import SuiteCase
    from ecu_daemon.suite import run_case
    from test_sideslip_latency_sens import DEMO_LATENCY_WALKED_OFF as sc

    monkeypatch.setattr(L, "TIMING_INFORMATION", True)
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert abs(row["latency_error_s"]) <= 0.01, row["latency_error_s"]
    est = np.genfromtxt(tmp_path / sc.name / "estimate.csv", delimiter=",", names=True)
    t = est["t"]
    assert np.max(np.abs(est["gnss_delay_s"][(t > 1216.0) & (t < 1224.0)] - TRUE_S)) <= 0.006
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]
    assert row["sideslip_worst_valid_deg"] < 1.0, row["sideslip_worst_valid_deg"]
    assert math.isfinite(row["sideslip_worst_valid_deg"])
