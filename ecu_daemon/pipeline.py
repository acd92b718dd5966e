"""One pipeline for live, replay and demo: raw inputs in, per step the published estimate and the
output frames out.

Why one: the step rule, the validity policy and the output encoding used to be written once per
shell (daemon, replay, demo), with different epsilons and in different orders (the recording held
estimates before the daemon's stale mask). Here they are decided once:

* **inbox** -- CAN frames, GNSS byte chunks and (live only) the host's health are pushed from any
  thread (``push_*`` append to a deque). Each CAN frame / GNSS chunk carries its ordinal in its
  log (``seq``), which is how a recording names it; the chunks of GNSS receiver ``i`` of the
  config (``[[gnss.receiver]]``) are their own log (:func:`gnss_source`: ``gnss``, ``gnss2``, ...),
  parsed by a parser of their own with that receiver's protocol.
* **step rule** (``step_grid``) -- an item belongs to step ``step_of(t)``. Live, the shell calls
  :meth:`tick` for the newest step due; everything received and due by then is decoded and handed
  to the estimator, sorted by (time, CAN before GNSS, seq). An item that arrives after its step ran
  is applied at the next step run and reported to ``on_late`` (the recording keeps it), never
  dropped: a GNSS sample is fused at its time of validity through the estimator's history, at the
  same step as if it had come in time; a CAN input enters the held inputs with its own receive
  time, but the step already run used the value before it (the history rewinds GNSS corrections,
  not the prediction's inputs), so a late CAN input is one step of zero-order hold late;
  :class:`TickRecord` makes a replay of the recording hand every item over at the same tick.
  Offline without such a record, :meth:`feed` hands each item over at its own step (and the
  estimator skips input gaps).
* **validity** -- the estimator's flags AND the decoder's input staleness (checked every
  ``DIAG_S`` of step time, with the diagnostics); a step with no estimate yet publishes the
  estimator's finite, all-invalid :meth:`~ecu_daemon.estimator.Estimator.no_estimate`.
* **outputs** -- every frame of the output DBC (``EST_DIAG`` from diagnostics built here on the
  step grid), counters and CRCs, by :class:`~ecu_daemon.outputs.OutputEncoder`.

The pipeline is deterministic in its inputs and the ticks: what the live daemon records
(inputs, tick record, output frames) replays to the same frames, byte for byte.
"""
from __future__ import annotations

import gc
import math
from collections import deque
from contextlib import contextmanager
from typing import Callable, NamedTuple

from .config import Config
from .diagnostics import Diagnostics, HostStatus
from .estimator import Estimate, Estimator
from .estimator import source_status
from .estimator.estimate import STATUS_INPUT_STALE
from .gnss.stream import GnssStreamParser, sum_stats
from .io.health import build_diagnostics
from .samples import INPUT_INDEX, GnssSample, InputSample
from .signals import SignalDecoder
from .step_grid import step_of, steps_of

_new_tuple = tuple.__new__
MAG_INDEX = INPUT_INDEX["mag_x"]
ROLL_INDEX = INPUT_INDEX["roll_rate"]
DIAG_S = 0.05  # diagnostics (and the input staleness behind the validity mask) every 50 ms of steps

CAN = "can"
GNSS = "gnss"


def gnss_source(receiver: int) -> str:
    """The log name of GNSS receiver number ``receiver`` (0-based): ``gnss``, ``gnss2``, ... -- its
    recording file (``gnss2.log``) and its items' ``source`` in the tick record."""
    return GNSS if receiver == 0 else f"{GNSS}{receiver + 1}"


class Step(NamedTuple):
    k: int
    estimate: Estimate  # as published (validity policy applied)
    frames: list  # can.Message (batch pipeline: (frame id, payload)), empty when this step is not sent


class Item(NamedTuple):
    t: float
    order: int
    seq: int
    source: str
    payload: object  # CAN: (id, data, extended, error frame); GNSS: (receiver, port, bytes); test: InputSample


