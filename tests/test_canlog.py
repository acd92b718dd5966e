"""CAN log reading (candump -L, ASC, BLF) and candump writing, against python-can and the real RAV4 log."""
from __future__ import annotations

import gzip
import re
from pathlib import Path

import can
import pytest

from ecu_daemon.canlog import CandumpWriter, CanLogError, log_channels, open_can_writer, read_can_log

DATA = Path(__file__).parent / "data" / "comma2k19"
SHARED_LOG = Path(__file__).resolve().parents[2] / "shared" / "data" / "comma2k19-rav4" / "rav4_bus0_candump.log"
LINE = re.compile(r"^\(\d+\.\d{6}\) can0 ([0-9A-F]{3}|[0-9A-F]{8})#(R\d?|#[0-9A-F])?[0-9A-F]*$")


def write(tmp_path: Path, text: str, name: str = "x.log") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_candump_syntax_variants(tmp_path):
    p = write(tmp_path, "\n".join([
        "(1621089000.123456) can0 0AA#1A2B3C",
        "(1621089000.123457) vcan1 12345678#DEADBEEF",  # extended
        "(1621089000.123458) can0 123#R",  # remote: skipped, counted
        "(1621089000.123459) can0 124#R4",
        "(1621089000.123460) can0 351#",  # empty payload
        "(1621089000.123461) can0 20000040#0000000000000000",  # bus-off error frame
        "(1621089000.123462) can0 20000004#0004000000000000",  # controller problem
        "(1621089000.123463) can0 7FF##1" + "11" * 12,  # CAN FD, 12 bytes
        "(1621089000.123464) can0 0AB#11.22.33 R",  # dotted data, -x direction flag
        "(1621089000.123465000) can0 0AC#0102030405060708 T",  # 9 decimals
        "",
        "# a comment",
        "(1621089000.123466) can0 0AD#0102030405060708_C",  # len8_dlc suffix
    ]) + "\n")
    r = read_can_log(p)
    frames = list(r)
    assert frames == [
        (1621089000.123456, 0x0AA, False, False, bytes.fromhex("1A2B3C")),
        (1621089000.123457, 0x12345678, True, False, bytes.fromhex("DEADBEEF")),
        (1621089000.12346, 0x351, False, False, b""),
        (1621089000.123461, 0x40, False, True, bytes(8)),
        (1621089000.123462, 0x04, False, True, bytes.fromhex("0004000000000000")),
        (1621089000.123463, 0x7FF, False, False, b"\x11" * 12),
        (1621089000.123464, 0x0AB, False, False, bytes.fromhex("112233")),
        (1621089000.123465, 0x0AC, False, False, bytes(range(1, 9))),
        (1621089000.123466, 0x0AD, False, False, bytes(range(1, 9))),
    ]
    assert r.remote_frames == 2 and r.lines == 13


@pytest.mark.parametrize("line, why", [
    ("(1621089000.123456) can0 0AA#1A2", "bad data '1A2'"),
    ("(1621089000.123456) can0 0AAA#1A2B", "bad CAN id '0AAA'"),
    ("(1621089000.123456) can0 0AA1A2B", "has no '#'"),
    ("(16210x9000.123456) can0 0AA#1A2B", "bad timestamp"),
    ("1621089000.123456 can0 0AA#1A2B", "expected '\\(timestamp\\) interface ID#DATA'"),
    ("(1621089000.123456) can0", "missing interface or frame"),
    ("(1621089000.123456) 0AA#1A2B", "no interface name before the frame"),
    ("(1621089000.123456) can0 0AA#1A2B extra", "unexpected text after the frame"),
    ("(1621089000.123456) can0 0AA#112233445566778899", "9 data bytes is not a valid classic CAN length"),
    ("(1621089000.123456) can0 7FF##1" + "11" * 9, "9 data bytes is not a valid CAN FD length"),
    ("(1621089000.123456) can0 800#11", "11-bit id 0x800 above 0x7FF"),
    ("(1621089000.123456) can0 5FFFFFFF#11", "29-bit id 5FFFFFFF above 0x1FFFFFFF"),
    ("(1621089000.123456) can0 60000040#11", "bad error-frame id 60000040"),
    ("(1621089000.123456) can0 0AA#1\u00e92B", "bad data"),
])
def test_malformed_line_is_one_clear_error_naming_file_and_line(tmp_path, line, why):
    p = write(tmp_path, "(1.000000) can0 001#00\n" + line + "\n(2.000000) can0 002#00\n", "bad.log")
    it = read_can_log(p)
    assert next(it) == (1.0, 1, False, False, b"\x00")  # frames before the bad line arrive
    with pytest.raises(CanLogError, match=why) as e:
        next(it)
    msg = str(e.value)
    assert msg.startswith(f"{p}:2: ") and "\n" not in msg


