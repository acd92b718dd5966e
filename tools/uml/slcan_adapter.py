#!/usr/bin/env python3
"""A serial-line CAN adapter emulated on a pseudo-terminal: gives a guest a real ``can0``.

vcan has no bit timing, so networkd's ``[CAN] BitRate=`` cannot be exercised on it. The kernel's
``slcan`` driver is a real can-dev device (bit rate, restart-ms, up/down via netlink) that talks
the LAWICEL ASCII protocol over a tty. We attach it to a pty slave, rename the interface to
``can0`` and play the adapter's side on the master:

* commands from the kernel (``S6`` bit rate, ``O`` open, ``C`` close) are recorded, so a test
  can see what networkd configured;
* frames the host transmits (``t``/``T`` lines: the daemon's outputs) are logged in candump
  ``-L`` format;
* a drive log (and GNSS capture, into a second pty) is played *into* can0 as received frames with
  the package's player (``ecu_daemon.io.player``), once the interface is open.

Needs root (TIOCSETD to N_SLCAN, ``ip link set name``) and the slcan module.
"""
from __future__ import annotations

import argparse
import fcntl
import json
import os
import select
import signal
import struct
import subprocess
import threading
import time
import tty
from pathlib import Path

import can

from ecu_daemon.io import player

N_SLCAN = 17
TIOCSETD = 0x5423
SIOCGIFNAME = 0x8910
SLCAN_BITRATES = {"0": 10000, "1": 20000, "2": 50000, "3": 100000, "4": 125000, "5": 250000,
                  "6": 500000, "7": 750000, "8": 1000000}


def encode_frame(msg: can.Message) -> bytes:
    """A CAN frame as the adapter reports a received one: ``tIIIL<data>\\r`` / ``TIIIIIIIIL...``."""
    if msg.is_extended_id:
        head = f"{'R' if msg.is_remote_frame else 'T'}{msg.arbitration_id:08X}"
    else:
        head = f"{'r' if msg.is_remote_frame else 't'}{msg.arbitration_id:03X}"
    body = "" if msg.is_remote_frame else bytes(msg.data).hex().upper()
    return f"{head}{min(msg.dlc, 8)}{body}\r".encode("ascii")


def decode_frame(line: str) -> tuple[int, bool, bytes] | None:
    kind = line[:1]
    n = 8 if kind in "TR" else 3
    try:
        can_id, dlc = int(line[1:1 + n], 16), int(line[1 + n], 16)
        data = b"" if kind in "rR" else bytes.fromhex(line[2 + n:2 + n + 2 * dlc])
    except (ValueError, IndexError):
        return None
    return can_id, kind in "TR", data


class SlcanLink:
    """The adapter end of an slcan pty; quacks like a python-can bus for :class:`player.Player`."""

    def __init__(self, name: str, tx_log: Path, events_log: Path):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        fcntl.ioctl(self.slave, TIOCSETD, struct.pack("i", N_SLCAN))
        ifname = fcntl.ioctl(self.slave, SIOCGIFNAME, b"\0" * 16).split(b"\0", 1)[0].decode()
        if ifname != name:
            subprocess.run(["ip", "link", "set", "dev", ifname, "name", name], check=True)
        self.name = name
        self.is_open = threading.Event()
        self.bitrate = None
        self.commands: list[str] = []
        self.tx_frames = 0
        self._tx_log = open(tx_log, "w", buffering=1)
        self._events_log = events_log
        self._lock = threading.Lock()
        self._stop = False
        self._reader = threading.Thread(target=self._read_loop, daemon=True)
        self._reader.start()

    def _event(self, what: str) -> None:
        with self._lock:
            self.commands.append(what)
            self._events_log.write_text(json.dumps({"commands": self.commands, "bitrate": self.bitrate,
                                                    "tx_frames": self.tx_frames}))

    def _read_loop(self) -> None:
        buf = b""
        while not self._stop:
            r, _, _ = select.select([self.master], [], [], 0.2)
            if not r:
                continue
            try:
                chunk = os.read(self.master, 4096)
            except OSError:
                return
            buf += chunk
            while b"\r" in buf:
                raw, buf = buf.split(b"\r", 1)
                line = raw.decode("ascii", "replace")
                if not line:
                    continue
                if line[0] in "tTrR":
                    f = decode_frame(line)
                    if f is not None:
                        can_id, ext, data = f
                        self.tx_frames += 1
                        ident = f"{can_id:08X}" if ext else f"{can_id:03X}"
                        self._tx_log.write(f"({time.time():.6f}) {self.name} {ident}#{data.hex().upper()}\n")
                    continue
                if line[0] == "S":
                    self.bitrate = SLCAN_BITRATES.get(line[1:2])
                elif line[0] == "O":
                    self.is_open.set()
                elif line[0] == "C":
                    self.is_open.clear()
                self._event(line)
                os.write(self.master, b"\r")  # ACK, as an adapter does

    # python-can bus duck type used by player.Player
    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if not self.is_open.is_set():
            raise can.CanOperationError("adapter closed (interface down)")
        try:
            os.write(self.master, encode_frame(msg))
        except OSError as e:
            raise can.CanOperationError(str(e)) from None

    def shutdown(self) -> None:
        self._stop = True
        self._reader.join(1)
        self._tx_log.close()
        for fd in (self.slave, self.master):
            try:
                os.close(fd)
            except OSError:
                pass


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--name", default="can0")
    p.add_argument("--out", required=True, help="directory for can0-tx.log and slcan-events.json")
    p.add_argument("--play", help="candump log to play into the interface as received frames")
    p.add_argument("--gnss", help="GNSS capture to play in step with --play")
    p.add_argument("--gnss-pty", help="symlink to create for the GNSS pseudo-terminal")
    p.add_argument("--gnss-group", default="dialout", help="group owning the GNSS pty (like a real tty)")
    p.add_argument("--loop", default="i")
    a = p.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    stop = threading.Event()
    gnss = None
    if a.gnss_pty:
        gnss = player.GnssPort(create_link=a.gnss_pty)
        import grp

        os.chown(gnss.slave_path, 0, grp.getgrnam(a.gnss_group).gr_gid)
        os.chmod(gnss.slave_path, 0o660)
    link = SlcanLink(a.name, out / "can0-tx.log", out / "slcan-events.json")
    print(f"slcan adapter: {a.name} on {os.ttyname(link.slave)}"
          + (f", GNSS on {gnss.slave_path}" if gnss else ""), flush=True)
    p_obj = None

    def on_signal(*_):
        stop.set()
        if p_obj is not None:
            p_obj.stop()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    try:
        while not stop.is_set() and not link.is_open.wait(0.1):
            pass
        if a.play and not stop.is_set():
            def events():
                return player.merged_events(a.play, a.gnss)
            loops = None if a.loop == "i" else int(a.loop)
            p_obj = player.Player(player.schedule(events, loops=loops), buses={None: link}, gnss=gnss)
            stats = p_obj.run()
            print(stats.summary(), flush=True)
        else:
            stop.wait()
    finally:
        link.shutdown()
        if gnss is not None:
            gnss.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
