"""Units behind the bad-input handling: time order, output files, the rate limiter, decoder and
CAN-reception robustness."""
from __future__ import annotations

import logging
import os
from pathlib import Path

import can
import pytest

from ecu_daemon import config
from ecu_daemon.config import ConfigError
from ecu_daemon.io.can_bus import CanIO
from ecu_daemon.io.logging_setup import RateLimitFilter, RateLimitedLog, setup_logging
from ecu_daemon.io.output_file import OutputFile, OutputPathError, check_output_paths, partial_name
from ecu_daemon.signals import SignalDecoder
from ecu_daemon.time_order import MAX_BACKWARDS, TimeOrder, TimeOrderError

ROOT = Path(__file__).resolve().parents[1]


# ----------------------------------------------------------------------------------- time order
def ts(*times):
    return [(t, i) for i, t in enumerate(times)]


def test_time_order_drops_a_stray_stamp_ahead_and_a_line_going_back():
    o = TimeOrder("log", gap_s=2.0)
    got = [t for t, _ in o(ts(1.0, 1.01, 3001.0, 1.02, 1.03, 1.025, 1.04))]
    assert got == [1.0, 1.01, 1.02, 1.03, 1.04]
    assert (o.outliers, o.backwards) == (1, 1)
    assert "3001" in o.first_problem and "stray" in o.summary()


def test_time_order_keeps_a_real_gap_and_a_lone_last_line():
    o = TimeOrder("log", gap_s=2.0)
    assert [t for t, _ in o(ts(1.0, 1.01, 500.0, 500.01, 9000.0))] == [1.0, 1.01, 500.0, 500.01, 9000.0]
    assert (o.outliers, o.backwards, o.summary()) == (0, 0, "")


def test_time_order_refuses_a_reversed_log_early():
    o = TimeOrder("CAN log x.log", gap_s=2.0)
    times = [1000.0 - 0.01 * i for i in range(100_000)]
    with pytest.raises(TimeOrderError, match=r"x.log is not in time order.*sort"):
        list(o(ts(*times)))
    assert o.items == MAX_BACKWARDS + 1  # stopped at once, not after reading the whole log


def test_time_order_takes_a_clock_stepped_back_as_one_jump_and_drops_only_the_overlap():
    """NTP stepping the logger's clock back 2 s: 200 lines (100 Hz) stamped before the last one
    replayed are dropped, the rest goes on; not refused as an unsorted log (sorting would interleave)."""
    o = TimeOrder("CAN log x.log", gap_s=2.0)
    times = [0.01 * i for i in range(1000)] + [9.99 - 2.0 + 0.005 + 0.01 * i for i in range(1000)]
    got = [t for t, _ in o(ts(*times))]
    assert len(got) == 1000 + 800 and got == sorted(got)
    assert (o.backwards, o.jumps) == (200, 1)
    assert "1 jump(s) back: a clock stepped back" in o.summary()


def test_time_order_refuses_logs_concatenated_out_of_order():
    """Not a clock step: the second drive stays behind the first for longer than MAX_STEP_BACK_S."""
    times = [1000.0 + 0.01 * i for i in range(10_000)] + [500.0 + 0.01 * i for i in range(10_000)]
    o = TimeOrder("log", gap_s=2.0)
    with pytest.raises(TimeOrderError, match=r"goes back 599.99 s and stays behind for more than 60 s"):
        list(o(ts(*times)))
    assert o.items < 10_000 + 6100  # refused about a minute into the second drive


def test_time_order_refuses_a_shuffled_log_whose_lines_each_jump():
    import random

    times = [0.01 * i for i in range(20_000)]
    random.Random(2).shuffle(times)
    with pytest.raises(TimeOrderError, match="not in time order"):
        list(TimeOrder("log", gap_s=2.0)(ts(*times)))


# ----------------------------------------------------------------------------------- output files
def test_partial_names_keep_the_suffix_that_selects_the_format():
    assert partial_name(Path("/a/out.csv")) == Path("/a/out.partial.csv")
    assert partial_name(Path("d.log.gz")) == Path("d.partial.log.gz")
    assert partial_name(Path("noext")) == Path("noext.partial")
    assert partial_name(Path(".hidden")) == Path(".hidden.partial")