def test_garbage_bytes_and_missing_files(tmp_path):
    p = tmp_path / "bin.log"
    p.write_bytes(b"(1.000000) can0 001#00\n\xff\xfe\x00garbage\n")
    with pytest.raises(CanLogError, match=r"bin.log:2: expected"):
        list(read_can_log(p))
    with pytest.raises(CanLogError, match="cannot read CAN log .*missing.log: No such file"):
        read_can_log(tmp_path / "missing.log")  # at once, not at the first next()
    with pytest.raises(CanLogError, match="cannot read CAN log"):
        read_can_log(tmp_path)  # a directory


def test_writer_output_is_canplayer_format_and_reads_back(tmp_path):
    msgs = [
        can.Message(timestamp=1621089000.5, arbitration_id=0x0AA, is_extended_id=False, data=b"\x01\x02"),
        can.Message(timestamp=1621089000.0000004, arbitration_id=0x1ABCDEF, is_extended_id=True, data=bytes(8)),
        can.Message(timestamp=2.0, arbitration_id=0x40, is_extended_id=False, is_error_frame=True, data=bytes(8)),
        can.Message(timestamp=3.0, arbitration_id=0x123, is_extended_id=False, is_remote_frame=True, dlc=4),
        can.Message(timestamp=4.0, arbitration_id=0x124, is_extended_id=False, is_fd=True, bitrate_switch=True,
                    data=bytes(range(16))),
        can.Message(timestamp=5.0, arbitration_id=0x351, is_extended_id=False, data=b""),
    ]
    p = tmp_path / "out.log"
    with CandumpWriter(p) as w:
        for m in msgs:
            w.write(m)
        w.write_frame(6.25, 0x7FF, b"\xAB")
    lines = p.read_text().splitlines()
    assert all(LINE.match(line) for line in lines), lines
    assert lines[0] == "(1621089000.500000) can0 0AA#0102"
    assert lines[2] == "(2.000000) can0 20000040#0000000000000000"
    assert lines[3] == "(3.000000) can0 123#R4"
    assert lines[4] == "(4.000000) can0 124##1" + bytes(range(16)).hex().upper()
    r = read_can_log(p)
    assert list(r) == [(1621089000.5, 0x0AA, False, False, b"\x01\x02"),
                       (1621089000.0, 0x1ABCDEF, True, False, bytes(8)),
                       (2.0, 0x40, False, True, bytes(8)),
                       (4.0, 0x124, False, False, bytes(range(16))),
                       (5.0, 0x351, False, False, b""),
                       (6.25, 0x7FF, False, False, b"\xAB")]
    assert r.remote_frames == 1
    # python-can reads our data frames identically (it mistakes 20000040# for an extended data frame)
    ours = [m for m in can.LogReader(str(p)) if not (m.is_error_frame or m.is_remote_frame or m.arbitration_id == 0x40)]
    assert [(m.arbitration_id, bytes(m.data)) for m in ours] == [
        (0x0AA, b"\x01\x02"), (0x1ABCDEF, bytes(8)), (0x124, bytes(range(16))), (0x351, b""), (0x7FF, b"\xAB")]
    with pytest.raises(ValueError, match="closed"):
        w.write(msgs[0])


def test_gzip_candump(tmp_path):
    p = tmp_path / "x.log.gz"
    with gzip.open(p, "wt") as f:
        f.write("(1.000000) can0 0AA#0102\n(2.000000) can0 0AB#\n")
    assert list(read_can_log(p)) == [(1.0, 0xAA, False, False, b"\x01\x02"), (2.0, 0xAB, False, False, b"")]


