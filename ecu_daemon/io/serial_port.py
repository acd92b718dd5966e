"""The GNSS serial port in the event loop: non-blocking reads, receive timestamps, reconnection.

pyserial opens and configures the tty (baud rate, raw mode); reading is ``os.read`` on its file
descriptor from ``loop.add_reader``, so the loop never blocks. Every chunk is stamped with the
daemon's monotonic clock just before it is read (rounded to 1 us, the capture log's resolution)
and handed to ``on_data(t, bytes)``.

A USB receiver can be unplugged: the read raises (EIO/ENODEV) or the tty hangs up. The port
is then closed, the loss logged once, and reopening is retried with a growing interval
(0.2 s .. 5 s) until it works, which is logged once more. No bytes already read are lost; the
ones in flight while unplugged never existed for us.
"""
from __future__ import annotations

import asyncio
import logging
import os
import select
import time
from typing import Callable

import serial

log = logging.getLogger("ecu_daemon.gnss")


class GnssSerial:
    RETRY_MIN_S = 0.2
    RETRY_MAX_S = 5.0

    def __init__(self, port: str, baudrate: int, *, on_data: Callable[[float, bytes], None],
                 clock: Callable[[], float] = time.monotonic, quantum_s: float = 1e-6) -> None:
        self.port = port
        self.baudrate = baudrate
        self.on_data = on_data
        self.clock = clock
        self.quantum_s = quantum_s
        self.connected = False
        self.bytes_read = 0
        self.losses = 0
        self.reconnects = 0
        self.open_failures = 0
        self._ser: serial.Serial | None = None
        self._fd = -1
        self._loop: asyncio.AbstractEventLoop | None = None
        self._retry_s = self.RETRY_MIN_S
        self._retry_handle: asyncio.TimerHandle | None = None
        self._lost_at: float | None = None
        self._closed = False
        self._last_t = 0.0
        self._last_err = ""

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        if not self._try_open():
            log.warning("GNSS port %s not available (%s); will keep trying", self.port, self._last_err)
            self._lost_at = time.monotonic()
            self._schedule_retry()

    def _try_open(self) -> bool:
        try:
            ser = serial.Serial(self.port, self.baudrate, timeout=0, exclusive=False)
        except (serial.SerialException, OSError, ValueError) as e:
            self.open_failures += 1
            err = getattr(e, "strerror", None) or str(e)
            self._last_err = err.split(": ")[-1] if isinstance(err, str) else err
            return False
        self._ser = ser
        self._fd = ser.fileno()
        assert self._loop is not None
        self._loop.add_reader(self._fd, self._on_readable)
        self.connected = True
        return True

    def _on_readable(self) -> None:
        t = self.clock()
        try:
            data = os.read(self._fd, 4096)
        except BlockingIOError:
            return
        except OSError as e:
            self._lost(e.strerror or str(e))
            return
        if not data:
            # With VMIN=0/VTIME=0 (pyserial, timeout=0) an empty read only means "nothing there";
            # a hung-up tty (USB unplugged, pty master closed) also reports POLLHUP.
            if self._hung_up():
                self._lost("hang-up")
            return
        q = self.quantum_s
        t = round(t / q) * q
        if t < self._last_t:
            t = self._last_t
        self._last_t = t
        self.bytes_read += len(data)
        try:
            self.on_data(t, data)
        except Exception as e:  # a parser bug must not lose the port
            log.error("error handling GNSS data: %s: %s", e.__class__.__name__, e)

    def _hung_up(self) -> bool:
        p = select.poll()
        p.register(self._fd, select.POLLIN)
        return any(ev & (select.POLLHUP | select.POLLERR | select.POLLNVAL) for _, ev in p.poll(0))

    def drain(self, max_reads: int = 64) -> None:
        """Read what is already buffered (at shutdown: no received byte is left behind)."""
        for _ in range(max_reads):
            if not self.connected:
                return
            before = self.bytes_read
            self._on_readable()
            if self.bytes_read == before:
                return

    def _close_port(self) -> None:
        if self._fd >= 0 and self._loop is not None:
            try:
                self._loop.remove_reader(self._fd)
            except (ValueError, RuntimeError):
                pass
        if self._ser is not None:
            try:
                self._ser.close()
            except (OSError, serial.SerialException):
                pass
        self._ser, self._fd = None, -1
        self.connected = False

    def _lost(self, why: str) -> None:
        self._close_port()
        self.losses += 1
        self._lost_at = time.monotonic()
        log.warning("GNSS port %s lost (%s); reconnecting", self.port, why)
        self._retry_s = self.RETRY_MIN_S
        self._schedule_retry()

    def _schedule_retry(self) -> None:
        if self._closed or self._loop is None:
            return
        self._retry_handle = self._loop.call_later(self._retry_s, self._retry)
        self._retry_s = min(self._retry_s * 2, self.RETRY_MAX_S)

    def _retry(self) -> None:
        self._retry_handle = None
        if self._closed:
            return
        if self._try_open():
            down = time.monotonic() - self._lost_at if self._lost_at is not None else 0.0
            if self.losses:
                self.reconnects += 1
                log.warning("GNSS port %s reconnected after %.1f s", self.port, down)
            else:
                log.warning("GNSS port %s available after %.1f s", self.port, down)
            self._retry_s = self.RETRY_MIN_S
        else:
            self._schedule_retry()

    def close(self) -> None:
        self._closed = True
        if self._retry_handle is not None:
            self._retry_handle.cancel()
            self._retry_handle = None
        self._close_port()
