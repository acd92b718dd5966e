"""Every shell example of the README (and the example configs' comments) runs as written.

The examples are read from the files, not copied here. Each one runs in ``bash -eo pipefail`` from
the repository root with the test's environment (``ecu-daemon`` on PATH, as after the README's
set-up). Substitutions, all visible below: ``/tmp/`` becomes the test's own temporary directory
(parallel runs must not share files); the set-up line's demo gets ``--duration 6`` (the built-in
drive lasts 65 s); the line that runs this very test suite is checked to be what ``.ci/run`` runs
(CI runs it as written). Examples that read ``../shared`` skip when it is absent, naming it.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
SETUP_PREFIX = "python3 -m venv .venv && .venv/bin/pip install -q "


def readme_examples() -> list[tuple[str, str]]:
    """(where, script) of every shell example: indented README blocks whose first line is a command,
    and ``#   ecu-daemon ...`` comment lines of ``examples/*.toml``."""
    out = []
    lines = (REPO / "README.md").read_text().splitlines()
    i = 0
    while i < len(lines):
        if lines[i].startswith("    ") and (i == 0 or not lines[i - 1].strip()):
            j = i
            while j < len(lines) and lines[j].startswith("    "):
                j += 1
            block = "\n".join(ln[4:] for ln in lines[i:j])
            if re.match(r"(ecu-daemon|python3) ", block) and not _installs_system_wide(block):
                out += [(f"README.md:{i + 1 + k}", cmd) for k, cmd in enumerate(_split_setup(block))]
            i = j
        else:
            i += 1
    for toml in sorted((REPO / "examples").glob("*.toml")):
        for n, ln in enumerate(toml.read_text().splitlines(), 1):
            m = re.match(r"#\s+(ecu-daemon (?:run|replay|demo|monitor|simulate|evaluate|show-config)\b.*)$", ln)
            if m:
                out.append((f"{toml.relative_to(REPO)}:{n}", m[1]))
    return out


def _installs_system_wide(block: str) -> bool:
    """The "Running under systemd" install steps write to /opt, /usr/local and /etc as root: run on
    the test machine they would change it for every later test (and CI). The unit they install is
    exercised under a real systemd in ``tests/kernel/test_systemd.py`` instead."""
    return bool(re.search(r"(^|\s)/(opt|etc|usr/local)/", block))


def _split_setup(block: str) -> list[str]:
    """The two set-up one-liners at the top are independent examples; other blocks are scripts."""
    if block.startswith(SETUP_PREFIX):
        return block.splitlines()
    return [block]


EXAMPLES = readme_examples()


def test_the_examples_are_found():
    where = [w for w, _ in EXAMPLES]
    assert len(EXAMPLES) >= 6 and any(w.startswith("examples/toyota_rav4.toml") for w in where)
    assert any("ecu-daemon monitor" in s for _, s in EXAMPLES) and any("--plots" in s for _, s in EXAMPLES)


@pytest.mark.parametrize("where, script", EXAMPLES, ids=[w for w, _ in EXAMPLES])
def test_readme_example_runs_as_written(where, script, tmp_path):
    if "../shared" in script and not SHARED.is_dir():
        pytest.skip(f"needs {SHARED} (the shared data beside the repository)")
    if script.startswith(SETUP_PREFIX):
        if "pytest" in script:  # this suite: CI runs exactly this line
            assert script in (REPO / ".ci" / "run").read_text()
            return
        _run_setup_line(script, tmp_path)
        return
    script = script.replace("/tmp/", f"{tmp_path}/")
    if "udp_multicast" in script:  # a port private to this run, so parallel runs do not mix
        script = script.replace("-c 239.74.163.2", f"-c 239.74.163.2 --bus-kwargs port={40000 + os.getpid() % 20000}")
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    r = subprocess.run(["bash", "-eo", "pipefail", "-c", script + "\nwait"], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, f"{where}: {script}\n{r.stderr[-2000:]}"
    assert "Traceback" not in r.stderr
    if "monitor" in script:
        assert "sideslip [deg]" in r.stdout and "fix FIX_3D" in r.stdout  # the monitor saw the demo
    for path in re.findall(rf"{re.escape(str(tmp_path))}/\S+", script):
        assert Path(path).exists() or Path(path).parent.exists(), path  # every file it names was written


def _run_setup_line(script: str, tmp_path: Path) -> None:
    """The install line in a copy of the repository (a real, non-editable install), then its demo."""
    setup, _, run = script.rpartition(" && ")
    copy = tmp_path / "repo"
    shutil.copytree(REPO, copy, ignore=shutil.ignore_patterns(".venv", ".git", "__pycache__", "*.egg-info",
                                                                "build"))
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    r = subprocess.run(["bash", "-eo", "pipefail", "-c", setup], cwd=copy, env=env, capture_output=True,
                       text=True, timeout=2400)  # a hung build's limit: it compiles every module (test_packaging)
    assert r.returncode == 0, f"{setup}\n{r.stderr[-2000:]}"
    assert run == ".venv/bin/ecu-daemon demo"
    r = subprocess.run(["bash", "-c", run + " --duration 6"], cwd=copy, env=env, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0 and "demo summary" in r.stdout, r.stderr[-2000:]


def test_ci_runs_the_suite_once_and_exits_with_its_status(tmp_path):
    """``.ci/run`` with stand-ins for python3, pip and the venv's python (so not the suite itself):
    a failed run is reported with pytest's status and is not run again (no automatic re-run)."""
    repo, fake = tmp_path / "repo", tmp_path / "bin"
    (repo / ".ci").mkdir(parents=True)
    shutil.copy2(REPO / ".ci" / "run", repo / ".ci" / "run")
    venv_bin = repo / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    fake.mkdir()
    calls = tmp_path / "calls"
    stubs = {fake / "python3": 'case "$1" in --version) echo "Python 3.11.0";; esac; echo "python3 $*" >> CALLS',
             venv_bin / "pip": 'echo "pip $*" >> CALLS',
             venv_bin / "python": 'echo "python $*" >> CALLS; exit 1'}
    for path, body in stubs.items():
        path.write_text("#!/bin/sh\n" + body.replace("CALLS", str(calls)) + "\n")
        path.chmod(0o755)
    r = subprocess.run([str(repo / ".ci" / "run")], cwd=tmp_path, capture_output=True, text=True, timeout=60,
                       env=dict(os.environ, PATH=f"{fake}{os.pathsep}{os.environ['PATH']}"))
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert "pytest exit status 1" in r.stdout
    ran = calls.read_text().splitlines()
    assert [c for c in ran if "pytest" in c] == ["python -m pytest -q"], ran
    # nothing in the test dependencies re-runs failures behind the run's back either
    deps = (REPO / "pyproject.toml").read_text()
    assert not re.search(r"rerunfailures|flaky|pytest-retry", deps)