@pytest.mark.parametrize("suffix, writer", [(".asc", can.ASCWriter), (".blf", can.BLFWriter)])
def test_asc_and_blf_through_python_can(tmp_path, suffix, writer):
    p = tmp_path / f"x{suffix}"
    msgs = [can.Message(timestamp=100.0 + i * 0.01, arbitration_id=0x0B0 + i, is_extended_id=False,
                        data=bytes([i] * 8), channel=0) for i in range(5)]
    msgs.append(can.Message(timestamp=101.0, arbitration_id=0x18FF00F1, is_extended_id=True, data=b"\x01", channel=0))
    w = writer(str(p))
    for m in msgs:
        w.on_message_received(m)
    w.stop()
    frames = list(read_can_log(p))
    assert [(f[1], f[2], f[3], f[4]) for f in frames] == [
        (m.arbitration_id, m.is_extended_id, False, bytes(m.data)) for m in msgs]
    # ASC stores times relative to the start of the measurement
    assert all(abs((f[0] - frames[0][0]) - (m.timestamp - msgs[0].timestamp)) < 1e-5 for f, m in zip(frames, msgs))


def test_corrupt_blf_is_a_can_log_error(tmp_path):
    p = tmp_path / "bad.blf"
    p.write_bytes(b"LOGG" + bytes(200))
    with pytest.raises(CanLogError, match="bad.blf"):
        list(read_can_log(p))


def compare_with_python_can(path: Path) -> int:
    ours = list(read_can_log(path))
    theirs = list(can.LogReader(str(path)))
    assert len(ours) == len(theirs)
    for (t, fid, ext, err, data), m in zip(ours, theirs):
        assert (fid, ext, err, data) == (m.arbitration_id, m.is_extended_id, m.is_error_frame, bytes(m.data))
        assert t == m.timestamp
    return len(ours)


def test_vendored_rav4_extract_matches_python_can_reader():
    assert compare_with_python_can(DATA / "rav4_bus0_candump_5s.log") == 4494


@pytest.mark.skipif(not SHARED_LOG.exists(), reason=f"{SHARED_LOG} not present")
def test_full_rav4_log_matches_python_can_reader_and_round_trips(tmp_path):
    assert compare_with_python_can(SHARED_LOG) == 53800
    out = tmp_path / "copy.log"
    with CandumpWriter(out) as w:
        for t, fid, ext, err, data in read_can_log(SHARED_LOG):
            w.write_frame(t, fid, data, ext, err)
    assert out.read_text() == SHARED_LOG.read_text()  # byte-identical: same 6-decimal format


TWO_BUSES = "\n".join([
    "(1700000000.000100) can0 0AA#0102",
    "(1700000000.000200) can1 0AA#FFFF",
    "(1700000000.000300) can0 123#R4",
    "(1700000000.000400) can1 7FF##3" + "22" * 16,  # FD with BRS and ESI
    "(1700000000.000500) can0 124##0" + "11" * 8,  # FD without flags, 8 bytes
    "(1700000000.000600) can0 12345678#DEADBEEF T",
    "(1700000000.000700) can1 125#R",
]) + "\n"


def test_messages_keep_channel_fd_flags_and_remote_frames_as_python_can_reads_them(tmp_path):
    p = write(tmp_path, TWO_BUSES)
    r = read_can_log(p, messages=True)
    ours = list(r)
    theirs = list(can.CanutilsLogReader(str(p)))
    assert len(ours) == len(theirs) == 7 and r.remote_frames == 2
    for a, b in zip(ours, theirs):
        assert a.equals(b, timestamp_delta=None, check_channel=True, check_direction=False), (a, b)
        assert a.timestamp == b.timestamp
    assert [(m.channel, m.is_fd, m.bitrate_switch, m.error_state_indicator, m.is_remote_frame, m.dlc)
            for m in ours] == [("can0", False, False, False, False, 2), ("can1", False, False, False, False, 2),
                               ("can0", False, False, False, True, 4), ("can1", True, True, True, False, 16),
                               ("can0", True, False, False, False, 8), ("can0", False, False, False, False, 4),
                               ("can1", False, False, False, True, 0)]


