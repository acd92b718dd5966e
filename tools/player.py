#!/usr/bin/env python3
"""Play a candump log and a GNSS capture in real time onto python-can buses and a serial port.

Why not ``canplayer`` / ``can_player``: a drive is two streams (CAN frames and the GNSS receiver's
bytes) that must keep their relative timing, and neither tool feeds a serial port. This player
merges both onto one timeline and sends every event at an *absolute* deadline
(``start + (t_log - epoch) / speed``), so a slow send never accumulates into drift.

Inputs:
  * CAN: candump ``-L`` logs (``(sec.usec) IFACE ID#DATA``, also ``ID#R``, ``ID##F...`` CAN FD and
    error frames ``2xxxxxxx#...``); other suffixes (.asc, .blf, .trc, ...) via ``can.LogReader``.
  * GNSS: the capture format of ``ecu-daemon --record`` / ``replay``:
    ``(sec.usec) PORT PAYLOAD``, one message a line, NMEA text (written with CR LF) or UBX as
    uppercase hex (written as bytes).

Outputs: any python-can bus (``-i/-c/-b/--bus-kwargs``, canplayer-style ``OUT=IN`` interface
mapping) and a serial device or pseudo-terminal (``--gnss-port PATH``, or ``--gnss-pty LINK`` to
create a pty and publish its slave as the symlink LINK for the program under test).

Usable as a module: :class:`Player`, :func:`read_candump`, :func:`read_gnss_capture`,
:func:`schedule`. SIGINT and SIGTERM stop playback between events; buses and ports are closed and a
one-line summary is printed.
"""
from __future__ import annotations

import argparse
import binascii
import heapq
import itertools
import os
import re
import signal
import sys
import threading
import time
import tty
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Iterator

import can
import can.cli

CAN_ERR_FLAG = 0x20000000

_LINE = re.compile(r"^\((\d+)\.(\d+)\)\s+(\S+)\s+(\S+)")


class PlayerError(Exception):
    """A problem with the player's input or options, reported as one line."""


@dataclass(frozen=True, slots=True)
class Event:
    """One thing to play: a CAN frame (``message``) or GNSS bytes (``data``) at log time ``t``."""

    t: float
    source: str  # the log's interface name (CAN) or port name (GNSS)
    message: can.Message | None = None
    data: bytes = b""

    @property
    def is_gnss(self) -> bool:
        return self.message is None


def _timestamp(sec: str, frac: str) -> float:
    return int(sec) + int(frac) / 10 ** len(frac)


def parse_candump_frame(frame: str) -> can.Message:
    """``ID#DATA`` in can-utils' compact syntax -> ``can.Message`` (error flag honoured)."""
    ident, sep, rest = frame.partition("#")
    if not sep or not ident or len(ident) not in (3, 8):
        raise ValueError(f"not a candump frame: {frame!r}")
    can_id = int(ident, 16)
    extended = len(ident) == 8
    is_error = extended and bool(can_id & CAN_ERR_FLAG)
    fd = rest.startswith("#")
    flags = 0
    if fd:
        flags, rest = int(rest[1], 16), rest[2:]
    remote = rest.upper().startswith("R")
    dlc = None
    if remote:
        dlc = int(rest[1:], 16) if len(rest) > 1 and rest[1:].isalnum() else 0
        data = b""
    else:
        hexdata = rest.replace(".", "")
        if "_" in hexdata:  # len8_dlc suffix (_<dlc>), keep the data only
            hexdata = hexdata.split("_", 1)[0]
        data = binascii.unhexlify(hexdata)
    return can.Message(
        arbitration_id=can_id & 0x1FFFFFFF,  # python-can adds CAN_ERR_FLAG back for error frames
        is_extended_id=extended and not is_error,
        is_error_frame=is_error,
        is_remote_frame=remote,
        is_fd=fd,
        bitrate_switch=bool(flags & 0x1),
        error_state_indicator=bool(flags & 0x2),
        dlc=dlc if dlc is not None else len(data),
        data=data,
        check=False,
    )


