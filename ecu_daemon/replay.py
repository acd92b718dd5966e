"""Offline replay: CAN log (+ GNSS capture) -> the same estimator core -> CSV and/or CAN log.

The contract outside tools rely on::

    ecu-daemon replay --config CFG.toml --can INPUT.log [--gnss GNSS.log [--gnss GNSS2.log ...]]
                      [--out-can OUTPUT.log] [--out-csv OUTPUT.csv]

No second path: frames and GNSS bytes go through the live daemon's :class:`~ecu_daemon.pipeline.Pipeline`
(decoder, GNSS parser, estimator, validity, output encoder). The step grid is absolute (k * dt).
A foreign log is stepped by the time rule: items in timestamp order, each step run once every
item stamped at or before it has been handed over. A daemon recording (``ticks.log`` beside the
CAN log, or ``--ticks``) is stepped tick by tick as the daemon did, and writes the frames it sent.
A re-run gives byte-identical files.
"""
from __future__ import annotations

import argparse
import heapq
import logging
import math
import sys
import time
from pathlib import Path

import numpy as np

from . import config as config_mod
from .can_arrays import read_can_arrays
from .canlog import CanLogError, open_can_writer, read_can_log
from .errors import UnusableInputError, UserError
from .estimate_csv import csv_header, format_rows
from .estimator import Estimator
from .gnss.logfile import GnssLogError, read_gnss_log
from .io.health import gap_line
from .io.logging_setup import RateLimitedLog
from .io.output_file import OutputFile, OutputPathError, check_output_paths
from .pipeline import CAN, Pipeline, TickRecord, gnss_source
from .replay_input import check_time_base, choose_channel, output_channel, report_other_channels
from .samples import INPUT_NAMES, GnssHeadingSample, InputSample
from .signals import SignalDecoder
from .step_grid import last_step_at, step_of
from .time_order import TimeOrder, TimeOrderError

log = logging.getLogger("ecu_daemon.replay")
#: inputs without which the estimator publishes nothing valid; a replay that never had one fails
REQUIRED_INPUTS = ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr",
                   "yaw_rate", "accel_x", "accel_y")
#: a required CAN input is usable when at least this share of its frames gave a sample: a wrong
#: checksum scheme still passes 1 frame in 256, a counter mapped onto a value signal a quarter of
#: them; more than half dropped is a mapping to fix (or a bus not to trust), not an input
MIN_USED_FRACTION = 0.5
#: the same for GNSS, whose frames also count the sentences and messages that carry no velocity
MIN_USED_FRACTION_GNSS = 0.1
#: steps written to the outputs at a time (about 1.5 s of drive)
WRITE_BATCH = 256

def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", "-C", help="TOML configuration (default: built-in defaults)")
    p.add_argument("--can", required=True, help="input CAN log: candump -L (.log), ASC or BLF")
    p.add_argument("--gnss", action="append", metavar="GNSS.log",
                   help="GNSS capture log: '(seconds.micros) PORT PAYLOAD' per line; once per receiver, in the"
                        " order of the config's [[gnss.receiver]] tables")
    p.add_argument("--can-channel", metavar="NAME", help="replay only the frames of this log channel"
                   " (canplayer's IF=NAME works too); needed for a log of several channels")
    p.add_argument("--can-time-offset", type=float, metavar="SECONDS", help="add SECONDS to every CAN log time"
                   " to line it up with the GNSS capture (an ASC/BLF without a start date counts from 0)")
    p.add_argument("--out-can", help="write the output CAN frames: candump -L (.log), or the format python-can"
                   " writes for the extension (.asc, .blf, ...)")
    p.add_argument("--out-csv", help="write one row per 6 ms estimator step")
    p.add_argument("--plots", metavar="DIR", help="write PNG plots of the drive into DIR (estimates, validity, "
                   "inputs; also DIR/out.csv when --out-csv is not given); needs matplotlib")
    p.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    p.add_argument("--ticks", metavar="FILE", help="tick record of a daemon recording (default: ticks.log"
                   " beside the CAN log, when there is one); 'none' replays by the time rule")
    p.add_argument("--state", metavar="FILE",
                   help="learned-state file, as the daemon's [daemon] state_file: restored at the start"
                        " when it exists, written at the end (a restart mid-drive is two replays)")