def test_channel_selection_keeps_one_bus_and_counts_all(tmp_path):
    p = write(tmp_path, TWO_BUSES)
    r = read_can_log(p, channel="can1")
    assert [(f[1], f[4]) for f in r] == [(0x0AA, b"\xff\xff"), (0x7FF, b"\x22" * 16)]
    assert r.channels == {"can0": 4, "can1": 3} and r.remote_frames == 1
    assert log_channels(p) == {"can0": 4, "can1": 3}
    asc = tmp_path / "two.asc"
    w = can.ASCWriter(str(asc))
    for m in read_can_log(p, messages=True):
        w.on_message_received(m)
    w.stop()
    assert log_channels(asc) == {"0": 4, "1": 3}  # python-can's channel numbers
    assert [(f[1], f[4]) for f in read_can_log(asc, channel="1")] == [(0x0AA, b"\xff\xff"), (0x7FF, b"\x22" * 16)]


def test_time_offset_is_added_to_every_frame_on_the_microsecond_grid(tmp_path):
    p = write(tmp_path, TWO_BUSES)
    plain = [f[0] for f in read_can_log(p)]
    shifted = [f[0] for f in read_can_log(p, time_offset=-1699999000.0)]
    assert shifted == [round(t - 1699999000.0, 6) for t in plain] and shifted[0] == 1000.0001


def test_asc_keeps_its_start_date_and_says_when_it_has_none(tmp_path):
    p = tmp_path / "x.asc"
    w = can.ASCWriter(str(p))
    for i in range(3):
        w.on_message_received(can.Message(timestamp=1700000000.25 + i * 0.01, arbitration_id=0x100 + i,
                                          is_extended_id=False, data=bytes([i])))
    w.stop()
    r = read_can_log(p)
    assert [f[0] for f in r] == [1700000000.25, 1700000000.26, 1700000000.27] and r.absolute_time
    undated = tmp_path / "undated.asc"
    undated.write_text("".join(line for line in p.read_text().splitlines(keepends=True)
                               if not line.lower().startswith(("date", "begin triggerblock"))))
    r = read_can_log(undated)
    assert [f[0] for f in r] == [0.0, 0.01, 0.02] and not r.absolute_time


def test_gzipped_asc_keeps_its_start_date(tmp_path):
    """``.asc.gz`` (python-can reads gzipped logs): the same absolute times as the ``.asc``, not
    times from 0 that cannot be lined up with the GNSS capture."""
    p = tmp_path / "x.asc"
    w = can.ASCWriter(str(p))
    for i in range(3):
        w.on_message_received(can.Message(timestamp=1700000000.25 + i * 0.01, arbitration_id=0x100 + i,
                                          is_extended_id=False, data=bytes([i])))
    w.stop()
    gz = tmp_path / "x.asc.gz"
    gz.write_bytes(gzip.compress(p.read_bytes()))
    r = read_can_log(gz)
    assert list(r) == list(read_can_log(p)) and r.absolute_time
    assert [f[0] for f in read_can_log(gz)] == [1700000000.25, 1700000000.26, 1700000000.27]
    assert log_channels(gz) == log_channels(p)


@pytest.mark.parametrize("suffix, reader", [(".asc", can.ASCReader), (".blf", can.BLFReader), (".log", None)])
def test_open_can_writer_writes_what_the_extension_names(tmp_path, suffix, reader):
    p = tmp_path / f"out{suffix}"
    msgs = [can.Message(timestamp=1700000000.006 * (1 + i * 1e-12), arbitration_id=0x300 + i, is_extended_id=False,
                        data=bytes([i] * 8)) for i in range(4)]
    with open_can_writer(p) as w:
        for m in msgs:
            w.write(m)
    if reader is None:
        assert p.read_text().startswith("(1700000000.006000) can0 300#0000000000000000")
    else:
        back = list(reader(str(p)))
        assert [(m.arbitration_id, bytes(m.data)) for m in back] == [(m.arbitration_id, bytes(m.data)) for m in msgs]
    assert [(f[1], f[4]) for f in read_can_log(p)] == [(m.arbitration_id, bytes(m.data)) for m in msgs]
    assert abs(next(iter(read_can_log(p)))[0] - 1700000000.006) < 1e-6


def test_asc_with_timestamps_relative_to_the_previous_event_is_refused(tmp_path):
    p = tmp_path / "delta.asc"
    p.write_text("date Mon Jan 01 00:00:00.000 2024\nbase hex  timestamps relative\ninternal events logged\n"
                 "   0.010000 1  100             Rx   d 1 01\n   0.010000 1  101             Rx   d 1 02\n")
    with pytest.raises(CanLogError, match="delta.asc: 'timestamps relative'.*export the log with absolute"):
        list(read_can_log(p))


