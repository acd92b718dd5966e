"""The compiled estimator kernels against their pure-Python references: each kernel alone on
random inputs, and a whole simulated drive both ways (within 1e-9, and byte-identical twice)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from ecu_daemon.estimator import Estimator, backend, kalman
from ecu_daemon.estimator import latency_sensitivity as ls
from ecu_daemon.estimator import latency
from ecu_daemon.estimator import lever_arm_check as lac
from ecu_daemon.estimator.fusion import single_track as st
from ecu_daemon.estimator.fusion import stiffness_regression as sr
from ecu_daemon.estimator.history import AUX_AY, AUX_R, NAUX, StepHistory, positive_definite
from ecu_daemon.estimator.kinematic import NX, KinematicModel
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config

from drive_samples import decoded_events

RNG = np.random.default_rng(7)


def spd(scale=1.0):
    a = RNG.normal(size=(NX, NX))
    return scale * (a @ a.T + 0.1 * np.eye(NX))


def test_the_compiled_kernels_are_built_and_active():
    """pip install builds them (setup.py); a silent fallback would hide a broken build."""
    assert backend.compiled is not None, backend._import_error
    assert backend.active() == "compiled"


def test_without_the_extension_one_log_line_and_the_reference_runs():
    """A process where ``_kernels`` cannot be imported: one warning naming why, then it works."""
    code = ("import sys, logging; sys.modules['ecu_daemon.estimator._kernels'] = None\n"
            "logging.basicConfig(level=logging.INFO, format='%(levelname)s %(message)s')\n"
            "from ecu_daemon import config\nfrom ecu_daemon.estimator import Estimator, backend\n"
            "Estimator(config.load(None)); Estimator(config.load(None)); print(backend.active())")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "reference"
    lines = [ln for ln in r.stderr.splitlines() if "kernels" in ln]
    assert len(lines) == 1 and lines[0].startswith("WARNING") and "reference" in lines[0], r.stderr
    assert "Traceback" not in r.stderr


def _both(fn):
    """fn() under the reference and under the compiled kernels."""
    with backend.selected(False):
        ref = fn()
    with backend.selected(True):
        out = fn()
    return ref, out


def test_predict_agrees():
    m = KinematicModel(0.006, 0.5, 0.01, 1e-4, 1e-3, 1e-4)
    x0 = np.array([20.0, 0.3, 6.2, 0.01, 0.1, -0.2, 1.01, 0.02])
    P0 = spd(0.01)

    def run():
        x, P, Po = x0.copy(), P0.copy(), np.empty((NX, NX))
        m.predict(x, P, Po, -0.5, 1.0, 3.0)  # turns psi past 2 pi: wrapped the same way
        return x, Po, m.F.copy()

    (xr, Pr, Fr), (xc, Pc, Fc) = _both(run)
    np.testing.assert_allclose(xc, xr, rtol=0, atol=1e-15)
    assert 0.0 <= xc[2] < 2 * np.pi
    np.testing.assert_allclose(Pc, Pr, rtol=1e-14, atol=1e-18)
    np.testing.assert_array_equal(Fc, Fr)


def test_predict_from_is_the_two_copies_and_predict():
    """The step's predict from the previous slot (x <- x_prev, predict, A <- F) in one call: the
    compiled one gives the same bits as the compiled predict around numpy's copies, and agrees
    with the reference; the previous slot is left as it was."""
    m = KinematicModel(0.006, 0.5, 0.01, 1e-4, 1e-3, 1e-4)
    X = np.array([[20.0, 0.3, 6.2, 0.01, 0.1, -0.2, 1.01, 0.02], np.full(NX, np.nan)])
    P = np.stack([spd(0.01), np.full((NX, NX), np.nan)])
    A = np.full((2, NX, NX), np.nan)

    def run(one_call):
        x, Pn, An = X.copy(), P.copy(), A.copy()
        if one_call:
            m.predict_from(x[0], x[1], Pn[0], Pn[1], An[1], -0.5, 1.0, 3.0)
        else:
            x[1] = x[0]
            m.predict(x[1], Pn[0], Pn[1], -0.5, 1.0, 3.0)
            An[1] = m.F
        return x, Pn, An

    for use_compiled in (False, True):
        with backend.selected(use_compiled):
            x, Pn, An = run(True)
            xs, Ps, As = run(False)
        assert x.tobytes() == xs.tobytes() and Pn.tobytes() == Ps.tobytes() and An.tobytes() == As.tobytes()
        assert X[0].tobytes() == x[0].tobytes() and P[0].tobytes() == Pn[0].tobytes()
    (xr, Pr, Ar), (xc, Pc, Ac) = _both(lambda: run(True))
    np.testing.assert_allclose(xc, xr, rtol=0, atol=1e-15)
    np.testing.assert_allclose(Pc[1], Pr[1], rtol=1e-14, atol=1e-18)
    np.testing.assert_array_equal(Ac, Ar)


@pytest.mark.parametrize("gate", [0.0, 3.0])
def test_scalar_and_index_updates_agree(gate):
    x0 = RNG.normal(size=NX)
    P0 = spd()
    A0 = RNG.normal(size=(NX, NX))
    h = RNG.normal(size=NX)

    def run():
        out = []
        for innov in (0.3, 50.0):  # the second one beyond a 3-sigma gate
            x, P, A = x0.copy(), P0.copy(), A0.copy()
            ok1 = kalman.scalar_update(x, P, innov, h, 0.2, gate, A)
            ok2 = kalman.index_update(x, P, innov, 3, 0.1, gate, A)
            kalman.symmetrize(P)
            out.append((ok1, ok2, x, P, A))
        return out

    for (o1, o2, xr, Pr, Ar), (c1, c2, xc, Pc, Ac) in zip(*_both(run)):
        assert (o1, o2) == (c1, c2)
        np.testing.assert_allclose(xc, xr, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(Pc, Pr, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(Ac, Ar, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(Pc, Pc.T)
    assert run()[1][:2] == ((False, False) if gate else (True, True))


def test_index_update_is_the_scalar_update_with_a_unit_row():
    for compiled in (False, True):
        with backend.selected(compiled):
            x, P, A = RNG.normal(size=NX), spd(), RNG.normal(size=(NX, NX))
            x2, P2, A2 = x.copy(), P.copy(), A.copy()
            kalman.index_update(x, P, 0.4, 5, 0.3, 0.0, A)
            kalman.scalar_update(x2, P2, 0.4, np.eye(NX)[5], 0.3, 0.0, A2)
            np.testing.assert_allclose(x, x2, rtol=1e-12, atol=1e-13)
            np.testing.assert_allclose(P, P2, rtol=1e-12, atol=1e-13)
            np.testing.assert_allclose(A, A2, rtol=1e-12, atol=1e-13)


def test_update_is_joseph_form():
    """The stored covariance is (I - K h') P (I - K h')' + K R K', exactly symmetric after the
    step's symmetrize, and stays positive definite where P - K h' P would not (a tiny R against
    a huge variance: the subtraction cancels all digits)."""
    for compiled in (False, True):
        with backend.selected(compiled):
            P = np.diag([1e8, 1.0, 1.0, 1e-6, 1.0, 1.0, 1e-4, 1.0])
            P[0, 1] = P[1, 0] = 9999.0
            x = np.zeros(NX)
            h = np.eye(NX)[0]
            K = P @ h / (P[0, 0] + 1e-10)
            I_Kh = np.eye(NX) - np.outer(K, h)
            want = I_Kh @ P @ I_Kh.T + 1e-10 * np.outer(K, K)
            kalman.scalar_update(x, P, 1.0, h, 1e-10)
            kalman.symmetrize(P)
            np.testing.assert_allclose(P, want, rtol=1e-9, atol=1e-12)
            np.testing.assert_array_equal(P, P.T)
            assert P[0, 0] > 0.0 and np.linalg.eigvalsh(P).min() > 0.0


@pytest.mark.parametrize("m", [1, 2])
def test_late_update_agrees_and_is_the_joseph_reduction(m):
    P0 = spd()
    H = RNG.normal(size=(m, NX))
    R = np.diag(RNG.uniform(0.1, 0.5, m))
    y = RNG.normal(size=m)

    def run():
        dx, M = np.zeros(NX), np.zeros((NX, NX))
        nis = kalman.late_update(P0.copy(), H, R, y, dx, M)
        return nis, dx, M

    (nr, dxr, Mr), (nc, dxc, Mc) = _both(run)
    S = H @ P0 @ H.T + R
    K = P0 @ H.T @ np.linalg.inv(S)
    assert nc == pytest.approx(float(y @ np.linalg.solve(S, y)), rel=1e-12) and nr == pytest.approx(nc, rel=1e-12)
    np.testing.assert_allclose(dxc, K @ y, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(dxr, dxc, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(Mc, K @ S @ K.T, rtol=1e-9, atol=1e-12)  # = P - Joseph(P) at the optimal K
    np.testing.assert_allclose(Mr, Mc, rtol=1e-10, atol=1e-13)
    assert np.array_equal(Mc, Mc.T) and np.array_equal(Mr, Mr.T)


def test_late_update_without_a_positive_innovation_covariance_is_nan():
    for compiled in (False, True):
        with backend.selected(compiled):
            P = np.zeros((NX, NX))
            dx, M = np.zeros(NX), np.zeros((NX, NX))
            nis = kalman.late_update(P, np.ones((2, NX)), np.zeros((2, 2)), np.ones(2), dx, M)
            assert nis != nis


def _history(n=40, last=100):
    h = StepHistory(n)
    h.reset(last - n + 1)
    h.last = last
    for k in range(h.oldest(), last + 1):
        i = h.slot(k)
        h.X[i] = RNG.normal(size=NX)
        h.X[i, 2] = RNG.uniform(0, 2 * np.pi)
        h.P[i] = spd()
        h.A[i] = np.eye(NX) + 0.02 * RNG.normal(size=(NX, NX))
    return h


def _reduction(kind):
    """A covariance reduction M small enough to keep every P positive definite: of rank 1 or 2
    (what a late update takes off), of full rank, or indefinite with a zero diagonal (the compiled
    rewind carries the last two whole instead of through a low-rank factor)."""
    if kind == "indefinite":
        M = np.zeros((NX, NX))
        M[0, 1] = M[1, 0] = 1e-3
        return M
    G = 0.03 * RNG.normal(size=(NX, {"rank1": 1, "rank2": 2, "full": NX}[kind]))
    return G @ G.T


def test_the_rewind_carries_a_late_update_through_its_low_rank_factor():
    """What a 1- or 2-D late update takes off the covariance (K S K') is carried through the
    history as K (8 x m), not as the 8 x 8 product: rank 1 and 2 found, the rest carried whole."""
    rank = backend.compiled.reduction_rank
    assert [rank(_reduction(k)) for k in ("rank1", "rank2", "full", "indefinite")] == [1, 2, -1, -1]
    assert rank(np.zeros((NX, NX))) == 0
    assert rank(np.full((NX, NX), np.nan)) == -1
    P0 = spd()
    for m in (1, 2):
        dx, M = np.zeros(NX), np.zeros((NX, NX))
        kalman.late_update(P0.copy(), RNG.normal(size=(m, NX)), np.diag(RNG.uniform(0.1, 0.5, m)),
                           RNG.normal(size=m), dx, M)
        assert rank(M) == m


@pytest.mark.parametrize("kind", ["rank1", "rank2", "full", "indefinite"])
@pytest.mark.parametrize("depth", [0, 1, 7, 39])
def test_correct_agrees(depth, kind):
    h0 = _history()
    s = h0.last - depth
    dx = 0.1 * RNG.normal(size=NX)
    M = _reduction(kind)

    def run():
        h = StepHistory(h0.n)
        h.X, h.P, h.A, h.first, h.last = h0.X.copy(), h0.P.copy(), h0.A.copy(), h0.first, h0.last
        assert h.correct(s, dx, M)
        return h.X, h.P

    (Xr, Pr), (Xc, Pc) = _both(run)
    np.testing.assert_allclose(Xc, Xr, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(Pc, Pr, rtol=1e-10, atol=1e-10)
    assert np.array_equal(Pc, Pc.transpose(0, 2, 1))


@pytest.mark.parametrize("compiled", [False, True])
def test_correct_refuses_a_covariance_that_is_not_positive_definite(compiled):
    """A reduction larger than what a later step knows would leave a negative variance there:
    refused, and the history is left exactly as it was."""
    h = _history()
    s = h.last - 10
    M = np.zeros((NX, NX))
    M[4, 4] = 1e3  # far more than any P[4, 4]
    X0, P0 = h.X.copy(), h.P.copy()
    with backend.selected(compiled):
        assert not h.correct(s, np.ones(NX), M)
    np.testing.assert_array_equal(h.X, X0)
    np.testing.assert_array_equal(h.P, P0)


def test_positive_definite_check():
    good = np.stack([spd(), spd()])
    bad = good.copy()
    bad[1, 2, 2] = -1.0
    nan = good.copy()
    nan[0, 0, 1] = np.nan
    assert positive_definite(good) and backend.compiled.positive_definite(good)
    for P in (bad, nan):
        assert not positive_definite(P) and not backend.compiled.positive_definite(P)


# ------------------------------------------------------------------------------------------------
# the latency sensitivity's kernels (latency_sensitivity.py)

def test_sensitivity_step_agrees_and_may_write_over_its_input():
    A = np.eye(NX) + 0.05 * RNG.normal(size=(NX, NX))
    S0 = RNG.normal(size=NX)
    ref, out = np.zeros(NX), np.zeros(NX)
    ls.sens_step_reference(A, S0, ref)
    backend.compiled.sens_step(A, S0, out)
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-15)
    inplace = S0.copy()
    backend.compiled.sens_step(A, inplace, inplace)  # S_out is S_prev: the product, not a half-updated one
    assert np.array_equal(inplace, out)


@pytest.mark.parametrize("m", [1, 2])
@pytest.mark.parametrize("depth", [0, 1, 7, 99])  # 99: the whole ring, across its wrap
def test_sensitivity_fused_agrees(m, depth):
    """A fix fused at a stored step and carried to the present: the compiled kernel (step by step)
    is the reference (the gain by numpy's inverse, the carry by prefix products) within 1e-12,
    and it touches no slot before the fix's step."""
    n, last = 100, 170
    A = np.eye(NX) + 0.05 * RNG.normal(size=(n, NX, NX))
    S0 = RNG.normal(size=(n, NX))
    P, H = spd(0.1), RNG.normal(size=(m, NX))
    R, h = np.diag(RNG.uniform(0.1, 0.5, m)), RNG.normal(size=m)
    s = last - depth
    ref, out = S0.copy(), S0.copy()
    ls.sens_fused_reference(ref, A, P, H, R, h, s, last)
    backend.compiled.sens_fused(out, A, P, H, R, h, s, last)
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)
    touched = np.arange(s, last + 1) % n
    untouched = np.setdiff1d(np.arange(n), touched)
    assert np.array_equal(out[untouched], S0[untouched])
    # the fix's step itself: (I - K H) S + K h, K the textbook gain
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    np.testing.assert_allclose(out[s % n], (np.eye(NX) - K @ H) @ S0[s % n] + K @ h, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError):  # a step the ring no longer holds
        backend.compiled.sens_fused(out, A, P, H, R, h, last - n, last)


# ------------------------------------------------------------------------------------------------
# the scale sensitivity's products (scale_sensitivity.py): numpy's own bits, not within a tolerance

def _bits(a):
    return np.ascontiguousarray(a).view(np.uint64)


needs_blas_bits = pytest.mark.skipif(backend.compiled is None or not backend.blas_bits_match(),
                                     reason="numpy's BLAS sums in another order here: the references run")


@needs_blas_bits
@pytest.mark.parametrize("count", [1, 2, 3, 83, 130])
def test_prefix_doubling_gives_numpys_bits(count):
    """The doubling of a rewind's transitions, compiled: bit for bit numpy's matmul (the estimate's
    bytes must not depend on which ran), on transitions with structural zeros."""
    A = np.eye(NX) + 0.05 * RNG.normal(size=(count, NX, NX))
    A[RNG.random(A.shape) < 0.3] = 0.0
    ref, out = A.copy(), A.copy()
    ls.prefix_doubling_reference(ref)
    backend.compiled.prefix_doubling(out)
    assert np.array_equal(_bits(out), _bits(ref))


@needs_blas_bits
@pytest.mark.parametrize("depth", [0, 1, 7, 83, 99])  # 99: across the ring's wrap
def test_carry_change_gives_numpys_bits_and_touches_only_later_slots(depth):
    from ecu_daemon.estimator import scale_sensitivity as ss
    n, last = 100, 170
    A = np.eye(NX) + 0.05 * RNG.normal(size=(n, NX, NX))
    S0 = RNG.normal(size=(n, NX))
    delta = RNG.normal(size=NX)
    s = last - depth
    ref, out = S0.copy(), S0.copy()
    ss.carry_change_reference(ref, A, s, last, delta)
    backend.compiled.carry_change(out, A, s, last, delta)
    assert np.array_equal(_bits(out), _bits(ref))
    untouched = np.setdiff1d(np.arange(n), np.arange(s + 1, last + 1) % n)
    assert np.array_equal(out[untouched], S0[untouched])
    with pytest.raises(ValueError):  # a window the ring no longer holds
        backend.compiled.carry_change(out, A, last - n, last, delta)


@needs_blas_bits
def test_scale_step_gives_numpys_bits_in_place_too():
    from ecu_daemon.estimator import scale_sensitivity as ss
    from ecu_daemon.estimator.kinematic import PSI
    for _ in range(200):
        A = np.eye(NX) + 0.05 * RNG.normal(size=(NX, NX))
        sp = RNG.normal(size=NX)
        r_dt = float(RNG.normal()) * 0.006
        ref, out = np.empty(NX), np.empty(NX)
        ss.scale_step_reference(A, sp, ref, PSI, r_dt)
        backend.compiled.scale_step(A, sp, out, PSI, r_dt)
        assert np.array_equal(_bits(out), _bits(ref))
        inplace = sp.copy()
        backend.compiled.scale_step(A, inplace, inplace, PSI, r_dt)  # S_out is S_prev
        assert np.array_equal(_bits(inplace), _bits(ref))


def test_numpys_products_stand_in_only_where_the_probe_matches(monkeypatch):
    """A numpy whose BLAS sums in another order (the probe fails): select keeps the references,
    so the bytes are numpy's either way; where it matches, the compiled ones run."""
    from ecu_daemon.estimator import scale_sensitivity as ss
    try:
        monkeypatch.setattr(backend, "_blas_checked", False)
        backend.select(True)
        assert ss.carry_change is ss.carry_change_reference and ss.scale_step is ss.scale_step_reference
        assert ls.prefix_doubling is ls.prefix_doubling_reference
        monkeypatch.setattr(backend, "_blas_checked", True)
        backend.select(False)
        assert ss.carry_change is ss.carry_change_reference
        backend.select(True)
        assert ss.carry_change is backend.compiled.carry_change
        assert ls.prefix_doubling is backend.compiled.prefix_doubling
    finally:
        monkeypatch.undo()
        backend.select(True)


@pytest.mark.parametrize("m", [1, 2])
@pytest.mark.parametrize("depth", [0, 1, 7, 83, 99])  # 83: a 0.5 s rewind; 99: across the ring's wrap
def test_scale_fused_agrees_and_touches_only_the_fix_and_later_slots(m, depth):
    """The scale sensitivity's whole fix in one call (perfg23): the gain summed in index order and
    the change carried one step at a time is the reference (numpy's inverse, the change carried by
    prefix products) within 1e-12; the slots before the fix's step keep their bits."""
    from ecu_daemon.estimator import scale_sensitivity as ss
    n, last = 100, 170
    A = np.eye(NX) + 0.05 * RNG.normal(size=(n, NX, NX))
    A[RNG.random(A.shape) < 0.3] = 0.0
    S0 = RNG.normal(size=(n, NX))
    P, H, R = spd(0.1), RNG.normal(size=(m, NX)), np.diag(RNG.uniform(0.1, 0.5, m))
    s = last - depth
    ref, out = S0.copy(), S0.copy()
    ss.scale_fused_reference(ref, A, P, H, R, s, last)
    backend.compiled.scale_fused(out, A, P, H, R, s, last)
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)
    untouched = np.setdiff1d(np.arange(n), np.arange(s, last + 1) % n)
    assert np.array_equal(_bits(out[untouched]), _bits(S0[untouched]))
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)  # the fix's step: (I - K H) S_s
    np.testing.assert_allclose(out[s % n], (np.eye(NX) - K @ H) @ S0[s % n], rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError):  # a step the ring no longer holds
        backend.compiled.scale_fused(out, A, P, H, R, last - n, last)
    with pytest.raises(ValueError):  # a singular innovation covariance
        backend.compiled.scale_fused(out, A, np.zeros((NX, NX)), H, np.zeros((m, m)), s, last)


