"""``ecu-daemon monitor``: the output frames decoded into a live terminal view.

Unit level: ``MonitorState`` fed with the real ``OutputEncoder``'s frames. End to end: the demo on
a python-can ``udp_multicast`` bus (what a user does to watch it from another terminal or over
ssh) and the monitor running in a real terminal (tmux), whose screen is captured and read.
"""
from __future__ import annotations

import io
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import can
import pytest

from ecu_daemon import config
from ecu_daemon.diagnostics import Diagnostics
from ecu_daemon.estimator import estimate as est_mod
from ecu_daemon.estimator.estimate import Estimate
from ecu_daemon.monitor import MonitorState, render, sparkline
from ecu_daemon.outputs import OutputEncoder

ESTIMATE = Estimate(t=12.5, sideslip_rad=0.02, sideslip_std_rad=0.002, heading_rad=1.0, heading_std_rad=0.02,
                    vx_mps=20.0, vy_mps=0.4, vx_std_mps=0.05, vy_std_mps=0.1, yaw_rate_radps=0.1,
                    yaw_rate_bias_radps=-0.007, yaw_rate_bias_std_radps=0.001, accel_x_bias_mps2=0.1,
                    accel_x_bias_std_mps2=0.05, accel_y_bias_mps2=-0.1, accel_y_bias_std_mps2=0.05,
                    gnss_delay_s=0.2, wheel_scale=0.99, steering_offset_rad=0.01,
                    cornering_stiffness_front_n_per_rad=1e5, cornering_stiffness_rear_n_per_rad=1.2e5,
                    sideslip_valid=True, heading_valid=False, velocity_valid=True, biases_valid=True,
                    status=est_mod.STATUS_HEADING_ALIGNED | est_mod.STATUS_GNSS_FRESH,
                    gnss_fused=7, gnss_rejected=1, gnss_late=0,
                    grade_rad=0.05, grade_std_rad=0.0035, grade_valid=True)


def _frames(steps: int = 250, diag: Diagnostics | None = None):
    enc = OutputEncoder(config.Config())
    diag = diag if diag is not None else Diagnostics()
    diag.gnss_fix_type, diag.gnss_num_sv = 3, 11
    out = []
    for k in range(steps):
        for m in enc.frames(k, ESTIMATE._replace(t=12.5 + 0.006 * k), diag):
            out.append(m)
    return enc.db, out


def test_state_decodes_every_output_and_checks_crc_and_counters():
    db, frames = _frames()
    st = MonitorState(db)
    bad = can.Message(arbitration_id=frames[0].arbitration_id, data=bytes([frames[0].data[0] ^ 1]) + frames[0].data[1:],
                      is_extended_id=False, timestamp=frames[0].timestamp)
    for m in frames[:50] + [bad] + frames[60:]:  # a corrupted frame, and 9 frames lost
        st.add(m)
    st.add(can.Message(arbitration_id=0x0B0, data=bytes(8), is_extended_id=False))  # an input frame
    assert st.bad_frames == 1 and "CRC" in st.last_error and st.counter_jumps >= 1 and st.other_frames == 1
    assert st.get("EST_SIDESLIP", "SIDESLIP") == pytest.approx(0.02, abs=1e-5)
    assert st.get("EST_VELOCITY", "VY") == pytest.approx(0.4, abs=1e-3)
    assert st.choice("EST_HEADING", "HEADING_VALID") == "INVALID"  # the DBC's value table
    assert st.choice("EST_DIAG", "GNSS_FIX_TYPE") == "FIX_3D" and st.diag["GNSS_NUM_SV"] == 11
    assert st.choice("EST_DIAG", "WS_FL_AGE") == "NEVER" and st.choice("EST_DIAG", "GNSS_LATENCY") == "UNKNOWN"
    assert len(st.history["vx [m/s]"]) >= 5  # ~4 Hz over 1.5 s of frame time


def test_render_shows_names_values_validity_and_status():
    from rich.console import Console

    db, frames = _frames()
    st = MonitorState(db)
    for m in frames:
        st.add(m)
    con = Console(file=io.StringIO(), width=140, color_system=None)
    con.print(render(st, "virtual:test", frames[-1].timestamp))
    text = con.file.getvalue()
    for s in ("sideslip [deg]", "1.146", "heading [deg]", "INVALID", "vx [m/s]", "20.000",
              "status: GNSS_FRESH HEADING_ALIGNED", "GNSS: fix FIX_3D  sv 11", "WS_FL", "tick lateness p50",
              "bank [deg]", "grade [deg]", "roll [deg]"):
        assert s in text, s
    assert "GNSS heading" not in text  # no dual-antenna receiver: no line for it
    grade = next(line for line in text.splitlines() if "grade [deg]" in line)
    assert "2.865" in grade and "0.201" in grade and "VALID" in grade and "INVALID" not in grade  # deg


