"""tools/player.py on real parts: python-can's ``virtual`` bus and real pseudo-terminals."""
from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import can
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import player  # noqa: E402

NMEA = "$GPRMC,123519.00,A,4807.03800,N,01131.00000,E,22.4,84.4,230394,,,A*46"
UBX_HEX = "B562010700000000"  # framing only; the player does not interpret payloads


def _write_logs(tmp_path: Path):
    can_log = tmp_path / "drive.log"
    can_log.write_text(
        "(100.000000) can0 123#0102\n"
        "(100.010000) can1 456#AA\n"
        "(100.020000) can0 12345678#DEADBEEF\n"
        "(100.030000) can0 20000040#0000000000000000\n"
        "(100.040000) can0 321#R\n"
        "(100.050000) can0 124#1122334455667788\n")
    gnss_log = tmp_path / "drive_gnss.log"
    gnss_log.write_text(
        f"(100.005000) ttyACM0 {NMEA}\n"
        f"(100.045000) ttyACM0 {UBX_HEX}\n")
    return can_log, gnss_log


def _read_until(fd: int, n: int, timeout: float = 10.0) -> bytes:
    """Read from a pty master until n bytes arrived (bounded wait on the condition)."""
    buf = b""
    end = time.monotonic() + timeout
    while len(buf) < n and time.monotonic() < end:
        r, _, _ = select.select([fd], [], [], 0.1)
        if r:
            buf += os.read(fd, 4096)
    return buf


def test_candump_frame_syntax(tmp_path):
    """The player reads logs with the package's one reader (canlog): every candump frame syntax."""
    log = tmp_path / "frames.log"
    log.write_text("".join(f"(1.{i:06d}) can0 {f}\n" for i, f in enumerate(
        ("123#0102", "12345678#DEADBEEF", "20000040#0000000000000000", "321#R", "123##1AABB", "7FF#01.02.03"))))
    m = [e.message for e in player.read_candump(log)]
    assert (m[0].arbitration_id, m[0].is_extended_id, bytes(m[0].data), m[0].dlc) == (0x123, False, b"\x01\x02", 2)
    assert m[1].is_extended_id and m[1].arbitration_id == 0x12345678
    assert m[2].is_error_frame and m[2].arbitration_id == 0x40 and not m[2].is_extended_id  # bus-off
    assert m[3].is_remote_frame and m[3].dlc == 0
    assert m[4].is_fd and m[4].bitrate_switch and bytes(m[4].data) == b"\xaa\xbb"
    assert bytes(m[5].data) == b"\x01\x02\x03"
    for bad in ("12#00", "123", "123#0"):
        log.write_text(f"(1.000000) can0 {bad}\n")
        with pytest.raises(player.PlayerError, match="frames.log:1"):
            list(player.read_candump(log))


def test_readers_and_bad_lines(tmp_path):
    can_log, gnss_log = _write_logs(tmp_path)
    evs = list(player.read_candump(can_log))
    assert [e.source for e in evs] == ["can0", "can1", "can0", "can0", "can0", "can0"]
    assert evs[2].t == pytest.approx(100.02)
    g = list(player.read_gnss_capture(gnss_log))
    assert g[0].data == NMEA.encode() + b"\r\n" and g[1].data == bytes.fromhex(UBX_HEX)

    bad = tmp_path / "bad.log"
    bad.write_text("# comment is skipped\n(1.000000) can0 123#01\n(1.1) can0 zz#01\n")
    with pytest.raises(player.PlayerError, match=r"bad.log:3"):
        list(player.read_candump(bad))
    badg = tmp_path / "bad_gnss.log"
    badg.write_text("(1.000000) ttyACM0 not-hex-nor-nmea\n")
    with pytest.raises(player.PlayerError, match=r"bad_gnss.log:1"):
        list(player.read_gnss_capture(badg))


def test_schedule_speed_start_loop_epoch():
    evs = [player.Event(10.0 + i, "can0", can.Message(arbitration_id=i)) for i in range(4)]  # t=10..13
    s = [round(d, 6) for d, _ in player.schedule(lambda: evs, speed=2.0)]
    assert s == [0.0, 0.5, 1.0, 1.5]
    s = [(round(d, 6), e.t) for d, e in player.schedule(lambda: evs, start=1.5)]
    assert s == [(0.5, 12.0), (1.5, 13.0)]  # events before epoch+start are skipped, times stay absolute
    s = [round(d, 6) for d, _ in player.schedule(lambda: evs, loops=3)]
    assert s == [0.0, 1.0, 2.0, 3.0, 3.001, 4.001, 5.001, 6.001, 6.002, 7.002, 8.002, 9.002]
    s = [round(d, 6) for d, _ in player.schedule(lambda: evs, epoch=9.0)]
    assert s == [1.0, 2.0, 3.0, 4.0]
    forever = player.schedule(lambda: evs, loops=None)
    assert len([next(forever) for _ in range(40)]) == 40
    with pytest.raises(player.PlayerError):
        list(player.schedule(lambda: evs, speed=0))
    assert player.parse_mapping(["vcan0=can0", "vcan1=can1"]) == {"can0": "vcan0", "can1": "vcan1"}
    with pytest.raises(player.PlayerError):
        player.parse_mapping(["vcan0"])


