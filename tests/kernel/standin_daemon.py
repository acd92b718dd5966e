#!/usr/bin/env python3
"""A tiny stand-in for ``ecu-daemon run``: proves the kernel harness independently of the daemon.

It does what the harness relies on and nothing else: opens the configured SocketCAN channel and
GNSS port, sends READY=1 to ``$NOTIFY_SOCKET`` once both are open, then on a 6 ms absolute-deadline
tick sends one frame (ID 0x7F0: 4-bit counter, frames-received count) and WATCHDOG=1. SIGTERM ends
it cleanly with a JSON summary on stdout. ``--freeze-after S`` stops ticking (but stays alive), so a
watchdog can be seen to fire.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import sys
import threading
import time
import tomllib

import can


def notify(msg: str) -> None:
    addr = os.environ.get("NOTIFY_SOCKET", "")
    if not addr:
        return
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as s:
        s.sendto(msg.encode(), "\0" + addr[1:] if addr.startswith("@") else addr)


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--config", required=True)
    p.add_argument("--freeze-after", type=float, default=0.0)
    a = p.parse_args()
    cfg = tomllib.loads(open(a.config, "rb").read().decode())
    bus = can.Bus(interface=cfg["can"]["interface"], channel=cfg["can"]["channel"])
    port_fd = os.open(cfg["gnss"]["port"], os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    counts = {"rx": 0, "gnss_bytes": 0, "tx": 0}

    def reader():
        while not stop.is_set():
            if bus.recv(0.1) is not None:
                counts["rx"] += 1

    threading.Thread(target=reader, daemon=True).start()
    notify("READY=1\nSTATUS=stand-in running")
    t_next = time.monotonic()
    t_freeze = t_next + a.freeze_after if a.freeze_after > 0 else float("inf")
    k = 0
    while not stop.is_set():
        t_next += 0.006
        while (rem := t_next - time.monotonic()) > 0 and not stop.is_set():
            time.sleep(rem)
        if time.monotonic() > t_freeze:
            continue  # alive but stuck: no frames, no watchdog
        try:
            counts["gnss_bytes"] += len(os.read(port_fd, 4096))
        except BlockingIOError:
            pass
        k += 1
        data = bytes([k & 0x0F]) + min(counts["rx"], 2**32 - 1).to_bytes(4, "little")
        try:
            bus.send(can.Message(arbitration_id=0x7F0, is_extended_id=False, data=data))
            counts["tx"] += 1
        except can.CanError:
            pass
        notify("WATCHDOG=1")
    notify("STOPPING=1")
    bus.shutdown()
    print(json.dumps(counts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
