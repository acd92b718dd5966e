"""The estimator's per-step Python modules, compiled from their own unchanged source (Cython).

Why: the 6 ms step is Python logic (``core.Estimator._step``, ``FaultDetector.step``,
``_estimate``, the fusion modules), not numerics; compiled as they are (objects stay Python
objects, every operation keeps Python's semantics, so the output bytes do not change) they run
~1.5x faster, and the ``.py`` stays the one place each rule is written: there is no second copy
of a rule to keep in step.

``setup.py`` builds each module in :data:`MODULES` as an extension of the same name next to its
``.py`` (which the import system then prefers), with one line appended that calls
:func:`adopt_source` with the SHA-256 of the source it was compiled from. When the ``.py`` has
changed since (edited without re-running ``pip install -e .``), or ``ECU_DAEMON_PURE_PYTHON=1`` is
set (the tests' reference run), the module runs its current ``.py`` instead, so an edit always
takes effect: a stale build costs speed and one log line, never a divergent rule.
"""
from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path

log = logging.getLogger(__name__)

#: the per-step modules compiled (paths relative to the repository root)
MODULES = (
    "ecu_daemon/estimator/core.py",
    "ecu_daemon/estimator/fault_detection.py",
    "ecu_daemon/estimator/road.py",
    "ecu_daemon/estimator/latency.py",
    "ecu_daemon/estimator/latency_consider.py",
    "ecu_daemon/estimator/steering_offset.py",  # SteeringOffset.observe: every gentle-path step
    "ecu_daemon/estimator/input_consistency.py",  # LongitudinalScaleCheck.step: every step
    "ecu_daemon/estimator/lateral_noise.py",  # LateralNoise.observe: every lateral-accelerometer sample
    "ecu_daemon/estimator/latency_sensitivity.py",  # LatencySensitivity: every step (one receiver)
    "ecu_daemon/estimator/lever_arm_check.py",  # the lever-arm checks' observe: every GNSS fix, two per receiver
    "ecu_daemon/estimator/yaw_scale_check.py",  # YawScaleCheck.observe: every GNSS course, one per receiver
    "ecu_daemon/estimator/scale_sensitivity.py",  # ScaleSensitivity.step: every step; .fused: every 2-D fix
    "ecu_daemon/estimator/bank_walk.py",  # BankWalk.step: every step
    "ecu_daemon/estimator/axis_swap_check.py",  # AxisSwapCheck.step: every step
    "ecu_daemon/estimator/gyro_scale_gate.py",  # GyroScaleGate.step: every GSC_EVERY steps until confirmed
    "ecu_daemon/estimator/wheel_yaw_check.py",  # WheelYawCheck: every step until the wheels are confirmed
    "ecu_daemon/estimator/wheel_launch_check.py",  # WheelLaunchCheck: likewise
    "ecu_daemon/estimator/line_fit.py",  # LineFit: the gyro-scale gate's and the wheel-yaw check's fits
    "ecu_daemon/estimator/rear_axle_yaw.py",  # rear_speed_difference: the spin check's every step, the gates'
    "ecu_daemon/estimator/spin_check.py",  # SpinCheck.step: every step
    "ecu_daemon/estimator/gnss_speed_gap.py",  # GnssSpeedGap.step, term: every step; spread_since: every fix
    "ecu_daemon/estimator/steered_wheel_vx.py",  # vx_error_bound: every step the sideslip is not vouched
    "ecu_daemon/estimator/fusion/wheel_speed.py",
    "ecu_daemon/estimator/fusion/wheel_slip.py",  # SlipWitness: every wheel-speed step
    "ecu_daemon/estimator/fusion/drive_slip.py",  # DriveSlip.step: every step of a rear-driven car
    "ecu_daemon/estimator/fusion/friction_limit.py",  # FrictionLimit.step: every step with fresh GNSS
    "ecu_daemon/estimator/fusion/brake_grip.py",  # BrakeGrip.step: every step with the IMU
    "ecu_daemon/estimator/fusion/single_track.py",
    "ecu_daemon/estimator/fusion/standstill.py",
    "ecu_daemon/estimator/fusion/gnss_velocity.py",
    "ecu_daemon/estimator/fusion/gnss_heading.py",
    "ecu_daemon/estimator/fusion/stiffness_regression.py",
    "ecu_daemon/estimator/fusion/wheel_lock.py",  # WheelLock.step: every step
    "ecu_daemon/estimator/fusion/slide_rate.py",  # SlideRate.step: every step
    "ecu_daemon/estimator/fusion/slip_ratio_limit.py",  # SlipRatioLimit.step: every step above walking speed
    "ecu_daemon/estimator/fusion/spin_grip.py",  # SpinGrip.step: every step
    "ecu_daemon/estimator/fusion/law_excess_bound.py",  # LawExcessBound.step: every step
    "ecu_daemon/estimator/input_age.py",  # InputAge.observe / at_mid: every sample, three a step
    # perf50: small per-step functions that ran interpreted (a Python frame per call, ~1-3 k
    # instructions each before any work; callgrind of the demo replay, DEVELOPERS.md). Not io/health.py:
    # compiled, build_diagnostics took 3 % more instructions (its cost is the calls it makes)
    "ecu_daemon/estimator/backend.py",  # _predict_from_compiled: every step (the kernel's wrapper)
    "ecu_daemon/estimator/kinematic.py",  # wrap_pi: every step
    "ecu_daemon/estimator/generated.py",  # wheel_speed / wheel_speed_H: every wheel-speed update
    "ecu_daemon/estimator/bank_lag.py",  # vy_var: every step
    "ecu_daemon/estimator/timing_trust.py",  # timing_std: every step (one per receiver)
    "ecu_daemon/estimator/slip_heading.py",  # heading_floor: every step
    "ecu_daemon/estimator/gyro_vote.py",  # onset_verdict: every step
    "ecu_daemon/estimator/slow_turn_heading.py",  # scale_sd: every step
    "ecu_daemon/step_grid.py",  # step_of: every sample and step of the pipeline (~6 a step)
    "ecu_daemon/pipeline.py",  # Pipeline.advance / _publish: the replay's and daemon's per-step loop
    "ecu_daemon/outputs.py",  # OutputEncoder.payloads: every output frame's fields
    "ecu_daemon/replay.py",  # the replay's per-step emit (CSV rows, output frames)
)
PURE_ENV = "ECU_DAEMON_PURE_PYTHON"