def test_the_scale_sensitivitys_fix_runs_the_compiled_kernel():
    """``ScaleSensitivity.fused`` is one ``scale_fused`` call, swapped by ``backend.select``."""
    from ecu_daemon.estimator import scale_sensitivity as ss
    with backend.selected(True):
        assert ss.scale_fused is backend.compiled.scale_fused
    with backend.selected(False):
        assert ss.scale_fused is ss.scale_fused_reference


@pytest.mark.parametrize("span", [0.03, 0.3, np.inf])
def test_across_secant_gives_the_references_bits(span):
    """The latency sensitivity's across-track secant (``_sensitivity_fused``), compiled: elementwise
    IEEE operations in numpy's order, so bit for bit the reference, a NaN row and the tangent's
    win (``slope`` larger than every secant) included."""
    for trial in range(300):
        n = int(RNG.integers(1, 150))
        aux = RNG.normal(size=(n, 6)) * RNG.choice([0.01, 1.0, 10.0])
        if trial % 50 == 7:
            aux[RNG.integers(0, n), RNG.integers(0, 6)] = np.nan
        psi = RNG.uniform(-7.0, 7.0, n)
        args = (aux, np.cos(psi), np.sin(psi), float(RNG.normal()), float(RNG.normal()), float(RNG.normal()),
                float(RNG.normal()), 0.006, int(RNG.integers(0, n)), span,
                float(RNG.normal()) * (1e6 if trial % 10 == 3 else 0.1))
        ref, out = ls.across_secant_reference(*args), backend.compiled.across_secant(*args)
        assert np.array_equal(_bits(np.array(out)), _bits(np.array(ref))), (trial, ref, out)


