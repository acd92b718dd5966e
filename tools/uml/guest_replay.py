#!/usr/bin/env python3
"""Inside the UML guest: replay a drive onto vcan0 past the daemon and capture the bus.

Runs as the job of ``guest_init.sh``. Order of events:

1. ``candump -L vcan0,0:0,#FFFFFFFF`` captures every data *and* error frame to ``bus.log``;
2. ``tools/player.py`` opens a pseudo-terminal for the GNSS feed (published as ``gnss0`` in the
   results directory) and waits;
3. the daemon starts with ``NOTIFY_SOCKET`` pointing at our abstract socket; we wait for READY=1
   (the systemd protocol, for real) and keep every notification with its time;
4. SIGUSR1 starts the GNSS player and ``canplayer -I drive.log vcan0=<log if>`` starts at once;
   faults from the job (error frames, a flood of unrelated IDs, wrong DLCs) are injected through
   a raw AF_CAN socket at their drive-log times, as far as canplayer has actually got (the log's
   frames seen on the bus, :class:`PlaybackProgress`), not by the wall clock;
5. when canplayer is done: SIGTERM the daemon (its exit status and shutdown time are recorded),
   SIGINT candump (SIGINT, not SIGTERM, so it flushes), stop the player;
6. ``cantools decode`` of the capture with the output DBC -> ``decoded.txt``.

Everything lands in the job's ``out`` directory with ``results.json``; the host checks it.
"""
from __future__ import annotations

import bisect
import importlib.util
import json
import math
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tools/, for player.py

CAN_ERR_FLAG = 0x20000000
CAN_FRAME = struct.Struct("=IB3x8s")


class Notifications(threading.Thread):
    """Collects sd_notify datagrams on an abstract AF_UNIX socket (what systemd would receive)."""

    def __init__(self, name: str):
        super().__init__(daemon=True)
        self.address = "@" + name
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind("\0" + name)
        self.sock.settimeout(0.2)
        self.messages: list[tuple[float, str]] = []
        self.ready = threading.Event()
        self.stopping = False

    def run(self):
        while not self.stopping:
            try:
                data = self.sock.recv(4096)
            except socket.timeout:
                continue
            except OSError:
                break
            text = data.decode("utf-8", "replace")
            self.messages.append((time.time(), text))
            if "READY=1" in text.split("\n"):
                self.ready.set()


def raw_can_socket(channel: str) -> socket.socket:
    s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    s.bind((channel,))
    return s


def send_frame(s: socket.socket, can_id: int, data: bytes, dlc: int | None = None) -> bool:
    """One classic frame; ``dlc`` may disagree with len(data) on purpose (wrong-DLC faults)."""
    dlc = len(data) if dlc is None else dlc
    try:
        s.send(CAN_FRAME.pack(can_id, dlc, data.ljust(8, b"\0")[:8]))
        return True
    except OSError:  # ENOBUFS under flood: count it, as a real controller would drop
        return False


BCM_HEAD = "@3I4l2I"  # struct bcm_msg_head (native alignment: 4 bytes of padding after count)
TX_SETUP, TX_DELETE, SETTIMER, STARTTIMER = 1, 2, 0x0001, 0x0002


