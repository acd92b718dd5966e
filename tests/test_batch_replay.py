"""The whole-log replay path (can_arrays + BatchDecoder + Pipeline.feed_log) against the item-by-item
one it replaced: the same samples, counters, steps and output bytes, on clean and damaged logs.

The reference is the frame-by-frame :class:`SignalDecoder` and the item-by-item pipeline
(``push_can`` / ``push_gnss`` + ``feed`` in ``heapq.merge`` order, as ``replay`` ran before), run
here on the same files; a damaged log carries every decoder error kind (wrong length, checksum,
counter, range), error frames, unmapped ids and a timestamp going back, so EST_DIAG's counters
and the dirty-frame hand-over are compared too, byte for byte.
"""
from __future__ import annotations

import copy
import heapq
import math
import re
from pathlib import Path

import numpy as np
import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.batch_decoder import DIRTY, BatchDecoder
from ecu_daemon.can_arrays import read_can_arrays
from ecu_daemon.canlog import CandumpWriter, read_can_log
from ecu_daemon.estimate_csv import csv_header, format_rows
from ecu_daemon.gnss.logfile import read_gnss_log
from ecu_daemon.pipeline import Pipeline
from ecu_daemon.replay import run_replay
from ecu_daemon.signals import SignalDecoder
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.writer import write_all
from ecu_daemon.time_order import TimeOrder

ROOT = Path(__file__).resolve().parents[1]
RAV4 = ROOT / "tests" / "data" / "comma2k19" / "rav4_bus0_candump_5s.log"


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    sc = SCENARIOS["demo"].with_(duration_s=14.0)
    d = tmp_path_factory.mktemp("batch")
    write_all(d, simulate(sc, vehicle_config(sc)))
    return d


def _damage(src: Path, dst: Path) -> None:
    """Every decoder error kind, error frames, unmapped ids and one timestamp going back."""
    out = []
    for i, line in enumerate(src.read_text().splitlines()):
        t, iface, fid, data = re.match(r"\((\S+)\) (\S+) (\S+)#(\S*)", line).groups()
        if i % 131 == 0:
            continue  # lost frame: a counter error next
        if i % 97 == 0:  # one bit flipped: a checksum error
            b = bytearray.fromhex(data)
            b[3] ^= 0x10
            data = b.hex().upper()
        if i % 211 == 0:
            data = data[:-2]  # wrong length
        if i == 700:
            t = f"{float(t) - 0.05:.6f}"  # goes back: dropped by the time order
        out.append(f"({t}) {iface} {fid}#{data}")
        if i % 503 == 0:
            out.append(f"({t}) {iface} 20000004#0000000000000000")  # error frame
        if i % 59 == 0:
            out.append(f"({t}) {iface} 123#0102")  # not mapped
    dst.write_text("\n".join(out) + "\n")


@pytest.fixture(scope="module")
def damaged(drive, tmp_path_factory):
    d = tmp_path_factory.mktemp("damaged")
    _damage(drive / "drive.log", d / "drive.log")
    (d / "drive_gnss.log").write_bytes((drive / "drive_gnss.log").read_bytes())
    cfg = config_mod.load(drive / "config.toml")
    cfg.inputs["accel_y"].max = 0.2  # range errors on the turns
    cfg.inputs["accel_y"].min = -0.2
    return d, cfg


def _frame_by_frame(cfg, log: Path, channel=None):
    """Per frame the reference decoder's samples, and its health at every 500th frame."""
    frames = list(read_can_log(log, channel=channel))
    ref = SignalDecoder(cfg)
    per_frame, health = [], {}
    for j, (t, fid, ext, err, data) in enumerate(frames):
        per_frame.append([] if err else ref.decode(t, fid, data, ext))
        if j % 500 == 0 or j == len(frames) - 1:
            health[j + 1] = {n: (h.frames, h.samples, h.last_t, dict(h.errors)) for n, h in ref.health.items()}
    return frames, per_frame, health


def _check_batch_decoder(cfg, log: Path, channel=None) -> int:
    frames, expected, health = _frame_by_frame(cfg, log, channel)
    can = read_can_arrays(str(log), TimeOrder("t", math.inf), channel)
    if len(can) != len(frames):  # (a log going back: compare the kept frames only)
        pytest.skip("log not in time order")
    dec = BatchDecoder(cfg)
    out = dec.prepare(can.t, can.keys(), can.data)
    dirty = 0
    for j, (t, fid, ext, err, data) in enumerate(frames):
        got = out[j]
        if got is DIRTY:
            dirty += 1
            got = dec.take(j, t, fid, data, ext)
        got = list(got or ())
        want = expected[j]
        assert [tuple(s) for s in got] == [tuple(s) for s in want], (j, frames[j])
        assert [type(s.value) for s in got] == [type(s.value) for s in want]
        assert all(type(s) is type(w) for s, w in zip(got, want))
        if j + 1 in health:
            dec.cursor = j + 1
            dec.sync()
            assert {n: (h.frames, h.samples, h.last_t, dict(h.errors)) for n, h in dec.health.items()} \
                == health[j + 1], j
    return dirty


