"""The yaw-rate bias at rest from each gyro sample once, at the scatter the gyro shows
(issue 7, stop 48; ``fusion/standstill.MEASURED_GYRO_R``).

Before: every 6 ms step fused the held sample at R = (2 x max(configured noise, 1e-3))^2, the
configured noise density read as a per-step std, while a 100 Hz sample is held ~10 ms (fused 1-2
times, the same noise each time) and the gyro's own per-sample scatter was not looked at: b_r's std
after a rest came out ~1.5x too small for a gyro of 0.0024 rad/s (drive 2946 of tools/random_drives.py,
written out in test_sideslip_scale_sens.py: b_r z 3.1 at the first row above 5 m/s, 534 valid
sideslip rows beyond 3 sigma). Now only a new sample is fused, at the variance of the gyro's new
samples at rest (half the mean squared difference of consecutive ones).
"""
from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from ecu_daemon.estimator.fusion import standstill
from ecu_daemon.estimator.fusion.standstill import StandstillFusion
from ecu_daemon.estimator.kinematic import BR, NX
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.suite import run_case

DT = 0.006


def rest(sigma: float, bias: float, seconds: float, rng: np.random.Generator, period: float = 0.01):
    """b_r and its std after ``seconds`` at rest: a gyro of per-sample noise ``sigma`` sampled every
    ``period`` (random phase), held between samples, fused at every 6 ms step as core.py does."""
    s = StandstillFusion(DT, 0.0005)
    x = np.zeros(NX)
    P = np.diag([0.5, 0.2, 0.01, 1e-4, 0.01, 0.01, 1e-4, 1e-4])  # b_r's prior std 0.01 rad/s
    A = np.eye(NX)
    t_s = rng.uniform(0.0, period)  # next sample's stamp
    r_t, r_m = -math.inf, 0.0
    for k in range(1, int(seconds / DT) + 1):
        while t_s <= k * DT:
            r_t, r_m = t_s, bias + sigma * rng.standard_normal()
            t_s += period
        if r_t > -math.inf:
            s.fuse(x, P, r_m, 0.0, 0.0, A, r_t)
    return x[BR], math.sqrt(P[BR, BR])


@pytest.mark.parametrize("sigma", [0.0007, 0.0024, 0.0035])
def test_the_bias_learned_at_rest_has_an_honest_std(sigma):
    """Over 60 rests of 4 s: the error over the std has rms ~1 (0.76-1.12; 0.76: the floor 0.001 above a 0.0007 gyro), for the random drives'
    range of gyro noise; with the flag off 0.47, 1.60, 2.38 (one std for every gyro)."""
    rng = np.random.default_rng(7)
    z = [(b - 0.006) / sd for b, sd in (rest(sigma, 0.006, 4.0, rng) for _ in range(60))]
    zrms = math.sqrt(sum(v * v for v in z) / len(z))
    assert 0.7 < zrms < 1.3, zrms


def test_each_sample_counts_once():
    """A sample held over two steps is fused once: the std after N samples is sigma / sqrt(N)."""
    rng = np.random.default_rng(3)
    _, sd = rest(0.003, 0.0, 4.0, rng)
    # ~400 samples, 20 of them only measuring the scatter: sigma / sqrt(380), the scatter within ~10 %
    assert sd == pytest.approx(0.003 / math.sqrt(380), rel=0.15), sd


def test_the_banked_circle_from_rest_keeps_its_sideslip_honest(tmp_path):
    """Drive 2946 (starts at rest 4.5 s): with the flag off (main d90b31e) 534 valid sideslip rows
    beyond 3 sigma (94.7 % within); on, none."""
    sys.path.insert(0, "tests")
    from test_sideslip_scale_sens import BANKED_CIRCLE

    sc = BANKED_CIRCLE
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]


def test_the_flag_switches_the_rule(monkeypatch):
    """Off: the old per-step rule (R = 4 x max(noise, 1e-3)^2 at every step), so the lead can land
    it apart: 667 steps of 4 s give b_r's std 0.002 / sqrt(667), whatever the gyro's scatter."""
    monkeypatch.setattr(standstill, "MEASURED_GYRO_R", False)
    _, sd = rest(0.003, 0.0, 4.0, np.random.default_rng(3))
    assert sd == pytest.approx(0.002 / math.sqrt(666), rel=0.05), sd