# ------------------------------------------------------------------------------------------------
# the lever-arm checks' fits (lever_arm_check.py)

@pytest.mark.parametrize("p", [3, 4])
def test_lever_fit_kernels_agree(p):
    """A fix added to a fit's information (the same bits: elementwise) and the regularised fit
    solved again (an inverse by Gauss-Jordan against LAPACK's: within 1e-12); the gate's terms."""
    g = RNG.normal(size=(p, p))
    info0, rhs0 = g @ g.T, RNG.normal(size=p)
    h, prior = RNG.normal(size=p), RNG.uniform(1e-9, 1.0, p)
    z, var = float(RNG.normal()), float(RNG.uniform(0.01, 1.0))
    ref = [info0.copy(), rhs0.copy(), np.zeros(p), np.zeros((p, p))]
    out = [info0.copy(), rhs0.copy(), np.zeros(p), np.zeros((p, p))]
    assert lac.fit_update_reference(ref[0], ref[1], h, z, var, prior, ref[2], ref[3])
    assert backend.compiled.fit_update(out[0], out[1], h, z, var, prior, out[2], out[3])
    assert np.array_equal(out[0], ref[0]) and np.array_equal(out[1], ref[1])
    np.testing.assert_allclose(out[3], ref[3], rtol=1e-12, atol=1e-12 * np.abs(ref[3]).max())
    np.testing.assert_allclose(out[2], ref[2], rtol=1e-12, atol=1e-12 * np.abs(ref[2]).max())
    np.testing.assert_allclose(out[3] @ (info0 + np.outer(h, h) / var + np.diag(prior)), np.eye(p), atol=1e-10)
    pr, pc = lac.fit_predict_reference(h, ref[2], ref[3]), backend.compiled.fit_predict(h, ref[2], ref[3])
    np.testing.assert_allclose(pc, pr, rtol=1e-12)