class TickRecord:
    """How a live run handed its inputs to the estimator, as far as the time rule does not say it:
    the first and last tick, the inputs applied after their step (late), the steps run without a
    tick of their own (overrun catch-up, not sent) and the host status each tick saw.

    Text, one record per line (``ticks.log`` of a recording)::

        start K | end K | late can|gnss|gnss2... SEQ K | skip K1 K2 | host K v1 ... v9
    """

    def __init__(self) -> None:
        self.start: int | None = None
        self.end: int | None = None
        self.late: dict[tuple[str, int], int] = {}
        self.skipped: list[tuple[int, int]] = []
        self.host: dict[int, HostStatus] = {}

    @staticmethod
    def line(kind: str, *fields) -> str:
        return " ".join([kind, *(repr(f) if isinstance(f, float) else str(f) for f in fields)]) + "\n"

    @classmethod
    def read(cls, path) -> "TickRecord":
        rec = cls()
        with open(path, encoding="ascii") as f:
            for lineno, line in enumerate(f, 1):
                w = line.split()
                if not w or w[0].startswith("#"):
                    continue
                try:
                    if w[0] == "start":
                        rec.start = int(w[1])
                    elif w[0] == "end":
                        rec.end = int(w[1])
                    elif w[0] == "late":
                        rec.late[(w[1], int(w[2]))] = int(w[3])
                    elif w[0] == "skip":
                        rec.skipped.append((int(w[1]), int(w[2])))
                    elif w[0] == "host":
                        v = w[2:]
                        rec.host[int(w[1])] = HostStatus(v[0] == "True", int(v[1]), int(v[2]), int(v[3]),
                                                         float(v[4]), float(v[5]), float(v[6]), int(v[7]),
                                                         float(v[8]))
                    else:
                        raise ValueError(f"unknown record {w[0]!r}")
                except (ValueError, IndexError) as e:
                    raise ValueError(f"{path}:{lineno}: not a tick record: {e}") from None
        if rec.start is None:
            raise ValueError(f"{path}: no 'start' record")
        return rec

    def ticks(self):
        """The live ticks, from the first to the recorded end (open-ended without one)."""
        skipped = sorted(self.skipped)
        i = 0
        k = self.start
        while self.end is None or k <= self.end:
            while i < len(skipped) and skipped[i][1] < k:
                i += 1
            if i < len(skipped) and skipped[i][0] <= k:
                k = skipped[i][1] + 1
                continue
            yield k
            k += 1


