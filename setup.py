"""Only the compiled estimator kernels, output frame packing and estimate CSV rows; everything else is in pyproject.toml.

Ahead-of-time C (no JIT: the service runs with MemoryDenyWriteExecute=yes). ``optional``: a
machine without a compiler still installs, and the estimator says so once and runs its
pure-Python reference (ecu_daemon/estimator/backend.py).
"""
from setuptools import Extension, setup

setup(ext_modules=[Extension(
    "ecu_daemon.estimator._kernels",
    sources=["ecu_daemon/estimator/_kernels.c"],
    depends=["ecu_daemon/estimator/_generated.h"],
    # -O3 vectorises across independent outputs only (no reassociation without -ffast-math, no
    # fused multiply-adds with -ffp-contract=off): the same bits as -O2, the rewind ~1.3x faster
    extra_compile_args=["-O3", "-ffp-contract=off"],
    optional=True,
), Extension(  # output frame packing (ecu_daemon/outputs.py falls back to its Python reference)
    "ecu_daemon._frames",
    sources=["ecu_daemon/_frames.c"],
    extra_compile_args=["-O2", "-ffp-contract=off"],
    optional=True,
), Extension(  # candump -L logs read in one pass, output lines written in one (can_arrays.py, canlog.py fall back to Python)
    "ecu_daemon._candump",
    sources=["ecu_daemon/_candump.c"],
    extra_compile_args=["-O2", "-ffp-contract=off"],
    optional=True,
) , Extension(  # estimate CSV rows (ecu_daemon/estimate_csv.py falls back to %-formatting)
    "ecu_daemon._estimate_csv",
    sources=["ecu_daemon/_estimate_csv.c"],
    extra_compile_args=["-O2", "-ffp-contract=off"],
    optional=True,
)])
