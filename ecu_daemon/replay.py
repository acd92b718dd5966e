"""Offline replay: CAN log (+ GNSS capture) -> the same estimator core -> CSV and/or CAN log.

The contract outside tools rely on::

    ecu-daemon replay --config CFG.toml --can INPUT.log [--gnss GNSS.log]
                      [--out-can OUTPUT.log] [--out-csv OUTPUT.csv]

No second estimator path: frames go through ``signals.SignalDecoder`` and GNSS bytes through
``gnss.stream.GnssStreamParser`` exactly as live, into ``estimator.Estimator``. The step grid is
absolute (k * dt), samples are pushed in timestamp order and each step runs once every sample
stamped at or before it has been pushed, so a re-run gives byte-identical files.
"""
from __future__ import annotations

import argparse
import heapq
import math
import sys
import time
from pathlib import Path

from . import config as config_mod
from .canlog import CandumpWriter, CanLogError, read_can_log
from .cli import UserError
from .estimator import ESTIMATE_FIELDS, Estimator
from .gnss.logfile import GnssLogError, read_gnss_log
from .gnss.stream import GnssStreamParser
from .signals import SignalDecoder

_BOOL_FIELDS = {"sideslip_valid", "heading_valid", "velocity_valid", "biases_valid"}
_INT_FIELDS = {"status", "gnss_fused", "gnss_rejected", "gnss_late"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", "-C", help="TOML configuration (default: built-in defaults)")
    p.add_argument("--can", required=True, help="input CAN log: candump -L (.log), ASC or BLF")
    p.add_argument("--gnss", help="GNSS capture log: '(seconds.micros) PORT PAYLOAD' per line")
    p.add_argument("--out-can", help="write the output CAN frames as a candump -L log")
    p.add_argument("--out-csv", help="write one row per 6 ms estimator step")
    p.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    p.add_argument("--state", metavar="FILE",
                   help="learned-state file, as the daemon's [daemon] state_file: restored at the start"
                        " when it exists, written at the end (a restart mid-drive is two replays)")


def csv_header() -> str:
    return ",".join(ESTIMATE_FIELDS) + "\n"


def _row_format() -> str:
    parts = []
    for name in ESTIMATE_FIELDS:
        if name == "t":
            parts.append("%.6f")
        elif name in _BOOL_FIELDS or name in _INT_FIELDS:
            parts.append("%d")
        else:
            parts.append("%.9g")
    return ",".join(parts) + "\n"


ROW_FORMAT = _row_format()


def format_row(est) -> str:
    return ROW_FORMAT % tuple(est)


def _gnss_samples(path: str, cfg: config_mod.Config, parsers: dict):
    """(t, sample) for every GNSS sample in a capture, one parser per port."""
    for t, port, payload in read_gnss_log(path):
        p = parsers.get(port)
        if p is None:
            p = parsers[port] = GnssStreamParser(cfg.gnss.protocol, cfg.gnss.nmea_speed_acc_mps,
                                                 name=f"gnss {port}")
        for s in p.feed(t, payload):
            yield s.t, 1, s
    for p in parsers.values():
        for s in p.finish():
            yield s.t, 1, s


def _can_samples(path: str, decoder: SignalDecoder, counters: dict):
    for t, fid, ext, err, data in read_can_log(path):
        counters["frames"] += 1
        if err:
            counters["error_frames"] += 1
            continue
        for s in decoder.decode(t, fid, data, ext):
            yield t, 0, s


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


def run_replay(cfg: config_mod.Config, can_path: str, gnss_path: str | None = None,
               out_csv: str | None = None, out_can: str | None = None, progress: bool = False,
               learned: dict | None = None) -> dict:
    """Replay one drive, starting from ``learned`` (see :class:`Estimator`); returns a summary
    (counts, duration, speed, the final learned state). Raises UserError on bad files."""
    for p, what in ((can_path, "CAN log"), (gnss_path, "GNSS log")):
        if p is not None and not Path(p).is_file():
            raise UserError(f"cannot read {what} {p}: no such file")
    decoder = SignalDecoder(cfg)
    est = Estimator(cfg, learned)
    encoder = None
    can_out = None
    if out_can:
        from .outputs import OutputEncoder

        encoder = OutputEncoder(cfg)
        can_out = CandumpWriter(out_can)
    csv_out = open(out_csv, "w", encoding="ascii", newline="\n") if out_csv else None
    counters = {"frames": 0, "error_frames": 0, "gnss_samples": 0, "steps": 0}
    parsers: dict = {}
    streams = [_can_samples(can_path, decoder, counters)]
    if gnss_path:
        streams.append(_gnss_samples(gnss_path, cfg, parsers))
    merged = heapq.merge(*streams, key=lambda e: (e[0], e[1]))
    bar = _Progress(_count_lines(can_path), progress)
    dt = cfg.estimator.dt_s
    fmt = ROW_FORMAT
    t_first = None
    t_last = None
    wall0 = time.perf_counter()
    try:
        write_csv = csv_out.write if csv_out else None
        if csv_out:
            csv_out.write(csv_header())

        def emit(results):
            for e in results:
                if write_csv:
                    write_csv(fmt % tuple(e))
                if encoder is not None:
                    for msg in encoder.frames(round(e.t / dt), e, None):
                        can_out.write(msg)
            counters["steps"] += len(results)

        n = 0
        for t, kind, s in merged:
            if not math.isfinite(t):
                continue
            if kind:
                est.push_gnss(s)
                counters["gnss_samples"] += 1
            else:
                est.push_input(s)
            if t_first is None:
                t_first = t
            if t_last is None or t > t_last:
                t_last = t
                # every step strictly before this sample's time has all its samples now
                if t - 2e-9 >= est.next_step_t - 1e-9 or est.k is None:
                    emit(est.advance_to(t - 2e-9))
            n += 1
            if not n & 1023:
                bar.update(counters["frames"], t - t_first)
        if t_last is not None:
            emit(est.advance_to(t_last))
    except CanLogError as e:
        raise UserError(str(e)) from None
    except GnssLogError as e:
        raise UserError(str(e)) from None
    finally:
        bar.done()
        if csv_out:
            csv_out.close()
        if can_out:
            can_out.close()
    wall = time.perf_counter() - wall0
    dur = (t_last - t_first) if t_first is not None else 0.0
    counters.update(duration_s=dur, wall_s=wall, realtime_factor=dur / wall if wall > 0 else math.inf,
                    late_inputs=est.late_inputs, learned=est.learned_state(),
                    gnss_parse=sum(sum(p.stats.values()) for p in parsers.values()))
    if t_first is None:
        raise UserError(f"no usable frames in {can_path}: check [inputs.*] message names / ids against the DBC")
    return counters


def main(args: argparse.Namespace) -> int:
    from .io.state_store import StateFileError, load_state, save_state

    cfg = config_mod.load(args.config)
    learned = None
    if args.state:
        try:
            learned = load_state(args.state)
        except StateFileError as e:
            raise UserError(str(e)) from None
    summary = run_replay(cfg, args.can, args.gnss, args.out_csv, args.out_can,
                         progress=not args.no_progress, learned=learned)
    if args.state:
        try:
            save_state(args.state, summary["learned"])
        except OSError as e:
            raise UserError(f"cannot write state file {args.state}: {e.strerror or e}") from None
    print(f"replayed {summary['duration_s']:.1f} s of drive ({summary['frames']} frames, "
          f"{summary['gnss_samples']} GNSS samples) into {summary['steps']} steps in "
          f"{summary['wall_s']:.2f} s (x{summary['realtime_factor']:.0f} real time)", file=sys.stderr)
    return 0