def test_output_file_commits_by_rename_and_keeps_a_failure_aside(tmp_path):
    target = tmp_path / "o.csv"
    target.write_text("old\n")
    o = OutputFile(target)
    assert o.write_path.parent == tmp_path and o.write_path.name.endswith("-o.csv")
    o.open().write("new\n")
    assert target.read_text() == "old\n"  # untouched until commit
    o.commit()
    assert target.read_text() == "new\n" and sorted(os.listdir(tmp_path)) == ["o.csv"]
    o = OutputFile(target)
    o.open().write("half")
    assert o.keep_partial() == tmp_path / "o.partial.csv"
    assert target.read_text() == "new\n" and (tmp_path / "o.partial.csv").read_text() == "half"
    assert o.keep_partial() is None  # idempotent
    o = OutputFile(target)
    o.open()
    assert o.keep_partial() is None and sorted(os.listdir(tmp_path)) == ["o.csv", "o.partial.csv"]


def test_output_file_writes_a_device_in_place(tmp_path):
    o = OutputFile("/dev/null")
    assert o.in_place and o.write_path == Path("/dev/null")
    o.open().write("x")
    o.commit()
    assert Path("/dev/null").exists() and not Path("/dev/null").is_file()


def test_check_output_paths_knows_hard_links_and_each_other(tmp_path):
    a = tmp_path / "a.log"
    a.write_text("x")
    os.link(a, tmp_path / "hard.log")
    with pytest.raises(OutputPathError, match="same file as --can"):
        check_output_paths({"--out-can": str(tmp_path / "hard.log")}, {"--can": str(a)})
    with pytest.raises(OutputPathError, match="same file as --out-csv"):
        check_output_paths({"--out-csv": str(tmp_path / "n"), "--out-can": str(tmp_path / "." / "n")}, {})
    check_output_paths({"--out-csv": str(tmp_path / "new.csv"), "--out-can": None}, {"--can": str(a), "--gnss": None})


# ----------------------------------------------------------------------------------- rate limiter
class Clock:
    now = 0.0

    def __call__(self):
        return self.now


def test_one_rate_limiter_on_the_caller_time_and_on_the_handler(caplog):
    logger = logging.getLogger("test.rl")
    rl = RateLimitedLog(logger, 10.0, clock=None)
    with caplog.at_level(logging.INFO, logger="test.rl"):
        for t in (100.0, 101.0, 105.0, 110.5, 50.0):  # stream time; going back (a restart) lets a line out
            rl.report("k", logging.WARNING, "bad", now=t)
    assert [r.getMessage() for r in caplog.records] == ["bad", "bad (+2 more in the last 10 s)", "bad"]
    clock = Clock()
    f = RateLimitFilter(10.0, clock)
    recs = [logging.LogRecord("x", logging.ERROR, "", 0, "error handling CAN frame 0x%X", (i,), None)
            for i in range(300)]
    passed = [f.filter(r) for r in recs[:299]]
    clock.now = 10.0
    assert sum(passed) == 1 and f.filter(recs[299])
    assert recs[299].getMessage().endswith("(+298 similar suppressed)")


def test_can_reception_errors_are_counted_and_throttled(capsys):
    setup_logging("info")

    def boom(t, msg):
        raise ValueError("cannot convert float NaN to integer")

    bus = can.Bus(interface="virtual", channel="bi-throttle")
    try:
        io = CanIO(bus, [(0x10, False)], on_frame=boom)
        for i in range(500):
            io._on_message(can.Message(arbitration_id=0x10, data=b"\x00", is_extended_id=False, timestamp=i * 1e-3))
    finally:
        bus.shutdown()
    assert io.callback_errors == 500
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "error handling CAN frame 0x10: ValueError" in lines[0]


