"""``ecu-daemon demo``: the real daemon on a virtual bus + pty, with the live view and summary."""
from __future__ import annotations

import io
import re

import pytest

from ecu_daemon.cli import main as cli_main
from ecu_daemon.demo import DemoSession
from ecu_daemon.io.logging_setup import reset_logging
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config


@pytest.fixture(autouse=True)
def _restore_logging():
    yield
    reset_logging()


def test_live_view_and_summary():
    scenario = SCENARIOS["demo"].with_(duration_s=9.0)  # standstill, then pulling away
    cfg = vehicle_config(scenario)
    sim = simulate(scenario, cfg)
    out = io.StringIO()
    session = DemoSession(cfg, sim, speed=2.0, tui=True, out=out)
    assert session.run() == 0
    text = out.getvalue()
    assert text.count("\x1b[H") >= 5  # redrawn in place, several times
    frame = text.split("\x1b[H")[-1]
    for label in ("sideslip [deg]", "heading [deg]", "vx [m/s]", "yaw-rate bias", "GNSS latency", "health:",
                  "tick lateness"):
        assert label in frame
    assert "demo summary" in text
    d = session.daemon
    assert d.steps > 0.8 * 9.0 / 0.006 and d.frames_sent > 0 and session.feeder.frames_sent == len(sim.can_frames)
    assert session.truth.vx_n > 100
    assert session.truth.rms_vx() < 0.5  # the estimator tracks the simulated car through the live path
    m = re.search(r"vx\s+RMS error ([0-9.]+) m/s", text)
    assert m and float(m.group(1)) == pytest.approx(session.truth.rms_vx(), abs=1e-3)


def test_plain_output_when_not_a_terminal(capsys):
    assert cli_main(["demo", "--duration", "3", "--speed", "3", "--no-tui"]) == 0
    out = capsys.readouterr().out
    assert "\x1b[" not in out and "demo summary" in out
    assert re.search(r"^t=\s*[0-9.]+ s", out, re.M)  # periodic plain lines
    # standing still for the first 3 s: no heading yet, and the line says so instead of a number
    last = [ln for ln in out.splitlines() if ln.startswith("t=") and "heading" in ln][-1]
    assert re.search(r"heading\s+- deg \(truth\s+35\.0\)", last), last


@pytest.mark.parametrize("args", [["--speed", "0"], ["--speed", "nan"], ["--duration", "0.5"]])
def test_bad_arguments_are_one_line_errors(args, capsys):
    assert cli_main(["demo", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error" in err


def test_dual_antenna_demo_has_the_heading_before_the_car_moves(capsys):
    assert cli_main(["demo", "--gnss", "dual-antenna", "--duration", "3", "--speed", "3", "--no-tui"]) == 0
    out = capsys.readouterr().out
    # standing still the whole 3 s: only the baseline can give the heading (velocity alone: 0 valid steps)
    m = re.search(r"heading\s+RMS error ([0-9.]+) deg over (\d+) valid steps", out)
    assert m and int(m.group(2)) > 200 and float(m.group(1)) < 0.5


def test_front_rear_demo_feeds_both_receivers_through_their_own_ptys(capsys):
    """Two receivers (issue 11): each gets its own pty and the daemon fuses both, each with its
    own latency (the summary names them; without the second pty the second fuses nothing)."""
    assert cli_main(["demo", "--gnss", "front-rear", "--duration", "14", "--speed", "4", "--no-tui"]) == 0
    out = capsys.readouterr().out
    m = re.search(r"GNSS receivers: #1 fused (\d+), latency ([0-9.]+) s; #2 fused (\d+), latency ([0-9.]+) s", out)
    assert m, out
    assert int(m.group(1)) > 10 and int(m.group(3)) > 10


@pytest.mark.parametrize("speed", [1.0, 4.0])
def test_the_feeder_stamps_each_frame_with_the_drive_s_receive_time(speed):
    """The demo's feeder stands in for the bus and the kernel: each frame carries the drive's
    receive time on the daemon's clock (wall-clock at speed 1), not when its thread got round to
    sending it -- so the daemon's inputs are the drive's, whatever the machine's load."""
    import os

    import can

    from ecu_daemon.demo import Feeder, open_gnss_pty
    from ecu_daemon.io.tick import ScaledClock

    scenario = SCENARIOS["demo"].with_(duration_s=2.0)
    cfg = vehicle_config(scenario)
    sim = simulate(scenario, cfg)
    master, _ = open_gnss_pty()
    channel = f"feeder-stamp-{os.getpid()}-{speed}"
    rx = can.Bus(interface="virtual", channel=channel)
    clock = ScaledClock(speed) if speed != 1.0 else None
    feeder = Feeder(sim, channel, master, speed=speed, **({"clock": clock} if clock else {}))
    try:
        feeder.start()
        assert feeder.played.wait(60), "feeder did not finish"
        got = []
        while (m := rx.recv(timeout=0)) is not None:
            got.append(m)
    finally:
        feeder.stop()
        rx.shutdown()
        os.close(master)
    assert [(m.arbitration_id, bytes(m.data)) for m in got] == [(fid, bytes(d)) for _, fid, d in sim.can_frames]
    want = [feeder.stamp(feeder.c0 + (t - sim.t0)) for t, _, _ in sim.can_frames]
    assert [m.timestamp for m in got] == want
