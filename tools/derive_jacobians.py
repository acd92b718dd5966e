#!/usr/bin/env python3
"""Derive the estimator's model and measurement functions and their Jacobians with SymPy, and
write them as code: ``ecu_daemon/estimator/generated.py`` (Python) and
``ecu_daemon/estimator/_generated.h`` (C, for the compiled step).

Typed Jacobians drift from the functions they differentiate (a term forgotten in one of the
two goes unnoticed); here each is written once, as the function, and differentiated by SymPy.
Both outputs are committed; ``tests/test_jacobians.py`` re-runs this and fails if they are stale.

    python3 tools/derive_jacobians.py           # rewrite the generated files
    python3 tools/derive_jacobians.py --check   # exit 1 if they are not up to date
"""
from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path

import sympy as sp
from sympy.printing.c import C99CodePrinter
from sympy.printing.pycode import PythonCodePrinter

ROOT = Path(__file__).resolve().parents[1]
PY_OUT = ROOT / "ecu_daemon" / "estimator" / "generated.py"
C_OUT = ROOT / "ecu_daemon" / "estimator" / "_generated.h"

STATE = sp.symbols("vx vy psi b_r b_ax b_ay k_w g_ay", real=True)
vx, vy, psi, b_r, b_ax, b_ay, k_w, g_ay = STATE
NX = len(STATE)
r_m, ax_m, ay_m, dt = sp.symbols("r_m ax_m ay_m dt", real=True)
r = sp.Symbol("r", real=True)  # bias-corrected yaw rate r_m - b_r, as stored per step
lever_x, lever_y, lf, frac, delta = sp.symbols("lever_x lever_y lf frac delta", real=True)


def kinematic_model():
    """One first-order step of the IMU-driven model (kinematic.py docstring), inputs held."""
    rr = r_m - b_r
    f = sp.Matrix(STATE)
    f[0] = vx + dt * (ax_m - b_ax + rr * vy)
    f[1] = vy + dt * (ay_m - b_ay - g_ay * ay_m - rr * vx)
    f[2] = psi - dt * rr  # wrapped to [0, 2 pi) by the caller
    return f


def antenna_velocity():
    """Antenna velocity at (lever_x, lever_y) from the CG in body axes, and its north/east."""
    rr = r_m - b_r
    vax = vx - rr * lever_y
    vay = vy + rr * lever_x
    c, s = sp.cos(psi), sp.sin(psi)
    return vax, vay, sp.Matrix([vax * c + vay * s, vax * s - vay * c])


def measurements():
    """name -> (function of the state (column), inputs, doc). ``r_m`` is replaced by r + b_r in
    the output, so callers pass the stored bias-corrected yaw rate."""
    vax, vay, ne = antenna_velocity()
    v = vx * (1 - frac + frac * sp.cos(delta)) + (vy + lf * (r_m - b_r)) * frac * sp.sin(delta)
    return {
        "gnss_velocity": (ne, (r, lever_x, lever_y),
                          "GNSS antenna velocity [north, east] (heading clockwise from north)."),
        "gnss_speed": (sp.Matrix([sp.sqrt(vax ** 2 + vay ** 2)]), (r, lever_x, lever_y),
                       "GNSS antenna speed (when the heading or the course is unknown)."),
        "wheel_speed": (sp.Matrix([v / k_w]), (r, lf, frac, delta),
                        "Wheel-derived speed at the configured radius: a front-pair share ``frac`` "
                        "sees vx cos(delta) + (vy + lf r) sin(delta), the rear pair vx."),
        "antenna_sideslip": (sp.Matrix([sp.atan2(vay, vax)]), (r, lever_x, lever_y),
                             "Sideslip of the antenna velocity, course = heading - it (alignment)."),
    }


def _rows(expr: sp.Matrix):
    """(value rows, [(row, col, expr)] of the Jacobian entries that are not identically zero)."""
    J = expr.jacobian(sp.Matrix(STATE))
    return [(i, j, J[i, j]) for i in range(J.rows) for j in range(NX) if J[i, j] != 0]


def _subs_r(e):
    return e.subs(r_m, r + b_r)


def _small_pow(printer, expr) -> str | None:
    """x**2, x**-1, x**-2 as plain products (same bits as the hand code, no pow()); else None."""
    if expr.exp not in (2, -1, -2):
        return None
    b = printer.parenthesize(expr.base, 100)
    return {2: f"({b}*{b})", -1: f"1.0/{b}", -2: f"1.0/({b}*{b})"}[int(expr.exp)]


class _Py(PythonCodePrinter):
    def _print_Pow(self, expr, rational=False):
        return _small_pow(self, expr) or super()._print_Pow(expr, rational)


class _C(C99CodePrinter):
    def _print_Pow(self, expr):
        return _small_pow(self, expr) or super()._print_Pow(expr)


def _py(e) -> str:
    return _Py({"standard": "python3"}).doprint(e).replace("math.", "")


def _c(e) -> str:
    return _C().doprint(e)


def _cse(exprs):
    return sp.cse(exprs, symbols=sp.numbered_symbols("t"), optimizations=None)


def _arg_names(args) -> list[str]:
    return [str(a) for a in args]


