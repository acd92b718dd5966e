"""tools/sideslip_budget.py: the per-row decomposition of the published sideslip std (issue 7 item 3).

The tool replays a drive with a read-only hook; what it reports must be the drive the suite
scored (the same rows, the same validity), its classes must partition those rows, and its
what-ifs must refuse a constant that does not exist instead of silently measuring nothing.
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from ecu_daemon.sim.suite import SUITE
from ecu_daemon.suite import run_case

REPO = Path(__file__).resolve().parents[1]
TOOL = REPO / "tools" / "sideslip_budget.py"
CASE = next(c for c in SUITE if c.name == "lowspeed_r25")


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    out = tmp_path_factory.mktemp("budget")
    row = run_case(CASE, out)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    return out / CASE.name


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(TOOL), *args], capture_output=True, text=True, timeout=600)


def test_budget_is_the_scored_drive_and_its_classes_partition_the_rows(drive):
    """The valid share equals the suite's ``valid above 5 m/s`` for the same drive (the hook changes
    nothing, the counted rows are the suite's), and the classes add up to every counted row."""
    p = _run(str(drive))
    assert p.returncode == 0, p.stderr
    shares = {}
    for line in p.stdout.splitlines():
        m = re.match(r"\s{2}(\S.*?)\s{2,}(\d\.\d{3})(\s|$)", line)
        if m:
            shares[m.group(1).strip()] = float(m.group(2))
    assert set(shares) == {"valid", "no bound (transient / GNSS stale)", "model-limited (bound < filter)",
                           "filter-limited (filter <= bound)", "other"}, p.stdout
    scored = json.loads((drive / "evaluation.json").read_text())["row"]["sideslip_valid_above_5mps"]
    assert shares["valid"] == pytest.approx(scored, abs=5e-4)
    assert sum(shares.values()) == pytest.approx(1.0, abs=3e-3)
    # a right sideslip that is invalid is invalid for a std term the tool names, never "other"
    assert shares["other"] == 0.0
    cov = re.search(r"valid rows within 3 sigma (\d\.\d+)", p.stdout)
    assert cov and float(cov.group(1)) >= 0.99, p.stdout


def test_what_if_refuses_an_unknown_constant(drive):
    p = _run(str(drive), "--set", "core.NO_SUCH_CONSTANT=0")
    assert p.returncode != 0
    assert "NO_SUCH_CONSTANT" in p.stderr
