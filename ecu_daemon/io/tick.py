"""The 6 ms tick: a dedicated thread that wakes on absolute deadlines of the monotonic clock.

Why a thread and not ``asyncio.sleep``: the selector rounds timeouts up to whole milliseconds,
which makes a 166 Hz loop ~0.6 ms late at p50 and >1 ms at p99 (research finding 3). Here the
thread sleeps (``clock_nanosleep`` under ``time.sleep``, with the thread's timer slack cut to
1 us) until shortly before the deadline and spins the rest. How much before is learned
(:class:`WakeLead`): a typical wake-up from the sleep (timer, scheduler, the GIL) takes a few
tens of microseconds, and a fixed 0.2 ms spin burned ~150 us of CPU per tick (2.5 % of a core,
a third of the daemon's budget) to save them.

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


class WakeLead:
    """How long before its deadline the tick asks to be woken: a quantile of its recent wake-up
    delays (how late ``time.sleep`` returned, GIL included), at most ``max_s``.

    Why a quantile and not the worst case: the spin after the wake-up is CPU burned, and the rare
    long delays (another process on the core) are not saved by any spin of a sane length; with
    the median half the ticks wake up in time and the others are a few tens of
    microseconds late. Recomputed every ``window`` wake-ups, so it costs nothing per tick.
    """

    def __init__(self, max_s: float = 0.0002, window: int = 64, quantile: float = 0.5) -> None:
        self.max_s = max_s
        self.quantile = quantile
        self._recent = [0.0] * window
        self._n = 0
        self.lead_s = max_s  # until there is a window of wake-ups to go by

    def observe(self, delay_s: float) -> None:
        """One wake-up ``delay_s`` after the time asked for (negative: early)."""
        recent = self._recent
        i = self._n % len(recent)
        recent[i] = delay_s
        self._n += 1
        if i == len(recent) - 1:
            q = sorted(recent)[int(self.quantile * (len(recent) - 1))]
            self.lead_s = min(self.max_s, max(0.0, q))


def _set_timer_slack(ns: int) -> None:
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_TIMERSLACK, ctypes.c_ulong(ns), 0, 0, 0)
    except (OSError, AttributeError):
        pass


class TickThread(threading.Thread):
    """Calls ``on_tick(k, now)`` once per period at ``k * period + offset_s`` (k = newest due index).

    ``spin_s``: the longest spin before a deadline (the wake-up lead is learned up to it, see
    :class:`WakeLead`).

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
        self.lead = WakeLead(spin_s)
        self.spun_s = 0.0  # time spent spinning before deadlines (CPU burned), real seconds
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
        period, offset, clock, speed, lead = self.period_s, self.offset_s, self.clock, self.speed, self.lead
        stop = self._stop_evt
        k = math.floor((clock() - offset) / period) + 1
        while not stop.is_set():
            deadline = k * period + offset
            wait = (deadline - clock()) / speed - lead.lead_s
            woke = clock()
            if wait > 0:
                time.sleep(wait)
                woke = clock()
                lead.observe((woke - deadline) / speed + lead.lead_s)
            while clock() < deadline:
                pass
            if stop.is_set():
                break
            now = clock()
            if now > woke:
                self.spun_s += (now - woke) / speed
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
