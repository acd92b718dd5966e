"""The CAN side of the shell: open the bus, receive in batches outside the tick thread, send with back-off.

Reception. Frames are taken in batches (what is waiting, at most ``max_batch``), filtered, their
times mapped, and handed on in one go, outside the tick thread: the tick never reads the bus, so
however many frames arrive (a flood, a backlog after the host held the process up) it only
shares the CPU and the GIL with the reception, and is never held up by a batch of unbounded
length before its step. Where the bus has a file descriptor (socketcan, which also filters in
the kernel, so only the frames we use arrive), the event loop reads a batch whenever the socket
is readable, as python-can's Notifier does but without a loop callback per frame. Otherwise
(virtual, interfaces without a descriptor) a reader thread blocks in ``recv`` and, with
``start(period_s=...)``, paces itself on the step grid: after a batch it sleeps until the next
step boundary (plus ``offset_s``), so at 2000 frames/s it wakes ~2 times per 6 ms step instead
of once per frame. A frame stamped before the boundary is then in the queue and handed over
before the tick of its step (which runs ``grace`` after the boundary); its time comes from its
own timestamp, not from when it was read. (Why not a thread on socketcan too: in the kernel
tests' user-mode Linux, where every system call and GIL hand-over is a ptrace round trip, a
reader thread, paced or not, fell 3-4 s behind where the loop kept up.)

Bus health: error frames (class bits in the id, controller state in data[1], error counters in
data[6..7], as in linux/can/error.h) drive :class:`BusHealth`; while the controller is bus-off,
:meth:`CanIO.send` suppresses transmission (counted) until a restart/active error frame or a
received data frame shows the controller is back, or a growing retry interval expires.
"""
from __future__ import annotations

import asyncio
import logging
import math
import threading
import time
from collections import deque
from typing import Callable, Iterable

import can

from .logging_setup import RateLimitedLog

log = logging.getLogger("ecu_daemon.can")

# linux/can/error.h
CAN_ERR_TX_TIMEOUT = 0x001
CAN_ERR_LOSTARB = 0x002
CAN_ERR_CRTL = 0x004
CAN_ERR_PROT = 0x008
CAN_ERR_TRX = 0x010
CAN_ERR_ACK = 0x020
CAN_ERR_BUSOFF = 0x040
CAN_ERR_BUSERROR = 0x080
CAN_ERR_RESTARTED = 0x100
CAN_ERR_CNT = 0x200
CAN_ERR_CRTL_RX_WARNING = 0x04
CAN_ERR_CRTL_TX_WARNING = 0x08
CAN_ERR_CRTL_RX_PASSIVE = 0x10
CAN_ERR_CRTL_TX_PASSIVE = 0x20
CAN_ERR_CRTL_ACTIVE = 0x40

# bus states reported in diagnostics (ordinal = severity)
BUS_ACTIVE, BUS_WARNING, BUS_PASSIVE, BUS_OFF = 0, 1, 2, 3
BUS_STATE_NAMES = ("active", "warning", "passive", "bus-off")


