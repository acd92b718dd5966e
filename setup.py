"""Only the compiled estimator kernels, output frame packing and estimate CSV rows; everything else is in pyproject.toml.

Ahead-of-time C (no JIT: the service runs with MemoryDenyWriteExecute=yes). ``optional``: a
machine without a compiler still installs, and the estimator says so once and runs its
pure-Python reference (ecu_daemon/estimator/backend.py).
"""
import importlib.util
import sys
from pathlib import Path

from setuptools import Extension, setup

ROOT = Path(__file__).resolve().parent


def _compiled_python() -> list:
    """The estimator's per-step Python modules, each compiled by Cython from its own unchanged source
    (ecu_daemon/compiled_python.py: which ones, why, and what a stale build does); none without
    Cython (the same modules then run as plain Python)."""
    try:
        from Cython.Build import cythonize
    except ImportError:
        print("setup.py: Cython not installed: the estimator's Python modules stay uncompiled", file=sys.stderr)
        return []
    # the list and the appended line from the module itself (by path: no package import at build time)
    spec = importlib.util.spec_from_file_location("_compiled_python", ROOT / "ecu_daemon" / "compiled_python.py")
    cp = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cp)
    MODULES, tail = cp.MODULES, cp.tail
    out = []
    for rel in MODULES:
        source = (ROOT / rel).read_bytes()
        # compiled from a copy with the one-line staleness check appended (build/: not shipped)
        copy = Path("build", "compiled_python", rel)
        copy.parent.mkdir(parents=True, exist_ok=True)
        text = source.decode() + tail(source)
        if not copy.exists() or copy.read_text() != text:  # unchanged: cythonize keeps its C file
            copy.write_text(text)
        # a .pxd beside the module (typed declarations augmenting it, ignored by plain Python)
        # goes beside the copy too, where Cython looks for it
        pxd, pxd_copy = (ROOT / rel).with_suffix(".pxd"), copy.with_suffix(".pxd")
        if pxd.exists():
            if not pxd_copy.exists() or pxd_copy.read_bytes() != pxd.read_bytes():
                pxd_copy.write_bytes(pxd.read_bytes())
        elif pxd_copy.exists():
            pxd_copy.unlink()
        ext = Extension(rel[:-3].replace("/", "."), [str(copy)],
                        extra_compile_args=["-O2", "-ffp-contract=off"], optional=True)
        try:  # Python semantics throughout (no C types from annotations or inference): the .py's bits
            out += cythonize([ext], quiet=True, compiler_directives={
                "language_level": 3, "binding": True, "annotation_typing": False, "infer_types": False})
        except Exception as e:  # noqa: BLE001 -- one module Cython cannot take stays plain Python
            print(f"setup.py: {rel} not compiled ({e}): it runs as plain Python", file=sys.stderr)
    return out


setup(ext_modules=_compiled_python() + [Extension(
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