class Pipeline:
    """See the module docstring. ``encode``: build output frames (replay without ``--out-can``
    does not need them); ``gnss_connected``: the offline stand-in for the serial port's state;
    ``record``: a :class:`TickRecord` to follow (replay of a recording); ``batch``: whole logs
    through :meth:`feed_log` (offline, time rule) instead of item by item, and the steps' frames
    as ``(frame id, payload)`` pairs (:meth:`OutputEncoder.payloads`) for a log writer."""

    def __init__(self, cfg: Config, learned: dict | None = None, *, encode: bool = True,
                 gnss_connected: bool = False, record: TickRecord | None = None, batch: bool = False) -> None:
        self.cfg = cfg
        self._baseline_configured = source_status.baseline_configured(cfg)
        self.dt = dt = cfg.estimator.dt_s
        if batch:
            from .batch_decoder import BatchDecoder

            self.decoder = BatchDecoder(cfg)
        else:
            self.decoder = SignalDecoder(cfg)
        self.estimator = Estimator(cfg, learned)
        self.encoder = None
        if encode:
            from .outputs import OutputEncoder

            self.encoder = OutputEncoder(cfg)
            self._encode = self.encoder.payloads if batch else self.encoder.frames
        self.parsers: dict[tuple[int, str], GnssStreamParser] = {}  # (receiver, port) -> its parser
        self.gnss_rx_t: dict[int, float] = {}  # receiver -> receive time of its last sample (any kind)
        self.gnss_connected = gnss_connected
        self.record = record
        self.inbox: deque = deque()  # push_* (any thread) -> the stepping thread
        self._held: list[Item] = []  # received, due at a later step
        self._host_in: HostStatus | None = None
        self.host: HostStatus | None = None
        self.diag: Diagnostics | None = None
        self.stale_mask: dict = {}
        self.gnss_last = None
        self.error_frames = 0
        self.gnss_samples = 0  # GNSS samples (velocity and heading) handed to the estimator
        self.last_k: int | None = None  # last step run
        self.late_items = 0
        self.earliest_late_t = math.inf
        self.items = 0
        self._seq: dict[str, int] = {}
        self._diag_every = max(1, round(DIAG_S / dt))
        self.on_late: Callable[[str, int, int], None] | None = None  # (source, seq, step applied)
        self.on_host: Callable[[int, HostStatus], None] | None = None  # (step, status)
        self.on_sample: Callable[[object], None] | None = None  # every decoded sample (replay's plots)

    # ------------------------------------------------------------------------------- inputs
    def push_can(self, t: float, arbitration_id: int, data: bytes, extended: bool = False,
                 error_frame: bool = False, seq: int | None = None) -> None:
        self.inbox.append(Item(t, 0, self._next_seq(CAN, seq), CAN, (arbitration_id, data, extended, error_frame)))

    def push_gnss(self, t: float, data: bytes, port: str = "", seq: int | None = None, receiver: int = 0) -> None:
        """A chunk of bytes from GNSS receiver number ``receiver`` (its ``port``: a capture may hold several)."""
        source = gnss_source(receiver)
        self.inbox.append(Item(t, 1, self._next_seq(source, seq), source, (receiver, port, data)))

    def parser(self, receiver: int, port: str = "", name: str | None = None) -> GnssStreamParser:
        """The parser of one receiver's port, made on first use with the receiver's protocol (the
        daemon makes its own up front, to watch their counters); ``name`` in its log lines."""
        p = self.parsers.get((receiver, port))
        if p is None:
            rxs = self.cfg.gnss.receivers()
            protocol = rxs[receiver].protocol if receiver < len(rxs) else self.cfg.gnss.protocol
            if name is None:
                name = f"gnss {port}" if receiver == 0 else f"gnss {port} #{receiver + 1}"
            p = self.parsers[(receiver, port)] = GnssStreamParser(protocol, name=name, source=receiver)
        return p

    def push_sample(self, s: InputSample) -> None:
        """An already decoded input (tests, tools): as a CAN frame carrying it."""
        self.inbox.append(Item(s.t, 0, self._next_seq("sample", None), "sample", s))

    def push_host(self, status: HostStatus) -> None:
        """Live: the host's health, taken into the diagnostics at the next tick."""
        self._host_in = status

    def _next_seq(self, source: str, seq: int | None) -> int:
        if seq is None:
            seq = self._seq.get(source, 0)
        self._seq[source] = seq + 1
        return seq

    # ------------------------------------------------------------------------------- stepping
    def tick(self, k: int) -> list[Step]:
        """Live (and replay of a recording): hand over what is due by step k, run the steps up to
        k; only step k gets frames (a catch-up after an overrun sends the newest step only)."""
        if self.record is not None:
            host = self.record.host.get(k)
        else:
            host = self._host_in
            if host is not None and host is not self.host and self.on_host is not None:
                self.on_host(k, host)
        if host is not None:
            self.host = host
        est = self.estimator
        self._drain()
        if self._held:
            held = self._held
            held.sort()
            last = self.last_k
            keep = []
            for it in held:
                due = self._due(it)
                if due > k:
                    keep.append(it)
                    continue
                if last is not None and due <= last and self.record is None:
                    self._late(it, last + 1)
                self._take(it)
            self._held = keep
        ests = est.advance_to(k * self.dt)
        self.last_k = k
        steps = [self._publish(e, False) for e in ests[:-1]]
        if ests:
            steps.append(self._publish(ests[-1], True))
        else:
            steps.append(self._publish(est.no_estimate(k * self.dt), True))
        return steps

    def feed(self, t: float) -> list[Step]:
        """Offline, time rule: hand over what was pushed (stamped ``t``), then run and encode every
        step before ``t`` (the estimator sees the next sample, so it skips a gap up to it)."""
        self._drain()
        for it in sorted(self._held):
            self._take(it)
        self._held.clear()
        est = self.estimator
        k_before = step_of(t, self.dt) - 1
        if est.k is not None and k_before < est.k:
            return []
        return [self._publish(e, True) for e in est.advance_to(k_before * self.dt)]

    def feed_log(self, can, gnss, emit: Callable[[list[Step]], None], progress=None) -> None:
        """Offline, time rule, whole logs at once: exactly what ``push_can`` / ``push_gnss`` and
        :meth:`feed` do item by item, in the order ``heapq.merge`` gives by (time, CAN before
        GNSS) -- the same steps, the same diagnostics -- without the per-item machinery.

        ``can``: a :class:`~ecu_daemon.can_arrays.CanArrays` of finite times; ``gnss``: the GNSS
        items ``(t, receiver, port, bytes, seq)`` in their merged order; ``emit``: called with
        the steps each hand-over ran. The decoder must be a
        :class:`~ecu_daemon.batch_decoder.BatchDecoder` (``Pipeline(..., batch=True)``): the
        frames are decoded before the first step, and its counters follow the hand-over
        (:attr:`BatchDecoder.cursor`), so EST_DIAG says at each step what it says item by item.
        """
        with _long_lived_heap():
            self._feed_log(can, gnss, emit, progress)

    def _feed_log(self, can, gnss, emit, progress) -> None:
        from .batch_decoder import DIRTY

        dec = self.decoder
        est = self.estimator
        dt = self.dt
        t_all = can.t
        collecting = gc.isenabled()
        gc.disable()  # see _long_lived_heap: a few objects per frame, all kept, none cyclic
        try:
            samples = dec.prepare(t_all, can.keys(), can.data)
        finally:
            if collecting:
                gc.enable()
        if gc.get_freeze_count() == 0:
            gc.freeze()  # the samples (and everything before them) out of the collector's scans
        before = (steps_of(t_all, dt) - 1).tolist()  # the last step before each frame
        times = t_all.tolist()
        fids = can.fid.tolist()
        exts = can.ext.tolist()
        errs = can.err.tolist()
        data = can.data
        push = est.queue.extend
        publish = self._publish
        on_sample = self.on_sample
        n = len(times)
        gnss = list(gnss)
        gi = 0
        tg = gnss[0][0] if gnss else math.inf

        def advance(k_before: int) -> None:  # what feed() runs after a hand-over
            ek = est.k
            if ek is None or k_before >= ek:
                emit([publish(e, True) for e in est.advance_to(k_before * dt)])

        def take_gnss(t, receiver, port, payload, seq) -> None:
            self._take(Item(t, 1, seq, gnss_source(receiver), (receiver, port, payload)))
            advance(step_of(t, dt) - 1)

        inf = math.inf
        # advance() runs steps only from est.k on (any step before an initialised estimator):
        # the frames of a step after its first one need no call (the decoder's cursor, which
        # only the steps' diagnostics read, is set when one runs)
        next_k = -inf if est.k is None else est.k
        for j in range(n):
            t = times[j]
            while tg < t:  # GNSS items stamped before this frame (CAN first at equal times)
                dec.cursor = j
                take_gnss(*gnss[gi])
                gi += 1
                tg = gnss[gi][0] if gi < len(gnss) else inf
                next_k = -inf if est.k is None else est.k
            s = samples[j]
            if s is not None:
                if s is DIRTY:
                    s = dec.take(j, t, fids[j], data[j], exts[j])
                push(s)
                if on_sample is not None:
                    for x in s:
                        on_sample(x)
            elif errs[j]:
                self.error_frames += 1
            b = before[j]
            if b >= next_k:
                dec.cursor = j + 1
                advance(b)
                next_k = -inf if est.k is None else est.k
            if progress is not None and not j & 1023:
                progress(j, t)
        dec.cursor = n
        for item in gnss[gi:]:
            take_gnss(*item)
        self.items += n + len(gnss)

    def finish(self, t: float) -> list[Step]:
        """Offline: the parsers' last samples, then every step up to ``t``."""
        for p in self.parsers.values():
            for s in p.finish():
                self._gnss_sample(s)
        return [self._publish(e, True) for e in self.estimator.advance_to(t)]

    def _drain(self) -> None:
        pop = self.inbox.popleft
        held = self._held
        try:
            while True:
                held.append(pop())
        except IndexError:
            pass

    def _due(self, it: Item) -> int:
        if self.record is not None:
            k = self.record.late.get((it.source, it.seq))
            if k is not None:
                return k
        return step_of(it.t, self.dt)

    def _late(self, it: Item, k: int) -> None:
        self.late_items += 1
        self.earliest_late_t = min(self.earliest_late_t, it.t)
        if self.on_late is not None and it.source != "sample":
            self.on_late(it.source, it.seq, k)

    def _take(self, it: Item) -> None:
        """Decode one item into the estimator's queue."""
        self.items += 1
        est = self.estimator
        if it.source == CAN:
            fid, data, ext, err = it.payload
            if err:
                self.error_frames += 1
                return
            for s in self.decoder.decode(it.t, fid, data, ext):
                est.push_input(s)
                if self.on_sample is not None:
                    self.on_sample(s)
        elif it.source == "sample":
            est.push_input(it.payload)
        else:
            receiver, port, data = it.payload
            for s in self.parser(receiver, port).feed(it.t, data):
                self._gnss_sample(s)

    def _gnss_sample(self, s) -> None:
        self.gnss_samples += 1
        self.gnss_rx_t[s.source] = s.t
        if type(s) is GnssSample:  # the velocity solution: what the diagnostics describe
            self.gnss_last = s
        self.estimator.push_gnss(s)
        if self.on_sample is not None:
            self.on_sample(s)

    # ------------------------------------------------------------------------------- outputs
    def _publish(self, e: Estimate, send: bool) -> Step:
        k = round(e.t / self.dt)
        if self.diag is None or k % self._diag_every == 0:
            self._update_diagnostics(e)
        mask = self.stale_mask
        if mask:
            e = e._replace(status=e.status | STATUS_INPUT_STALE, **mask)
        frames = self._encode(k, e, self.diag) if send and self.encoder is not None else []
        return _new_tuple(Step, (k, e, frames))  # = Step(k, e, frames) without its Python-level __new__

    def _update_diagnostics(self, e: Estimate) -> None:
        t = e.t
        self.stale_mask = stale_validity_mask(self.decoder.check_stale(t))
        self.diag = build_diagnostics(
            t, decoder=self.decoder, gnss_stats=self.gnss_stats(), gnss_last=self.gnss_last,
            gnss_delay_s=e.gnss_delay_s, host=self.host, gnss_connected=self.gnss_connected,
            error_frames=self.error_frames, status=e.status, isolation_events=dict(self.estimator.fdi.events),
            gnss_heading=self.estimator.heading, gnss_timeout_s=self.cfg.gnss.timeout_s,
            mag=self.estimator.mag, mag_timeout_s=self.estimator.timeouts[MAG_INDEX],
            road=self.estimator.road, roll_rate_t=self.estimator.held_t[ROLL_INDEX],
            roll_rate_timeout_s=self.estimator.timeouts[ROLL_INDEX], baseline_configured=self._baseline_configured)

    def gnss_stats(self) -> dict:
        """GNSS parser counters summed over every receiver's ports."""
        return sum_stats(self.parsers)


