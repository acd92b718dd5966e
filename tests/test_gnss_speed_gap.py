"""The GNSS speed gap's spread at a fix (gnss_speed_gap.spread_since, perf39): the per-step terms the
estimator stores beside the history's aux rows, summed in step order, give the bits of the loop over
the aux rows that it replaced (spread_from_rows), on random rings and on a whole simulated drive."""
from __future__ import annotations

import numpy as np

from ecu_daemon.estimator import Estimator
from ecu_daemon.estimator import core
from ecu_daemon.estimator import gnss_speed_gap as gsg
from ecu_daemon.estimator.history import AUX_AX, AUX_AY, NAUX
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config

from drive_samples import decoded_events

RNG = np.random.default_rng(39)


def _bits(v: float) -> bytes:
    return np.float64(v).tobytes()


def test_the_stored_terms_summed_are_the_aux_rows_loop_bit_for_bit():
    n, dt = 170, 0.006
    for _ in range(200):
        aux = RNG.normal(size=(n, NAUX)) * 10.0 ** RNG.integers(-3, 2, size=(n, NAUX))
        terms = [gsg.term(float(a[AUX_AX]), float(a[AUX_AY]), dt) for a in aux]
        last = int(RNG.integers(n, 5 * n))
        for s in (last - n + 1, int(RNG.integers(last - n + 1, last + 1)), last, last + 1):  # whole ring, any, one, none
            ref = gsg.spread_from_rows(aux, s, last, n, dt, AUX_AX, AUX_AY)
            out = gsg.spread_since(terms, s, last, n)
            assert type(out) is float and _bits(out) == _bits(ref), (s, last)


def test_on_a_whole_drive_the_estimators_terms_give_the_aux_rows_spread():
    assert core.GNSS_SPEED_GAP
    sc = SCENARIOS["dlc_dry"]
    cfg = vehicle_config(sc)
    est = Estimator(cfg)
    checked = 0
    for t, kind, s in decoded_events(cfg, simulate(sc, cfg)):
        (est.push_gnss if kind else est.push_input)(s)
        est.advance_to(t - 1e-6)
        h = est.hist
        if est.initialized and h.last % 37 == 0 and h.last >= h.first:
            for s0 in range(h.oldest(), h.last + 1, 7):
                ref = gsg.spread_from_rows(h.aux, s0, h.last, h.n, est.dt, AUX_AX, AUX_AY)
                assert _bits(gsg.spread_since(est.gap_terms, s0, h.last, h.n)) == _bits(ref), (h.last, s0)
                checked += 1
    assert checked > 1000 and est.gnss.fused > 50
