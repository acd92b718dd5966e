#!/usr/bin/env python3
"""Play a candump log and a GNSS capture in real time onto python-can buses and a serial port.

A thin command line over the package's player (:mod:`ecu_daemon.io.player`: why a player of our
own, the timing model, the GNSS port); its names are re-exported here for the scripts that import
this file (``tools/uml``, the kernel tests).

Inputs:
  * CAN: candump ``-L`` logs (``(sec.usec) IFACE ID#DATA``, also ``ID#R``, ``ID##F...`` CAN FD and
    error frames ``2xxxxxxx#...``); other suffixes (.asc, .blf, .trc, ...) via python-can.
  * GNSS: the capture format of ``ecu-daemon --record`` / ``replay``:
    ``(sec.usec) PORT PAYLOAD``, NMEA text (written with CR LF) or hex (written as bytes).

Outputs: any python-can bus (``-i/-c/-b/--bus-kwargs``, canplayer-style ``OUT=IN`` interface
mapping) and a serial device or pseudo-terminal (``--gnss-port PATH``, or ``--gnss-pty LINK`` to
create a pty and publish its slave as the symlink LINK for the program under test).

SIGINT and SIGTERM stop playback between events; buses and ports are closed and a one-line
summary is printed.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time

import can
import can.cli

from ecu_daemon.io.player import (  # noqa: F401  (re-exported for tools/uml and the kernel tests)
    Event, GnssPort, Player, PlayerError, Stats, merged_events, parse_mapping, read_candump,
    read_gnss_capture, schedule)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="player.py", description=__doc__.splitlines()[0])
    p.add_argument("-I", "--infile", help="CAN log (candump -L .log; .asc/.blf/... via python-can)")
    p.add_argument("--gnss", help="GNSS capture file ((sec.usec) PORT PAYLOAD lines)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--gnss-port", help="serial device or pty slave to write the GNSS bytes to")
    g.add_argument("--gnss-pty", metavar="LINK",
                   help="create a pseudo-terminal and publish its slave path as the symlink LINK")
    p.add_argument("--gnss-baudrate", type=int, default=115200)
    p.add_argument("-s", "--speed", type=float, default=1.0, help="speed factor (2 = twice as fast)")
    p.add_argument("-l", "--loop", default="1", help="play N times, or 'i' for ever (default 1)")
    p.add_argument("--start", type=float, default=0.0, help="skip the first SECONDS of the log")
    p.add_argument("--epoch", type=float, default=None,
                   help="log time that maps to playback start (default: the first event's time); "
                        "give the CAN log's first timestamp to keep a GNSS-only playback in step")
    p.add_argument("--at", type=float, default=None,
                   help="start playback at this CLOCK_REALTIME time (syncs with another player)")
    p.add_argument("--wait-signal", action="store_true",
                   help="open the outputs, then start playback when SIGUSR1 arrives (syncs with canplayer)")
    p.add_argument("--hold", action="store_true",
                   help="after playback keep the buses and the GNSS port open until SIGINT/SIGTERM "
                        "(so the reader sees no hang-up when the capture ends)")
    p.add_argument("-v", "--verbose", action="store_true", help="print the pty path and progress")
    p.add_argument("mapping", nargs="*", help="canplayer-style OUT=IN interface mapping, e.g. vcan0=can0")
    can.cli.add_bus_arguments(p)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    stop_signals = {}
    buses: dict = {}
    gnss = None
    try:
        if not args.infile and not args.gnss:
            raise PlayerError("nothing to play: give -I CANLOG and/or --gnss CAPTURE")
        if args.gnss and not (args.gnss_port or args.gnss_pty):
            raise PlayerError("--gnss needs --gnss-port PATH or --gnss-pty LINK")
        loops = None if args.loop in ("i", "inf") else int(args.loop)
        for f in (args.infile, args.gnss):
            if f and not os.path.exists(f):
                raise PlayerError(f"no such file: {f}")

        route = parse_mapping(args.mapping) if args.mapping else None
        if args.infile:
            outs = sorted(set(route.values())) if route else [None]
            for key in outs:
                ns = argparse.Namespace(**vars(args))
                if key is not None:
                    ns.channel = key
                buses[key] = can.cli.create_bus_from_namespace(ns)
        if args.gnss:
            gnss = GnssPort(args.gnss_port, create_link=args.gnss_pty, baudrate=args.gnss_baudrate)
            if args.verbose:
                print(f"player: GNSS on {gnss.slave_path}" + (f" (link {gnss.link})" if gnss.link else ""),
                      file=sys.stderr, flush=True)

        def make_events():
            return merged_events(args.infile, args.gnss)

        start_at = None
        if args.at is not None:
            start_at = time.monotonic() + (args.at - time.time())
        player = Player(schedule(make_events, speed=args.speed, start=args.start, loops=loops, epoch=args.epoch),
                        buses=buses, route=route, gnss=gnss, start_at=start_at)
        for sig in (signal.SIGINT, signal.SIGTERM):
            stop_signals[sig] = signal.signal(sig, lambda *_: player.stop())
        if args.wait_signal:
            go = threading.Event()
            stop_signals[signal.SIGUSR1] = signal.signal(
                signal.SIGUSR1, lambda *_: (setattr(player, "start_at", time.monotonic()), go.set()))
            print("player: ready, waiting for SIGUSR1", file=sys.stderr, flush=True)
            while not go.is_set() and not player.stopped:
                go.wait(0.05)
        if args.verbose or args.wait_signal:
            print(f"player: playback starts at CLOCK_REALTIME "
                  f"{time.time() - (time.monotonic() - (player.start_at or time.monotonic())):.6f}",
                  file=sys.stderr, flush=True)
        stats = player.run()
        print(stats.summary() + (" (stopped)" if player.stopped else ""), file=sys.stderr, flush=True)
        while args.hold and not player.stopped:
            player._stop.wait(0.2)
        return 0
    except PlayerError as e:
        print(f"player: error: {e}", file=sys.stderr)
        return 2
    except (argparse.ArgumentError, can.CanError, OSError) as e:
        cause = f": {e.__cause__}" if e.__cause__ else ""
        print(f"player: error: {e}{cause}", file=sys.stderr)
        return 2
    finally:
        for sig, old in stop_signals.items():
            signal.signal(sig, old)
        for bus in buses.values():
            bus.shutdown()
        if gnss is not None:
            gnss.close()


if __name__ == "__main__":
    raise SystemExit(main())
