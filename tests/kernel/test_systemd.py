"""systemd under test: our unit, network file and config in a UML guest booting systemd as PID 1.

The guest's root is a minimal Debian bookworm made once by ``tools/uml/build_rootfs.sh`` (cached in
/var/cache/ecu-daemon-uml/rootfs) with Debian's python3 and a venv holding our dependencies; every
run installs the current wheel, the template unit ``systemd/ecu-daemon@.service``, ``systemd/80-can.network`` and a
config into it. ``can0`` is a real can-dev device: the kernel's slcan driver on a pseudo-terminal
whose other end (``tools/uml/slcan_adapter.py``) plays a simulated drive into the bus and logs what
the daemon transmits. networkd sets its bit rate and restart-ms from our .network file; the
device's appearance starts the service (``WantedBy=``/``BindsTo=`` the device).

The probe (``tools/uml/systemd_probe.sh``) checks inside and writes files; the tests judge them:
active only after READY=1, outputs on can0, SIGSTOP -> watchdog restart, ``systemd-analyze
verify`` and ``security``, a clean stop, learned state persisted in the StateDirectory.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import cantools
import pytest

import harness
from conftest import FACTS, TIMINGS

ROOTFS = Path(os.environ.get("ECU_UML_ROOTFS", "/var/cache/ecu-daemon-uml/rootfs"))
TEMPLATE = "ecu-daemon@.service"
UNIT = "ecu-daemon@can0.service"  # the instance is the CAN interface

SLCAN_UNIT = """[Unit]
Description=test: emulated slcan adapter as can0, replaying a simulated drive
After=systemd-udevd.service

[Service]
Type=simple
RuntimeDirectory=ecu-test
RuntimeDirectoryPreserve=yes
# PID 1 logs every sd_notify message at debug level: on before can0 (and so the daemon) exists
ExecStartPre=/usr/bin/systemd-analyze log-level debug
ExecStartPre=/sbin/modprobe -a can can-raw can-dev slcan
ExecStart=/opt/ecu-daemon/venv/bin/python /opt/ecu-test/tools/uml/slcan_adapter.py --out /opt/ecu-test/out \
    --play /opt/ecu-test/drive.log --gnss /opt/ecu-test/drive_gnss.log --gnss-pty /run/ecu-test/gnss0

[Install]
WantedBy=multi-user.target
"""

PROBE_UNIT = """[Unit]
Description=test: probe ecu-daemon@can0.service
After=ecu-test-slcan.service

[Service]
Type=oneshot
ExecStart=/bin/sh /opt/ecu-test/probe.sh
TimeoutStartSec=600