# ----------------------------------------------------------------------------------- decoder
def _dbc_with_counter(tmp_path, counter_def: str, tail: str = "") -> Path:
    text = (ROOT / "ecu_daemon" / "dbc" / "ecu_daemon_inputs.dbc").read_text()
    assert text.count(' SG_ COUNTER : 8|4@1+ (1,0) [0|15] "" ECU_DAEMON') == 5  # WHEEL_SPEEDS, STEERING, IMU, MAGNETOMETER, IMU_ROLL
    p = tmp_path / "in.dbc"
    p.write_text(text.replace(' SG_ COUNTER : 8|4@1+ (1,0) [0|15] "" ECU_DAEMON', counter_def) + tail)
    return p


@pytest.mark.parametrize("counter_def, tail, why", [
    (' SG_ COUNTER : 8|4@1+ (0,0) [0|15] "" ECU_DAEMON', "", "cannot be a rolling counter \\(scale 0"),
    # NaN, inf and 1e38 are values a float signal can carry (int(round(...)) raised on them)
    (' SG_ COUNTER : 8|32@1+ (1,0) [0|0] "" ECU_DAEMON', "SIG_VALTYPE_ 176 COUNTER : 1;\n",
     "cannot be a rolling counter \\(a float signal"),
    (' SG_ COUNTER : 0|64@1+ (1,0) [0|0] "" ECU_DAEMON', "", "is 64 bits long; a rolling counter has at most 32"),
])
def test_a_counter_that_cannot_be_one_is_refused_when_binding(tmp_path, counter_def, tail, why):
    cfg = config.load(None)
    cfg.can.dbc = str(_dbc_with_counter(tmp_path, counter_def, tail))
    with pytest.raises(ConfigError, match=f"counter 'COUNTER' {why}"):
        SignalDecoder(cfg)


def test_an_exception_inside_the_decoder_is_a_counted_decode_error_in_one_line(caplog, monkeypatch):
    """The daemon's safety net below the reception thread: whatever a frame makes the decoder raise
    (a bug not yet found) drops its samples, counts a decode error per input, which EST_DIAG carries,
    and says so once per input, not once per frame."""
    dec = SignalDecoder(config.load(None))

    def bug(plan, t, data):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(dec, "_decode", bug)
    msg = dec.db.get_message_by_name("IMU")
    with caplog.at_level(logging.WARNING, logger="ecu_daemon"):
        for i in range(200):
            assert dec.decode(i * 0.01, msg.frame_id, bytes(8)) == []
    diag = dec.input_diagnostics(2.0)
    assert [diag[n].decode_errors for n in ("yaw_rate", "accel_x", "accel_y")] == [200, 200, 200]
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3 and all("ZeroDivisionError" in ln and "sample dropped" in ln for ln in lines), lines


def test_a_counter_mapped_onto_a_value_signal_is_counted_not_raised(caplog):
    cfg = config.load(None)
    for name in ("yaw_rate", "accel_x", "accel_y"):
        cfg.inputs[name].counter, cfg.inputs[name].checksum = "", "none"
    cfg.inputs["yaw_rate"].counter = "ACCEL_X"  # a signed value signal with a fractional scale
    with caplog.at_level(logging.WARNING, logger="ecu_daemon"):
        dec = SignalDecoder(cfg)
    assert any("ACCEL_X" in r.getMessage() and "value signal" in r.getMessage() for r in caplog.records)
    msg = dec.db.get_message_by_name("IMU")
    for i, ax in enumerate((-3.0, -20.0, 5.0, -1e-3)):
        data = msg.encode({s.name: 0 for s in msg.signals} | {"ACCEL_X": ax, "COUNTER": i})
        dec.decode(i * 0.01, msg.frame_id, data)
    assert dec.health["yaw_rate"].errors["counter"] >= 2
    assert dec.input_diagnostics(0.05)["yaw_rate"].counter_errors >= 2  # what EST_DIAG carries


def test_library_warnings_and_records_go_through_the_one_handler(capsys):
    import warnings

    setup_logging("info")
    warnings.warn("a library complains", UserWarning)
    logging.getLogger("can.interfaces.x").warning("python-can says %s", "hello")
    logging.getLogger("can.interfaces.x").info("python-can chatter")  # libraries: warnings only
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2, err
    assert " WARNING " in err[0] and "a library complains" in err[0]
    assert " WARNING python-can says hello" in err[1]
