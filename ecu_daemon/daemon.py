"""``ecu-daemon run``: the live daemon, the imperative shell around the pure estimator.

Threads and data flow::

    CAN reader thread (buses without a file descriptor; io/can_bus.py)
    CAN frames, a batch per wake-up -> filter,
      ClockMapper ----------------------------------+
    GNSS reader thread per port (io/serial_port.py) |
    bytes -> stamp when the read returns -> queue   |
    event loop (asyncio, main thread)               |  tick thread (io/tick.py)
    ---------------------------------               |  ------------------------
    (socketcan: the same, on the loop) -------------+--> every 6 ms at k*dt + grace:
    GNSS chunks, in order, from the queue ----------+--> Pipeline.tick(k): decode what is due,
    host health (20 Hz) ----------------------------+    estimate, validity, frames -> bus.send
                                                         WATCHDOG=1
      recording, STATUS=, state persistence <---------- received frames (reader), published
                                                         estimates / sent frames (deque)

Everything between the raw inputs and the frames is :class:`~ecu_daemon.pipeline.Pipeline`,
owned by the tick thread alone; the CAN reception and the loop hand it raw frames and byte chunks
through its inbox (a deque: append/popleft are atomic), so there is no lock on the hot path. The
tick thread never reads the bus itself: a flood or a backlog costs it CPU share, never a batch of
unbounded length before its step (see ``io/can_bus.py``). Inputs carry receive
times on the monotonic clock (CAN: kernel timestamps mapped once, see ``io/can_bus.py``; GNSS:
when the port's reader thread's read returned, not when the loop got round to the chunk, see
``io/serial_port.py``), rounded to 1 us as the recording writes them.

Live/replay equivalence: the recording (``--record``) keeps the inputs, the frames sent, the
published estimates and the tick record (``ticks.log``: first tick, inputs that reached the tick
thread after their step ran and were applied one step late, steps run without a tick of their
own, the host health each tick saw). ``ecu-daemon replay`` of the recording follows the tick
record and writes the frames the daemon sent, byte for byte.

Overrun policy: a tick woken more than a period late runs the missed estimator steps at once
(``advance_to``), sends only the newest step's frames and counts the overrun; the skipped output
slots stay empty and each message's COUNTER steps by one per frame actually sent.
"""
from __future__ import annotations

import argparse
import asyncio
import gc
import importlib
import logging
import math
import os
import signal
import sys
import threading
import time
import tomllib
from collections import deque
from pathlib import Path

import can

from . import config as config_mod
from .config import Config, ConfigError
from .diagnostics import Diagnostics
from .errors import UserError
from .estimator import Estimate
from .gnss.stream import GnssStreamParser
from .io import health as health_mod
from .io.can_bus import CanIO, resolve_bus_config
from .io.logging_setup import setup_logging
from .io.notify import SystemdNotifier
from .io.serial_port import GnssSerial
from .io.state_store import StateFileError, load_state, save_state
from .io.tick import TickStats, TickThread
from .pipeline import DIAG_S, Pipeline, TickRecord

log = logging.getLogger("ecu_daemon.daemon")

INPUT_GRACE_S = 0.001  # the step for time T runs at T + grace: frames stamped <= T get there first
HOUSEKEEPING_S = 0.05  # the loop's housekeeping at least this often (real time), half-way between ticks
FLUSH_S = 1.0
STATUS_S = 5.0
PERSIST_S = 60.0  # learned state written this often (and at exit)
RX_OFFSET = 0.25  # the CAN reader wakes this fraction of the input grace after each step boundary
SWITCH_INTERVAL_S = 0.0002  # GIL hand-over: the longest a waking tick waits for a thread running Python


