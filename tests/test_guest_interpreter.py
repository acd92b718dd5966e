"""The interpreter the user-mode-Linux guests run, checked on the host (no UML needed).

A fresh machine's base interpreter has none of our packages; the guests once ran it (the venv's
``bin/python`` resolved through ``realpath``) and every kernel test died of ``No module named 'can'``
in the player. The harness must hand over the test environment's own interpreter, and the guest job
must stop at once, naming the interpreter and ``sys.prefix``, when it is given another.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GUEST_JOB = ROOT / "tools" / "uml" / "guest_replay.py"
sys.path.insert(0, str(ROOT / "tests" / "kernel"))

import harness  # noqa: E402

CHECK = ("import sys; sys.path.insert(0, sys.argv[1]); import guest_replay;"
         " print(guest_replay.missing_modules_error())")


def test_the_guest_interpreter_is_this_environments_and_imports_what_the_guest_needs():
    py = harness.python_for_guest()
    assert Path(py).is_absolute()
    # by the path this run was started with (a venv's link), so Python finds the venv's packages
    assert Path(py) == Path(sys.executable).absolute()
    r = subprocess.run([py, "-c", CHECK, str(GUEST_JOB.parent)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "None", (r.stdout, r.stderr)


def test_a_guest_job_on_an_interpreter_without_the_packages_fails_at_once_naming_it(tmp_path):
    """``-S -I``: this very interpreter without its site-packages, as a base interpreter would be."""
    job = tmp_path / "job.json"
    job.write_text(json.dumps({"out": str(tmp_path), "python": "unused", "repo": str(ROOT)}))
    r = subprocess.run([sys.executable, "-S", "-I", str(GUEST_JOB), str(job)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, (r.stdout, r.stderr)
    line = r.stderr.strip()
    assert "\n" not in line and "Traceback" not in line, line
    probe = subprocess.run([sys.executable, "-S", "-I", "-c", "import sys; print(sys.executable); print(sys.prefix)"],
                           capture_output=True, text=True, timeout=60).stdout.split("\n")
    assert f"guest interpreter {probe[0]} (sys.prefix {probe[1]}) cannot import can," in line, line
    assert json.loads((tmp_path / "results.json").read_text()) == {"error": line}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["job.json", "results.json"]  # nothing started
