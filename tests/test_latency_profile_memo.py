"""The latency identification keeps a reference's likelihood profile while its statistics are
unchanged (estimator/latency.py, ``LatencyEstimator._profile``): a speed-only change, so the
identification must run to the same bits with and without it, on two attached references as
the estimator feeds them (wheels, then the accelerometer, at every fix)."""
from __future__ import annotations

import math

import numpy as np

from ecu_daemon.estimator.latency import LatencyEstimator

DT = 0.006
FIX_EVERY = 33  # steps: GNSS at ~5 Hz
DELAY_S = 0.35


def speed(t):
    return 15.0 + 3.0 * np.sin(2 * math.pi * t / 7.0) + 1.5 * np.sin(2 * math.pi * t / 2.9)


def identify(memo: bool, fixes: int = 400):
    """Per fix: (delay, std, both cost profiles) as bytes; and how many profiles were computed."""
    wheels = LatencyEstimator(DT, 0.2, max_s=0.8)
    accel = LatencyEstimator(DT, 0.2, max_s=0.8, extra=1)
    wheels.attach(accel)
    computed = [0]
    for lat in (wheels, accel):
        fit = lat._profile_of_statistics

        def counted(fit=fit):
            computed[0] += 1
            return fit()

        lat._profile_of_statistics = counted
        if not memo:
            lat._profile = counted
    rng = np.random.default_rng(4)
    out = []
    cand = (np.arange(wheels.max_steps + 1) + 1) * DT  # candidate delays
    for f in range(1, fixes + 1):
        t_rx = f * FIX_EVERY * DT
        y = float(speed(t_rx - DELAY_S)) + 0.03 * rng.normal()
        # the accelerometer's speed integral (a bias ramp), re-anchored at every fix as
        # SpeedIntegral does: a change of its statistics that neither counts an update nor
        # touches y'y, here seen by the wheels' refinement before the accelerometer's own
        accel.shift((0.0, FIX_EVERY * DT))
        wheels.observe_series(speed(t_rx - cand), y)
        accel.observe_series(speed(t_rx - cand) - 0.1 * cand, y, (0.0,))
        out.append((wheels.delay_s, wheels.std_s, wheels.cost.tobytes(), accel.cost.tobytes()))
    return out, computed[0]


def test_a_kept_profile_gives_the_same_identification_to_the_bit_at_half_the_fits():
    kept, n_kept = identify(memo=True)
    fresh, n_fresh = identify(memo=False)
    assert kept == fresh
    assert abs(kept[-1][0] - DELAY_S) < 0.02 < abs(0.2 - DELAY_S)  # the profiles did move the delay
    # each fix refines twice and reads both profiles each time: 4 fits; the wheels' statistics do
    # not change between the two, so their second fit is kept (in the estimator's own order, the
    # accelerometer's first one too: half)
    assert n_fresh == 4 * 400 and n_kept == 3 * 400