def _gnss_items(path: str, order: TimeOrder, receiver: int = 0):
    """Pipeline items for every line of the GNSS capture of receiver number ``receiver`` (``seq``:
    its entry in the log)."""
    source = gnss_source(receiver)
    for t, port, payload, seq in order((t, port, payload, seq)
                                       for seq, (t, port, payload) in enumerate(read_gnss_log(path))):
        yield t, 1, seq, source, (receiver, port, payload)


def _can_items(path: str, counters: dict, order: TimeOrder, channel: str | None, time_offset: float):
    """Pipeline items for every frame of a CAN log (``seq``: its entry in the log, as a recording's
    tick record names it)."""
    reader = read_can_log(path, channel=channel, time_offset=time_offset)
    counters["channels"] = reader.channels  # frames per log channel, replayed or not
    for t, fid, ext, err, data, seq in order((*f, seq) for seq, f in enumerate(reader)):
        counters["frames"] += 1
        if err:
            counters["error_frames"] += 1
        yield t, 0, seq, CAN, (fid, data, ext, err)


def _feed_logs(pl: Pipeline, can_path: str, channel: str | None, time_offset: float, order: TimeOrder,
               gnss_merged, counters: dict, emit, bar: "_Progress") -> tuple[float | None, float | None]:
    """The CAN log as arrays and the merged GNSS items through :meth:`Pipeline.feed_log`; returns
    the first and last item time (None without items)."""
    can = read_can_arrays(can_path, order, channel, time_offset)
    counters["channels"] = can.channels
    counters["frames"] += len(can)
    counters["error_frames"] += int(can.err.sum())
    can = can.finite()
    gnss = [(t, payload[0], payload[1], payload[2], seq) for t, _, seq, _, payload in gnss_merged
            if math.isfinite(t)]
    times = [float(can.t[0]), float(can.t[-1])] if len(can) else []
    times += [gnss[0][0], gnss[-1][0]] if gnss else []
    t0 = min(times) if times else None
    progress = (lambda j, t: bar.update(j, t - t0)) if bar.enabled else None
    pl.feed_log(can, gnss, emit, progress)
    return t0, (max(times) if times else None)


def _count_lines(path: str) -> int:
    try:
        with open(path, "rb") as f:
            return sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 20), b""))
    except OSError:
        return 0