def bcm_flood(channel: str, ids: list[int], rate: float, data: bytes) -> socket.socket:
    """Start one kernel Broadcast Manager job per ID so the IDs together send ``rate`` frames/s.

    The kernel's own timers send the frames: a flood at a 500 kbit/s bus's full rate without a
    user-space sender competing with the daemon for the (single, ptrace-slow) UML CPU.
    """
    s = socket.socket(socket.AF_CAN, socket.SOCK_DGRAM, socket.CAN_BCM)
    s.connect((channel,))
    interval_us = round(len(ids) * 1e6 / rate)
    for can_id in ids:
        head = struct.pack(BCM_HEAD, TX_SETUP, SETTIMER | STARTTIMER, 0, 0, 0,
                           interval_us // 1_000_000, interval_us % 1_000_000, can_id, 1)
        s.send(head + CAN_FRAME.pack(can_id, len(data), data))
    return s


def bcm_stop(s: socket.socket, ids: list[int]) -> None:
    for can_id in ids:
        s.send(struct.pack(BCM_HEAD, TX_DELETE, 0, 0, 0, 0, 0, 0, can_id, 0))
    s.close()


def tx_packets(channel: str) -> int:
    return int(Path(f"/sys/class/net/{channel}/statistics/tx_packets").read_text())


class PlaybackProgress(threading.Thread):
    """Where canplayer is in the drive log, from the log's own frames seen on the bus.

    A fault due at log time ``at`` (seconds after the first frame) must meet the drive where the
    drive is, not where the wall clock says it should be: under a loaded host canplayer starts late
    and falls behind. So each frame received on ``channel`` (kernel-filtered to the log's IDs) is
    matched, in order, against the log; the newest match anchors log time to CLOCK_MONOTONIC, and
    :meth:`due` answers only once the last log frame at or before the fault's time has been seen,
    and then extrapolates from the newest match (through silent stretches of the log, such as a
    bus-off): a fault never comes before the drive has got there. Frames that match nothing ahead
    (the injector's own wrong-DLC frames) are passed over.
    """

    LOOKAHEAD = 64  # log frames searched ahead of the last match (a frame our socket missed)

    def __init__(self, channel: str, drive_log: str, t0: float):
        super().__init__(daemon=True)
        import player  # tools/player.py; imported here, after the interpreter check in main()

        events = list(player.read_candump(drive_log))
        first = events[0].t
        self.log = [(ev.t - first, ev.message.arbitration_id, bytes(ev.message.data)) for ev in events]
        self.times = [t for t, _, _ in self.log]
        self.anchor = (0.0, t0)  # (log time, monotonic time) of the newest matched frame
        self.matched = 0
        self._next = 0
        self.sock = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
        ids = sorted({can_id for _, can_id, _ in self.log})
        self.sock.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FILTER,
                             b"".join(struct.pack("=II", i, 0x7FF) for i in ids))
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.sock.bind((channel,))

    def run(self):
        while self._next < len(self.log):
            try:
                can_id, dlc, data = CAN_FRAME.unpack(self.sock.recv(16))
            except OSError:
                return
            now = time.monotonic()
            data = data[:dlc]
            for j in range(self._next, min(self._next + self.LOOKAHEAD, len(self.log))):
                t, lid, ldata = self.log[j]
                if lid == can_id & 0x7FF and ldata == data:
                    self.anchor, self._next = (t, now), j + 1
                    self.matched += 1
                    break

    def due(self, at: float) -> float:
        """CLOCK_MONOTONIC time at which the playback reaches log time ``at`` (inf: not known yet)."""
        if self._next < bisect.bisect_right(self.times, at):  # the last frame before ``at`` not seen yet
            return math.inf
        t, m = self.anchor
        return m + (at - t)

    def close(self):
        self.sock.close()


def inject(faults: list[dict], progress: PlaybackProgress, channel: str, log: list) -> None:
    """Run the fault schedule: ``at`` in seconds of drive-log time, met where canplayer has got to."""
    s = raw_can_socket(channel)
    try:
        for f in sorted(faults, key=lambda f: f["at"]):
            while (rem := progress.due(f["at"]) - time.monotonic()) > 0 and progress.is_alive():
                time.sleep(min(rem, 0.01))
            deadline = time.monotonic()  # the fault's own durations run from when it started
            kind, started, sent, failed = f["kind"], time.time(), 0, 0
            if kind == "error_frame":  # canerrsim-style: class bits in the ID, details in data
                ok = send_frame(s, CAN_ERR_FLAG | f["class"], bytes.fromhex(f.get("data", "00" * 8)))
                sent, failed = int(ok), int(not ok)
            elif kind == "flood":
                data = bytes.fromhex(f.get("data", "55" * 8))
                before = tx_packets(channel)
                bcm = bcm_flood(channel, f["ids"], f["rate"], data)
                end = deadline + f["duration"]
                while (rem := end - time.monotonic()) > 0:
                    time.sleep(min(rem, 0.1))
                bcm_stop(bcm, f["ids"])
                sent = tx_packets(channel) - before  # every frame on vcan0 in the window, flood included
            elif kind == "wrong_dlc":
                ids = f["ids"]
                period = f.get("period", 0.01)
                per_tick = max(1, round(f.get("rate", 100) * period))
                data = bytes.fromhex(f.get("data", "55" * 8))
                n_ticks = max(1, round(f["duration"] / period))
                k = 0
                for tick in range(n_ticks):
                    tick_deadline = deadline + tick * period
                    while (rem := tick_deadline - time.monotonic()) > 0:
                        time.sleep(rem)
                    for _ in range(per_tick):
                        ok = send_frame(s, ids[k % len(ids)], data, f.get("dlc"))
                        k += 1
                        sent += ok
                        failed += not ok
            else:
                raise ValueError(f"unknown fault kind {kind!r}")
            log.append({**f, "started": started, "ended": time.time(), "sent": sent, "failed": failed})
    finally:
        s.close()