class Daemon:
    """The live daemon; also the engine of ``ecu-daemon demo`` and the integration tests.

    ``clock`` is the monotonic time base of everything (the demo passes a ScaledClock and the
    matching ``speed``); ``estimate_sink(list[Estimate])`` is called in the loop thread with
    every batch of estimates (the demo's live view).
    """

    def __init__(self, cfg: Config, *, bus_config: dict | None = None, record_dir: str | Path | None = None,
                 clock=time.monotonic, speed: float = 1.0, notifier: SystemdNotifier | None = None,
                 estimate_sink=None, input_grace_s: float = INPUT_GRACE_S,
                 persist_interval_s: float = PERSIST_S) -> None:
        self.cfg = cfg
        self.bus_config = dict(bus_config) if bus_config else {"interface": cfg.can.interface,
                                                                "channel": cfg.can.channel}
        self.record_dir = record_dir
        self.clock = clock
        self.speed = speed
        self.notifier = notifier or SystemdNotifier()
        self.estimate_sink = estimate_sink
        self.grace_s = input_grace_s
        self.persist_interval_s = persist_interval_s
        self.dt = cfg.estimator.dt_s
        # live state, read by tests / demo / status
        self.tick_stats = TickStats()
        self.latest: Estimate | None = None
        self._gaps_said = 0  # estimator gaps (clock jumps) already logged
        self.frames_sent = 0
        self.steps = 0
        self.running = False
        self.ready = threading.Event()
        self.stopped = threading.Event()
        self.learned_restored = False
        # internals
        self.pipeline: Pipeline | None = None
        self._can_seq = 0  # line of the next received frame in the recording's can.log
        self._gnss_seq: dict[int, int] = {}  # receiver -> line of its next chunk in its capture
        self._gnss_names: list[str] = []
        self._out: deque = deque()  # tick thread, CAN reception -> loop thread (recording, live view)
        self._rx_record: list = []  # the CAN reader's batch for the recording, handed on per batch
        self._last_tick: int | None = None
        self._learned_req = False
        self._learned_snap: dict | None = None
        self._stop_evt: asyncio.Event | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._wd_next = 0.0
        self._wd_interval = self.notifier.watchdog_s / 3.0 if self.notifier.watchdog_s > 0 else 0.0
        self._gnss_silent: set[int] = set()  # receivers reported silent
        self.canio: CanIO | None = None
        # one serial port and parser per GNSS receiver ([[gnss.receiver]], in order)
        self.serials: list[GnssSerial] = []
        self.parsers: list[GnssStreamParser] = []
        self.recorder = None
        self.tick: TickThread | None = None
        self.cpu = health_mod.CpuMeter()

    # ----------------------------------------------------------------------------- pipeline views
    @property
    def estimator(self):
        return self.pipeline.estimator if self.pipeline is not None else None

    @property
    def decoder(self):
        return self.pipeline.decoder if self.pipeline is not None else None

    @property
    def diag(self) -> Diagnostics:
        """The diagnostics of the latest EST_DIAG (empty before the first)."""
        d = self.pipeline.diag if self.pipeline is not None else None
        return d if d is not None else Diagnostics()

    @property
    def late_samples(self) -> int:
        """Inputs that reached the tick thread after their step ran (applied one step late)."""
        return self.pipeline.late_items if self.pipeline is not None else 0

    @property
    def earliest_late_t(self) -> float:
        return self.pipeline.earliest_late_t if self.pipeline is not None else math.inf

    @property
    def serial(self) -> GnssSerial | None:
        """The first receiver's port (the one a single-receiver config has)."""
        return self.serials[0] if self.serials else None

    @property
    def parser(self) -> GnssStreamParser | None:
        return self.parsers[0] if self.parsers else None

    # ----------------------------------------------------------------------------- lifecycle
    def request_stop(self) -> None:
        """Thread-safe: ask the daemon to shut down cleanly (what SIGTERM/SIGINT do)."""
        loop, evt = self._loop, self._stop_evt
        if loop is None or evt is None:
            return
        if threading.current_thread() is threading.main_thread() and _running_loop() is loop:
            evt.set()
        else:
            loop.call_soon_threadsafe(evt.set)

    async def run(self, duration: float | None = None) -> int:
        self._loop = loop = asyncio.get_running_loop()
        self._stop_evt = asyncio.Event()
        handlers = self._install_signal_handlers(loop)
        old_switch = sys.getswitchinterval()
        try:
            self._setup()
            _preload()
            # Everything allocated so far (modules, DBCs, config) lives as long as the process:
            # take it out of the cyclic GC's scans so a full collection does not stall the tick.
            gc.collect()
            gc.freeze()
            sys.setswitchinterval(SWITCH_INTERVAL_S)
            self._start(loop)
            if duration is not None:
                loop.call_later(duration / self.speed, self.request_stop)
            self.running = True
            self.ready.set()
            self.notifier.ready(f"running on {self._bus_name()}")
            log.info("ecu-daemon running: CAN %s, GNSS %s, %d Hz estimator%s", self._bus_name(),
                     ", ".join(rx.port for _, rx in self._gnss_receivers()) or "off", round(1 / self.dt),
                     f", recording into {self.record_dir}" if self.recorder else "")
            await self._housekeeping()
        finally:
            self.running = False
            self._shutdown()
            sys.setswitchinterval(old_switch)
            self._restore_loop_priority()
            gc.unfreeze()
            for sig in handlers:
                loop.remove_signal_handler(sig)
            self.stopped.set()
        return 0

    def _install_signal_handlers(self, loop) -> list:
        done = []
        for sig in (signal.SIGTERM, signal.SIGINT):
            try:
                loop.add_signal_handler(sig, self._on_signal, sig)
                done.append(sig)
            except (ValueError, RuntimeError, NotImplementedError):
                pass  # not the main thread (tests, embedding): the caller stops us
        return done

    def _on_signal(self, sig) -> None:
        log.info("%s received: shutting down", signal.Signals(sig).name)
        self._stop_evt.set()

    def _bus_name(self) -> str:
        return f"{self.bus_config.get('interface')}:{self.bus_config.get('channel')}"

    def _setup(self) -> None:
        cfg = self.cfg
        learned = self._restore_learned()
        self.pipeline = pl = Pipeline(cfg, learned, encode=cfg.can.send_outputs)
        # each receiver's port as its capture names it (ttyACM0, ttyUSB1: what replay reads back)
        self._gnss_names = [_short_port(rx.port) for rx in cfg.gnss.receivers()]
        if self.record_dir:
            from .io.recorder import Recorder
            self.recorder = Recorder(self.record_dir, can_channel=str(self.bus_config.get("channel") or "can0"),
                                     gnss_port=self._gnss_names[0], extra_gnss_ports=self._gnss_names[1:])
            pl.on_late = self._record_late
            pl.on_host = self._record_host
        # the pipeline's parser of each receiver, made here so that their counters can be watched
        self.parsers = [pl.parser(i, self._gnss_names[i], name=f"GNSS {rx.port}") for i, rx in self._gnss_receivers()]
        try:
            bus = can.Bus(**self.bus_config)
        except (can.CanError, OSError, ValueError, TypeError, ImportError) as e:
            if self.recorder:
                self.recorder.close()
            raise UserError(f"cannot open CAN bus {self._bus_name()}: {e}") from None
        self.canio = CanIO(bus, pl.decoder.frame_ids, clock=self.clock, on_frame=self._on_frame,
                           on_error_frame=self._on_error_frame, on_batch=self._on_can_batch)

    def _restore_learned(self) -> dict | None:
        path = self.cfg.daemon.state_file
        if not path:
            return None
        try:
            learned = load_state(path)
        except StateFileError as e:
            log.warning("%s; ignoring it and starting from the configured priors", e)
            return None
        if learned is not None:
            self.learned_restored = True
            log.info("restored learned state from %s", path)
        return learned

    def _raise_loop_priority(self) -> None:
        """With ``realtime_priority`` the loop thread runs SCHED_FIFO one below the tick.

        Why: the tick needs the GIL, and a normal-priority loop thread preempted by another
        process while holding it would make the real-time tick wait for a whole time slice
        (priority inversion through the GIL). Threads started afterwards (the CAN reader)
        inherit the policy.
        """
        prio = self.cfg.daemon.realtime_priority
        if prio <= 0 or not hasattr(os, "sched_setscheduler"):
            return
        try:
            self._old_sched = (os.sched_getscheduler(0), os.sched_getparam(0))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(max(1, prio - 1)))
        except OSError as e:
            self._old_sched = None
            log.warning("cannot use SCHED_FIFO for the event loop (%s); running without it", e.strerror or e)

    def _restore_loop_priority(self) -> None:
        if getattr(self, "_old_sched", None):
            try:
                os.sched_setscheduler(0, *self._old_sched)
            except OSError:
                pass
            self._old_sched = None

    def _start(self, loop) -> None:
        self._raise_loop_priority()
        # socketcan: read on the loop; else a reader thread once per step, between the step
        # boundary and the tick (grace later); see io/can_bus.py
        self.canio.start(loop, period_s=self.dt, offset_s=RX_OFFSET * self.grace_s, speed=self.speed)
        for (i, rx), parser in zip(self._gnss_receivers(), self.parsers):
            ser = GnssSerial(rx.port, rx.baudrate, on_data=lambda t, b, i=i: self._on_gnss_bytes(t, b, i),
                             clock=self.clock)
            self.serials.append(ser)
            ser.start(loop)
        self._update_diagnostics(self.clock())  # the first tick already has the host's part
        self.tick = TickThread(self.dt, self._on_tick, offset_s=self.grace_s, clock=self.clock,
                               speed=self.speed, realtime_priority=self.cfg.daemon.realtime_priority,
                               stats=self.tick_stats)
        self.tick.start()

    def _shutdown(self) -> None:
        self.notifier.stopping()
        if self.tick is not None:
            self.tick.stop()  # no more sending from here on
        if self.canio is not None:
            self.canio.stop()
            self.canio.drain()  # frames already received go into the recording too
        for ser in self.serials:
            ser.drain()  # what the receivers already delivered is not lost
            ser.close()
        if self.recorder is not None and self._last_tick is not None:
            self._out.append(("tick", TickRecord.line("end", self._last_tick)))
        self._drain_out()
        if self.recorder is not None:
            self.recorder.close()
        self._persist()
        if self.canio is not None:
            self.canio.shutdown()
        self.notifier.close()
        if self.tick is None:
            return  # failed at start-up: the error says it all
        s = self.tick_stats.snapshot()
        h = self.canio.health if self.canio else None
        log.info("stopped after %d ticks: lateness p50 %.0f us, p99 %.0f us, max %.0f us; %d overruns;"
                 " %d late samples; %d frames sent, %d suppressed, %d tx failures; %d received frames"
                 " whose handling failed",
                 s.ticks, s.late_p50_s * 1e6, s.late_p99_s * 1e6, s.late_max_total_s * 1e6, s.overruns,
                 self.late_samples, h.tx_sent if h else 0, h.tx_suppressed if h else 0,
                 h.tx_failures if h else 0, self.canio.callback_errors if self.canio else 0)

    # ----------------------------------------------------------------------------- CAN reception (reader thread or loop)
    def _on_frame(self, t: float, msg: can.Message) -> None:
        t = _to_us(t)
        if self.recorder is not None:
            self._rx_record.append((t, msg))
        self.pipeline.push_can(t, msg.arbitration_id, msg.data, msg.is_extended_id, False, self._can_seq)
        self._can_seq += 1

    def _on_error_frame(self, t: float, msg: can.Message) -> None:
        t = _to_us(t)
        if self.recorder is not None:  # BusHealth has counted it; the recording keeps it too
            self._rx_record.append((t, msg))
        self.pipeline.push_can(t, msg.arbitration_id, msg.data, msg.is_extended_id, True, self._can_seq)
        self._can_seq += 1

    def _on_can_batch(self) -> None:
        """The batch's frames to the loop's recorder, in reception order (one reader at a time:
        the reader thread or the loop, then at shutdown the loop's drain after it stopped)."""
        if self._rx_record:
            self._out.append(("can", self._rx_record))
            self._rx_record = []

    # ----------------------------------------------------------------------------- loop thread

    def _gnss_receivers(self) -> list:
        """(index in the config, receiver) of the receivers to open (a single-receiver config with
        its port "off" has none)."""
        return [(i, rx) for i, rx in enumerate(self.cfg.gnss.receivers()) if rx.port]

    def _on_gnss_bytes(self, t: float, data: bytes, receiver: int) -> None:
        t = _to_us(t)
        if self.recorder is not None:
            self.recorder.on_gnss(t, data, receiver)
        seq = self._gnss_seq.get(receiver, 0)  # line of this chunk in the receiver's capture
        self._gnss_seq[receiver] = seq + 1
        self.pipeline.push_gnss(t, data, self._gnss_names[receiver], seq, receiver)

    def _record_late(self, source: str, seq: int, k: int) -> None:
        self._out.append(("tick", TickRecord.line("late", source, seq, k)))

    def _record_host(self, k: int, status) -> None:
        self._out.append(("tick", TickRecord.line("host", k, *status)))

    async def _housekeeping(self) -> None:
        stop = self._stop_evt
        now = self.clock()
        next_diag = next_flush = now
        next_status = now + STATUS_S
        next_persist = now + self.persist_interval_s * self.speed
        persist_task = None
        while not stop.is_set():
            # half a step away from the ticks: the loop holding the GIL when the tick thread wakes
            # costs the tick up to a switch interval of lateness
            wake = between_ticks(self.clock() + HOUSEKEEPING_S * self.speed, self.dt, self.grace_s)
            try:
                await asyncio.wait_for(stop.wait(), max(0.0, (wake - self.clock()) / self.speed))
            except asyncio.TimeoutError:
                pass
            now = self.clock()
            self._drain_out()
            self._say_gaps()
            if now >= next_diag:
                next_diag = now + DIAG_S
                self._update_diagnostics(now)
            if now >= next_flush:
                next_flush = now + FLUSH_S
                if self.recorder is not None:
                    self.recorder.flush()
                self.canio.poll_library_state()
                self._check_gnss(now)
            if now >= next_status:
                next_status = now + STATUS_S
                self.notifier.status(self.diag.summary())
            if self._learned_snap is not None:
                snap, self._learned_snap = self._learned_snap, None
                if persist_task is None or persist_task.done():
                    persist_task = asyncio.get_running_loop().run_in_executor(None, self._save, snap)
            if now >= next_persist:
                next_persist = now + self.persist_interval_s * self.speed
                self._learned_req = True
        if persist_task is not None:
            await persist_task

    def _say_gaps(self) -> None:
        """One line per input gap the estimator skipped (a clock jump, a stopped process)."""
        est = self.estimator
        if est is not None and est.gaps != self._gaps_said:
            self._gaps_said = est.gaps
            log.warning("%s", health_mod.gap_line(est))

    def _drain_out(self) -> None:
        out = self._out
        rec = self.recorder
        batch = []
        while out:
            kind, payload = out.popleft()
            if kind == "est":
                batch.extend(payload)
                if rec is not None:
                    rec.on_estimates(payload)
            elif rec is None:
                continue
            elif kind == "can":
                for t, m in payload:
                    rec.on_can(t, m)
            elif kind == "tick":
                rec.on_tick_record(payload)
            else:
                for m in payload:
                    rec.on_output(m.timestamp, m)  # the time of the step the frame belongs to
        if batch:
            self.latest = batch[-1]
            if self.estimate_sink is not None:
                self.estimate_sink(batch)

    def _update_diagnostics(self, now: float) -> None:
        """The host's part of EST_DIAG, for the pipeline's next tick (the rest is built there)."""
        self.pipeline.push_host(health_mod.host_status(
            bus=self.canio.health, tick=self.tick_stats.snapshot(), cpu_pct=self.cpu.update(),
            gnss_connected=bool(self.serials) and all(ser.connected for ser in self.serials)))

    def _check_gnss(self, now: float) -> None:
        """One line when a connected receiver goes silent (no solution for ``timeout_s``), one when
        it speaks again; each receiver on its own."""
        timeout = self.cfg.gnss.timeout_s
        started = self.tick_stats.ticks * self.dt > timeout
        for (i, _), ser in zip(self._gnss_receivers(), self.serials):
            if not ser.connected:
                continue
            last = self.pipeline.gnss_rx_t.get(i)
            silent = (last is None or now - last > timeout) and started
            if silent and i not in self._gnss_silent:
                log.warning("GNSS: no solution from %s for more than %.1f s", ser.port, timeout)
                self._gnss_silent.add(i)
            elif not silent and i in self._gnss_silent:
                log.info("GNSS: receiving solutions from %s again", ser.port)
                self._gnss_silent.discard(i)

    def _save(self, learned: dict) -> None:
        path = self.cfg.daemon.state_file
        if not path or not learned:
            return
        try:
            save_state(path, learned, saved_at=time.time())
        except (OSError, TypeError, ValueError) as e:
            log.error("cannot save learned state to %s: %s", path, getattr(e, "strerror", None) or e)

    def _persist(self) -> None:
        if self.estimator is None or (self.tick is not None and self.tick.is_alive()):
            return
        self._save(self.estimator.learned_state())

    # ----------------------------------------------------------------------------- tick thread
    def _on_tick(self, k: int, now: float) -> None:
        steps = self.pipeline.tick(k)
        last, self._last_tick = self._last_tick, k
        if self.recorder is not None:
            if last is None:
                self._out.append(("tick", TickRecord.line("start", k)))
            elif k > last + 1:  # an overrun: steps last+1..k-1 ran in this tick, unsent
                self._out.append(("tick", TickRecord.line("skip", last + 1, k - 1)))
        if self._learned_req:
            self._learned_req = False
            self._learned_snap = self.pipeline.estimator.learned_state()
        if self._wd_interval:
            rt = time.monotonic()
            if rt >= self._wd_next:
                self._wd_next = rt + self._wd_interval
                self.notifier.watchdog()
        self.steps += len(steps)
        self._out.append(("est", [s.estimate for s in steps]))
        # Catching up after an overrun: only the newest step has frames (no burst; each
        # message's COUNTER still steps by one per frame encoded); the slots missed stay empty.
        frames = steps[-1].frames
        if not frames:
            return
        sent = []
        send = self.canio.send
        for m in frames:
            if send(m):
                sent.append(m)
        if sent:
            self.frames_sent += len(sent)
            if self.recorder is not None:
                self._out.append(("out", sent))


