"""Which implementation of the estimator's numerical kernels runs: compiled or reference.

The compiled kernels (``_kernels.c``, built at ``pip install``) replace, under the same names,
``kinematic.KinematicModel.predict`` / ``predict_from``, ``kalman.scalar_update`` / ``index_update`` /
``late_update`` / ``symmetrize``, ``history.StepHistory.correct`` and the stiffness regression's
``axle_*`` / ``gyro_sum`` / ``window_fit`` (``fusion/stiffness_regression.py``) and the
single-track learner's ``rls_update`` (``fusion/single_track.py``) and the latency sensitivity's
``sens_step`` / ``sens_fused`` (``latency_sensitivity.py``) and the lever-arm checks'
``fit_update`` / ``fit_predict`` / ``yaw_sum`` (``lever_arm_check.py``; ``yaw_sum`` numpy's own bits, its pairwise sum) and the latency identification's
``latency_costs`` / ``accumulate`` / ``median`` / ``shift_statistics`` / ``latency_window`` /
``speed_window`` / ``refine_scan`` (``latency.py``) and the prefix products
doubling (``latency_sensitivity.prefix_doubling``) and the scale sensitivity's ``scale_step`` /
``carry_change`` (``scale_sensitivity.py``): unlike the others these three reproduce numpy's
bits, and are installed only where a probe shows they do (:func:`blas_bits_match`); and the scale
sensitivity's whole fix, ``scale_fused`` (the same math as its reference, its own bits); the pure-Python
``*_reference`` versions of the same math stay, for machines without the extension and for the
tests that compare the two.
"""
from __future__ import annotations

import contextlib
import logging

import numpy as np

from . import history, kalman, kinematic, latency, latency_sensitivity, lever_arm_check, scale_sensitivity
from .fusion import single_track, stiffness_regression

log = logging.getLogger(__name__)

KERNELS = ("predict", "predict_from", "scalar_update", "index_update", "late_update", "symmetrize", "correct")
STIFFNESS_KERNELS = ("axle_propagate", "axle_update", "axle_latency", "gyro_sum", "window_fit")
SINGLE_TRACK_KERNELS = ("rls_update",)
SENSITIVITY_KERNELS = ("sens_step", "sens_fused", "across_secant")
LEVER_KERNELS = ("fit_update", "fit_predict", "yaw_sum")
LATENCY_KERNELS = ("latency_costs", "accumulate", "median", "shift_statistics", "latency_window",
                   "speed_window", "refine_scan")
SCALE_KERNELS = ("scale_step", "carry_change")
SCALE_FIT_KERNELS = ("scale_fused",)

try:
    from . import _kernels as compiled
    _import_error = ""
except ImportError as e:  # no compiler at install time, or a source checkout never built
    compiled = None
    _import_error = str(e)
if compiled is not None and not all(hasattr(compiled, name)
                                    for name in KERNELS + STIFFNESS_KERNELS + SINGLE_TRACK_KERNELS
                                    + SENSITIVITY_KERNELS + LEVER_KERNELS + LATENCY_KERNELS
                                    + ("prefix_doubling",) + SCALE_KERNELS + SCALE_FIT_KERNELS):
    _import_error = f"{compiled.__file__} is an older build"  # a checkout updated without reinstalling
    compiled = None

_announced = False
_blas_checked = None  # blas_bits_match(), once per process


def blas_bits_match() -> bool:
    """Do the compiled products that stand in for numpy's (``prefix_doubling``, ``carry_change``,
    ``scale_step``: numpy's BLAS reproduced, ``_kernels.c``) give numpy's own bits on fixed probes?
    The estimate's bytes must not depend on which of the two ran: where numpy's BLAS sums in
    another order (another library or CPU), the references stay."""
    global _blas_checked
    if _blas_checked is None:
        rng = np.random.default_rng(20)
        ok = True
        for scale in (0.05, 1.0, 30.0):
            A = np.eye(8) + scale * rng.standard_normal((40, 8, 8))
            A[rng.random(A.shape) < 0.25] = 0.0  # structural zeros, as a transition's
            S = rng.standard_normal((40, 8))
            delta = rng.standard_normal(8)
            refs, outs = (A[3:36].copy(), S.copy(), S.copy()), (A[3:36].copy(), S.copy(), S.copy())
            latency_sensitivity.prefix_doubling_reference(refs[0])
            compiled.prefix_doubling(outs[0])
            scale_sensitivity.carry_change_reference(refs[1], A, 37, 40 + 30, delta)  # wraps the ring
            compiled.carry_change(outs[1], A, 37, 40 + 30, delta)
            for k in range(1, 40):
                scale_sensitivity.scale_step_reference(A[k], refs[2][k - 1], refs[2][k], 2, 0.01 * k)
                compiled.scale_step(A[k], outs[2][k - 1], outs[2][k], 2, 0.01 * k)
            ok = ok and all(np.array_equal(r.view(np.uint64), o.view(np.uint64)) for r, o in zip(refs, outs))
        _blas_checked = ok
    return _blas_checked