@pytest.mark.parametrize("compiled", [False, True])
def test_a_singular_lever_fit_keeps_its_last_solution(compiled):
    """Information and prior that do not pin every unknown (a zero row): the fix is added, but
    theta and cov stay as they were (the check keeps its last fit), as with numpy's LinAlgError."""
    info, rhs = np.zeros((4, 4)), np.zeros(4)
    theta, cov = np.full(4, 7.0), np.full((4, 4), 7.0)
    fit = backend.compiled.fit_update if compiled else lac.fit_update_reference
    assert not fit(info, rhs, np.array((1.0, 2.0, 0.0, 3.0)), 0.5, 0.25, np.zeros(4), theta, cov)
    assert info[0, 1] == 8.0 and rhs[3] == 6.0
    assert (theta == 7.0).all() and (cov == 7.0).all()


# ------------------------------------------------------------------------------------------------
# the latency identification's cost profile (latency.py)

def _latency_statistics(p, n=167, fixes=60):
    """Forgotten sufficient statistics of y ~ a x + c . e + b per candidate, as latency.py keeps them."""
    x = RNG.normal(20.0, 3.0, size=(fixes, n))
    e = RNG.normal(size=(fixes, p - 2))
    z = np.concatenate((x[:, :, None], np.broadcast_to(e[:, None, :], (fixes, n, p - 2)), np.ones((fixes, n, 1))), axis=2)
    y = 1.02 * x[:, 40] + 0.3 + 0.05 * RNG.normal(size=fixes)
    w = 0.995 ** np.arange(fixes)[::-1]
    zz = np.einsum("f,fki,fkj->kij", w, z, z)
    zy = np.einsum("f,fki,f->ki", w, z, y)
    return zz, zy, float(np.sum(w * y * y))