class ClockMapper:
    """Message clock -> monotonic clock by a windowed minimum-latency offset (see module doc)."""

    def __init__(self, block_s: float = 1.0, blocks: int = 5, step_s: float = 0.05,
                 quantum_s: float = 1e-6) -> None:
        self.block_s, self.step_s, self.quantum_s = block_s, step_s, quantum_s
        self._history: deque[float] = deque(maxlen=blocks)
        self._block_start = -math.inf
        self._block_min = math.inf
        self.offset_s = math.nan
        self.last_t = -math.inf
        self.steps = 0  # clock steps detected (window resets)
        self.untimestamped = 0  # messages without a usable timestamp (stamped at reception)

    def observe(self, ts: float, now: float) -> None:
        """Take a frame's latency into the window without mapping it. A batch's newest frame (the
        smallest latency) goes in before the older ones are mapped, so frames read together keep
        their own spacing even while the window is young (at start, after a clock step)."""
        if ts > 0.0 and math.isfinite(ts):
            if now - self._block_start >= self.block_s:
                self._close_block(now)
            if now - ts < self._block_min:
                self._block_min = now - ts

    def map(self, ts: float, now: float) -> float:
        q = self.quantum_s
        if not (ts > 0.0 and math.isfinite(ts)):
            self.untimestamped += 1
            t = round(now / q) * q
        else:
            d = now - ts
            if now - self._block_start >= self.block_s:
                self._close_block(now)
            if d < self._block_min:
                self._block_min = d
            off = self._block_min
            for h in self._history:
                if h < off:
                    off = h
            self.offset_s = off
            t = round((ts + off) / q) * q
        if t < self.last_t:
            t = self.last_t
        self.last_t = t
        return t

    def _close_block(self, now: float) -> None:
        bm = self._block_min
        if math.isfinite(bm):
            if self._history and bm - min(self._history) > self.step_s:
                self.steps += 1
                log.warning("CAN timestamp clock stepped back by %.3f s; time base re-synchronised",
                            bm - min(self._history))
                self._history.clear()
            self._history.append(bm)
        self._block_start = now
        self._block_min = math.inf


class BusHealth:
    """Error-frame bookkeeping and the bus-off transmit gate."""

    # Without any sign of recovery (RESTARTED / error-active frame, a frame from another node),
    # transmission is tried again after this long, doubling: a safety net for drivers that do not
    # report the restart. With networkd's RestartSec=100ms the restart frame comes long before.
    RETRY_MIN_S = 2.0
    RETRY_MAX_S = 60.0
    TX_FAIL_LIMIT = 3  # consecutive send failures before transmission pauses
    TX_PAUSE_MIN_S = 0.01
    TX_PAUSE_MAX_S = 1.0

    def __init__(self) -> None:
        self.state = BUS_ACTIVE
        self.error_frames = 0
        self.bus_off_count = 0
        self.restarts = 0
        self.tx_error_counter = 0
        self.rx_error_counter = 0
        self.tx_failures = 0
        self.tx_suppressed = 0
        self.tx_sent = 0
        self.last_error_class = 0
        self._retry_s = self.RETRY_MIN_S
        self._tx_resume_at = -math.inf
        self._consecutive_fail = 0
        self._pause_s = self.TX_PAUSE_MIN_S

    @property
    def bus_off(self) -> bool:
        return self.state == BUS_OFF

    def on_error_frame(self, msg: can.Message, now: float) -> None:
        self.error_frames += 1
        cls = msg.arbitration_id & 0x1FFFFFFF
        self.last_error_class = cls
        data = bytes(msg.data)
        if len(data) >= 8 and (cls & CAN_ERR_CNT or data[6] or data[7]):
            self.tx_error_counter, self.rx_error_counter = data[6], data[7]
        if cls & CAN_ERR_BUSOFF:
            if self.state != BUS_OFF:
                self.bus_off_count += 1
                log.error("CAN bus-off (error class 0x%03X): transmission suspended", cls)
            self.state = BUS_OFF
            self._tx_resume_at = now + self._retry_s
            self._retry_s = min(self._retry_s * 2, self.RETRY_MAX_S)
            return
        if cls & CAN_ERR_RESTARTED or (cls & CAN_ERR_CRTL and len(data) > 1 and data[1] & CAN_ERR_CRTL_ACTIVE):
            self._recover("controller restarted" if cls & CAN_ERR_RESTARTED else "controller error-active")
            return
        if cls & CAN_ERR_CRTL and len(data) > 1:
            c = data[1]
            if c & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE):
                new = BUS_PASSIVE
            elif c & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING):
                new = BUS_WARNING
            else:
                new = self.state
            if self.state != BUS_OFF and new != self.state:
                log.warning("CAN controller is error-%s (class 0x%03X, ctrl 0x%02X)",
                            BUS_STATE_NAMES[new], cls, c)
                self.state = new

    def on_data_frame(self) -> None:
        """An input frame arrived: a bus-off controller cannot receive, so it is back on the bus."""
        if self.state == BUS_OFF:
            self._recover("frames received again")

    def on_library_state(self, state, now: float) -> None:
        """python-can's ``BusState`` where the interface reports one (ERROR ~ bus-off)."""
        if state == can.BusState.ERROR and self.state != BUS_OFF:
            self.bus_off_count += 1
            self.state = BUS_OFF
            self._tx_resume_at = now + self._retry_s
            log.error("CAN interface reports error state: transmission suspended")

    def _recover(self, why: str) -> None:
        if self.state == BUS_OFF:
            self.restarts += 1
            log.warning("CAN bus recovered from bus-off (%s); transmission resumed", why)
        self.state = BUS_ACTIVE
        self._retry_s = self.RETRY_MIN_S
        self._tx_resume_at = -math.inf

    def may_send(self, now: float) -> bool:
        if now >= self._tx_resume_at:
            return True
        self.tx_suppressed += 1
        return False

    def on_send_ok(self) -> None:
        self.tx_sent += 1
        self._consecutive_fail = 0
        self._pause_s = self.TX_PAUSE_MIN_S

    def on_send_failed(self, now: float, err: Exception) -> None:
        self.tx_failures += 1
        self._consecutive_fail += 1
        log.warning("CAN send failed: %s", err)
        if self._consecutive_fail >= self.TX_FAIL_LIMIT:
            self._tx_resume_at = max(self._tx_resume_at, now + self._pause_s)
            self._pause_s = min(self._pause_s * 2, self.TX_PAUSE_MAX_S)
            self._consecutive_fail = 0