def read_candump(path: str | Path) -> Iterator[Event]:
    """Events of a CAN log in file order. candump ``-L`` natively; other formats via python-can.

    Lines not starting with ``(`` are skipped like canplayer does; a malformed frame line is an
    error naming the line (canplayer would abort too, but without saying where).
    """
    p = Path(path)
    if p.suffix.lower() not in (".log", ".txt", ""):
        for msg in can.LogReader(str(p)):
            yield Event(msg.timestamp, str(msg.channel) if msg.channel is not None else "", msg)
        return
    with open(p, encoding="ascii", errors="replace") as f:
        for n, line in enumerate(f, 1):
            if not line.startswith("("):
                continue
            m = _LINE.match(line)
            if not m:
                raise PlayerError(f"{p}:{n}: malformed candump line: {line.strip()!r}")
            try:
                msg = parse_candump_frame(m.group(4))
            except ValueError as e:
                raise PlayerError(f"{p}:{n}: {e}") from None
            t = _timestamp(m.group(1), m.group(2))
            msg.timestamp = t
            msg.channel = m.group(3)
            yield Event(t, m.group(3), msg)


def gnss_payload(text: str) -> bytes:
    """A capture line's payload as the bytes a receiver sent: NMEA + CR LF, or UBX hex decoded."""
    if text.startswith(("$", "!")):
        return text.encode("ascii") + b"\r\n"
    try:
        return binascii.unhexlify(text)
    except (binascii.Error, ValueError):
        raise ValueError(f"payload is neither NMEA nor hex: {text[:40]!r}") from None


def read_gnss_capture(path: str | Path) -> Iterator[Event]:
    """Events of a GNSS capture (``(sec.usec) PORT PAYLOAD``) in file order."""
    p = Path(path)
    with open(p, encoding="ascii", errors="replace") as f:
        for n, line in enumerate(f, 1):
            if not line.startswith("("):
                continue
            m = re.match(r"^\((\d+)\.(\d+)\)\s+(\S+)\s+(\S+)\s*$", line)
            if not m:
                raise PlayerError(f"{p}:{n}: malformed GNSS capture line: {line.strip()[:60]!r}")
            try:
                data = gnss_payload(m.group(4))
            except ValueError as e:
                raise PlayerError(f"{p}:{n}: {e}") from None
            yield Event(_timestamp(m.group(1), m.group(2)), m.group(3), None, data)


def parse_mapping(specs: Iterable[str]) -> dict[str, str]:
    """canplayer-style ``OUT=IN`` assignments -> {log interface: output channel}."""
    out: dict[str, str] = {}
    for spec in specs:
        dst, sep, src = spec.partition("=")
        if not sep or not dst or not src:
            raise PlayerError(f"interface mapping must be OUT=IN (like vcan0=can0), got {spec!r}")
        out[src] = dst
    return out


def schedule(make_events: Callable[[], Iterable[Event]], *, speed: float = 1.0, start: float = 0.0,
             loops: int | None = 1, epoch: float | None = None) -> Iterator[tuple[float, Event]]:
    """(deadline in seconds after playback start, event), pure: the player's whole timing model.

    ``start`` skips the first seconds of the log (relative to ``epoch``, which defaults to the
    first event's time). Loop k is shifted by k times the played span so the timeline stays
    absolute; ``loops=None`` repeats forever.
    """
    if speed <= 0:
        raise PlayerError(f"speed must be positive, got {speed}")
    span = None
    for k in itertools.count() if loops is None else range(loops):
        first = last = None
        for ev in make_events():
            if epoch is None:
                epoch = ev.t
            if ev.t < epoch + start:
                continue
            if first is None:
                first = ev.t
            last = ev.t
            shift = 0.0 if k == 0 else k * span
            yield ((ev.t - epoch - start) + shift) / speed, ev
        if first is None:
            return
        if span is None:
            # the next loop starts one median-ish gap after the last event: use 1 ms like canplayer
            span = (last - (epoch + start)) + 0.001


@dataclass
class Stats:
    can_sent: int = 0
    can_errors: int = 0
    can_unmapped: int = 0
    gnss_bytes: int = 0
    gnss_messages: int = 0
    gnss_dropped: int = 0
    #: seconds after its deadline each event was sent (the most recent 200k events)
    lateness: deque = field(default_factory=lambda: deque(maxlen=200_000))

    def summary(self) -> str:
        late = sorted(self.lateness)

        def q(p):
            return late[min(len(late) - 1, int(p * len(late)))] * 1e3 if late else float("nan")

        return (f"player: {self.can_sent} CAN frames sent ({self.can_errors} send errors, "
                f"{self.can_unmapped} unmapped), {self.gnss_messages} GNSS messages / {self.gnss_bytes} bytes "
                f"({self.gnss_dropped} dropped); lateness p50 {q(0.5):.2f} ms p99 {q(0.99):.2f} ms "
                f"max {late[-1] * 1e3 if late else float('nan'):.2f} ms")


