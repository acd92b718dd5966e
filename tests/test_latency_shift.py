"""Issue 10 (perf43): the GNSS latency path's replacements of library calls give the library's bits.

``LatencyEstimator.shift`` re-anchors the accelerometer's statistics at every fix; it was two
einsums (6 % of all instructions on random drive 1442 with 10 Hz GNSS, plain Python) and is now
``latency.shift_statistics`` (the reference in numpy, or ``_kernels.c``'s), the einsums' products
in their order; ``_antenna_to_wheel``'s ``np.nan_to_num`` is :func:`latency.nan_to_num`, and the
refinement's ``np.sum`` of the profiles :func:`latency.profile_sum`. Each is compared here with
the library call it replaces, on random data and on a real drive (with the einsums forced back:
the same estimates to the bit), so a numpy whose einsum sums in another order fails here, not in
a replay's bytes.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from ecu_daemon.estimator import backend, latency
from ecu_daemon.estimator.latency import LatencyEstimator, nan_to_num, profile_sum, shift_statistics_reference

sys.path.insert(0, str(Path(__file__).resolve().parent))
from drive_samples import scenario_estimates  # noqa: E402


def einsum_shift(zz: np.ndarray, zy: np.ndarray, offsets) -> tuple[np.ndarray, np.ndarray]:
    """LatencyEstimator.shift as it was (main 7f4496e): the reference."""
    p = zz.shape[1]
    m = np.eye(p)
    m[:-1, -1] = -np.asarray(offsets, dtype=float)
    return (np.ascontiguousarray(np.einsum("ij,kjl,ml->kim", m, zz, m)),
            np.ascontiguousarray(np.einsum("ij,kj->ki", m, zy)))


def random_statistics(rng, k: int, p: int, t: int):
    zz = rng.standard_normal((k, p, p)) * 10.0 ** rng.uniform(-3, 8, size=(k, p, p))
    zz = zz + zz.transpose(0, 2, 1)
    if t % 7 == 0:
        zz[rng.random((k, p, p)) < 0.2] = 0.0
    if t % 11 == 0:
        zz[rng.random((k, p, p)) < 0.2] = -0.0
    zy = rng.standard_normal((k, p)) * 10.0 ** rng.uniform(-3, 6, size=(k, p))
    if t % 5 == 0:
        zy[rng.random((k, p)) < 0.3] = -0.0
    off = tuple(float(v) for v in rng.standard_normal(p - 1) * 10.0 ** rng.uniform(-4, 4, size=p - 1))
    if t % 13 == 0:
        off = tuple(0.0 if rng.random() < 0.5 else -0.0 for _ in off)
    return zz, zy, off


IMPLEMENTATIONS = [shift_statistics_reference] + ([backend.compiled.shift_statistics] if backend.compiled else [])


@pytest.mark.parametrize("shift", IMPLEMENTATIONS)
@pytest.mark.parametrize("p", [3, 4])
def test_shift_statistics_are_the_einsums_bits(p, shift):
    rng = np.random.default_rng(43 + p)
    for t in range(400):
        k = int(rng.integers(1, 700))  # the estimator's 134-168 candidates and beyond numpy's 8192-element buffer
        zz, zy, off = random_statistics(rng, k, p, t)
        want = einsum_shift(zz, zy, off)
        assert shift(zz, zy, off) is True
        assert zz.tobytes() == want[0].tobytes() and zy.tobytes() == want[1].tobytes(), (t, k)


@pytest.mark.parametrize("shift", IMPLEMENTATIONS)
def test_shift_keeps_the_einsums_where_the_products_would_differ(shift):
    rng = np.random.default_rng(2)
    zz, zy, off = random_statistics(rng, 50, 3, 1)
    before = zz.tobytes(), zy.tobytes()
    assert shift(zz, zy, (off[0], float("inf"))) is False
    bad = zz.copy()
    bad[3, 1, 2] = float("nan")
    assert shift(bad, zy, off) is False
    assert (zz.tobytes(), zy.tobytes()) == before  # nothing written
    # and the method gives the einsums' bits whichever path it takes (2 regressors: numpy's einsum
    # sums in another order there, so the method keeps it)
    for p, zz_, zy_, off_ in ((3, bad, zy, off), (2,) + random_statistics(rng, 50, 2, 1)):
        lat = LatencyEstimator(0.006, 0.3, 0.8, extra=p - 2)
        lat.zz, lat.zy = zz_.copy(), zy_.copy()
        want = einsum_shift(lat.zz, lat.zy, off_)
        lat.shift(off_)
        assert lat.zz.tobytes() == want[0].tobytes() and lat.zy.tobytes() == want[1].tobytes()
    assert latency.shift_bits_match()


def test_profile_sum_is_numpys_sum_over_the_stack():
    rng = np.random.default_rng(3)
    for t in range(3000):
        k, n = int(rng.integers(1, 5)), int(rng.integers(1, 300))
        rows = [rng.standard_normal(n) * 10.0 ** rng.uniform(-5, 5, n) for _ in range(k)]
        for r in rows:
            r[rng.random(n) < 0.1] = -0.0
            r[rng.random(n) < 0.05] = 0.0
        profiles = [(r, False, 1.0) for r in rows]
        assert profile_sum(profiles).tobytes() == np.sum([p[0] for p in profiles], axis=0).tobytes()


def test_nan_to_num_is_numpys():
    rng = np.random.default_rng(7)
    special = np.array([np.nan, -np.nan, np.inf, -np.inf, 0.0, -0.0, 5e-324, -5e-324, 1.7976931348623157e308])
    for t in range(2000):
        n = int(rng.integers(1, 40))
        d = rng.standard_normal(n) * 10.0 ** rng.uniform(-300, 300, n)
        mask = rng.random(n) < 0.3
        d[mask] = rng.choice(special, int(mask.sum()))
        if t % 3 == 0:
            d = d[::2]  # a strided column, as aux[:, AUX_DELTA] is
        got, want = nan_to_num(d), np.nan_to_num(d)
        assert got.dtype == want.dtype and got.shape == want.shape and got.tobytes() == want.tobytes()


def _estimates_of_dlc_dry(seconds: float) -> tuple[list, int]:
    """dlc_dry's first ``seconds`` through a real Estimator: every estimate's repr, and how many
    re-anchorings (with the probe's) took ``latency.shift_statistics``."""
    taken = [0]
    fast = latency.shift_statistics

    def counted(*a):
        out = fast(*a)
        taken[0] += out
        return out

    latency.shift_statistics = counted
    try:
        out = scenario_estimates("dlc_dry", seconds)
    finally:
        latency.shift_statistics = fast
    return out, taken[0]


def test_a_drive_gives_the_same_estimates_with_the_einsums(monkeypatch):
    fast, n_fast = _estimates_of_dlc_dry(30.0)
    assert n_fast > 50 + 8  # beyond the probe's 8: the accelerometer's statistics at its fixes
    monkeypatch.setattr(latency, "shift_statistics", lambda *a: False)  # every shift by the einsums
    slow, n_slow = _estimates_of_dlc_dry(30.0)
    assert n_slow == 0 and len(fast) == len(slow) > 1000
    assert fast == slow