def resolve_bus_config(cfg_can, explicit_keys: Iterable[str] = (), overrides: dict | None = None) -> dict:
    """Effective ``can.Bus`` keyword arguments.

    Precedence: command-line flags > keys written in the TOML ``[can]`` table (and its
    ``bus_kwargs``) > python-can's own configuration (``can.rc``, ``CAN_INTERFACE`` /
    ``CAN_CHANNEL`` / ``CAN_BITRATE`` / ``CAN_CONFIG``, ``/etc/can.conf``, ``~/.canrc``) > our
    built-in defaults (``virtual`` bus).
    """
    from can.exceptions import CanInterfaceNotImplementedError

    from ..config import ConfigError

    explicit = set(explicit_keys)
    given: dict = dict(cfg_can.bus_kwargs)
    for key in ("interface", "channel", "bitrate"):
        if key in explicit:
            given[key] = getattr(cfg_can, key)
    given.update({k: v for k, v in (overrides or {}).items() if v is not None})
    try:
        merged = dict(can.util.load_config(config=dict(given)))
    except CanInterfaceNotImplementedError as e:
        if given.get("interface"):
            raise ConfigError(f"[can] interface: {e}") from None
        merged = dict(can.util.load_config(config={**given, "interface": cfg_can.interface}))
    except ValueError as e:
        raise ConfigError(f"python-can configuration: {e}") from None
    if merged.get("channel") is None:
        merged["channel"] = cfg_can.channel
    if merged.get("bitrate") is None:
        merged["bitrate"] = cfg_can.bitrate
    return {k: v for k, v in merged.items() if v is not None}


def _has_own_filtering(bus) -> bool:
    """True if the interface filters in the kernel / hardware (socketcan), not in Python."""
    cls = bus if isinstance(bus, type) else type(bus)
    return cls._apply_filters is not can.BusABC._apply_filters


