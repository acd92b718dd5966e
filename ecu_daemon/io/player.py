"""Play CAN frames and GNSS bytes in real time: onto python-can buses and a serial port / pty.

Why not ``canplayer`` / ``can_player``: a drive is two streams (CAN frames and the GNSS receiver's
bytes) that must keep their relative timing, and neither tool feeds a serial port. The player
merges both onto one timeline and sends every event at an *absolute* deadline
(``start + (t_log - epoch) / speed``), so a slow send never accumulates into drift.

The one player of the project: ``tools/player.py`` (command line), ``tools/uml/slcan_adapter.py``
(the kernel tests' CAN adapter) and the demo's feeder (``demo.Feeder``) all play through
:class:`Player`. Logs are read by the package's readers (``canlog``, ``gnss.logfile``).
"""
from __future__ import annotations

import heapq
import itertools
import os
import threading
import time
import tty
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Iterator

import can

from ..canlog import CanLogError, read_can_log
from ..gnss.logfile import GnssLogError, read_gnss_log


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


def read_candump(path: str | Path) -> Iterator[Event]:
    """Events of a CAN log in file order (candump ``-L``, or any format python-can reads), through
    the package's one CAN log reader (:func:`~ecu_daemon.canlog.read_can_log`)."""
    try:
        for msg in read_can_log(path, messages=True):
            yield Event(msg.timestamp, "" if msg.channel is None else str(msg.channel), msg)
    except CanLogError as e:
        raise PlayerError(str(e)) from None


def read_gnss_capture(path: str | Path) -> Iterator[Event]:
    """Events of a GNSS capture (``(sec.usec) PORT PAYLOAD``) in file order, through the
    package's one capture reader (:func:`~ecu_daemon.gnss.logfile.read_gnss_log`)."""
    try:
        for t, port, data in read_gnss_log(path):
            yield Event(t, port, None, data)
    except GnssLogError as e:
        raise PlayerError(str(e)) from None


def merged_events(can_path: str | Path | None, gnss_path: str | Path | None) -> Iterator[Event]:
    """A drive's CAN log and GNSS capture on one timeline (CAN first on a tie)."""
    streams = []
    if can_path:
        streams.append(read_candump(can_path))
    if gnss_path:
        streams.append(read_gnss_capture(gnss_path))
    return heapq.merge(*streams, key=lambda e: (e.t, e.is_gnss))


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

    def __init__(self, path: str | None = None, *, create_link: str | None = None, baudrate: int = 115200,
                 fd: int | None = None):
        self._serial = None
        self._fd = None
        self._slave = None
        self._owned = True
        self.link = None
        if fd is not None:  # a non-blocking fd someone else owns (the demo's pty master)
            self._fd, self._owned = fd, False
            self.slave_path = None
        elif create_link:
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
            raise PlayerError("GnssPort needs a path, create_link or fd")

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
        for fd in (self._fd if self._owned else None, self._slave):
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
    counted as unmapped and skipped, as canplayer skips them. ``gnss``: the port every GNSS event
    goes to, or a dict from an event's ``source`` to its port (several receivers; events of a
    source not in it are skipped). ``stamp(deadline)``: each frame's timestamp from its deadline
    on ``clock`` (for a bus that keeps the sender's timestamps, e.g. the demo's virtual bus).
    """

    def __init__(self, events: Iterable[tuple[float, Event]], *, buses: dict, route: dict | None = None,
                 gnss: GnssPort | dict[str, GnssPort] | None = None, clock: Callable[[], float] = time.monotonic,
                 start_at: float | None = None, rate: float = 1.0, stamp: Callable[[float], float] | None = None,
                 idle: Callable[[], None] | None = None):
        self.events = events
        self.buses = buses
        self.route = route
        self.gnss = gnss
        self.clock = clock
        self.start_at = start_at  # on ``clock``; default: now
        self.rate = rate  # seconds of ``clock`` per real second (the demo's fast-forward clock)
        # when set, each frame is stamped ``stamp(deadline)``: the time it is due, not when this
        # thread got round to sending it (see :meth:`run`)
        self.stamp = stamp
        self.idle = idle  # called while waiting for the next deadline (the demo drains its bus)
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
            if self.idle is not None:
                self.idle()
                remaining = deadline - self.clock()
                if remaining <= 0:
                    return True
            self._stop.wait(min(remaining / self.rate, 0.05))
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
                port = self.gnss.get(ev.source) if isinstance(self.gnss, dict) else self.gnss
                if port is None:
                    continue
                dropped = port.write(ev.data)
                self.stats.gnss_messages += 1
                self.stats.gnss_bytes += len(ev.data) - dropped
                self.stats.gnss_dropped += dropped
            else:
                bus = self._bus_for(ev)
                if bus is None:
                    self.stats.can_unmapped += 1
                    continue
                if self.stamp is not None:
                    # The receive time a bus would give the frame: its deadline. A player standing
                    # in for the bus and the kernel (the demo) that is late (its thread descheduled,
                    # the GIL) delivers the frame late, as a late reader would find it, but with
                    # the drive's own time, never with the player's lateness folded into the data.
                    ev.message.timestamp = self.stamp(deadline)
                try:
                    bus.send(ev.message, timeout=0.01)
                    self.stats.can_sent += 1
                except can.CanError:
                    self.stats.can_errors += 1
            self.stats.lateness.append(max(0.0, self.clock() - deadline))
        return self.stats