def py_function(name: str, args, exprs, doc: str) -> str:
    subs, red = _cse(list(exprs))
    doc = textwrap.fill(doc, 96, initial_indent="    ", subsequent_indent="    ").lstrip()
    lines = [f"def {name}({', '.join(_arg_names(args))}):", f'    """{doc}"""']
    lines += [f"    {s} = {_py(e)}" for s, e in subs]
    body = ", ".join(_py(e) for e in red)
    lines.append(f"    return ({body},)" if len(red) == 1 else f"    return ({body})")
    return "\n".join(lines)


def c_function(name: str, args, exprs, doc: str) -> str:
    subs, red = _cse(list(exprs))
    params = ", ".join(f"double {a}" for a in _arg_names(args))
    lines = [f"/* {doc} */", f"static inline void {name}({params}, double *out)", "{"]
    lines += [f"    const double {s} = {_c(e)};" for s, e in subs]
    lines += [f"    out[{i}] = {_c(e)};" for i, e in enumerate(red)]
    lines.append("}")
    return "\n".join(lines)


def render() -> tuple[str, str]:
    names = [str(s) for s in STATE]
    f = kinematic_model()
    F = _rows(f)
    # F's structure: the identity, entries that depend on dt only, entries that vary per step
    const = [(i, j, e) for i, j, e in F if i != j and not (e.free_symbols - {dt})]
    var = [(i, j, e) for i, j, e in F if i != j and e.free_symbols - {dt}]
    assert all(e == 1 for i, j, e in F if i == j), "the model's diagonal is no longer the identity"
    moving = [i for i in range(NX) if f[i] != STATE[i]]
    f_args = (*STATE, r_m, ax_m, ay_m, dt)

    py = ['"""GENERATED by tools/derive_jacobians.py from its SymPy model: do not edit.',
          "",
          "Model and measurement functions of the estimator and their Jacobians (d/d state), as",
          "plain arithmetic on floats. State order: " + ", ".join(names) + ".",
          "``r`` is the bias-corrected yaw rate r_m - b_r (the Jacobians include its b_r term).",
          '"""',
          "from math import atan2, cos, sin, sqrt  # noqa: F401",
          "",
          f"STATE = {tuple(names)!r}",
          "#: rows of the state the model moves (the others are random walks: f = x)",
          f"MODEL_ROWS = {tuple(moving)!r}",
          "#: (row, col) of the off-diagonal entries of F = df/dx that depend on dt only",
          f"F_CONST = {tuple((i, j) for i, j, _ in const)!r}",
          "#: (row, col) of the off-diagonal entries of F that vary per step (kinematic_F_var's order)",
          f"F_VAR = {tuple((i, j) for i, j, _ in var)!r}",
          "", ""]
    py.append(py_function("kinematic_f", f_args, [f[i] for i in moving],
                          "The moved rows (MODEL_ROWS) of x after one step; psi not wrapped."))
    py += ["", ""]
    py.append(py_function("kinematic_F_const", (dt,), [e for *_, e in const], "Values of F_CONST."))
    py += ["", ""]
    py.append(py_function("kinematic_F_var", f_args, [e for *_, e in var], "Values of F_VAR."))
    c = ["/* GENERATED by tools/derive_jacobians.py from its SymPy model: do not edit. */",
         "#ifndef ECU_GENERATED_H", "#define ECU_GENERATED_H", "#include <math.h>", "",
         f"#define GEN_NX {NX}",
         f"#define GEN_N_MODEL_ROWS {len(moving)}",
         f"static const int GEN_MODEL_ROWS[{len(moving)}] = {{{', '.join(map(str, moving))}}};",
         f"#define GEN_N_F_CONST {len(const)}",
         f"static const int GEN_F_CONST[{len(const)}][2] = {{{', '.join(f'{{{i}, {j}}}' for i, j, _ in const)}}};",
         f"#define GEN_N_F_VAR {len(var)}",
         f"static const int GEN_F_VAR[{len(var)}][2] = {{{', '.join(f'{{{i}, {j}}}' for i, j, _ in var)}}};",
         ""]
    c.append(c_function("gen_kinematic_f", f_args, [f[i] for i in moving], "moved rows of x after one step"))
    c.append(c_function("gen_kinematic_F_const", (dt,), [e for *_, e in const], "values of GEN_F_CONST"))
    c.append(c_function("gen_kinematic_F_var", f_args, [e for *_, e in var], "values of GEN_F_VAR"))
    for name, (h_of_r_m, inputs, doc) in measurements().items():
        h = h_of_r_m.applyfunc(_subs_r)
        rows = [(i, j, _subs_r(e)) for i, j, e in _rows(h_of_r_m)]  # d/d b_r through r_m - b_r
        args = (*STATE, *inputs)
        cols = tuple((i, j) for i, j, _ in rows)
        py += ["", "", f"{name.upper()}_H = {cols!r}  # nonzero (row, col) of {name}_H, in order", "", ""]
        py.append(py_function(name, args, list(h), doc))
        py += ["", ""]
        py.append(py_function(f"{name}_H", args, [e for *_, e in rows],
                              f"Nonzero entries of d {name} / dx, in the order of {name.upper()}_H."))
    c += ["#endif", ""]
    return "\n".join(py) + "\n", "\n".join(c)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if the committed files are stale")
    args = ap.parse_args()
    stale = []
    for path, text in zip((PY_OUT, C_OUT), render()):
        if not path.exists() or path.read_text() != text:
            stale.append(path)
            if not args.check:
                path.write_text(text)
    if args.check and stale:
        print("stale (run tools/derive_jacobians.py): " + ", ".join(str(p.relative_to(ROOT)) for p in stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