class CanIO:
    """One python-can bus: filtered reception into ``on_frame``/``on_error_frame``, sends.

    ``frame_ids`` are (id, is_extended) pairs the decoder consumes. Interfaces that filter in the
    kernel or hardware (socketcan) get them as ``can_filters``; for the rest (virtual) the check
    is a set lookup here, because python-can's software filter would also drop error frames.

    Reception runs in the reader thread of :meth:`start` (see the module doc): ``on_frame`` /
    ``on_error_frame`` are called there for each frame of a batch, in order, then ``on_batch()``
    once (where a consumer hands the whole batch on).
    """

    RX_TIMEOUT_S = 0.2  # the reader's longest wait in the bus: how soon it notices stop()
    MAX_BATCH = 256  # frames handed on at once; a longer backlog is read on at once, batch by batch

    def __init__(self, bus: can.BusABC, frame_ids: Iterable[tuple[int, bool]], *,
                 clock: Callable[[], float] = time.monotonic,
                 on_frame: Callable[[float, can.Message], None],
                 on_error_frame: Callable[[float, can.Message], None] | None = None,
                 on_batch: Callable[[], None] | None = None, max_batch: int = MAX_BATCH) -> None:
        self.bus = bus
        self.clock = clock
        self.mapper = ClockMapper()
        self.health = BusHealth()
        self.on_frame = on_frame
        self.on_error_frame = on_error_frame
        self.on_batch = on_batch
        self.max_batch = max(1, int(max_batch))
        self.wanted = {(int(i), bool(e)) for i, e in frame_ids}
        self.rx_frames = 0
        self.rx_ignored = 0
        self.rx_batches = 0
        self.callback_errors = 0
        self._err_log = RateLimitedLog(log)
        self.kernel_filters = False
        self._reader: threading.Thread | None = None
        self._loop_fd: tuple | None = None  # (loop, fd) while the loop reads
        self._stop_evt = threading.Event()
        if _has_own_filtering(bus) and self.wanted:
            bus.set_filters([{"can_id": i, "can_mask": 0x1FFFFFFF if e else 0x7FF, "extended": e}
                             for i, e in sorted(self.wanted)])
            if getattr(bus, "_is_filtered", True):
                self.kernel_filters = True
            else:
                # The kernel refused (python-can logged it) and fell back to its software filter,
                # which would drop error frames and end a recv(0) batch at the first frame it
                # drops: take the filter off and check the ids here, as on a virtual bus.
                bus.set_filters(None)

    def start(self, loop: asyncio.AbstractEventLoop | None = None, *, period_s: float | None = None,
              offset_s: float = 0.0, speed: float = 1.0) -> None:
        """Start reception: on ``loop`` if the bus has a file descriptor, else in a reader thread
        that, with ``period_s``, reads at most about once per period after the first frame of
        each (wakes at ``k * period_s + offset_s`` of ``clock``, which runs ``speed`` times real
        time). See the module doc."""
        if loop is not None:
            try:
                fd = self.bus.fileno()
            except (NotImplementedError, AttributeError, OSError, ValueError):
                fd = -1
            if isinstance(fd, int) and fd >= 0:
                loop.add_reader(fd, self._on_readable)
                self._loop_fd = (loop, fd)
                return
        self._stop_evt.clear()
        self._reader = threading.Thread(target=self._read, args=(period_s, offset_s, speed),
                                        name="ecu-can-rx", daemon=True)
        self._reader.start()

    def _on_readable(self) -> None:
        """The loop's reader: one batch (a longer backlog keeps the socket readable: the loop
        comes back after its other callbacks)."""
        self._take([])

    def _read(self, period_s: float | None, offset_s: float, speed: float) -> None:
        recv, stop, clock = self.bus.recv, self._stop_evt, self.clock
        while not stop.is_set():
            try:
                msg = recv(self.RX_TIMEOUT_S)
            except (can.CanError, OSError) as e:  # interface down: say so (rate-limited), keep trying
                self._err_log.report(e.__class__.__name__, logging.ERROR, f"receiving from the CAN bus: {e}")
                stop.wait(0.1)
                continue
            if msg is None:
                continue
            if self._take([msg]) >= self.max_batch or not period_s:
                continue  # a backlog: read on at once
            now = clock()
            wait = ((math.floor((now - offset_s) / period_s) + 1) * period_s + offset_s - now) / speed
            if wait > 0:
                time.sleep(wait)

    def _take(self, msgs: list) -> int:
        """Add what else is waiting (up to ``max_batch`` in all) to ``msgs`` and hand them on."""
        recv = self.bus.recv
        limit = self.max_batch
        try:
            while len(msgs) < limit:
                msg = recv(0)
                if msg is None:
                    break
                msgs.append(msg)
        except (can.CanError, OSError) as e:
            self._err_log.report(e.__class__.__name__, logging.ERROR, f"receiving from the CAN bus: {e}")
        self.handle(msgs)
        return len(msgs)

    def handle(self, msgs: list) -> None:
        """One batch of received frames, in order: filter, map times, hand on (any one thread).

        The clock is read once, after the frames were taken, so every mapped time is <= it; the
        newest frame's latency enters the clock window first (``ClockMapper.observe``)."""
        if not msgs:
            return
        now = self.clock()
        if len(msgs) > 1:
            self.mapper.observe(max(m.timestamp or 0.0 for m in msgs), now)
        for msg in msgs:
            self._on_message(msg, now)
        self.rx_batches += 1
        if self.on_batch is not None:
            try:
                self.on_batch()
            except Exception as e:
                self.callback_errors += 1
                self._err_log.report(e.__class__.__name__, logging.ERROR,
                                     f"error handing on received CAN frames: {e.__class__.__name__}: {e}")

    def _on_message(self, msg: can.Message, now: float | None = None) -> None:
        if now is None:
            now = self.clock()
        try:
            if msg.is_error_frame:
                self.health.on_error_frame(msg, now)
                if self.on_error_frame is not None:
                    self.on_error_frame(self.mapper.map(msg.timestamp, now), msg)
                return
            # NB: no ``is_rx`` test -- socketcan marks every frame created on this host (canplayer
            # replaying a log onto vcan0, a co-located ECU) as not received; the id set keeps our
            # own echoed outputs out.
            if not self.kernel_filters and (msg.arbitration_id, msg.is_extended_id) not in self.wanted:
                self.rx_ignored += 1
                return
            self.health.on_data_frame()
            self.rx_frames += 1
            t = self.mapper.map(msg.timestamp, now)
            self.on_frame(t, msg)
        except Exception as e:  # a listener error must not kill reception (python-can #1912)
            self.callback_errors += 1
            self._err_log.report(e.__class__.__name__, logging.ERROR,
                                 f"error handling CAN frame 0x{msg.arbitration_id:X}: {e.__class__.__name__}: {e}")

    def drain(self, max_frames: int = 100000) -> int:
        """Handle the frames already waiting in the bus (after :meth:`stop`, at shutdown)."""
        n = 0
        while n < max_frames:
            got = self._take([])
            n += got
            if got < self.max_batch:
                break
        return n

    def poll_library_state(self) -> None:
        try:
            self.health.on_library_state(self.bus.state, self.clock())
        except Exception:  # interfaces that do not implement it
            pass

    def send(self, msg: can.Message) -> bool:
        """Send without blocking; False if suppressed (bus-off / back-off) or failed (counted)."""
        h = self.health
        now = self.clock()
        if not h.may_send(now):
            return False
        try:
            self.bus.send(msg, timeout=0)
        except (can.CanOperationError, OSError) as e:
            h.on_send_failed(now, e)
            return False
        h.on_send_ok()
        return True

    def stop(self) -> None:
        """Stop reception (a reader thread notices within ``RX_TIMEOUT_S``; the loop's reader is
        removed at once: call this in the loop's thread)."""
        if self._loop_fd is not None:
            loop, fd = self._loop_fd
            self._loop_fd = None
            try:
                loop.remove_reader(fd)
            except (RuntimeError, ValueError, OSError):  # the loop is already closed
                pass
        self._stop_evt.set()
        if self._reader is not None:
            if self._reader is not threading.current_thread():
                self._reader.join(2.0)
            self._reader = None

    def shutdown(self) -> None:
        self.stop()
        try:
            self.bus.shutdown()
        except Exception as e:
            log.warning("closing the CAN bus: %s", e)
