"""The generated model/measurement code: up to date with its SymPy derivation, and every Jacobian
equal to the finite differences of the function it claims to differentiate."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ecu_daemon.estimator import generated as gen
from ecu_daemon.estimator.kinematic import BR, NX, KinematicModel

ROOT = Path(__file__).resolve().parents[1]
RNG = np.random.default_rng(20261202)


def random_states(n=25):
    """Plausible states: speeds of either sign, any heading, biases, wheel scale near 1."""
    x = np.empty((n, NX))
    x[:, 0] = RNG.uniform(-5.0, 45.0, n)
    x[:, 1] = RNG.uniform(-3.0, 3.0, n)
    x[:, 2] = RNG.uniform(0.0, 2 * np.pi, n)
    x[:, 3] = RNG.uniform(-0.05, 0.05, n)
    x[:, 4:6] = RNG.uniform(-0.5, 0.5, (n, 2))
    x[:, 6] = RNG.uniform(0.9, 1.1, n)
    x[:, 7] = RNG.uniform(-0.05, 0.05, n)
    return x


def jacobian(entries, values, rows):
    """A dense Jacobian from a generated function's nonzero ``entries`` and their ``values``."""
    H = np.zeros((rows, NX))
    for (i, j), v in zip(entries, values):
        H[i, j] = v
    return H


def numeric_jacobian(fun, x, eps=1e-6):
    """Central differences, step scaled to each state's magnitude."""
    f0 = np.atleast_1d(fun(x))
    J = np.zeros((f0.size, NX))
    for j in range(NX):
        h = eps * max(1.0, abs(x[j]))
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        J[:, j] = (np.atleast_1d(fun(xp)) - np.atleast_1d(fun(xm))) / (2 * h)
    return J


def test_generated_code_is_what_the_derivation_produces():
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "derive_jacobians.py"), "--check"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr


def test_model_jacobian_matches_finite_differences():
    dt = 0.006
    F_const = dict(zip(gen.F_CONST, gen.kinematic_F_const(dt)))
    for x in random_states():
        u = tuple(RNG.uniform(-1.0, 1.0, 3) * (0.5, 3.0, 8.0))  # r_m, ax_m, ay_m

        def f(xx, u=u):
            out = xx.copy()
            out[list(gen.MODEL_ROWS)] = gen.kinematic_f(*xx, *u, dt)
            return out

        F = np.eye(NX)
        for (i, j), v in (*F_const.items(), *zip(gen.F_VAR, gen.kinematic_F_var(*x, *u, dt))):
            F[i, j] = v
        np.testing.assert_allclose(F, numeric_jacobian(f, x, eps=1e-4), rtol=1e-6, atol=1e-9)


def test_the_predict_the_estimator_runs_is_the_generated_model():
    """KinematicModel.predict (compiled or reference) moves x by f and P by F P F' + Q."""
    m = KinematicModel(0.006, 0.5, 0.01, 1e-4, 1e-3, 1e-4)
    x = random_states(1)[0]
    A = RNG.normal(size=(NX, NX))
    P = A @ A.T + np.eye(NX)
    u = (0.2, 1.5, -4.0)
    x1, P1 = x.copy(), np.empty((NX, NX))
    m.predict(x1, P, P1, *u)
    want = x.copy()
    want[:3] = gen.kinematic_f(*x, *u, 0.006)
    want[2] %= 2 * np.pi
    np.testing.assert_allclose(x1, want, rtol=1e-14, atol=1e-14)
    F = numeric_jacobian(lambda xx: np.concatenate([gen.kinematic_f(*xx, *u, 0.006), xx[3:]]), x, eps=1e-4)
    np.testing.assert_allclose(m.F, F, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(P1, m.F @ P @ m.F.T + m.Qd, rtol=1e-12, atol=1e-12)


MEASUREMENTS = {
    "gnss_velocity": lambda: (RNG.uniform(-1, 1), RNG.uniform(-2, 3), RNG.uniform(-1, 1)),
    "gnss_speed": lambda: (RNG.uniform(-1, 1), RNG.uniform(-2, 3), RNG.uniform(-1, 1)),
    "antenna_sideslip": lambda: (RNG.uniform(-1, 1), RNG.uniform(-2, 3), RNG.uniform(-1, 1)),
    # r, lf, front-pair share (rear, all-wheel, front), road-wheel angle
    "wheel_speed": lambda: (RNG.uniform(-1, 1), RNG.uniform(0.8, 1.6), RNG.choice([0.0, 0.5, 1.0]),
                            RNG.uniform(-0.5, 0.5)),
}


@pytest.mark.parametrize("name", sorted(MEASUREMENTS))
def test_measurement_jacobian_matches_finite_differences(name):
    """r (first input) is the bias-corrected yaw rate r_m - b_r: the derivative includes b_r."""
    h = getattr(gen, name)
    h_jac = getattr(gen, f"{name}_H")
    entries = getattr(gen, f"{name.upper()}_H")
    rows = max(i for i, _ in entries) + 1
    assert rows == len(h(*random_states(1)[0], *MEASUREMENTS[name]()))
    for x in random_states():
        inputs = MEASUREMENTS[name]()
        r_m = inputs[0] + x[BR]

        def fun(xx, inputs=inputs, r_m=r_m):
            return np.array(h(*xx, r_m - xx[BR], *inputs[1:]))

        H = jacobian(entries, h_jac(*x, *inputs), rows)
        np.testing.assert_allclose(H, numeric_jacobian(fun, x), rtol=1e-6, atol=1e-8)