@contextmanager
def _long_lived_heap():
    """Keep Python's cyclic garbage collector off the whole log's decoded samples.

    Why: :meth:`Pipeline.feed_log` makes every sample of the log before the first step (~80,000
    tuples on a 100 s drive), all alive until their step. Each young-generation collection that
    finds them surviving counts towards a full one, and a full collection walks the whole heap
    (these samples, the DBCs, numpy, every module): allocating them with the collector on cost
    ~3x the allocation itself (82 ms instead of 24 ms, ~3.5 us of every 6 ms step). So they are
    made with the collector off (tuples of floats and ints: no cycles to find), then frozen
    (``gc.freeze``, as the daemon does after start-up) for the step loop, whose collections
    then scan only what the steps allocate; unfrozen at the end, so a fleet worker's next drive
    starts from the same heap. Garbage collection decides no output: the bytes are the same.
    A heap frozen by someone else (``gc.get_freeze_count()``) is left as it is.
    """
    frozen = gc.get_freeze_count()
    try:
        yield
    finally:
        if frozen == 0:
            gc.unfreeze()


_IMU = ("yaw_rate", "accel_x", "accel_y")
_WHEELS = ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr")
_ALL_INVALID = {"sideslip_valid": False, "heading_valid": False, "velocity_valid": False, "biases_valid": False}


def stale_validity_mask(stale: list[str]) -> dict:
    """Validity flags to clear on the published estimate while these inputs are stale.

    The decoder declares an input stale after 10 missed cycles of its observed rate (or its
    ``timeout_s``). IMU -> everything; a wheel speed -> velocity and sideslip; steering ->
    sideslip (the single-track model needs it). The estimator's own flags still apply on top.
    """
    if not stale:
        return {}
    s = set(stale)
    if s.intersection(_IMU):
        return dict(_ALL_INVALID)
    mask = {}
    if s.intersection(_WHEELS):
        mask.update(velocity_valid=False, sideslip_valid=False)
    if "steering_wheel_angle" in s:
        mask["sideslip_valid"] = False
    return mask