def terminate(proc: subprocess.Popen | None, sig: int, timeout: float) -> dict:
    """Send ``sig``, wait up to ``timeout``; SIGKILL if needed. Returns what happened."""
    if proc is None:
        return {"started": False}
    if proc.poll() is not None:
        return {"exited_before": True, "returncode": proc.returncode}
    t = time.monotonic()
    proc.send_signal(sig)
    try:
        rc = proc.wait(timeout=timeout)
        return {"returncode": rc, "seconds": round(time.monotonic() - t, 3), "killed": False}
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return {"returncode": proc.returncode, "seconds": round(time.monotonic() - t, 3), "killed": True}


def cpu_seconds(pid: int) -> float | None:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


#: what the guest's programs import: tools/player.py, the daemon, ``cantools decode``
REQUIRED_MODULES = ("can", "cantools", "serial", "numpy", "ecu_daemon")


def missing_modules_error() -> str | None:
    """None if this interpreter can import every module the job needs, else a one-line reason.

    The guest must run the test environment's interpreter (a venv's ``bin/python``, not the base
    interpreter it links to); the reason names the interpreter and its ``sys.prefix``.
    """
    missing = [m for m in REQUIRED_MODULES if importlib.util.find_spec(m) is None]
    if not missing:
        return None
    return (f"guest interpreter {sys.executable} (sys.prefix {sys.prefix}) cannot import "
            f"{', '.join(missing)}: not the test environment's interpreter?")