[Install]
WantedBy=multi-user.target
"""

# Test-only difference from the shipped unit: the GNSS "receiver" is a pseudo-terminal.
DROPIN = """[Service]
DeviceAllow=char-pts rw
"""

# Test-only difference from the shipped .network file: the kernel's slcan driver has no
# do_set_mode, so it rejects restart-ms ("Device doesn't support restart from Bus Off") and networkd
# would fail the whole link. Real controllers (mcp251x, m_can, gs_usb ...) take RestartSec= as shipped.
NETWORK_DROPIN = """[CAN]
RestartSec=0
"""


def _chroot(*cmd, timeout=300):
    return subprocess.run(["chroot", str(ROOTFS), *cmd], capture_output=True, text=True, timeout=timeout)


def _rootfs_or_skip() -> None:
    if os.geteuid() != 0:
        pytest.skip("the systemd guest needs root (debootstrap, chroot)")
    stamp = ROOTFS / ".ecu-rootfs-stamp"
    build = harness.TOOLS / "uml" / "build_rootfs.sh"
    need_build = True
    if stamp.exists():  # the script itself decides whether the stamp is current; cheap when it is
        need_build = False
    if shutil.which("debootstrap") is None:
        if not harness.uml_boot.install_allowed():
            if need_build:
                pytest.skip("no root filesystem for the systemd guest and no debootstrap: apt-get install "
                            f"debootstrap, then run {build}")
        else:
            harness.uml_boot.ensure_installed(("debootstrap",))
    t = time.monotonic()
    r = subprocess.run(["sh", str(build), str(ROOTFS)], capture_output=True, text=True, timeout=900)
    if r.returncode != 0:
        pytest.fail(f"building the root filesystem failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    if "up to date" not in r.stdout:
        TIMINGS.append(("debootstrap root filesystem + venv (first run only)", time.monotonic() - t))


def _install(sim_drive: Path, work: Path) -> None:
    """Put the current wheel, units, config and test scaffolding into the root filesystem."""
    t = time.monotonic()
    wheels = work / "wheel"
    # The wheel compiles the C and Cython modules in an isolated build env: ~2 min on an idle 2-core machine,
    # over 5 min when the machine is loaded. The timeout only guards against a hang.
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(wheels), str(harness.REPO)],
                       capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr[-2000:]
    whl = next(wheels.glob("ecu_daemon-*.whl"))
    shutil.copy(whl, ROOTFS / "tmp" / whl.name)
    r = _chroot("/opt/ecu-daemon/venv/bin/pip", "install", "-q", "--no-deps", "--force-reinstall",
                "--disable-pip-version-check", f"/tmp/{whl.name}")
    assert r.returncode == 0, r.stderr[-2000:]
    link = ROOTFS / "usr/local/bin/ecu-daemon"
    link.unlink(missing_ok=True)
    link.symlink_to("/opt/ecu-daemon/venv/bin/ecu-daemon")

    etc = ROOTFS / "etc"
    shutil.copy(harness.REPO / "systemd" / TEMPLATE, etc / "systemd/system" / TEMPLATE)
    (etc / "systemd/network").mkdir(parents=True, exist_ok=True)
    shutil.copy(harness.REPO / "systemd/80-can.network", etc / "systemd/network/80-can.network")
    (etc / "systemd/network/80-can.network.d").mkdir(exist_ok=True)
    (etc / "systemd/network/80-can.network.d/50-test-slcan.conf").write_text(NETWORK_DROPIN)
    (etc / "ecu-daemon").mkdir(exist_ok=True)
    cfg = harness.guest_config(sim_drive / "config.toml", etc / "ecu-daemon/ecu-daemon.toml", "/run/ecu-test/gnss0",
                               channel="can0", state_file="/var/lib/ecu-daemon/state.json")
    text = cfg.read_text()  # DBCs as existing configs name them: the package data of the installed wheel
    cfg.write_text(text.replace(str(harness.REPO / "ecu_daemon") + "/", ""))
    dropin = etc / "systemd/system" / f"{UNIT}.d"
    dropin.mkdir(exist_ok=True)
    (dropin / "50-test-pty.conf").write_text(DROPIN)
    (etc / "systemd/system/ecu-test-slcan.service").write_text(SLCAN_UNIT)
    (etc / "systemd/system/ecu-test-probe.service").write_text(PROBE_UNIT)
    confd = etc / "systemd/system.conf.d"
    confd.mkdir(exist_ok=True)
    guest_env = harness.uml_boot.guest_environment()
    (confd / "50-uml-cpu.conf").write_text(
        "[Manager]\n# UML keeps only SSE register state: every service must stay off AVX (see tools/uml/boot.py)\n"
        + ("DefaultEnvironment=" + " ".join(f'"{k}={v}"' for k, v in guest_env.items()) + "\n" if guest_env else ""))

    test = ROOTFS / "opt/ecu-test"
    shutil.rmtree(test, ignore_errors=True)
    (test / "tools/uml").mkdir(parents=True)
    (test / "out").mkdir()
    shutil.copy(harness.TOOLS / "player.py", test / "tools/player.py")
    shutil.copy(harness.TOOLS / "uml/slcan_adapter.py", test / "tools/uml/slcan_adapter.py")
    shutil.copy(harness.TOOLS / "uml/systemd_probe.sh", test / "probe.sh")
    shutil.copy(sim_drive / "drive.log", test / "drive.log")
    shutil.copy(sim_drive / "drive_gnss.log", test / "drive_gnss.log")
    for d in ("var/lib/private/ecu-daemon", "var/lib/ecu-daemon"):  # no learned state from earlier runs
        p = ROOTFS / d
        if p.is_symlink() or p.is_file():
            p.unlink()
        elif p.exists():
            shutil.rmtree(p)
    r = _chroot("systemctl", "enable", UNIT, "ecu-test-slcan.service", "ecu-test-probe.service")
    assert r.returncode == 0, r.stderr
    TIMINGS.append(("systemd guest: wheel + units installed into the root filesystem", time.monotonic() - t))


@pytest.fixture(scope="module")
def guest(uml, sim_drive, tmp_path_factory):
    _rootfs_or_skip()
    work = tmp_path_factory.mktemp("systemd")
    _install(sim_drive, work)
    out = ROOTFS / "opt/ecu-test/out"
    r = harness.uml_boot.boot("/lib/systemd/systemd", rootfs=str(ROOTFS), console=work / "console.log",
                              mem="1024M", timeout=420)
    TIMINGS.append(("systemd guest (boot + probe + poweroff)", r.seconds))
    harness.copy_artifacts(out, "systemd")
    if r.timed_out:
        pytest.fail(f"systemd guest hung, killed after 420 s; probe log:\n"
                    f"{(out / 'probe.log').read_text()[-3000:] if (out / 'probe.log').exists() else '-'}\n"
                    f"console:\n{r.console_tail(40)}")
    if not (out / "probe.done").exists():
        pytest.fail(f"the probe did not finish; probe log:\n"
                    f"{(out / 'probe.log').read_text()[-3000:] if (out / 'probe.log').exists() else '-'}\n"
                    f"console:\n{r.console_tail(60)}")
    return out


def _show(path: Path) -> dict:
    return dict(line.split("=", 1) for line in path.read_text().splitlines() if "=" in line)


def _rc(out: Path, name: str) -> str:
    return (out / name).read_text().strip()


def _journal(out: Path) -> str:
    return (out / "journal-all.txt").read_text(errors="replace")


def test_active_only_after_ready(guest):
    assert _rc(guest, "active.rc") == "0", (guest / "show-start.txt").read_text()[-2000:]
    pid1 = (guest / "pid1-start.txt").read_text()
    t_ready = t_running = None
    for line in pid1.splitlines():
        t = float(line.split("]", 1)[0].strip("[ "))
        if t_ready is None and "READY=1" in line:
            t_ready = t
        if t_running is None and "Changed start -> running" in line:
            t_running = t
    assert t_ready is not None, f"PID 1 never logged READY=1:\n{pid1[-2000:]}"
    assert t_running is not None and t_running >= t_ready, pid1[-2000:]
    show = _show(guest / "show-start.txt")
    to_ready = (int(show["ActiveEnterTimestampMonotonic"]) - int(show["ExecMainStartTimestampMonotonic"])) / 1e6
    assert to_ready > 0.2, f"active {to_ready:.3f} s after exec: not waiting for READY=1?"
    assert show["Type"] == "notify" and show["NotifyAccess"] == "main"
    FACTS.append(f"systemd: ecu-daemon active {to_ready:.2f} s after exec, on READY=1 (Type=notify)")


def test_networkd_configured_can0(guest):
    link = (guest / "can0-link.txt").read_text()
    assert "bitrate 500000" in link, link
    assert re.search(r"<[^>]*\bUP\b", link), link
    status = (guest / "networkctl.txt").read_text()
    assert "80-can.network" in status and "failed" not in status, status
    shipped = (harness.REPO / "systemd/80-can.network").read_text()
    assert re.search(r"^RestartSec=100ms$", shipped, re.M)  # bus-off restart on real controllers
    events = json.loads((guest / "slcan-events.json").read_text())
    assert events["bitrate"] == 500000 and "O" in events["commands"], events


def test_outputs_on_can0_with_good_crcs(guest):
    assert _rc(guest, "tx.rc") == "0"
    cap = harness.Capture.read(guest / "can0-tx.log")
    db = cantools.database.load_file(str(harness.OUTPUT_DBC))
    for name in ("EST_SIDESLIP", "EST_VELOCITY", "EST_HEADING", "EST_DIAG"):
        r = harness.integrity(cap, db.get_message_by_name(name))
        assert r["count"] > 50 and r["bad_crc"] == 0 and r["bad_dlc"] == 0, (name, r)


def test_watchdog_restarts_a_frozen_daemon(guest):
    assert _rc(guest, "restart.rc") == "0", (guest / "probe.log").read_text()[-2000:]
    assert _rc(guest, "active-again.rc") == "0"
    assert _rc(guest, "tx-again.rc") == "0", "no outputs after the restart"
    show = _show(guest / "show-restarted.txt")
    assert int(show["NRestarts"]) == 1
    assert show["MainPID"] != _rc(guest, "frozen.pid")
    journal = _journal(guest)
    assert "Watchdog timeout" in journal and "Failed with result 'watchdog'" in journal, \
        [ln for ln in journal.splitlines() if UNIT in ln][-20:]
    FACTS.append(f"systemd: SIGSTOP -> watchdog kill -> restart, NRestarts={show['NRestarts']}")


def test_systemd_analyze_verify_and_security(guest):
    verify = (guest / "verify.txt").read_text()
    assert _rc(guest, "verify.rc") == "0", verify
    assert not [ln for ln in verify.splitlines() if "ecu-daemon" in ln], verify
    sec = (guest / "security.txt").read_text()
    m = re.search(r"Overall exposure level for " + re.escape(UNIT) + r": ([0-9.]+) (\S+)", sec)
    assert m, sec[-2000:]
    score = float(m.group(1))
    FACTS.append(f"systemd-analyze security {UNIT}: {score} {m.group(2)}")
    assert score <= 2.0, sec


def test_clean_stop_and_persisted_state(guest):
    show = _show(guest / "show-stopped.txt")
    assert show["ActiveState"] == "inactive" and show["Result"] == "success", show.get("Result")
    assert show["ExecMainStatus"] == "0"
    t0, t1 = map(float, (guest / "stop-times.txt").read_text().split())
    assert t1 - t0 < 10.0
    state_dir = ROOTFS / "var/lib/private/ecu-daemon/can0"  # StateDirectory=ecu-daemon/%i, DynamicUser=yes
    state = sorted(state_dir.glob("*")) if state_dir.exists() else []
    assert [p.name for p in state] == ["state.json"], "no learned-state file in the StateDirectory after a clean stop"
    journal = (guest / "journal-unit.txt").read_text(errors="replace")
    assert "Traceback" not in journal, journal[-3000:]
    FACTS.append(f"systemd: stop took {t1 - t0:.2f} s; state files {[p.name for p in state]}")