class GnssPort:
    """Where GNSS bytes go: an existing serial device / pty slave, or a pty we create.

    With ``create_link`` a new pseudo-terminal is made (raw mode, so the line discipline neither
    echoes nor rewrites CR/LF) and its slave path is published as the symlink ``create_link``; we
    keep the slave open so the pty survives the reader closing and reopening it (USB-unplug style
    tests). Writes never block: when the reader is not keeping up, bytes are dropped and counted,
    as a real UART overrun would lose them.
    """

    def __init__(self, path: str | None = None, *, create_link: str | None = None, baudrate: int = 115200):
        self._serial = None
        self._fd = None
        self._slave = None
        self.link = None
        if create_link:
            master, slave = os.openpty()
            tty.setraw(slave)
            os.set_blocking(master, False)
            self._fd, self._slave = master, slave
            self.slave_path = os.ttyname(slave)
            tmp = f"{create_link}.tmp{os.getpid()}"
            os.symlink(self.slave_path, tmp)
            os.replace(tmp, create_link)
            self.link = create_link
        elif path:
            import serial  # pyserial: sets raw mode and the baud rate on a real UART or a pty

            try:
                self._serial = serial.Serial(path, baudrate=baudrate, timeout=0, write_timeout=0)
            except (serial.SerialException, OSError) as e:
                raise PlayerError(f"cannot open GNSS port {path}: {e}") from None
            self.slave_path = path
        else:
            raise PlayerError("GnssPort needs a path or create_link")

    def write(self, data: bytes) -> int:
        """Write without blocking; returns the number of bytes dropped."""
        try:
            if self._serial is not None:
                n = self._serial.write(data) or 0
            else:
                n = os.write(self._fd, data)
        except BlockingIOError:
            n = 0
        except OSError:
            return len(data)
        except Exception as e:  # pyserial's SerialTimeoutException on a full buffer
            if type(e).__name__ == "SerialTimeoutException":
                return len(data)
            raise
        return len(data) - n

    def close(self) -> None:
        if self._serial is not None:
            self._serial.close()
        for fd in (self._fd, self._slave):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        if self.link and os.path.islink(self.link):
            os.unlink(self.link)
        self._serial = self._fd = self._slave = None


class Player:
    """Sends scheduled events on their absolute deadlines until done or :meth:`stop` is called.

    ``buses`` maps an output key to a python-can bus; ``route`` maps a log interface name to an
    output key (``None`` key = the single default bus). Frames from interfaces with no route are
    counted as unmapped and skipped, as canplayer skips them.
    """

    def __init__(self, events: Iterable[tuple[float, Event]], *, buses: dict, route: dict | None = None,
                 gnss: GnssPort | None = None, clock: Callable[[], float] = time.monotonic,
                 start_at: float | None = None):
        self.events = events
        self.buses = buses
        self.route = route
        self.gnss = gnss
        self.clock = clock
        self.start_at = start_at  # on ``clock``; default: now
        self.stats = Stats()
        self._stop = threading.Event()

    def stop(self) -> None:
        self._stop.set()

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def _sleep_until(self, deadline: float) -> bool:
        """Sleep in short slices so a stop request is honoured promptly; False if stopped."""
        while not self._stop.is_set():
            remaining = deadline - self.clock()
            if remaining <= 0:
                return True
            self._stop.wait(min(remaining, 0.05))
        return False

    def _bus_for(self, ev: Event):
        if self.route is None:
            return self.buses.get(None)
        key = self.route.get(ev.source)
        return None if key is None else self.buses.get(key)

    def run(self) -> Stats:
        t0 = self.start_at if self.start_at is not None else self.clock()
        for offset, ev in self.events:
            deadline = t0 + offset
            if not self._sleep_until(deadline):
                break
            if ev.is_gnss:
                if self.gnss is None:
                    continue
                dropped = self.gnss.write(ev.data)
                self.stats.gnss_messages += 1
                self.stats.gnss_bytes += len(ev.data) - dropped
                self.stats.gnss_dropped += dropped
            else:
                bus = self._bus_for(ev)
                if bus is None:
                    self.stats.can_unmapped += 1
                    continue
                try:
                    bus.send(ev.message, timeout=0.01)
                    self.stats.can_sent += 1
                except can.CanError:
                    self.stats.can_errors += 1
            self.stats.lateness.append(max(0.0, self.clock() - deadline))
        return self.stats


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
            streams = []
            if args.infile:
                streams.append(read_candump(args.infile))
            if args.gnss:
                streams.append(read_gnss_capture(args.gnss))
            return heapq.merge(*streams, key=lambda e: e.t)

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