def source_digest(source: bytes) -> str:
    return hashlib.sha256(source).hexdigest()


def tail(source: bytes) -> str:
    """The line setup.py appends to a module's source before compiling it (one line: the
    module's own line numbers, in tracebacks, stay those of its ``.py``)."""
    return (f"\nimport ecu_daemon.compiled_python as _compiled_python; "
            f"_compiled_python.adopt_source(globals(), {source_digest(source)!r})\n")


def adopt_source(g: dict, digest: str) -> None:
    """At the end of a compiled module's import: keep the compiled code if its ``.py`` is the
    source it was built from, else run the ``.py`` in the same namespace (which replaces every
    function and class by the current source's). Sets ``__compiled__`` either way."""
    name = g["__name__"].rpartition(".")[2]
    py = Path(g["__file__"]).with_name(name + ".py")
    try:
        source = py.read_bytes()
    except OSError:  # installed without its sources: the compiled code is all there is
        g["__compiled__"] = True
        return
    stale = source_digest(source) != digest
    if not stale and not os.environ.get(PURE_ENV):
        g["__compiled__"] = True
        return
    if stale:
        log.warning("%s changed since it was compiled: running it as plain Python (slower); "
                    "re-run pip install -e . to compile it again", py)
    exec(compile(source, str(py), "exec"), g)  # noqa: S102 -- the module's own source file
    g["__compiled__"] = False


def compiled_modules() -> dict[str, bool]:
    """Each module of :data:`MODULES` (dotted name) -> whether its compiled build is running."""
    import importlib

    out = {}
    for path in MODULES:
        dotted = path[:-3].replace("/", ".")
        out[dotted] = bool(getattr(importlib.import_module(dotted), "__compiled__", False))
    return out