# Modules the pipeline's code imports on first use, in the middle of a drive: loaded before the
# first tick instead of in it (numpy.ma, which np.median's NaN check pulls in at the first GNSS
# latency fit: 20-80 ms in the tick thread, a burst of overruns).
LAZY_MODULES = ("numpy.ma",)


def _preload() -> None:
    for name in LAZY_MODULES:
        importlib.import_module(name)


def between_ticks(t: float, period: float, offset: float) -> float:
    """The first time >= ``t`` half-way between two ticks (ticks at ``k * period + offset``)."""
    mid = offset + 0.5 * period
    return (math.ceil((t - mid) / period) * period) + mid


def _short_port(port: str) -> str:
    """A serial port's name in a GNSS capture: /dev/ttyACM0 -> ttyACM0, /dev/serial/by-id/x/0 -> x0."""
    p = Path(port or "gnss")
    return p.parent.name + p.name if p.name.isdigit() else p.name


def _to_us(t: float) -> float:
    """A receive time as the recording writes it (%.6f) and replay reads it back, to the bit."""
    return float("%.6f" % t)


def _running_loop():
    try:
        return asyncio.get_running_loop()
    except RuntimeError:
        return None


# --------------------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from can.cli import add_bus_arguments

    parser.add_argument("--config", "-C", help="TOML configuration file (default: built-in defaults)")
    add_bus_arguments(parser, group_title="CAN bus (overrides [can] and python-can's own configuration)")
    parser.add_argument("--gnss-port", metavar="PORT", help="GNSS serial port (overrides [gnss] port;"
                        " 'none' disables GNSS)")
    parser.add_argument("--record", metavar="DIR", help="record the received CAN frames and GNSS messages"
                        " (replayable), the estimates and the sent frames into DIR")
    parser.add_argument("--state-file", metavar="FILE", help="learned-state file (overrides [daemon] state_file;"
                        " 'none' disables persistence)")
    parser.add_argument("--no-send", action="store_true", help="listen only: do not transmit estimates")
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    parser.add_argument("--log-level", choices=("debug", "info", "warning", "error"),
                        help="overrides [daemon] log_level")


