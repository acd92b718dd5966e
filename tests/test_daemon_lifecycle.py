"""``ecu-daemon run`` as systemd runs it: a real process, sd_notify on a real socket, SIGTERM."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import tty
from pathlib import Path

import pytest

from ecu_daemon.gnss import encode as gnss_encode
from ecu_daemon.gnss.logfile import read_gnss_log
from ecu_daemon.io.notify import SystemdNotifier

REPO = Path(__file__).resolve().parents[1]


def recv_until(sock, pred, timeout=20.0):
    got = []
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        sock.settimeout(max(0.01, end - time.monotonic()))
        try:
            msg = sock.recv(4096).decode()
        except socket.timeout:
            break
        got.append(msg)
        if pred(msg):
            return got
    raise AssertionError(f"no matching notification; got {got}")


def nmea(k):
    utc = 1_700_000_000.0 + 0.2 * k
    return (gnss_encode.nmea_rmc(utc=utc, lat_deg=48.1, lon_deg=11.5, speed_mps=5.0, course_deg=90.0) + "\r\n"
            + gnss_encode.nmea_vtg(speed_mps=5.0, course_deg=90.0) + "\r\n").encode()


def test_notifier_talks_to_abstract_and_path_sockets(tmp_path):
    for addr in (str(tmp_path / "notify.sock"), f"@ecu-daemon-test-{os.getpid()}"):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        s.bind(addr.replace("@", "\0", 1) if addr.startswith("@") else addr)
        n = SystemdNotifier({"NOTIFY_SOCKET": addr, "WATCHDOG_USEC": "2000000"})
        assert n.enabled and n.watchdog_s == 2.0
        assert n.ready("up") and n.watchdog() and n.status("a\nb") and n.stopping()
        s.settimeout(1)
        assert [s.recv(100) for _ in range(4)] == [b"READY=1\nSTATUS=up", b"WATCHDOG=1", b"STATUS=a b",
                                                   b"STOPPING=1"]
        s.close()
        n.close()
    off = SystemdNotifier({})
    assert not off.enabled and not off.ready() and off.errors == 0
    other = SystemdNotifier({"WATCHDOG_USEC": "1000", "WATCHDOG_PID": "1"})  # meant for another process
    assert other.watchdog_s == 0.0


def test_sigterm_flushes_the_recording_and_notifies_systemd(tmp_path):
    sock_path = str(tmp_path / "notify.sock")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(sock_path)
    master, slave = os.openpty()
    tty.setraw(slave)
    port = tmp_path / "ttyGNSS"
    port.symlink_to(os.ttyname(slave))
    os.close(slave)
    cfgfile = tmp_path / "ecu.toml"
    cfgfile.write_text('[can]\ninterface = "virtual"\nchannel = "sigterm-test"\n'
                       '[gnss]\nprotocol = "nmea"\n')
    env = dict(os.environ, NOTIFY_SOCKET=sock_path, WATCHDOG_USEC="300000", JOURNAL_STREAM="8:1234",
               PYTHONPATH=str(REPO))
    rec = tmp_path / "rec"
    proc = subprocess.Popen(
        [sys.executable, "-m", "ecu_daemon", "run", "--config", str(cfgfile), "--gnss-port", str(port),
         "--record", str(rec), "--state-file", str(tmp_path / "state.json")],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    try:
        recv_until(sock, lambda m: m.startswith("READY=1"))
        recv_until(sock, lambda m: m == "WATCHDOG=1")  # fed from the tick
        data = b"".join(nmea(k) for k in range(200))  # 32 kB: more than one read, more than one buffer
        view = memoryview(data)
        while view:  # the pty buffer is small: write as the daemon reads
            try:
                n = os.write(master, view)
                view = view[n:]
            except BlockingIOError:
                time.sleep(0.001)
        proc.send_signal(signal.SIGTERM)  # right away: part of it is still in the tty buffer
        _, err = proc.communicate(timeout=20)
        notes = recv_until(sock, lambda m: m == "STOPPING=1")
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
        sock.close()
    assert proc.returncode == 0, err.decode()
    assert "STOPPING=1" in notes
    lines = err.decode().splitlines()
    assert lines and all(line.startswith("<") and line[2] == ">" for line in lines)  # journald priorities
    assert any(line.startswith("<6>") and "SIGTERM" in line for line in lines)
    assert "Traceback" not in err.decode()
    recorded = b"".join(p for _, _, p in read_gnss_log(rec / "gnss.log"))
    assert recorded == data  # every byte written before SIGTERM made it into the recording
    assert (rec / "estimates.csv").read_text().startswith("t,sideslip_rad")
    assert (rec / "can.log").exists()


def test_bad_config_is_one_line_and_exit_2(tmp_path):
    cfgfile = tmp_path / "bad.toml"
    cfgfile.write_text("[can]\ninterfce = 'virtual'\n")
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "run", "--config", str(cfgfile)],
                       capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(REPO)), timeout=60)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "interfce" in r.stderr and "did you mean 'interface'" in r.stderr


@pytest.mark.parametrize("args, text", [
    (["-i", "socketcan", "-c", "nosuchcan0"], "cannot open CAN bus socketcan:nosuchcan0"),
    (["--duration", "-1"], "--duration"),
])
def test_startup_failures_are_one_line(tmp_path, args, text):
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "run", "--gnss-port", "none", "--state-file", "none",
                        *args], capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(REPO)),
                       timeout=20, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert text in r.stderr and "Traceback" not in r.stderr