def test_batch_decoder_gives_the_frame_by_frame_samples_and_counters(drive):
    assert _check_batch_decoder(config_mod.load(drive / "config.toml"), drive / "drive.log") == 0


def test_batch_decoder_hands_damaged_frames_over_with_the_counter_state_before_them(drive, tmp_path):
    src = tmp_path / "d.log"
    lines = [ln for ln in (drive / "drive.log").read_text().splitlines()]
    dst = tmp_path / "damaged.log"
    src.write_text("\n".join(lines) + "\n")
    _damage(src, dst)
    text = dst.read_text().splitlines()
    text.pop(next(i for i, ln in enumerate(text) if "20000004" not in ln and i > 700))  # keep time order
    dst.write_text("\n".join(sorted(text, key=lambda ln: float(ln[1:ln.index(")")]))) + "\n")
    cfg = config_mod.load(drive / "config.toml")
    cfg.inputs["accel_y"].max = 0.2
    dirty = _check_batch_decoder(cfg, dst)
    assert dirty > 100  # every kind went through SignalDecoder.decode


def test_batch_decoder_on_sign_magnitude_and_toyota_checksums(drive, tmp_path):
    vw = config_mod.load(ROOT / "examples" / "vw_mqb.toml")
    sc = SCENARIOS["slalom_dry"].with_(duration_s=6.0)
    write_all(tmp_path, simulate(sc, vehicle_config(sc, vw)), vehicle_config(sc, vw))
    _check_batch_decoder(vehicle_config(sc, vw), tmp_path / "drive.log")
    rav4 = config_mod.load(ROOT / "examples" / "toyota_rav4.toml")
    assert _check_batch_decoder(rav4, RAV4) >= 0


def _item_by_item(cfg, can_path: Path, gnss_path: Path, channel=None) -> tuple[str, str]:
    """CSV and candump text of the replay as it ran before the batch path: one item at a time."""
    pl = Pipeline(cfg, encode=True, gnss_connected=True)
    gap = pl.estimator.gap_s
    can = ((t, 0, seq, "can", (fid, data, ext, err)) for seq, (t, fid, ext, err, data, seq) in
           enumerate((*f, i) for i, f in enumerate(TimeOrder("c", gap)(read_can_log(can_path, channel=channel)))))
    gnss = ((t, 1, seq, "gnss", (0, port, p)) for seq, (t, port, p) in
            enumerate(TimeOrder("g", gap)(read_gnss_log(gnss_path))))
    rows, lines = [csv_header()], []
    out = Path(str(can_path) + ".ref.log")
    w = CandumpWriter(out)

    def emit(steps):
        rows.append(format_rows([s.estimate for s in steps]))
        for s in steps:
            for m in s.frames:
                w.write(m)

    t_last = None
    for t, _, seq, source, payload in heapq.merge(can, gnss, key=lambda e: (e[0], e[1])):
        if source == "can":
            pl.push_can(t, *payload, seq)
        else:
            pl.push_gnss(t, payload[2], payload[1], seq, payload[0])
        emit(pl.feed(t))
        t_last = t if t_last is None else max(t, t_last)
    emit(pl.finish(t_last))
    w.close()
    return "".join(rows), out.read_text()


@pytest.mark.parametrize("which", ["clean", "damaged"])
def test_replay_writes_the_item_by_item_bytes(drive, damaged, tmp_path, which):
    if which == "clean":
        d, cfg = drive, config_mod.load(drive / "config.toml")
    else:
        d, cfg = damaged
    want_csv, want_can = _item_by_item(copy.deepcopy(cfg), d / "drive.log", d / "drive_gnss.log")
    summary = run_replay(cfg, str(d / "drive.log"), str(d / "drive_gnss.log"), out_csv=str(tmp_path / "o.csv"),
                         out_can=str(tmp_path / "o.log"))
    assert (tmp_path / "o.csv").read_text() == want_csv
    assert (tmp_path / "o.log").read_text() == want_can
    assert want_can.count("\n") > 1000
    if which == "damaged":
        rows = summary["inputs"]
        assert rows["steering_wheel_angle"]["dlc"] and rows["accel_y"]["range"] and rows["yaw_rate"]["counter"]
        assert rows["wheel_speed_fl"]["checksum"] and summary["error_frames"] > 0