@pytest.mark.parametrize("p", [2, 3])
def test_latency_costs_agree(p):
    """Every candidate's residual sum of squares (the compiled solves against numpy's stacked
    LAPACK ones: within 1e-9 of the largest cost, which is a difference of large sums), the
    best candidate the same; an uninformative regressor (its spread below the floor) leaves c alone."""
    zz, zy, syy = _latency_statistics(p)
    ref, out = np.zeros(len(zz)), np.zeros(len(zz))
    assert latency.latency_costs_reference(zz, zy, syy, 1.0, ref)
    assert backend.compiled.latency_costs(zz, zy, syy, 1.0, out)
    np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-9 * ref.max())
    assert np.argmin(out) == np.argmin(ref) == 40  # the candidate y was made from
    keep = np.full(len(zz), 7.0)
    for fn in (latency.latency_costs_reference, backend.compiled.latency_costs):
        assert not fn(zz, zy, syy, 1e12, keep)
        assert (keep == 7.0).all()


@pytest.mark.parametrize("p", [2, 3, 4])
def test_accumulate_is_bit_exact(p):
    """One fix into the statistics: the compiled in-place update gives numpy's bits (elementwise,
    no reduction), with x a strided column of a history array as observe passes it, and the
    statistics of whole runs of fixes (forgetting on) stay byte-equal."""
    zz, zy, _ = _latency_statistics(p, n=83, fixes=5)
    ref = (zz.copy(), zy.copy())
    out = (zz.copy(), zy.copy())
    for _ in range(40):
        aux = RNG.normal(15.0, 4.0, size=(83, 9))
        extra = tuple(float(v) for v in RNG.normal(size=p - 2))
        y = np.float64(RNG.normal(15.0, 4.0))
        latency.accumulate_reference(*ref, aux[:, 4], extra, y, 0.995)
        backend.compiled.accumulate(*out, aux[:, 4], extra, y, 0.995)
        assert ref[0].tobytes() == out[0].tobytes() and ref[1].tobytes() == out[1].tobytes()
    # the textbook form of one update: lam Z'Z + z z'
    z = np.concatenate(([3.0], [0.5] * (p - 2), [1.0]))
    zz1, zy1 = np.zeros((1, p, p)), np.zeros((1, p))
    backend.compiled.accumulate(zz1, zy1, np.array([3.0]), (0.5,) * (p - 2), 2.0, 0.9)
    np.testing.assert_array_equal(zz1[0], np.outer(z, z))
    np.testing.assert_array_equal(zy1[0], 2.0 * z)
    with pytest.raises(ValueError):  # a statistics array of the wrong size is refused, not overrun
        backend.compiled.accumulate(np.zeros((2, p, p)), np.zeros((2, p)), np.zeros(3), (0.0,) * (p - 2), 1.0, 1.0)