def _as_screen_output(log_line: str) -> str:
    """What ``candump -ta -x can0`` prints for the frame of one candump -L line (classic and FD,
    the way can-utils' lib.c lays it out: 11-bit ids indented, lengths ``[8]`` / ``[08]``)."""
    ts, iface, frame = log_line.split()
    ident, _, data = frame.partition("#")
    flags = "- -"
    if data.startswith("#"):
        f = int(data[1], 16)
        flags = ("B" if f & 1 else "-") + " " + ("E" if f & 2 else "-")
        data = data[2:]
        length = f"[{len(data) // 2:02d}]"
    else:
        length = f"[{len(data) // 2}]"
    ident = ident if len(ident) == 8 else "     " + ident
    body = " ".join(data[i:i + 2] for i in range(0, len(data), 2))
    sec, frac = ts.strip("()").split(".")
    return f" ({int(sec):010d}.{frac})  {iface}  RX {flags}  {ident}   {length}  {body}"


def test_candump_screen_output_with_absolute_times_reads_as_its_log_format(tmp_path):
    """``candump -ta can0 > capture.txt`` is what many users have: read as the same frames as
    ``candump -L``, with the -x direction/flag columns, -a's ASCII, remote and error frames."""
    log_lines = (DATA / "rav4_bus0_candump_5s.log").read_text().splitlines()
    screen = tmp_path / "rav4_ta.txt"
    screen.write_text("\n".join(_as_screen_output(line) for line in log_lines) + "\n")
    assert list(read_can_log(screen)) == list(read_can_log(DATA / "rav4_bus0_candump_5s.log"))
    assert log_channels(screen) == {"can0": 4494}

    p = write(tmp_path, "\n".join([
        " (1700000000.000100)  can0  0AA   [2]  01 02                     '..'",
        " (1700000000.000200)  can1  12345678   [4]  DE AD BE EF",
        " (1700000000.000300)  can0  123   [4]  remote request",
        " (1700000000.000400)  can0  TX B E  7FF  [12]  " + " ".join(["22"] * 12),
        " (1700000000.000500)  can0  20000040   [8]  00 00 00 00 00 00 00 00   ERRORFRAME\r",
        " (1700000000.000600)  can0  124   [0] ",
    ]) + "\n", "mixed.txt")
    r = read_can_log(p)
    assert list(r) == [
        (1700000000.0001, 0x0AA, False, False, b"\x01\x02"),
        (1700000000.0002, 0x12345678, True, False, bytes.fromhex("DEADBEEF")),
        (1700000000.0004, 0x7FF, False, False, b"\x22" * 12),
        (1700000000.0005, 0x40, False, True, bytes(8)),
        (1700000000.0006, 0x124, False, False, b""),
    ]
    assert r.remote_frames == 1
    fd = [m for m in read_can_log(p, messages=True) if m.is_fd]
    assert len(fd) == 1 and fd[0].bitrate_switch and fd[0].error_state_indicator


@pytest.mark.parametrize("line, why", [
    (" (000.000749)  can0  0B2   [8]  33 00 33 00 00 00 00 00", r"relative times \(-td/-tz\)"),
    (" (1200.004166)  can0  0B2   [8]  33 00 33 00 00 00 00 00", r"relative times \(-td/-tz\)"),
    (" (2026-12-03 06:50:15.123456)  can0  0B2   [8]  33 00", r"local date and time without a time zone"),
    ("  can0  0B2   [8]  33 00 33 00 00 00 00 00", r"without times \(no -t\)"),
    (" (1700000000.000749)  can0  0B2   [8]  33 00 33", r"\[8\] but 3 data bytes"),
    (" (1700000000.000749)  can0  0B2   [2]  33 00 33", r"\[2\] but 2 data bytes"),
])
def test_candump_screen_output_that_cannot_be_replayed_is_one_line_with_the_fix(tmp_path, line, why):
    """Screen output without absolute times cannot be put on the GNSS capture's clock: refused
    at its first line, saying how to record a log that can (not 'unexpected text')."""
    p = write(tmp_path, line + "\n", "screen.txt")
    with pytest.raises(CanLogError, match=why) as e:
        list(read_can_log(p))
    msg = str(e.value)
    assert msg.startswith(f"{p}:1: ") and "\n" not in msg
    if "data bytes" not in why:
        assert "candump -L" in msg