def test_can_arrays_keep_the_reader_order_and_drop_what_the_time_order_drops(damaged):
    d, _ = damaged
    order = TimeOrder("x", 1.0)
    can = read_can_arrays(str(d / "drive.log"), order)
    ref_order = TimeOrder("x", 1.0)
    ref = list(ref_order(read_can_log(d / "drive.log")))
    assert order.backwards == ref_order.backwards == 1
    assert can.t.tolist() == [f[0] for f in ref] and can.data == [f[4] for f in ref]
    assert can.err.sum() == sum(f[3] for f in ref) > 0
    assert np.all(can.keys()[can.err] == -1)


def _reader_arrays(path, channel=None, offset=0.0):
    r = read_can_log(path, channel=channel, time_offset=offset)
    fr = list(r)
    return ([f[0] for f in fr], [f[1] for f in fr], [f[2] for f in fr], [f[3] for f in fr], [f[4] for f in fr],
            r.channels)


@pytest.mark.parametrize("channel,offset", [(None, 0.0), (None, 3.1415927), ("can0", 0.0), ("can1", 0.0)])
def test_compiled_candump_parser_gives_the_readers_frames(damaged, tmp_path, channel, offset):
    from ecu_daemon.can_arrays import _candump, _parse_candump

    if _candump is None:
        pytest.skip("ecu_daemon._candump not built")
    d, _ = damaged
    lines = (d / "drive.log").read_text().splitlines()
    lines += ["(1700000000.000001) can1 1FFFFFFF#00112233445566  T", "  (1700000000.5) can1 7FF#   ",
              "(1700000001.000000) can1 20000080#0000000000000000 R\r"]
    log = tmp_path / "two.log"
    log.write_text("\n".join(lines) + "\n")
    got = _parse_candump(str(log), channel, offset)
    assert got is not None
    want = _reader_arrays(log, channel, offset)
    assert (got.t.tolist(), got.fid.tolist(), got.ext.tolist(), got.err.tolist(), got.data, got.channels) == want


@pytest.mark.parametrize("line", ["# a comment", "", "(1.000000) can0 123#R", "(1.000000) can0 123##1001122",
                                  "(1.000000) can0 123#01.02", "(1.000000) can0 123#012", "(1.000000) can0 800#00",
                                  "(1.000000) can0 123#000102030405060708", "(1.0) can0 123#00 X",
                                  "(1.000000) can0 123#00_9", "(1.000000)can0 123#00", "(1) can0 123#00"])
def test_compiled_candump_parser_leaves_other_lines_to_the_reader(tmp_path, line):
    from ecu_daemon.can_arrays import _candump, _parse_candump

    if _candump is None:
        pytest.skip("ecu_daemon._candump not built")
    log = tmp_path / "x.log"
    log.write_text(f"(0.500000) can0 0B0#0011\n{line}\n(2.000000) can0 0B0#0011\n")
    assert _parse_candump(str(log), None, 0.0) is None  # the reader reads it, or names the bad line


@pytest.mark.parametrize("frozen_before, collecting", [(False, True), (False, False), (True, True)])
def test_feed_log_leaves_the_garbage_collector_as_it_found_it(drive, tmp_path, frozen_before, collecting):
    """feed_log makes the log's samples with the cyclic collector off and freezes the heap for the
    step loop (pipeline._long_lived_heap): afterwards the collector is on or off as before, nothing
    of the replay stays frozen, a heap frozen by the caller stays frozen, and an exception in an
    emit does not leave the collector off or the heap frozen either."""
    import gc

    cfg = config_mod.load(drive / "config.toml")
    args = (cfg, str(drive / "drive.log"), str(drive / "drive_gnss.log"))
    gc.collect()
    if frozen_before:
        gc.freeze()
    count = gc.get_freeze_count()

    def unchanged(now):  # frozen objects still die by reference count: the count only shrinks
        assert (0 < now <= count) if frozen_before else now == 0

    if not collecting:
        gc.disable()
    try:
        seen = []
        real = Pipeline._publish

        def spy(self, e, send):
            if not seen:
                seen.append((gc.isenabled(), gc.get_freeze_count()))
            return real(self, e, send)

        Pipeline._publish = spy
        try:
            run_replay(*args, out_csv=str(tmp_path / "a.csv"))
        finally:
            Pipeline._publish = real
        assert gc.isenabled() is collecting
        unchanged(gc.get_freeze_count())
        # during the steps: collector as the caller had it, and the samples frozen (unless the
        # caller had frozen a heap already: that one is left alone)
        assert seen[0][0] is collecting
        assert seen[0][1] > 0
        if frozen_before:
            unchanged(seen[0][1])

        def failing(self, e, send):
            raise RuntimeError("emit failed")

        Pipeline._publish = failing
        try:
            with pytest.raises(RuntimeError, match="emit failed"):
                run_replay(*args, out_csv=str(tmp_path / "b.csv"))
        finally:
            Pipeline._publish = real
        assert gc.isenabled() is collecting
        unchanged(gc.get_freeze_count())
    finally:
        gc.enable()
        gc.unfreeze()
