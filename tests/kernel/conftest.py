"""Kernel tests: a real SocketCAN stack and a real systemd inside user-mode Linux.

Every test here is marked ``kernel``. They need the ``user-mode-linux``, ``kmod`` and ``can-utils``
Debian packages (and ``debootstrap`` for the systemd test); as root in CI (``CI=true``) or with
``ECU_UML_INSTALL=1`` the harness installs them once, otherwise the tests skip and say what to
install. Where UML cannot run at all (no ptrace, not x86-64, not root for the systemd guest) they
skip with the reason. Anything else is a failure: a failed install that was asked for, the
simulator, a guest, with the guest's console and logs in the message.
"""
from __future__ import annotations

import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import harness  # noqa: E402

#: (what, seconds) of the expensive steps, printed in the terminal summary for the CI log
TIMINGS: list[tuple[str, float]] = []
#: free-form facts (exposure score, tick lateness ...) printed in the summary
FACTS: list[str] = []


def pytest_collection_modifyitems(config, items):
    here = Path(__file__).resolve().parent
    for item in items:
        if here in Path(str(item.fspath)).resolve().parents:
            item.add_marker(pytest.mark.kernel)


def pytest_terminal_summary(terminalreporter):
    if not TIMINGS and not FACTS:
        return
    terminalreporter.section("kernel tests (user-mode Linux)")
    for what, s in TIMINGS:
        terminalreporter.write_line(f"{s:7.1f} s  {what}")
    for fact in FACTS:
        terminalreporter.write_line(fact)


@pytest.fixture(scope="session")
def uml(tmp_path_factory):
    """Packages present and a smoke boot passed (kernel up, CAN modules loaded, vcan0 up)."""
    if platform.machine() != "x86_64":
        pytest.skip(f"user-mode Linux tests need an x86-64 host, this is {platform.machine()}")
    t = time.monotonic()
    try:
        harness.uml_boot.ensure_installed()  # a failed apt-get (asked to install) raises: a failure
    except harness.uml_boot.UmlUnavailable as e:
        pytest.skip(f"user-mode Linux not available: {e}")
    TIMINGS.append(("UML packages present/installed", time.monotonic() - t))
    out = tmp_path_factory.mktemp("uml-smoke")
    r = harness.uml_boot.boot(str(harness.TOOLS / "uml" / "guest_init.sh"), console=out / "console.log",
                              timeout=120, env={"ECU_UML_OUT": str(out)})
    TIMINGS.append(("UML smoke boot (kernel + CAN modules + vcan0 + halt)", r.seconds))
    console = r.console_tail(60)
    if "ptrace" in console and "Operation not permitted" in console:
        pytest.skip("user-mode Linux cannot run here: ptrace is not permitted (container without "
                    "CAP_SYS_PTRACE / seccomp profile blocks it)")
    if r.timed_out:
        pytest.fail(f"UML smoke boot hung (killed after 120 s):\n{console}")
    rc = (out / "guest-modules.rc").read_text().strip() if (out / "guest-modules.rc").exists() else None
    if rc != "0":
        pytest.fail(f"UML smoke boot failed (modules rc {rc}, UML exit {r.returncode}):\n{console}")
    assert "vcan0" in (out / "guest-net.txt").read_text()
    return out


@pytest.fixture(scope="session")
def sim_drive(tmp_path_factory):
    """A 30 s simulated drive (the demo scenario: straight, lane change, slalom, circle)."""
    out = tmp_path_factory.mktemp("sim-drive")
    t = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "simulate", "--scenario", "demo", "--duration", "30",
                        "--out", str(out)], cwd=harness.REPO, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and (out / "drive.log").exists(), f"the simulator failed: {r.stderr[-2000:]}"
    TIMINGS.append(("simulate 30 s demo drive", time.monotonic() - t))
    return out


@pytest.fixture(scope="session")
def artifacts_dir():
    return os.environ.get("ECU_KERNEL_ARTIFACTS")