def test_render_shows_the_dual_antenna_heading_once_there_is_one():
    from rich.console import Console

    d = Diagnostics(gnss_heading_state=3, gnss_heading_carr_soln=1, gnss_heading_acc_rad=math.radians(0.25),
                    gnss_heading_baseline_m=1.312, gnss_heading_fused=40, gnss_heading_rejected=2)
    db, frames = _frames(diag=d)
    st = MonitorState(db)
    for m in frames:
        st.add(m)
    con = Console(file=io.StringIO(), width=140, color_system=None)
    con.print(render(st, "virtual:test", frames[-1].timestamp))
    assert "GNSS heading: BASELINE_MISMATCH  carrier FLOAT  acc 0.25 deg  baseline 1.312 m  fused 40 rejected 2" \
        in con.file.getvalue()


def test_sparkline_scales_to_its_own_range():
    assert sparkline([0, 1, 2, 3, 4, 5, 6, 7], 8) == "▁▂▃▄▅▆▇█"
    assert sparkline([float("nan")] * 3, 8) == "" and sparkline([2.0, 2.0], 8) == "▁▁"


# --------------------------------------------------------------------------------- in a real terminal

def _tmux() -> str:
    """tmux, installed with apt-get when missing and root (as CI runs); otherwise skip saying so."""
    if shutil.which("tmux") is None:
        if os.geteuid() != 0:
            pytest.skip("tmux is not installed (apt-get install -y tmux)")
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        for cmd in (["apt-get", "update", "-q"], ["apt-get", "install", "-y", "-q", "tmux"]):
            subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, timeout=600)
    return shutil.which("tmux")


def test_monitor_in_a_terminal_shows_the_demo_running_on_a_shared_bus(tmp_path):
    tmux = _tmux()
    exe = str(Path(sys.executable).with_name("ecu-daemon"))
    group, port = "239.74.163.7", str(40000 + os.getpid() % 20000)  # private to this test run
    bus = ["-i", "udp_multicast", "-c", group, "--bus-kwargs", f"port={port}"]
    session = f"ecu-monitor-test-{os.getpid()}"
    demo = subprocess.Popen([exe, "demo", "--duration", "30", "--no-tui", *bus],
                            stdout=subprocess.DEVNULL, stderr=(tmp_path / "demo.err").open("w"))
    try:
        subprocess.run([tmux, "new-session", "-d", "-s", session, "-x", "140", "-y", "50",
                        # the pane's size, not a COLUMNS/LINES inherited from pytest's environment
                        " ".join(["env", "-u", "COLUMNS", "-u", "LINES", exe, "monitor", *bus, "--duration", "60"])],
                       check=True)
        deadline, screen = time.monotonic() + 90, ""
        while time.monotonic() < deadline:
            time.sleep(1.0)
            screen = subprocess.run([tmux, "capture-pane", "-p", "-t", session], capture_output=True,
                                    text=True).stdout
            if "fix FIX_3D" in screen and "HEADING_ALIGNED" in screen:
                break
        assert "ecu-daemon monitor on udp_multicast:" + group in screen, screen
        rows = {ln.split("│")[1].strip(): ln for ln in screen.splitlines() if ln.count("│") >= 5}
        for label in ("sideslip [deg]", "heading [deg]", "vx [m/s]", "yaw-rate bias [deg/s]"):
            cells = [c.strip() for c in rows[label].split("│")]
            assert float(cells[2]) == float(cells[2]) and cells[4] in ("VALID", "INVALID"), rows[label]
        vx = float([c.strip() for c in rows["vx [m/s]"].split("│")][2])
        assert 0.0 < vx < 30.0  # the simulated car pulling away, decoded from EST_VELOCITY
        assert float([c.strip() for c in rows["WS_FL"].split("│")][3]) > 50  # wheel-speed rate in Hz (100)
        assert "fix FIX_3D" in screen and "status:" in screen and "tick lateness p50" in screen
        assert "bad 0" in screen  # every output frame passed its CRC
    finally:
        subprocess.run([tmux, "kill-session", "-t", session], capture_output=True)
        demo.terminate()
        demo.wait(30)
