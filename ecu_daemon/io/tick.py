"""The 6 ms tick: a dedicated thread that wakes on absolute deadlines of the monotonic clock.

Why a thread and not ``asyncio.sleep``: the selector rounds timeouts up to whole milliseconds,
which makes a 166 Hz loop ~0.6 ms late at p50 and >1 ms at p99 (research finding 3). Here the
thread sleeps (``clock_nanosleep`` under ``time.sleep``, with the thread's timer slack cut to
1 us) until shortly before the deadline and spins the last ``spin_s``.

Deadlines are ``k * period + offset_s`` for integer k, computed from k each time (never by
adding periods), so there is no drift and a late tick does not delay the next one. When a tick
is woken more than one period late, the deadlines in between are not serviced one by one: the
callback gets the newest due index (the estimator's ``advance_to`` runs the missed steps) and the
missed deadlines are counted as ``skipped``. A tick ``overruns`` when it woke more than a period
late or its callback ended after the next deadline.

The demo's ``--speed`` runs the daemon on a :class:`ScaledClock`; the tick then sleeps
``(deadline - now) / speed`` of real time and lateness is reported in real seconds.
"""
from __future__ import annotations

import ctypes
import logging
import math
import os
import threading
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

log = logging.getLogger("ecu_daemon.tick")

_PR_SET_TIMERSLACK = 29


class ScaledClock:
    """A monotonic clock running ``speed`` times faster than ``time.monotonic`` (demo fast-forward)."""

    def __init__(self, speed: float = 1.0) -> None:
        if not (speed > 0 and math.isfinite(speed)):
            raise ValueError("speed must be a positive number")
        self.speed = float(speed)
        self._t0 = time.monotonic()

    def __call__(self) -> float:
        return self._t0 + (time.monotonic() - self._t0) * self.speed


@dataclass
class TickSnapshot:
    """Tick timing summary (seconds of real time)."""

    ticks: int = 0
    late_p50_s: float = 0.0
    late_p99_s: float = 0.0
    late_max_s: float = 0.0  # maximum over the window
    late_max_total_s: float = 0.0  # maximum since start
    overruns: int = 0
    skipped: int = 0
    work_p99_s: float = 0.0


class TickStats:
    """Lateness and callback duration of recent ticks (ring) plus whole-run histogram and counters."""

    HIST_BIN_S = 10e-6
    HIST_BINS = 2000  # 0 .. 20 ms, last bin = everything later

    def __init__(self, window: int = 2048) -> None:
        self._late = np.zeros(window)
        self._work = np.zeros(window)
        self._n = 0
        self.hist = np.zeros(self.HIST_BINS + 1, dtype=np.int64)
        self.overruns = 0
        self.skipped = 0
        self.late_max_total_s = 0.0

    def record(self, late_s: float, work_s: float, skipped: int, overrun: bool) -> None:
        i = self._n % len(self._late)
        self._late[i] = late_s
        self._work[i] = work_s
        self._n += 1
        b = int(late_s / self.HIST_BIN_S) if late_s > 0 else 0
        self.hist[b if b < self.HIST_BINS else self.HIST_BINS] += 1
        if late_s > self.late_max_total_s:
            self.late_max_total_s = late_s
        self.skipped += skipped
        self.overruns += bool(overrun or skipped)

    @property
    def ticks(self) -> int:
        return self._n

    def snapshot(self) -> TickSnapshot:
        n = min(self._n, len(self._late))
        if n == 0:
            return TickSnapshot()
        late = np.sort(self._late[:n])
        return TickSnapshot(ticks=self._n, late_p50_s=_percentile(late, 50), late_p99_s=_percentile(late, 99),
                            late_max_s=float(late[-1]), late_max_total_s=self.late_max_total_s,
                            overruns=self.overruns, skipped=self.skipped,
                            work_p99_s=_percentile(np.sort(self._work[:n]), 99))

    def total_percentile(self, q: float) -> float:
        """Percentile of lateness over the whole run from the histogram (bin resolution 10 us)."""
        total = int(self.hist.sum())
        if total == 0:
            return 0.0
        idx = int(np.searchsorted(np.cumsum(self.hist), math.ceil(q / 100.0 * total)))
        return (idx + 1) * self.HIST_BIN_S


def _percentile(ordered: np.ndarray, q: float) -> float:
    """``np.percentile`` (linear interpolation) of an already sorted array. Why not that: the
    daemon's loop takes a snapshot every 50 ms, and numpy's general path was half its CPU."""
    pos = q / 100.0 * (len(ordered) - 1)
    i = int(pos)
    if i + 1 >= len(ordered):
        return float(ordered[-1])
    a, b = float(ordered[i]), float(ordered[i + 1])
    return a + (b - a) * (pos - i)


def _set_timer_slack(ns: int) -> None:
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_TIMERSLACK, ctypes.c_ulong(ns), 0, 0, 0)
    except (OSError, AttributeError):
        pass


class TickThread(threading.Thread):
    """Calls ``on_tick(k, now)`` once per period at ``k * period + offset_s`` (k = newest due index).

    ``on_tick`` runs in this thread; exceptions in it are logged (rate-limited) and the tick
    goes on, so one bad step never stops the outputs or the watchdog for good.
    """

    def __init__(self, period_s: float, on_tick: Callable[[int, float], None], *,
                 offset_s: float = 0.0, clock: Callable[[], float] = time.monotonic,
                 speed: float = 1.0, spin_s: float = 0.0002, realtime_priority: int = 0,
                 stats: TickStats | None = None, name: str = "ecu-tick") -> None:
        super().__init__(name=name, daemon=True)
        self.period_s = period_s
        self.offset_s = offset_s
        self.on_tick = on_tick
        self.clock = clock
        self.speed = speed
        self.spin_s = spin_s
        self.realtime_priority = realtime_priority
        self.stats = stats or TickStats()
        self.errors = 0
        self.realtime = False
        self._stop_evt = threading.Event()

    def stop(self, join_timeout: float = 2.0) -> None:
        self._stop_evt.set()
        if self.is_alive() and threading.current_thread() is not self:
            self.join(join_timeout)

    def _setup_thread(self) -> None:
        _set_timer_slack(1000)
        if self.realtime_priority > 0:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.realtime_priority))
                self.realtime = True
                log.info("tick thread runs SCHED_FIFO priority %d", self.realtime_priority)
            except (OSError, AttributeError) as e:
                log.warning("cannot use SCHED_FIFO priority %d for the tick (%s); running without it",
                            self.realtime_priority, getattr(e, "strerror", None) or e)

    def run(self) -> None:
        self._setup_thread()
        period, offset, clock, speed, spin = self.period_s, self.offset_s, self.clock, self.speed, self.spin_s
        stop = self._stop_evt
        k = math.floor((clock() - offset) / period) + 1
        while not stop.is_set():
            deadline = k * period + offset
            wait = (deadline - clock()) / speed - spin
            if wait > 0:
                time.sleep(wait)
            while clock() < deadline:
                pass
            if stop.is_set():
                break
            now = clock()
            k_due = math.floor((now - offset) / period)
            if k_due < k:  # float edge: never go back
                k_due = k
            try:
                self.on_tick(k_due, now)
            except Exception as e:  # keep ticking; the error is counted and reported
                self.errors += 1
                log.error("tick callback failed: %s: %s", e.__class__.__name__, e)
            end = clock()
            self.stats.record((now - deadline) / speed, (end - now) / speed, k_due - k,
                              end > (k_due + 1) * period + offset)
            k = k_due + 1