@pytest.mark.parametrize("n", [1, 2, 83, 84, 167])
def test_median_matches_numpy(n):
    """The profile's median: numpy's value bit for bit (odd and even counts, ties, a strided
    view), NaN when the profile holds one."""
    for c in (RNG.gamma(2.0, 3.0, size=n), np.round(RNG.gamma(2.0, 3.0, size=n)), RNG.normal(size=2 * n)[::2]):
        assert np.float64(backend.compiled.median(c)).tobytes() == np.float64(latency.median_reference(c)).tobytes()
    c = RNG.gamma(2.0, 3.0, size=n)
    c[n // 2] = np.nan
    assert np.isnan(backend.compiled.median(c)) and np.isnan(latency.median_reference(c))


# ------------------------------------------------------------------------------------------------
# the stiffness regression's kernels (fusion/stiffness_regression.py)

def spd6():
    a = RNG.normal(size=(sr.NS, sr.NS))
    return a @ a.T + 0.1 * np.eye(sr.NS)


def _stiffness_kernels(fn):
    """fn(module) with the module's reference kernels and with the compiled ones."""
    with backend.selected(False):
        assert sr.axle_update is sr.axle_update_reference
        ref = fn()
    with backend.selected(True):
        assert sr.axle_update is backend.compiled.axle_update
        out = fn()
    return ref, out


def test_axle_filter_kernels_agree():
    """Propagation, the considered-latency shift and the Joseph update of one axle's filter, in
    place, compiled against numpy on random covariances; the update's covariance exactly symmetric."""
    x0, P0, h = RNG.normal(size=sr.NS), spd6(), RNG.normal(size=sr.NS)

    def run():
        x, P = x0.copy(), P0.copy()
        sr.axle_propagate(P, 0.2, 1e-4, 1e-6)
        out = [P.copy()]
        sr.axle_latency(x, P, 0.31, 0.02 ** 2)
        out += [x.copy(), P.copy()]
        nu = sr.axle_update(x, P, 0.7, h, 0.05)
        return out + [x.copy(), P.copy(), np.array([nu])]

    ref, comp = _stiffness_kernels(run)
    for r, c in zip(ref, comp):
        np.testing.assert_allclose(c, r, rtol=1e-12, atol=1e-14)
    P = comp[4]
    assert np.array_equal(P, P.T) and comp[3][sr.TAU] == comp[1][sr.TAU]  # tau considered: not updated
    assert comp[1][sr.TAU] == pytest.approx(0.31)


@pytest.mark.parametrize("case", ["inside the prior", "forgotten beyond it", "beyond it, not PD"])
def test_single_track_rls_update_agrees(case):
    """The single-track compliance learner's RLS step (single_track.rls_update): the plain step,
    and forgetting that would inflate P beyond the prior (clipped to it entrywise while P stays
    positive definite, else reset to it)."""
    P0 = np.diag([0.04, 0.09])
    k0 = np.array([0.2, 0.1])
    P_in = {"inside the prior": np.array([[0.01, 0.004], [0.004, 0.02]]),
            "forgotten beyond it": np.array([[0.0405, 0.01], [0.01, 0.05]]),
            "beyond it, not PD": np.array([[0.0405, 0.3], [0.3, 0.05]])}[case]

    def run():
        k, P = k0.copy(), P_in.copy()
        e = st.rls_update(k, P, P0, 0.8, 0.3, 0.5, 1e-3 if case == "inside the prior" else 1e6, 0.999)
        return st.rls_update is st.rls_update_reference, e, k, P

    (ref, er, kr, Pr), (ref_c, ec, kc, Pc) = _both(run)
    assert ref and not ref_c
    assert er == pytest.approx(0.5 - (0.8 * 0.2 + 0.8 * 0.3 * 0.1), rel=1e-12) and ec == pytest.approx(er, rel=1e-12)
    np.testing.assert_allclose(kc, kr, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(Pc, Pr, rtol=1e-12, atol=1e-15)
    if case == "inside the prior":
        assert Pc[0, 0] < P_in[0, 0] and kc[0] > k0[0]
    elif case == "forgotten beyond it":  # clipped to the prior entrywise, not reset
        assert Pc[0, 0] == P0[0, 0] and Pc[0, 1] == Pc[1, 0] == 0.0 and P_in[1, 1] < Pc[1, 1] < P0[1, 1]
    else:
        np.testing.assert_array_equal(Pc, P0)


@pytest.mark.parametrize("lo,hi,s", [(3, 23, 13), (40, 60, 50), (45, 55, 47), (55, 75, 65)])
def test_ring_window_kernels_agree(lo, hi, s):
    """The gyro sum and the windowed line fit / mean / standard error over ring-buffer steps,
    also across the buffer's wrap-around (a 64-row buffer here)."""
    aux, X = RNG.normal(size=(64, NAUX)), RNG.normal(size=(64, NX))

    def run():
        return (sr.gyro_sum(aux, AUX_R, X, 3, lo, hi),
                *sr.window_fit(aux, AUX_R, AUX_AY, lo, hi, s, 0.006))

    ref, comp = _stiffness_kernels(run)
    np.testing.assert_allclose(comp, ref, rtol=1e-12, atol=1e-12)
    with backend.selected(True), pytest.raises(ValueError):
        sr.window_fit(aux, AUX_R, NAUX, lo, hi, s, 0.006)  # column out of range: an error, not a read


@pytest.mark.parametrize("ring", [False, True])
def test_yaw_sum_gives_numpys_bits(ring):
    """The checks' gyro turn between fixes (lever_arm_check.yaw_sum): np.sum's own pairwise
    summation, bit for bit, for every window length a 170-slot ring holds (the fixes are ~33 steps
    apart; the pairwise blocks change at 8 and 128), across the wrap, with and without the division
    by the applied scales (perfg23)."""
    from ecu_daemon.estimator import lever_arm_check as lac
    n = 170
    for count in range(0, n + 1):
        aux = RNG.normal(size=(n, NAUX)) * 10.0 ** RNG.integers(-3, 2, size=(n, NAUX))
        q = RNG.uniform(-0.05, 0.05, n) if ring else None
        k0 = int(RNG.integers(0, 3 * n))
        ref = lac.yaw_sum_reference(aux, AUX_R, k0, k0 + count - 1, q)
        out = backend.compiled.yaw_sum(aux, AUX_R, k0, k0 + count - 1, q)
        assert type(out) is float and np.float64(out).tobytes() == np.float64(ref).tobytes(), count
    with pytest.raises(ValueError):  # a window longer than the ring
        backend.compiled.yaw_sum(aux, AUX_R, 0, n, q)
    with pytest.raises(ValueError):  # a column out of range
        backend.compiled.yaw_sum(aux, NAUX, 0, 3, q)


# ------------------------------------------------------------------------------------------------
# a whole drive

@pytest.fixture(scope="module")
def drive_events():
    sc = SCENARIOS["dlc_dry"]
    cfg = vehicle_config(sc)
    return cfg, decoded_events(cfg, simulate(sc, cfg))


def run_drive(cfg, events):
    est = Estimator(cfg)
    out, Ps = [], []
    for t, kind, s in events:
        (est.push_gnss if kind else est.push_input)(s)
        for e in est.advance_to(t - 1e-6):
            out.append(tuple(e))
            h = est.hist
            Ps.append(h.P[h.slot(h.last)].copy() if est.initialized else None)
    return est, out, Ps


def test_a_whole_drive_compiled_and_reference_agree_within_1e9(drive_events):
    cfg, events = drive_events
    (er, ref, _), (ec, comp, Ps) = _both(lambda: run_drive(cfg, events))
    assert ec.gnss.fused > 50 and ec.resets == er.resets and len(comp) == len(ref) > 3000
    worst = 0.0
    for a, b in zip(ref, comp):
        for u, v in zip(a, b):
            if isinstance(u, float):
                worst = max(worst, abs(u - v) / max(1.0, abs(u)))
            else:
                assert u == v
    assert worst < 1e-9
    # the per-drive stiffness regression (reported in the learned state) too
    assert ec.stiffness.rear.updates == er.stiffness.rear.updates > 20
    for key, v in er.stiffness.learned().items():
        assert ec.stiffness.learned()[key] == pytest.approx(v, rel=1e-9)
        assert ec.stiffness.learned_std()[key] == pytest.approx(er.stiffness.learned_std()[key], rel=1e-9)
    # the single-track model's live compliance learner (its RLS step a kernel too); it stops once
    # it takes the drive regression's stiffness (ttv7b), so only a few updates run before that
    assert ec.single_track.rear.updates == er.single_track.rear.updates > 5
    # (2e-9: the latency's cost profiles carry latency_costs' last-bit differences into the delay's
    # slew, and since the accelerometer's earlier runs bridge its break-offs (lat27) that reaches
    # this learner's few updates: 1.26e-9 here; the state rows and the drive regression within 1e-9)
    for key, v in er.single_track.learned().items():
        assert ec.single_track.learned()[key] == pytest.approx(v, rel=2e-9)
    # every step's covariance exactly symmetric (and positive definite) as stored
    stored = [P for P in Ps if P is not None]
    assert len(stored) > 3000
    assert all(np.array_equal(P, P.T) for P in stored)
    assert positive_definite(np.stack(stored))


def test_two_compiled_runs_are_byte_identical(drive_events):
    cfg, events = drive_events
    _, a, _ = run_drive(cfg, events)
    _, b, _ = run_drive(cfg, events)
    assert repr(a).encode() == repr(b).encode()
