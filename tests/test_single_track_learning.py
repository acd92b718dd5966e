"""Cornering-compliance learning (fusion/single_track.py): what its model-error estimate learns from,
what it takes from the per-drive regression, and what the learned-state file carries over."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.core import LEARNED_VERSION, Estimator
from ecu_daemon.estimator.fusion.single_track import SingleTrackFusion
from ecu_daemon.io.state_store import load_state, save_state

M, IZ, LF, LR, CF, CR = 1500.0, 2500.0, 1.2, 1.5, 100e3, 120e3


def _fusion() -> SingleTrackFusion:
    return SingleTrackFusion(M, IZ, LF, LR, CF, CR, adapt=True)


def test_a_regressor_buried_in_the_vy_noise_does_not_inflate_the_model_error():
    # nearly straight (0.005 g): a slip term of 0.005 m/s under vy noise of 0.1 m/s; residuals
    # of that noise over so small a regressor once read as a 1000 % model error
    st = _fusion()
    rel0 = st.rear.rel_var
    vx, ay = 18.0, 0.05
    r = ay / vx
    vy = LR * r + (M / CR) * st.regressor_rear(vx, ay, 0.0)
    for i in range(200):
        st.adapt_from(vx, vy + (0.1 if i % 2 else -0.1), 0.05 ** 2, r, ay, 0.0, math.nan)
    assert st.rear.rel_var <= rel0


def _taught() -> SingleTrackFusion:
    """A model whose rear compliance a drive has taught: 5 % std, correlated with k3."""
    st = _fusion()
    k = M / CR
    st.rear.k[:] = (1.1 * k, 0.3 * k)
    st.rear.P = np.array([[(0.05 * k) ** 2, -0.5 * 0.05 * 0.1 * k * k], [-0.5 * 0.05 * 0.1 * k * k, (0.1 * k) ** 2]])
    st.rear.rel_var = (0.1 * k) ** 2
    return st


def test_the_learned_state_file_carries_the_stiffness_uncertainty(tmp_path):
    # saved and loaded as the daemon does (estimator key check, JSON file): the model restored
    # from it is as certain as the one that saved it -- it used to restart at its 40 % prior
    st = _taught()
    learned = {"version": LEARNED_VERSION, **st.learned()}
    save_state(tmp_path / "state.json", learned)
    restored = Estimator._check_learned(load_state(tmp_path / "state.json"))
    again = SingleTrackFusion(M, IZ, LF, LR, CF, CR, adapt=True, learned=restored)
    np.testing.assert_allclose(again.rear.k, st.rear.k, rtol=1e-12)
    np.testing.assert_allclose(again.rear.P, st.rear.P, rtol=1e-9)
    assert again.rear.rel_var == pytest.approx(st.rear.rel_var, rel=1e-9)
    args = (25.0, 0.2, 5.0, 0.0)
    assert again.pseudo_measurement(*args) == pytest.approx(st.pseudo_measurement(*args), rel=1e-9)
    assert again.pseudo_measurement(*args)[1] < 0.3 * _fusion().pseudo_measurement(*args)[1]


def test_a_state_file_without_the_uncertainty_restores_the_stiffness_at_the_prior_std():
    # files written before the std keys: the value is taken, trusted no more than the config
    k = M / CR
    st = SingleTrackFusion(M, IZ, LF, LR, CF, CR, adapt=True,
                           learned={"version": LEARNED_VERSION, "kappa_r": 1.1 * k, "kappa_r3": 0.5 * k})
    assert st.rear.k[0] == 1.1 * k
    np.testing.assert_allclose(st.rear.P, np.diag([(0.4 * 1.1 * k) ** 2, (0.8 * 1.1 * k) ** 2]))
    assert Estimator._check_learned({"version": LEARNED_VERSION, "kappa_r_std": -1.0, "kappa_r_corr": 3.0}) \
        == {"version": LEARNED_VERSION}  # out of range: dropped


def test_a_restored_uncertainty_is_bounded_by_a_floor_and_the_prior():
    k = M / CR
    tight = SingleTrackFusion(M, IZ, LF, LR, CF, CR, adapt=True, learned={
        "kappa_r": k, "kappa_r_std": 1e-9, "kappa_r3_std": 1e-9, "kappa_r_corr": 0.0, "kappa_r_model_std": 1e-9})
    assert tight.rear.P[0, 0] == pytest.approx((0.03 * k) ** 2) and tight.rear.rel_var == pytest.approx((0.03 * k) ** 2)
    wide = SingleTrackFusion(M, IZ, LF, LR, CF, CR, adapt=True, learned={
        "kappa_r": k, "kappa_r_std": 1.0, "kappa_r3_std": 1.0, "kappa_r_corr": 0.0, "kappa_r_model_std": 1.0})
    np.testing.assert_allclose(wide.rear.P, wide.rear.P0)
    assert wide.rear.rel_var == pytest.approx((0.3 * k) ** 2)


def test_the_model_takes_a_drive_estimate_only_when_it_is_the_more_certain():
    k = M / CR
    st = _fusion()
    sure = ((1.2 * k, 0.2 * k), np.diag([(0.05 * k) ** 2, (0.2 * k) ** 2]), 0.1 ** 2)
    st.take_drive_estimate((((0.8 * k, 0.0), np.diag([(0.5 * k) ** 2, k * k]), None), None))  # less certain
    assert st.rear.k[0] == k
    st.take_drive_estimate((sure, None))
    assert st.rear.k[0] == 1.2 * k and st.rear.P[0, 0] == (0.05 * k) ** 2
    assert st.rear.rel_var == pytest.approx((0.1 * 1.2 * k) ** 2)  # the law's error the drive showed
    # from then on the model follows the drive estimate (even a less certain one: the same drive,
    # revised) and no longer learns from the filter's vy, which it holds itself
    st.take_drive_estimate((((1.15 * k, 0.2 * k), np.diag([(0.08 * k) ** 2, (0.2 * k) ** 2]), None), None))
    assert st.rear.k[0] == 1.15 * k and st.rear.from_drive
    n = st.rear.updates
    st.adapt_from(20.0, 0.3, 0.01 ** 2, 0.2, 4.0, 0.0, 0.0)
    assert st.rear.updates == n and st.rear.k[0] == 1.15 * k
    off = SingleTrackFusion(M, IZ, LF, LR, CF, CR, adapt=False)
    off.take_drive_estimate((sure, sure))  # adaptation switched off in the config: the config stands
    assert off.rear.k[0] == k and off.front.k[0] == M / CF


def _var(st: SingleTrackFusion, vx: float, ay: float, once: bool = True) -> tuple[float, float, float]:
    """(predicted slip variance, its regressors h0 = phi and h1 = phi n^2) of the rear axle, steady;
    ``once``: as the published bound (model_error) counts it, else as the filter's pseudo-measurement."""
    phi = st.regressor_rear(vx, ay, 0.0)
    n2 = (ay / 9.81) ** 2
    return st.rear.predict(phi, n2, once)[1], phi, phi * n2