def _predict_compiled(self, x, P, P_out, r_m, ax_m, ay_m):
    compiled.predict(x, P, P_out, self.F, self.q, r_m, ax_m, ay_m, self.dt)


def _predict_from_compiled(self, x_prev, x, P_prev, P_out, A, r_m, ax_m, ay_m):
    compiled.predict_from(x_prev, x, P_prev, P_out, self.F, A, self.q, r_m, ax_m, ay_m, self.dt)


def _correct_compiled(self, s, dx, M):
    return compiled.correct(self.X, self.P, self.A, s, self.last, dx, M)


def select(use_compiled: bool = True) -> str:
    """Install the compiled kernels (if built and asked for) or the references; the name of the
    one now active. Process-wide: every Estimator uses the same."""
    on = use_compiled and compiled is not None
    kinematic.KinematicModel.predict = _predict_compiled if on else kinematic.KinematicModel.predict_reference
    kinematic.KinematicModel.predict_from = (_predict_from_compiled if on
                                             else kinematic.KinematicModel.predict_from_reference)
    history.StepHistory.correct = _correct_compiled if on else history.StepHistory.correct_reference
    kalman.scalar_update = compiled.scalar_update if on else kalman.scalar_update_reference
    kalman.index_update = compiled.index_update if on else kalman.index_update_reference
    kalman.symmetrize = compiled.symmetrize if on else kalman.symmetrize_reference
    kalman.late_update = compiled.late_update if on else kalman.late_update_reference
    for name in STIFFNESS_KERNELS:
        setattr(stiffness_regression, name,
                getattr(compiled, name) if on else getattr(stiffness_regression, name + "_reference"))
    for name in SINGLE_TRACK_KERNELS:
        setattr(single_track, name, getattr(compiled, name) if on else getattr(single_track, name + "_reference"))
    for name in SENSITIVITY_KERNELS:
        setattr(latency_sensitivity, name,
                getattr(compiled, name) if on else getattr(latency_sensitivity, name + "_reference"))
    for name in LEVER_KERNELS:
        setattr(lever_arm_check, name, getattr(compiled, name) if on else getattr(lever_arm_check, name + "_reference"))
    for name in LATENCY_KERNELS:
        setattr(latency, name, getattr(compiled, name) if on else getattr(latency, name + "_reference"))
    for name in SCALE_FIT_KERNELS:
        setattr(scale_sensitivity, name, getattr(compiled, name) if on else getattr(scale_sensitivity, name + "_reference"))
    blas = on and blas_bits_match()
    latency_sensitivity.prefix_doubling = (compiled.prefix_doubling if blas
                                           else latency_sensitivity.prefix_doubling_reference)
    for name in SCALE_KERNELS:
        setattr(scale_sensitivity, name, getattr(compiled, name) if blas else getattr(scale_sensitivity, name + "_reference"))
    return active()


@contextlib.contextmanager
def selected(use_compiled: bool):
    """:func:`select` for a block (tests comparing the two), the previous choice restored after."""
    before = active() == "compiled"
    select(use_compiled)
    try:
        yield
    finally:
        select(before)


def active() -> str:
    return "compiled" if kalman.scalar_update is not kalman.scalar_update_reference else "reference"


def announce() -> None:
    """One log line, once per process, when the compiled kernels are missing."""
    global _announced
    if compiled is None and not _announced:
        _announced = True
        log.warning("compiled estimator kernels not available (%s): using the pure-Python reference, "
                    "several times slower; reinstall with a C compiler to build them", _import_error)


select()