def test_plays_mapped_frames_onto_virtual_bus_and_gnss_into_pty(tmp_path):
    can_log, gnss_log = _write_logs(tmp_path)
    master, slave = os.openpty()
    port = player.GnssPort(os.ttyname(slave))  # pyserial on the pty slave, as on a real UART
    rx = can.Bus(interface="virtual", channel="player-test-out", receive_own_messages=False)
    tx = can.Bus(interface="virtual", channel="player-test-out")
    try:
        def events():
            import heapq
            return heapq.merge(player.read_candump(can_log), player.read_gnss_capture(gnss_log),
                               key=lambda e: e.t)
        p = player.Player(player.schedule(events, speed=5.0), buses={"player-test-out": tx},
                          route={"can0": "player-test-out"}, gnss=port)
        th = threading.Thread(target=p.run)
        th.start()
        got = []
        while len(got) < 5:
            m = rx.recv(timeout=10)
            assert m is not None, f"only {len(got)} frames arrived"
            got.append(m)
        th.join(10)
        assert not th.is_alive()
        assert rx.recv(timeout=0) is None  # the can1 frame was not mapped
        assert [(m.arbitration_id, m.is_extended_id, m.is_error_frame, m.is_remote_frame) for m in got] == [
            (0x123, False, False, False), (0x12345678, True, False, False), (0x40, False, True, False),
            (0x321, False, False, True), (0x124, False, False, False)]
        assert bytes(got[4].data) == bytes.fromhex("1122334455667788")
        want = NMEA.encode() + b"\r\n" + bytes.fromhex(UBX_HEX)
        assert _read_until(master, len(want)) == want
        assert p.stats.can_sent == 5 and p.stats.can_unmapped == 1 and p.stats.gnss_messages == 2
        assert p.stats.gnss_dropped == 0 and p.stats.can_errors == 0
    finally:
        rx.shutdown()
        tx.shutdown()
        port.close()
        os.close(master)
        os.close(slave)


def test_cli_pty_loop_and_sigterm(tmp_path):
    can_log, gnss_log = _write_logs(tmp_path)
    link = tmp_path / "gnss0"
    proc = subprocess.Popen(
        [sys.executable, str(ROOT / "tools" / "player.py"), "-I", str(can_log), "--gnss", str(gnss_log),
         "--gnss-pty", str(link), "--loop", "i", "-i", "virtual", "-c", "nobody-listens", "-v"],
        stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 20
        while not link.exists() and time.monotonic() < end and proc.poll() is None:
            time.sleep(0.02)  # polling for the condition, bounded
        assert link.is_symlink(), proc.stderr.read() if proc.poll() is not None else "no pty link"
        fd = os.open(link, os.O_RDONLY | os.O_NOCTTY)
        try:
            first = _read_until(fd, len(NMEA) + 2)
        finally:
            os.close(fd)
        assert first.startswith(NMEA.encode())  # raw pty: no echo, CR LF untouched
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "(stopped)" in err and "CAN frames sent" in err
    assert not link.exists()  # the published link is removed on exit


def test_cli_errors_are_one_line(tmp_path):
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "player.py"), "-I", str(tmp_path / "missing.log"),
                        "-i", "virtual"], capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "no such file" in r.stderr
    can_log, _ = _write_logs(tmp_path)
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "player.py"), "-I", str(can_log),
                        "badmap", "-i", "virtual"], capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and "OUT=IN" in r.stderr and r.stderr.strip().count("\n") == 0


def test_a_late_player_stamps_frames_with_their_deadlines():
    """With ``stamp``, a frame's timestamp is its deadline however late the player sends it (the
    clock here is always 5 ms past whatever was asked): the lateness goes into the arrival, never
    into the data."""
    from ecu_daemon.io.player import Event, Player

    now = [100.0]

    def late_clock():
        now[0] += 0.005
        return now[0]

    channel = f"player-stamp-{os.getpid()}"
    rx = can.Bus(interface="virtual", channel=channel)
    tx = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
    try:
        events = [(0.01 * i, Event(0.01 * i, "can0", can.Message(arbitration_id=0x100 + i, data=b"\x01")))
                  for i in range(5)]
        p = Player(events, buses={None: tx}, clock=late_clock, start_at=100.0, stamp=lambda d: d + 1000.0)
        p.run()
        got = [rx.recv(timeout=0) for _ in range(5)]
        assert [m.arbitration_id for m in got] == [0x100 + i for i in range(5)]
        assert [m.timestamp for m in got] == [1100.0 + 0.01 * i for i in range(5)]
        assert min(p.stats.lateness) > 0  # every one of them was sent late
    finally:
        rx.shutdown()
        tx.shutdown()
