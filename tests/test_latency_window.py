"""Issue 10 (perf44): the GNSS fix's window over the candidate delays, compiled, gives numpy's bits.

``LatencyEstimator.observe`` read its window (the wheels' speed, the speed's rate, the ratio's vy
error over ~160 candidate delays) and ``SpeedIntegral.observe`` its regressor with ~25 numpy calls
and gathers of whole history rows per fix; ``latency.latency_window`` and ``latency.speed_window``
are those statements (the numpy references) or ``_kernels.c``'s one pass each. Elementwise, each
operation numpy's (``hypot`` is libm's in both), so the compiled ones are held to the references'
bits here: on random histories (NaN, inf, negative variances, the ring's wrap) and on a drive.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from ecu_daemon.estimator import backend, latency
from ecu_daemon.estimator.fusion.wheel_speed import SLIP_PER_MPS2

sys.path.insert(0, str(Path(__file__).resolve().parent))
from drive_samples import scenario_estimates  # noqa: E402

needs_compiled = pytest.mark.skipif(backend.compiled is None, reason="compiled kernels not built")


def _history(rng, n: int, t: int):
    X = rng.standard_normal((n, 8)) * np.array([15.0, 1.5, 3.0, 0.01, 0.1, 0.1, 0.01, 0.1])
    X[:, 0] += 10.0
    aux = rng.standard_normal((n, 6)) * np.array([0.5, 3.0, 1.0, 2.0, 0.1, 3.0])
    aux[:, 3] += 12.0  # the wheels' speed, m/s
    P = rng.standard_normal((n, 8, 8)) * 10.0 ** rng.uniform(-6, 0, (n, 8, 8))
    if t % 3 == 0:
        X[rng.random(n) < 0.1, :2] = 0.0  # |v| below 1 m/s: the rate's denominator held at 1
    if t % 4 == 0:
        P[rng.random(n) < 0.1, 1, 1] = -0.0 if t % 8 else np.nan
    if t % 5 == 0:
        aux[int(rng.integers(n)), 3] = (np.nan, np.inf, 1.0)[t % 3]  # no fix: None
    if t % 7 == 0:
        X[int(rng.integers(n)), 1] = np.inf
    return X, aux, P


@needs_compiled
def test_latency_window_is_the_references_bits():
    rng = np.random.default_rng(44)
    nones = 0
    for t in range(600):
        n = int(rng.integers(170, 260))
        count = int(rng.integers(3, 168))
        X, aux, P = _history(rng, n, t)
        last = int(rng.integers(-3 * n, 3 * n))  # negative and wrapping slots
        lever_x = float(rng.standard_normal())
        slip = SLIP_PER_MPS2 if t % 2 else None
        outs = []
        for fn in (latency.latency_window_reference, backend.compiled.latency_window):
            x, rate = np.full(count, 7.0), np.full(count, 7.0)
            with np.errstate(invalid="ignore"):  # inf - inf, 0 * inf: NaN, as the window's test expects
                err = fn(X, aux, P, last, lever_x, slip, latency.MIN_SPEED, x, rate)
            outs.append((err, x, rate))
        (e0, x0, r0), (e1, x1, r1) = outs
        if e0 is None:
            nones += 1
            assert e1 is None, t
            continue
        assert type(e1) is float and (e0 == e1 or (np.isnan(e0) and np.isnan(e1))), (t, e0, e1)
        assert x0.tobytes() == x1.tobytes() and r0.tobytes() == r1.tobytes(), t
    assert 30 < nones < 300


@needs_compiled
def test_speed_window_is_the_references_bits():
    rng = np.random.default_rng(45)
    for t in range(600):
        n = int(rng.integers(140, 200))
        count = int(rng.integers(1, n))
        v = np.cumsum(rng.standard_normal(n)) * 10.0 ** rng.uniform(-2, 3)
        vel = rng.standard_normal((n, 3)) * np.array([20.0, 2.0, 0.5])
        if t % 6 == 0:
            vel[rng.random(n) < 0.1] = 0.0
        lever = (float(rng.standard_normal()), float(rng.standard_normal()))
        last, total = int(rng.integers(-2 * n, 5 * n)), float(rng.standard_normal() * 100.0)
        want, got = np.empty(count), np.empty(count)
        latency.speed_window_reference(v, vel, last, total, *lever, want)
        assert backend.compiled.speed_window(v, vel, last, total, *lever, got) is None
        assert want.tobytes() == got.tobytes(), t


@needs_compiled
def test_a_drive_gives_the_same_estimates_with_the_numpy_windows(monkeypatch):
    with backend.selected(True):
        assert latency.latency_window is backend.compiled.latency_window
        calls = []
        compiled = (latency.latency_window, latency.speed_window)

        def counted(*a):
            out = compiled[0](*a)
            calls.append(out is not None)
            return out

        monkeypatch.setattr(latency, "latency_window", counted)
        fast = scenario_estimates("dlc_dry", 20.0)
        assert sum(calls) > 50  # the fixes' windows were read (and the accelerometer's with them)
        monkeypatch.setattr(latency, "latency_window", latency.latency_window_reference)
        monkeypatch.setattr(latency, "speed_window", latency.speed_window_reference)
        slow = scenario_estimates("dlc_dry", 20.0)
    assert len(fast) == len(slow) > 1000
    assert fast == slow