def main(job_path: str) -> int:
    job = json.loads(Path(job_path).read_text())
    out = Path(job["out"])
    problem = missing_modules_error()
    if problem:
        print(problem, file=sys.stderr)
        (out / "results.json").write_text(json.dumps({"error": problem}, indent=1))
        return 1
    py = job["python"]
    channel = job.get("channel", "vcan0")
    res: dict = {"uname": os.uname().release, "t_boot_to_job": time.monotonic()}
    procs: dict[str, subprocess.Popen] = {}
    notes = Notifications(f"ecu-uml-notify-{os.getpid()}")
    notes.start()
    env = dict(os.environ, PYTHONPATH=job["repo"], PYTHONUNBUFFERED="1")
    try:
        with open(out / "bus.log", "wb") as bus_log:
            # every data frame except a fault flood's IDs, plus all error frames
            cap_filter = job.get("capture_filter", "0:0")
            procs["candump"] = subprocess.Popen(["candump", "-L", f"{channel},{cap_filter},#FFFFFFFF"], stdout=bus_log,
                                                stderr=open(out / "candump.err", "wb"))
        gnss_link = out / "gnss0"
        player_cmd = [py, str(Path(job["repo"]) / "tools" / "player.py"), "--wait-signal", "--hold",
                      "--gnss", job["gnss_log"], "--gnss-pty", str(gnss_link), "--epoch", str(job["epoch"])]
        procs["player"] = subprocess.Popen(player_cmd, stderr=open(out / "player.log", "wb"), env=env)
        end = time.monotonic() + 60
        while not gnss_link.is_symlink() and time.monotonic() < end and procs["player"].poll() is None:
            time.sleep(0.01)
        res["gnss_pty"] = os.readlink(gnss_link) if gnss_link.is_symlink() else None
        if res["gnss_pty"] is None:
            raise RuntimeError("the GNSS player did not create its pseudo-terminal")

        t = time.monotonic()
        daemon_env = dict(env, NOTIFY_SOCKET=notes.address, **job.get("daemon_env", {}))
        procs["daemon"] = subprocess.Popen(job["daemon_cmd"], cwd=job.get("daemon_cwd", job["repo"]), env=daemon_env,
                                           stdout=open(out / "daemon.out", "wb"),
                                           stderr=open(out / "daemon.log", "wb"))
        if not notes.ready.wait(job.get("ready_timeout", 90)):
            res["daemon_ready"] = False
            raise RuntimeError(f"daemon not READY=1 within {job.get('ready_timeout', 90)} s "
                               f"(exit status {procs['daemon'].poll()})")
        res["daemon_ready"] = True
        res["daemon_ready_s"] = round(time.monotonic() - t, 3)

        # Go: the GNSS player and canplayer start together; the host measures the residual offset.
        t0 = time.monotonic()
        progress = None
        if job.get("faults"):  # listening before canplayer sends its first frame
            progress = PlaybackProgress(channel, job["drive_log"], t0)
            progress.start()
        res["playback_start_realtime"] = time.time()
        procs["player"].send_signal(signal.SIGUSR1)
        procs["canplayer"] = subprocess.Popen(
            ["canplayer", "-I", job["drive_log"], f"{channel}={job['log_iface']}"],
            stdout=open(out / "canplayer.log", "wb"), stderr=subprocess.STDOUT)
        fault_log: list = []
        injector = None
        if progress is not None:
            injector = threading.Thread(target=inject, args=(job["faults"], progress, channel, fault_log), daemon=True)
            injector.start()
        try:
            res["canplayer_rc"] = procs["canplayer"].wait(timeout=job.get("play_timeout", 300))
        except subprocess.TimeoutExpired:
            res["canplayer_rc"] = None
            procs["canplayer"].kill()
        res["playback_s"] = round(time.monotonic() - t0, 3)
        if injector is not None:
            injector.join(timeout=30)
            res["progress_frames_matched"] = progress.matched
            progress.close()
        res["faults"] = fault_log
        time.sleep(job.get("tail_s", 0.5))  # let the last outputs reach candump before stopping
        res["daemon_cpu_s"] = cpu_seconds(procs["daemon"].pid)
        res["daemon_alive_at_end"] = procs["daemon"].poll() is None
        res["daemon_stop"] = terminate(procs.pop("daemon"), signal.SIGTERM, 15)
        return_code = 0
    except Exception as e:  # noqa: BLE001 - reported to the host, which fails the test with it
        res["error"] = f"{type(e).__name__}: {e}"
        return_code = 1
    finally:
        for name in ("canplayer", "daemon"):
            if name in procs:
                res[f"{name}_stop"] = terminate(procs.pop(name), signal.SIGTERM, 10)
        res["player_stop"] = terminate(procs.pop("player", None), signal.SIGTERM, 10)
        res["candump_stop"] = terminate(procs.pop("candump", None), signal.SIGINT, 10)
        notes.stopping = True
        notes.join(1)
        (out / "notify.log").write_text("".join(f"{t:.6f} {m!r}\n" for t, m in notes.messages))
        res["notifications"] = len(notes.messages)
        res["watchdog_pings"] = sum("WATCHDOG=1" in m for _, m in notes.messages)
        res["stopping_sent"] = any("STOPPING=1" in m for _, m in notes.messages)

    if job.get("output_dbc"):
        with open(out / "bus.log", "rb") as src, open(out / "decoded.txt", "wb") as dst:
            r = subprocess.run([py, "-m", "cantools", "decode", job["output_dbc"]], stdin=src, stdout=dst,
                               stderr=subprocess.PIPE, timeout=300, env=env)
        res["cantools_rc"] = r.returncode
        res["cantools_stderr"] = r.stderr.decode(errors="replace")[-2000:]
    (out / "results.json").write_text(json.dumps(res, indent=1))
    return return_code


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1]))
