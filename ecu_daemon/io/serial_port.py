"""The GNSS serial port: a reader thread, receive timestamps, reconnection.

pyserial opens and configures the tty (baud rate, raw mode). A reader thread per port waits for
bytes with ``poll`` on its file descriptor, reads them with ``os.read`` and stamps the chunk
with the daemon's monotonic clock the moment the read returns (rounded to 1 us, the capture
log's resolution). The stamped chunks go to the event loop through a queue, in order, and the
loop hands each to ``on_data(t, bytes)`` (in the loop's thread, as before).

Why a thread: the stamp is the fix's receive time, which dates the GNSS measurement for the
estimator (a course dated d late in a corner at yaw rate r is off by r * d). Read from
``loop.add_reader``, the stamp was when the loop got round to the port: in the live demo
(live49, load 2.5-18) 0.2-3.6 ms after the bytes at the median, 34-43 ms at p99, up to 163 ms,
because the loop was busy with the recording, the housekeeping or waiting for the GIL. The
thread blocks in ``poll`` only, so it wakes as soon as the kernel has the bytes and the GIL
is free, whatever the loop is doing.

A USB receiver can be unplugged: the read raises (EIO/ENODEV) or the tty hangs up. The port
is then closed, the loss logged once, and reopening is retried with a growing interval
(0.2 s .. 5 s) until it works, which is logged once more. No bytes already read are lost; the
ones in flight while unplugged never existed for us. :meth:`close` wakes the thread at once
(a pipe in its ``poll``) and joins it; :meth:`drain` stops it, reads what is still buffered in
the port and delivers everything queued, in order.
"""
from __future__ import annotations

import asyncio
import logging
import os
import select
import threading
import time
from collections import deque
from typing import Callable

import serial

log = logging.getLogger("ecu_daemon.gnss")

_HUP = select.POLLHUP | select.POLLERR | select.POLLNVAL


class GnssSerial:
    RETRY_MIN_S = 0.2
    RETRY_MAX_S = 5.0
    READ_SIZE = 4096

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
        self._lost_at: float | None = None
        self._last_t = 0.0
        self._last_err = ""
        self._queue: deque[tuple[float, bytes]] = deque()  # stamped chunks for the loop, in order
        self._reader: threading.Thread | None = None
        self._stop = threading.Event()
        self._wake_r = self._wake_w = -1  # a pipe that wakes the reader's poll at stop

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        if not self._try_open():
            log.warning("GNSS port %s not available (%s); will keep trying", self.port, self._last_err)
            self._lost_at = time.monotonic()
        self._stop.clear()
        self._wake_r, self._wake_w = os.pipe()
        self._reader = threading.Thread(target=self._run, name=f"ecu-gnss-rx {self.port}", daemon=True)
        self._reader.start()

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
        self.connected = True
        return True

    # ----------------------------------------------------------------------------- reader thread
    def _run(self) -> None:
        """The reader thread: read while connected, else retry opening with a growing interval."""
        while not self._stop.is_set():
            if self.connected:
                self._read_until_lost()
            elif self._sleep(self._retry_s):
                break
            else:
                self._retry_s = min(self._retry_s * 2, self.RETRY_MAX_S)
                self._retry()

    def _sleep(self, s: float) -> bool:
        """Wait ``s`` seconds or until stopped; True if stopped."""
        p = select.poll()
        p.register(self._wake_r, select.POLLIN)
        p.poll(s * 1e3)
        return self._stop.is_set()

    def _read_until_lost(self) -> None:
        p = select.poll()
        p.register(self._fd, select.POLLIN)
        p.register(self._wake_r, select.POLLIN)
        fd = self._fd
        while not self._stop.is_set():
            events = p.poll()
            if self._stop.is_set():
                return
            for efd, ev in events:
                if efd == fd and not self._read_once(ev):
                    return

    def _read_once(self, ev: int = 0) -> bool:
        """Read one chunk, stamp it and queue it for the loop; False if the port was lost."""
        try:
            data = os.read(self._fd, self.READ_SIZE)
            t = self.clock()  # when the read returned: the bytes were there by then
        except BlockingIOError:
            return True
        except OSError as e:
            self._lost(e.strerror or str(e))
            return False
        if not data:
            # With VMIN=0/VTIME=0 (pyserial, timeout=0) an empty read only means "nothing there";
            # a hung-up tty (USB unplugged, pty master closed) also reports POLLHUP.
            if ev & _HUP or self._hung_up():
                self._lost("hang-up")
                return False
            return True
        q = self.quantum_s
        t = round(t / q) * q
        if t < self._last_t:
            t = self._last_t
        self._last_t = t
        self.bytes_read += len(data)
        self._queue.append((t, data))
        loop = self._loop
        if loop is not None and len(self._queue) == 1:  # one wake-up for a run of chunks
            try:
                loop.call_soon_threadsafe(self._deliver)
            except RuntimeError:  # the loop is closed: drain() delivers
                pass
        return True

    def _hung_up(self) -> bool:
        p = select.poll()
        p.register(self._fd, select.POLLIN)
        return any(ev & _HUP for _, ev in p.poll(0))

    def _lost(self, why: str) -> None:
        self._close_port()
        self.losses += 1
        self._lost_at = time.monotonic()
        log.warning("GNSS port %s lost (%s); reconnecting", self.port, why)
        self._retry_s = self.RETRY_MIN_S

    def _retry(self) -> None:
        if self._try_open():
            down = time.monotonic() - self._lost_at if self._lost_at is not None else 0.0
            if self.losses:
                self.reconnects += 1
                log.warning("GNSS port %s reconnected after %.1f s", self.port, down)
            else:
                log.warning("GNSS port %s available after %.1f s", self.port, down)
            self._retry_s = self.RETRY_MIN_S

    # ----------------------------------------------------------------------------- loop thread
    def _deliver(self) -> None:
        """Hand the queued chunks to ``on_data``, in order (in the loop; at shutdown the caller)."""
        q = self._queue
        while q:
            t, data = q.popleft()
            try:
                self.on_data(t, data)
            except Exception as e:  # a parser bug must not lose the port
                log.error("error handling GNSS data: %s: %s", e.__class__.__name__, e)

    def _stop_reader(self) -> None:
        self._stop.set()
        if self._wake_w >= 0:
            try:
                os.write(self._wake_w, b"x")
            except OSError:
                pass
        if self._reader is not None:
            if self._reader is not threading.current_thread():
                self._reader.join(2.0)
            self._reader = None
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                os.close(fd)
        self._wake_r = self._wake_w = -1

    def drain(self, max_reads: int = 64) -> None:
        """Stop the reader, read what is already buffered in the port and deliver every chunk
        still queued, in order (at shutdown: no received byte is left behind)."""
        self._stop_reader()
        for _ in range(max_reads):
            if not self.connected:
                break
            before = self.bytes_read
            self._read_once()
            if self.bytes_read == before:
                break
        self._deliver()

    def _close_port(self) -> None:
        if self._ser is not None:
            try:
                self._ser.close()
            except (OSError, serial.SerialException):
                pass
        self._ser, self._fd = None, -1
        self.connected = False

    def close(self) -> None:
        """Stop the reader thread (at once: it is woken, then joined) and close the port."""
        self._stop_reader()
        self._close_port()
