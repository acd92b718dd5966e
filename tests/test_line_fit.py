"""line_fit.LineFit against numpy's least squares (with the prior as one more row) on random data."""
import math

import numpy as np
from hypothesis import given, settings, strategies as st

from ecu_daemon.estimator.line_fit import LineFit


def _data(seed: int, n: int, scale_b: float):
    rng = np.random.default_rng(seed)
    a = rng.normal(0.0, 1.0, n)
    b = scale_b + rng.normal(0.0, 0.3, n)
    d = 1.7 * a - 0.4 * b + rng.normal(0.0, 0.1, n)
    return a, b, d


def _fit(a, b, d, lam=0.0) -> LineFit:
    f = LineFit(lam)
    for x, y, z in zip(a, b, d):
        f.add(float(x), float(y), float(z))
    return f


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 200), scale_b=st.floats(-5.0, 5.0))
def test_without_prior_it_is_ordinary_least_squares(seed, n, scale_b):
    a, b, d = _data(seed, n, scale_b)
    f = _fit(a, b, d)
    assert f.solve()
    X = np.column_stack([a, b])
    beta, res, rank, _ = np.linalg.lstsq(X, d, rcond=None)
    assert rank == 2
    np.testing.assert_allclose([f.k, f.c], beta, rtol=1e-7, atol=1e-9)
    rss = float(np.sum((d - X @ beta) ** 2))
    assert math.isclose(f.rss(), rss, rel_tol=1e-6, abs_tol=1e-9)
    var = f.residual_var()
    assert math.isclose(var, rss / (n - 2), rel_tol=1e-6, abs_tol=1e-9)
    cov = var * np.linalg.inv(X.T @ X)
    assert math.isclose(f.k_var(var), cov[0, 0], rel_tol=1e-6)
    assert math.isclose(f.c_var(var), cov[1, 1], rel_tol=1e-6)
    assert math.isclose(f.kc_cov(var), cov[0, 1], rel_tol=1e-6, abs_tol=1e-12 * math.sqrt(cov[0, 0] * cov[1, 1]))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 200), scale_b=st.floats(-5.0, 5.0),
       lam=st.floats(1e-3, 1e3))
def test_the_prior_is_one_more_observation_of_c(seed, n, scale_b, lam):
    """Weighted least squares with the row sqrt(lam) (0, 1) = 0 appended: the same k, c and
    covariance; the residual is the data's alone, over n - 1 degrees of freedom."""
    a, b, d = _data(seed, n, scale_b)
    f = _fit(a, b, d, lam)
    assert f.solve()
    X = np.vstack([np.column_stack([a, b]), [0.0, math.sqrt(lam)]])
    beta, _, _, _ = np.linalg.lstsq(X, np.append(d, 0.0), rcond=None)
    np.testing.assert_allclose([f.k, f.c], beta, rtol=1e-7, atol=1e-9)
    rss = float(np.sum((d - np.column_stack([a, b]) @ beta) ** 2))
    assert math.isclose(f.rss(), rss, rel_tol=1e-6, abs_tol=1e-9)
    var = f.residual_var(floor=0.0)
    assert math.isclose(var, rss / (n - 1), rel_tol=1e-6, abs_tol=1e-9)
    cov = var * np.linalg.inv(X.T @ X)
    assert math.isclose(f.k_var(var), cov[0, 0], rel_tol=1e-6)
    assert math.isclose(f.c_var(var), cov[1, 1], rel_tol=1e-6)
    assert math.isclose(f.kc_cov(var), cov[0, 1], rel_tol=1e-6, abs_tol=1e-12 * math.sqrt(cov[0, 0] * cov[1, 1]))


def test_a_prior_bounds_k_where_the_regressors_are_proportional():
    """A steady circle (a, b in proportion): without a prior nothing is identified (and a relative
    determinant floor says so), with one k is bounded by what the prior allows of c."""
    a = np.full(20, 2.0)
    b = np.full(20, 1.0)
    d = 2.0 * a + 0.01 * np.sin(np.arange(20))
    free = _fit(a, b, d)
    assert not free.solve(min_det_rel=1e-12)
    assert math.isnan(free.k)
    held = _fit(a, b, d, lam=1.0)
    assert held.solve()
    assert math.isfinite(held.k_var(held.residual_var(0.01)))
    assert abs(held.k - 2.0) < 0.1


def test_the_variance_floor_and_an_exact_fit():
    a, b, _ = _data(7, 30, 1.0)
    f = _fit(a, b, 3.0 * a + 0.5 * b)
    assert f.solve()
    assert math.isclose(f.k, 3.0) and math.isclose(f.c, 0.5)
    assert f.rss() >= 0.0
    assert f.residual_var(0.03) == 0.03 * 0.03
