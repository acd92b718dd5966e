"""Issue 10 (perf45): the latency refinement's reading of its profile, compiled, gives numpy's bits.

``LatencyEstimator._refine`` (three times a GNSS fix) read its summed likelihood-ratio profile with
~12 numpy calls on ~160 values (argmin, ``lr - lr[i]``, ``flatnonzero(share * lr < LR_REJECT)``, the
scalar reads); ``latency.refine_scan`` is those statements (the numpy reference) or ``_kernels.c``'s
one pass. Each is an elementwise operation or numpy's argmin (the first minimum, the first NaN), so
the compiled one is held to the reference's values here, bit for bit, on random profiles (ties,
zeros of both signs, NaN, inf, the minimum at either end, an empty set) and on a drive.
"""
from __future__ import annotations

import math
import struct
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ecu_daemon.estimator import backend, latency

sys.path.insert(0, str(Path(__file__).resolve().parent))
from drive_samples import scenario_estimates  # noqa: E402

needs_compiled = pytest.mark.skipif(backend.compiled is None, reason="compiled kernels not built")


def _bits(v):
    """A scan's result as comparable bits: floats by their IEEE bytes (-0.0 and NaN payloads count)."""
    if v is None or isinstance(v, type):
        return v
    return tuple(struct.pack("<d", x) if isinstance(x, float) else (type(x), x) for x in v)


def _outcome(fn, lr, share, cur):
    try:
        return _bits(fn(lr.copy(), share, latency.LR_REJECT, cur))
    except IndexError:
        return IndexError


def _agree(lr, share, cur):
    want = _outcome(latency.refine_scan_reference, lr, share, cur)
    got = _outcome(backend.compiled.refine_scan, lr, share, cur)
    assert got == want, (lr, share, cur)
    return want


@needs_compiled
def test_random_profiles_give_the_reference_bits():
    rng = np.random.default_rng(45)
    seen = {"none": 0, "scan": 0, "empty": 0}
    for t in range(3000):
        n = int(rng.integers(3, 200))
        lr = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 4)
        if t % 3 == 0:
            lr = np.round(lr)  # ties: the first minimum
        if t % 5 == 0:
            lr[rng.random(n) < 0.3] = 0.0 if t % 2 else -0.0
        if t % 7 == 0:
            lr[int(rng.integers(n))] = (np.nan, np.inf, -np.inf)[t % 3]
        if t % 11 == 0:
            lr[int(rng.integers(2))] = -1e9  # the best at either end: None
            lr = lr if t % 2 else lr[::-1].copy()
        share = float(rng.uniform(0.3, 1.0)) if t % 13 else (math.inf if t % 2 else math.nan)
        out = _agree(lr, share, int(rng.integers(n)))
        seen["none" if out is None else "empty" if out is IndexError else "scan"] += 1
    assert min(seen.values()) > 10, seen


@needs_compiled
@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, st.integers(3, 40), elements=st.floats(allow_nan=True, allow_infinity=True)),
       st.floats(0.0, 2.0) | st.sampled_from([math.inf, math.nan]), st.data())
def test_any_profile_gives_the_reference_bits(lr, share, data):
    _agree(lr, share, data.draw(st.integers(0, len(lr) - 1)))


@needs_compiled
def test_a_drive_gives_the_same_estimates_with_the_numpy_scan(monkeypatch):
    with backend.selected(True):
        assert latency.refine_scan is backend.compiled.refine_scan
        calls = []
        compiled = latency.refine_scan

        def counted(*a):
            out = compiled(*a)
            calls.append(out is not None)
            return out

        monkeypatch.setattr(latency, "refine_scan", counted)
        fast = scenario_estimates("dlc_dry", 20.0)
        assert sum(calls) > 50  # the refinements read their profiles
        monkeypatch.setattr(latency, "refine_scan", latency.refine_scan_reference)
        slow = scenario_estimates("dlc_dry", 20.0)
    assert len(fast) == len(slow) > 1000
    assert fast == slow