def test_an_untaught_axle_counts_the_law_error_once():
    # a 10 m circle at 6.3 m/s (0.4 g), the configured stiffness untaught (k1 unobservable there):
    # the configuration's prior is the stated law's whole error (a stated stiffness is a fit that
    # includes the law's shape error); the law's own error stacked on it made the slip 0.5
    # relative uncertain, the sideslip invalid from ~0.4 g on while right
    st = _fusion()
    P0, rel0 = st.rear.P0, st.rear.rel_var0
    var, h0, h1 = _var(st, 6.3, 4.0)
    assert var == pytest.approx(h0 * h0 * P0[0, 0] + h1 * h1 * P0[1, 1], rel=1e-12)
    vy, s = st.model_error(6.3, 4.0 / 6.3, 4.0, 0.0)  # the published bound: prior, k3, floor
    assert s == pytest.approx(math.sqrt(var + (st.base_sigma_beta * 6.3) ** 2), rel=1e-12)
    # the filter's pseudo-measurement keeps both (its weight gates the live RLS: adapt_from)
    assert _var(st, 6.3, 4.0, False)[0] == pytest.approx(var + h0 * h0 * rel0, rel=1e-12)
    # beyond the fitted range (0.6 g) the law is an extrapolation: its error stays on top
    var, h0, h1 = _var(st, 7.9, 6.4)
    assert var == pytest.approx(h0 * h0 * (P0[0, 0] + rel0) + h1 * h1 * P0[1, 1], rel=1e-12)
    # a taught axle (k1 fitted to 5 %) keeps the law's error apart, as it was
    t = _taught()
    var, h0, h1 = _var(t, 6.3, 4.0)
    P = t.rear.P
    assert var == pytest.approx(h0 * h0 * (P[0, 0] + t.rear.rel_var) + 2 * h0 * h1 * P[0, 1] + h1 * h1 * P[1, 1],
                                rel=1e-12)


def test_learning_never_widens_the_model_error_and_residuals_can():
    st = _fusion()
    untaught = _var(st, 20.0, 3.0)[0]
    k = M / CR
    vx, ay = 20.0, 3.0
    vy = LR * ay / vx + k * st.regressor_rear(vx, ay, 0.0) * (1.0 + 0.6 * (ay / 9.81) ** 2)
    st.adapt_from(vx, vy, 0.05 ** 2, ay / vx, ay, 0.0, math.nan)  # one consistent RLS step
    assert st.rear.updates == 1 and st.rear.P[0, 0] < st.rear.P0[0, 0]
    assert _var(st, 20.0, 3.0)[0] <= untaught
    # residuals that show the law worse than its prior (twice its std) count on top of the prior
    st.rear.rel_var = 4.0 * st.rear.rel_var0
    assert _var(st, 20.0, 3.0)[0] > untaught


def test_live_rls_learns_only_where_the_data_saw_vy():
    """learn14: in a steady single-antenna corner only the model holds vy (a heading error, vy off
    by vx d_psi and a body-fixed accelerometer bias explain the same fixes): no RLS step there; a
    transient (the lateral load changed by half within the window) or a fresh dual-antenna heading
    lets it learn."""
    from ecu_daemon import config as config_mod
    from ecu_daemon.estimator.core import LEARN_EXCITE_FIXES
    est = Estimator(config_mod.Config())
    k, dt = 100_000, est.dt
    steady = [est._vy_seen_by_data(k + 33 * i, 15.0, 3.0, 0.0) for i in range(3 * LEARN_EXCITE_FIXES)]
    assert not any(steady)
    assert est._vy_seen_by_data(k + 33 * 3 * LEARN_EXCITE_FIXES, 15.0, 6.0, 0.0)  # a transient
    est.learn_phi.clear()
    est.last_heading_fused_t = (k + 1000) * dt  # a second antenna measures the heading
    assert est._vy_seen_by_data(k + 1000, 15.0, 3.0, 0.0)
    st = _fusion()
    vx, ay = 20.0, 3.0
    st.adapt_from(vx, 0.01, 0.05 ** 2, ay / vx, ay, 0.0, math.nan, False)
    assert st.rear.updates == 0
    st.adapt_from(vx, 0.01, 0.05 ** 2, ay / vx, ay, 0.0, math.nan, True)
    assert st.rear.updates == 1