class _Progress:
    """A one-line progress bar on stderr, only on a terminal, at most every 0.2 s."""

    def __init__(self, total: int, enabled: bool):
        self.total = max(total, 1)
        self.enabled = enabled and sys.stderr.isatty()
        self.last = 0.0
        self.start = time.monotonic()

    def update(self, done: int, sim_s: float) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self.last < 0.2:
            return
        self.last = now
        frac = min(done / self.total, 1.0)
        bar = "#" * int(30 * frac)
        el = now - self.start
        rate = sim_s / el if el > 0 else 0.0
        sys.stderr.write(f"\rreplay [{bar:<30}] {100 * frac:5.1f}%  {sim_s:7.1f} s of drive  x{rate:.0f} real time")
        sys.stderr.flush()

    def done(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")


def default_ticks(can_path: str) -> str | None:
    """The tick record of a daemon recording: ``ticks.log`` beside its ``can.log``."""
    p = Path(can_path).with_name("ticks.log")
    return str(p) if p.is_file() else None


def run_replay(cfg: config_mod.Config, can_path: str, gnss_path: str | list[str] | None = None,
               out_csv: str | None = None, out_can: str | None = None, progress: bool = False,
               config_path: str | None = None, inputs: dict | None = None, can_channel: str | None = None,
               can_time_offset: float | None = None, learned: dict | None = None,
               ticks_path: str | None = None) -> dict:
    """Replay one drive, starting from ``learned`` (see :class:`Estimator`); returns a summary
    (counts, duration, speed, per-input table, the final learned state).

    Raises UserError on bad files (nothing is opened for writing before the paths are checked;
    outputs are written aside and renamed at the end, a failure keeps them as ``*.partial.*``) and
    :class:`~ecu_daemon.errors.UnusableInputError` when a required input never gave a usable sample.
    ``inputs``: when a dict, receives every decoded input as ``{name: ([t], [SI value])}``, the
    GNSS speed as ``"gnss_speed"`` and a dual-antenna heading as ``"gnss_heading"`` (for plots). ``can_channel``/``can_time_offset``: see
    :mod:`ecu_daemon.replay_input`. ``gnss_path``: one capture, or one per receiver of the config
    (``[[gnss.receiver]]``, in order). ``ticks_path``: a daemon recording's tick record (see
    :class:`~ecu_daemon.pipeline.TickRecord`); None: the time rule.
    """
    gnss_paths = [gnss_path] if isinstance(gnss_path, (str, Path)) else list(gnss_path or [])
    n_rx = len(cfg.gnss.receivers())
    if len(gnss_paths) > n_rx:
        raise UserError(f"{len(gnss_paths)} GNSS captures given but the config has {n_rx} receiver"
                        f"{'s' if n_rx > 1 else ''}: one --gnss per [[gnss.receiver]], in order")
    for p, what in [(can_path, "CAN log"), *((g, "GNSS log") for g in gnss_paths), (ticks_path, "tick record")]:
        if p is not None and not Path(p).is_file():
            raise UserError(f"cannot read {what} {p}: no such file")
    try:
        check_output_paths({"--out-csv": out_csv, "--out-can": out_can},
                           {"--can": can_path, "--config": config_path,
                            **{"--gnss" + (f" #{i + 1}" if i else ""): g for i, g in enumerate(gnss_paths)}})
    except OutputPathError as e:
        raise UserError(str(e)) from None
    channel = choose_channel(can_path, can_channel, cfg.can.channel)
    for g in gnss_paths:
        check_time_base(can_path, g, channel, can_time_offset)
    record = None
    if ticks_path is not None:
        try:
            record = TickRecord.read(ticks_path)
        except (OSError, ValueError) as e:
            raise UserError(f"cannot read tick record {ticks_path}: {getattr(e, 'strerror', None) or e}") from None
        log.info("following the tick record %s (a daemon recording: the steps and frames it sent)", ticks_path)
    pl = Pipeline(cfg, learned, encode=out_can is not None, gnss_connected=bool(gnss_paths), record=record,
                  batch=record is None)
    est = pl.estimator
    counters = {"frames": 0, "error_frames": 0, "gnss_samples": 0, "steps": 0}

    def on_sample(s):
        kind = type(s)
        name = (INPUT_NAMES[s.index] if kind is InputSample
                else "gnss_heading" if kind is GnssHeadingSample else "gnss_speed")
        ts, vs = inputs.setdefault(name, ([], []))
        ts.append(s.t)
        vs.append(s.value if kind is InputSample else s.heading_rad if kind is GnssHeadingSample else s.speed_mps)

    if inputs is not None:  # only for plots: a call per sample costs ~2 us per step
        pl.on_sample = on_sample
    outputs: list[OutputFile] = []
    try:
        csv_file = OutputFile(out_csv) if out_csv else None
        outputs += [csv_file] if csv_file else []
        can_file = OutputFile(out_can) if out_can else None
        outputs += [can_file] if can_file else []
        csv_out = csv_file.open() if csv_file else None
        can_out = (open_can_writer(can_file.write_path, output_channel(can_path, channel), name=can_file.path)
                   if can_file else None)
    except (OutputPathError, CanLogError) as e:
        for o in outputs:
            o.keep_partial()
        raise UserError(str(e)) from None
    orders = [TimeOrder(f"CAN log {can_path}", est.gap_s)]
    streams = [] if record is None else [_can_items(can_path, counters, orders[0], channel, can_time_offset or 0.0)]
    for i, g in enumerate(gnss_paths):
        orders.append(TimeOrder(f"GNSS log {g}", est.gap_s))
        streams.append(_gnss_items(g, orders[-1], i))
    merged = heapq.merge(*streams, key=lambda e: (e[0], e[1]))
    bar = _Progress(_count_lines(can_path), progress)
    dt = cfg.estimator.dt_s
    t_first = None
    t_last = None
    gaps_said = 0
    gap_log = RateLimitedLog(log)
    wall0 = time.perf_counter()
    failed = True
    flush = _nothing
    try:
        if csv_out:
            _write(csv_file, csv_out.write, csv_header())

        def write_frames(steps):
            if record is None:  # the batch pipeline: (frame id, payload) pairs
                can_out.write_steps([(st.estimate.t, st.frames) for st in steps if st.frames])
                return
            for st in steps:
                for msg in st.frames:
                    can_out.write(msg)

        pending: list = []  # steps not written yet: written WRITE_BATCH at a time (fewer calls per row)

        def flush():
            if not pending:
                return
            batch = pending[:]
            pending.clear()
            try:
                if csv_out:
                    _write(csv_file, csv_out.write, format_rows([st.estimate for st in batch]))
            finally:  # one output failing does not keep the other from what it had
                if can_out is not None:
                    _write(can_file, write_frames, batch)

        def emit(steps):
            nonlocal gaps_said
            if not steps:
                return
            if est.gaps != gaps_said:
                gaps_said = est.gaps
                gap_log.report("gap", logging.WARNING, gap_line(est))
            pending.extend(steps)
            if len(pending) >= WRITE_BATCH:
                flush()
            counters["steps"] += len(steps)

        ticks = record.ticks() if record is not None else None
        next_tick = next(ticks, None) if ticks is not None else None
        push_can, push_gnss = pl.push_can, pl.push_gnss
        n = 0
        if ticks is None:  # the time rule: whole logs at once (Pipeline.feed_log)
            t_first, t_last = _feed_logs(pl, can_path, channel, can_time_offset or 0.0, orders[0], merged,
                                         counters, emit, bar)
            merged = ()
        for t, _, seq, source, payload in merged:
            if not math.isfinite(t):
                continue
            if source == CAN:
                push_can(t, *payload, seq)
            else:
                receiver, port, data = payload
                push_gnss(t, data, port, seq, receiver)
            if ticks is None:
                emit(pl.feed(t))
            else:
                k_item = step_of(t, dt)
                while next_tick is not None and next_tick < k_item:
                    emit(pl.tick(next_tick))
                    next_tick = next(ticks, None)
            if t_first is None:
                t_first = t
            if t_last is None or t > t_last:
                t_last = t
            n += 1
            if not n & 1023:
                bar.update(counters["frames"], t - t_first)
        if t_last is not None:
            if ticks is None:
                emit(pl.finish(t_last))
            else:
                k_end = last_step_at(t_last, dt) if record.end is None else record.end
                while next_tick is not None and next_tick <= k_end:
                    emit(pl.tick(next_tick))
                    next_tick = next(ticks, None)
        flush()
        if can_out is not None:
            _write(can_file, lambda _: can_out.close(), None)
        for o in outputs:
            o.commit()
        failed = False
    except (CanLogError, GnssLogError, TimeOrderError, OutputPathError, OSError) as e:
        _flush_quietly(flush)
        _close_quietly(can_out)
        if isinstance(e, OSError):
            e = f"I/O error: {e.strerror or e}" + (f": {e.filename}" if e.filename else "")
        raise UserError(str(e) + _kept(outputs)) from None
    finally:
        bar.done()
        if failed:  # anything else (Ctrl-C, a bug): still keep what was written
            _flush_quietly(flush)
            _close_quietly(can_out)
            for o in outputs:
                o.keep_partial()
    report_other_channels(can_path, channel, counters.pop("channels", {}))
    wall = time.perf_counter() - wall0
    dur = (t_last - t_first) if t_first is not None else 0.0
    counters.update(gnss_samples=pl.gnss_samples, duration_s=dur, wall_s=wall, realtime_factor=dur / wall if wall > 0 else math.inf,
                    late_inputs=est.late_inputs, learned=est.learned_state(),
                    learned_std=est.learned_std(), gaps=est.gaps,
                    gnss_parse=sum(sum(p.stats.values()) for p in pl.parsers.values()),
                    inputs=input_table(pl.decoder, pl if gnss_paths else None, est))
    for line in format_input_table(counters["inputs"]):
        log.info("%s", line)
    for o in orders:
        if o.summary():
            log.warning("%s", o.summary())
    disagreement = gnss_rejection_warning(counters["inputs"].get("gnss"))
    if disagreement:
        log.warning("%s", disagreement)
    unusable = unusable_inputs(counters["inputs"])
    if unusable:
        can_inputs = any(not u.startswith("gnss (") for u in unusable)
        raise UnusableInputError("required input(s) not usable: " + "; ".join(unusable)
                                 + " (see the input table above); check "
                                 + ("[inputs.*] against the DBC (message, signal, counter, checksum)" if can_inputs
                                    else "the GNSS capture and [gnss]"), counters)
    return counters


def _write_plots(plots_dir: str, csv_path: str, inputs: dict) -> list[Path]:
    from .evaluate import ESTIMATE_REQUIRED, read_csv
    from .plots import write_plots

    try:
        return write_plots(read_csv(csv_path, ESTIMATE_REQUIRED, "estimate CSV"), plots_dir,
                           inputs={k: (np.asarray(t), np.asarray(v)) for k, (t, v) in inputs.items()})
    except ImportError as e:
        raise UserError(f"--plots needs matplotlib (pip install 'ecu-daemon[plot]'): {e}") from None
    except OSError as e:
        raise UserError(f"cannot write plots to {plots_dir}: {e.strerror or e}") from None


def _write(out: OutputFile, write, data) -> None:
    """``write(data)``, a failure (full disk...) phrased with the output's own name."""
    try:
        write(data)
    except OSError as e:
        raise OutputPathError(f"cannot write {out.path}: {e.strerror or e}") from None


def _flush_quietly(flush) -> None:
    """Write the steps still buffered, on the way out of a failed replay (a second failure is
    not worth more than the first)."""
    try:
        flush()
    except (OSError, OutputPathError, ValueError):
        pass


def _nothing() -> None:
    pass


def _close_quietly(writer) -> None:
    if writer is not None:
        try:
            writer.close()
        except OSError:
            pass


def _kept(outputs: list[OutputFile]) -> str:
    """What a failed replay keeps, for its error line (the files are renamed by keep_partial)."""
    kept = []
    for o in outputs:
        where = o.keep_partial()
        if where is not None:
            kept.append(str(where))
    return f"; output so far kept in {', '.join(kept)}" if kept else ""


#: columns of the end-of-replay input table: (key in the row, heading)
_TABLE = (("frames", "frames"), ("samples", "used"), ("dlc", "dlc"), ("decode", "decode"),
          ("range", "range"), ("counter", "counter"), ("checksum", "checksum"))


def input_table(decoder: SignalDecoder, pipeline: Pipeline | None, est: Estimator) -> dict[str, dict]:
    """Per input: frames that carried it, samples used, samples dropped by reason; plus ``gnss``
    (when a GNSS log was given): samples decoded, fused, rejected and the parser's error counts."""
    rows = {}
    for name, h in decoder.health.items():
        rows[name] = {"frames": h.frames, "samples": h.samples, **{k: v for k, v in h.errors.items() if k != "stale"}}
    if pipeline is not None:
        st = pipeline.gnss_stats()
        rows["gnss"] = {"frames": st.get("ubx_frames", 0) + st.get("nmea_sentences", 0),
                        "samples": st.get("samples", 0), "fused": est.gnss_counts()[0],
                        "rejected": est.gnss_counts()[1],
                        "checksum": st.get("checksum_errors", 0),
                        "decode": st.get("malformed", 0) + st.get("truncated", 0),
                        "fixes": sum(p.fixes for p in pipeline.parsers.values())}
        if not rows["gnss"]["fixes"]:
            rows["gnss"]["why"] = "; ".join(dict.fromkeys(filter(None, (p.why_unusable()
                                                                      for p in pipeline.parsers.values()))))
    return rows


def format_input_table(rows: dict[str, dict]) -> list[str]:
    """The table as lines (one log record each, so journald keeps them whole)."""
    head = f"{'input':22s}" + "".join(f"{h:>9s}" for _, h in _TABLE)
    lines = ["inputs at the end of the replay:", head]
    for name, r in rows.items():
        line = f"{name:22s}" + "".join(f"{r.get(k, 0):9d}" for k, _ in _TABLE)
        if name == "gnss":
            line += f"  (fused {r['fused']}, rejected {r['rejected']})"
        lines.append(line)
    return lines


#: GNSS is the one absolute velocity reference, and on a sound drive the estimator rejects only its
#: glitches (at most 12 % of the samples over the scenario suite: a 5 s glitch in a 50 s drive).
#: Most of them rejected means GNSS and the wheels (or the filter) disagree for good: velocity and
#: heading then rest on the wheels alone, and the likeliest cause is a mapping error (wheel speeds
#: in km/h read as m/s are 3.6x too fast, and four wheels outvote one receiver).
GNSS_REJECTED_WARN_SHARE = 0.5
#: ... judged only from this many decided samples on (a few at the start say nothing).
GNSS_REJECTED_WARN_MIN = 20


def gnss_rejection_warning(row: dict | None) -> str | None:
    """One line when the estimator rejected most GNSS samples (see ``GNSS_REJECTED_WARN_SHARE``);
    the replay still ends normally: a receiver with poor accuracy all drive long does the same."""
    if not row:
        return None
    fused, rejected = row.get("fused", 0), row.get("rejected", 0)
    decided = fused + rejected
    if decided < GNSS_REJECTED_WARN_MIN or rejected <= GNSS_REJECTED_WARN_SHARE * decided:
        return None
    return (f"gnss: {rejected} of {decided} samples ({100.0 * rejected / decided:.0f} %) rejected by the"
            " estimator (quality check, gate, or disagreement with the wheels): velocity and heading"
            " rest on the wheels alone; check the GNSS accuracy and the wheel speed mapping"
            " ([inputs.wheel_speed_*] scale: a unit error, e.g. km/h read as m/s is 3.6x too fast, an mph"
            " factor on m/s 0.45x; the estimator's wheel-speed line, when it says one, names the ratio)")


def unusable_inputs(rows: dict[str, dict]) -> list[str]:
    """'name (why)' for each required input (and GNSS, when given) that was not usable: no sample,
    or samples from fewer than :data:`MIN_USED_FRACTION` (GNSS: :data:`MIN_USED_FRACTION_GNSS`)
    of its frames; GNSS also when no sample had a fix (its row's ``why`` says what the receiver
    sent instead: ``GnssStreamParser.why_unusable``)."""
    out = []
    for name in REQUIRED_INPUTS + ("gnss",):
        r = rows.get(name)
        share = MIN_USED_FRACTION_GNSS if name == "gnss" else MIN_USED_FRACTION
        if r is None or (r["samples"] > 0 and r["samples"] >= share * r["frames"] and r.get("fixes", 1)):
            continue
        drops = ", ".join(f"{r[k]} {h}" for k, h in _TABLE[2:] if r.get(k))
        out.append(f"{name} ({r['samples']} of {r['frames']} frames used"
                   + (f"; dropped: {drops}" if drops else "") + (f"; {r['why']})" if r.get("why") else ")"))
    return out


def main(args: argparse.Namespace) -> int:
    from .io.state_store import StateFileError, load_state, save_state

    cfg = config_mod.load(args.config)
    out_csv = args.out_csv
    if args.plots and not out_csv:
        try:
            Path(args.plots).mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise UserError(f"cannot write plots to {args.plots}: {e.strerror or e}") from None
        out_csv = str(Path(args.plots) / "out.csv")
    inputs: dict | None = {} if args.plots else None
    learned = None
    if args.state:
        try:
            learned = load_state(args.state)
        except StateFileError as e:
            raise UserError(str(e)) from None
    ticks = config_mod.off_if_none(args.ticks) if args.ticks else default_ticks(args.can)
    summary = run_replay(cfg, args.can, args.gnss, out_csv, args.out_can,
                         progress=not args.no_progress, config_path=args.config, inputs=inputs,
                         can_channel=args.can_channel, can_time_offset=args.can_time_offset, learned=learned,
                         ticks_path=ticks or None)
    if args.state:
        try:
            save_state(args.state, summary["learned"])
        except OSError as e:
            raise UserError(f"cannot write state file {args.state}: {e.strerror or e}") from None
    files = _write_plots(args.plots, out_csv, inputs) if args.plots else []
    log.info("replayed %.1f s of drive (%d frames, %d GNSS samples) into %d steps in %.2f s"
             " (x%.0f real time)", summary["duration_s"], summary["frames"], summary["gnss_samples"],
             summary["steps"], summary["wall_s"], summary["realtime_factor"])
    for f in files:
        log.info("wrote %s", f)
    return 0