def explicit_can_keys(config_path: str | None) -> set[str]:
    """The keys the user actually wrote in ``[can]`` (they beat python-can's own configuration)."""
    if not config_path:
        return set()
    try:
        with open(config_path, "rb") as f:
            can_table = tomllib.load(f).get("can", {})
    except (OSError, tomllib.TOMLDecodeError):
        return set()
    return set(can_table) if isinstance(can_table, dict) else set()


def apply_overrides(cfg: Config, args: argparse.Namespace) -> None:
    if getattr(args, "gnss_port", None):
        cfg.gnss.port = config_mod.off_if_none(args.gnss_port)
        if cfg.gnss.receiver:  # the first receiver's port
            cfg.gnss.receiver[0].port = cfg.gnss.port
    if getattr(args, "state_file", None):
        cfg.daemon.state_file = config_mod.off_if_none(args.state_file)
    if getattr(args, "no_send", False):
        cfg.can.send_outputs = False
    if getattr(args, "log_level", None):
        cfg.daemon.log_level = args.log_level
    if getattr(args, "duration", None) is not None and not args.duration > 0:
        raise ConfigError("--duration must be a positive number of seconds")


def bus_overrides(args: argparse.Namespace) -> dict:
    out = {}
    for key in ("interface", "channel", "bitrate", "fd", "data_bitrate", "timing"):
        if key in args:
            out[key] = getattr(args, key)
    if "bus_kwargs" in args:
        out.update(args.bus_kwargs)
    return out


def main(args: argparse.Namespace) -> int:
    cfg = config_mod.load(args.config)
    apply_overrides(cfg, args)
    setup_logging(cfg.daemon.log_level)
    bus_config = resolve_bus_config(cfg.can, explicit_can_keys(args.config), bus_overrides(args))
    log.info("CAN bus: %s", ", ".join(f"{k}={v}" for k, v in sorted(bus_config.items())))
    daemon = Daemon(cfg, bus_config=bus_config, record_dir=args.record)
    return asyncio.run(daemon.run(duration=args.duration))
