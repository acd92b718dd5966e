"""The GNSS capture log: format, strict reading with file:line errors, and lossless round trips."""
from __future__ import annotations

import re

import pytest

from ecu_daemon.gnss import GnssLogError, GnssLogWriter, GnssStreamParser, read_gnss_log, samples_from_log
from ecu_daemon.gnss import encode as enc
from test_gnss_captures import GPSD, PYUBX2, capture_bytes, key, parse_all

T0 = 1700000000.0


def test_encode_to_log_to_samples_round_trip(tmp_path):
    """Simulator path: encoder output written per message, replayed through the parser."""
    path = tmp_path / "gnss.log"
    expected = []
    with GnssLogWriter(path, port="/dev/ttyACM0") as w:
        for k in range(5):
            t_rx = 100.0 + 0.1 * k + 0.12  # receive time, as the daemon stamps it
            frame = enc.nav_pvt(**enc.utc_fields(T0 + 0.1 * k), lat_deg=48.1, lon_deg=11.5,
                                vel_n_mps=10.0 + k, vel_e_mps=-1.5 * k)
            w.write(t_rx, frame)
            w.write(t_rx + 0.003, enc.nmea_rmc(utc=T0 + 0.1 * k, lat_deg=48.1, lon_deg=11.5,
                                               speed_mps=10.0, course_deg=0.0).encode())
            expected.append((round(t_rx, 6), 10.0 + k, -1.5 * k))
    text = path.read_text().splitlines()
    assert text[0].startswith("(100.120000) ttyACM0 B56201075C00")
    assert text[1].startswith("(100.123000) ttyACM0 $GNRMC,221320.00,A,4806.00000,N,01130.00000,E,19.438,0.00,")
    samples = list(samples_from_log(path, {"protocol": "ubx"}))
    assert [(s.t, s.vel_n_mps, s.vel_e_mps) for s in samples] == expected
    nmea = list(samples_from_log(path, {"protocol": "nmea"}))
    assert [s.t for s in nmea] == [round(t + 0.003, 6) for t, _, _ in expected]


@pytest.mark.parametrize("path", [GPSD / "ublox-zed-f9t-ubx_nmea_l5.log", PYUBX2 / "pygpsdata-BADCK2.log",
                                  GPSD / "firefly-II.log", PYUBX2 / "pygpsdata-MIXED-RTCM3BADCRC.log"])
def test_raw_sink_log_replays_to_identical_samples_and_counters(tmp_path, path):
    """Daemon path: every framed message (and every rejected byte run) is logged; replay is exact."""
    data = capture_bytes(path)
    log = tmp_path / "capture.log"
    with GnssLogWriter(log) as w:
        live = GnssStreamParser(raw_sink=w.write)
        live_samples = []
        for i in range(0, len(data), 97):  # serial reads of arbitrary size
            live_samples += live.feed(round(10.0 + i * 1e-4, 6), data[i:i + 97])  # the log keeps us
        live_samples += live.finish()
    parsers = {}
    replayed = list(samples_from_log(log, parsers=parsers))
    assert [key(s) for s in replayed] == [key(s) for s in live_samples]
    assert parsers["ttyACM0"].stats == live.stats
    assert b"".join(p for _, _, p in read_gnss_log(log)).replace(b"\r\n", b"\n") == data.replace(b"\r\n", b"\n")


def test_reader_payloads(tmp_path):
    path = tmp_path / "g.log"
    path.write_text("# GNSS capture\n\n"
                    "(1.000001) ttyACM0 $GNVTG,,T,,M,0.025,N,0.045,K,A*3B\n"
                    "(1.500000) ttyUSB1 b56205\n"
                    "(2.000000) ttyACM0 $PGRMT,GPS 17N VER 2.10,P,P,R,R,P,,23,R*05\n")
    assert list(read_gnss_log(path)) == [
        (1.000001, "ttyACM0", b"$GNVTG,,T,,M,0.025,N,0.045,K,A*3B\r\n"),
        (1.5, "ttyUSB1", b"\xb5\x62\x05"),
        (2.0, "ttyACM0", b"$PGRMT,GPS 17N VER 2.10,P,P,R,R,P,,23,R*05\r\n"),  # spaces kept
    ]


@pytest.mark.parametrize("line, what", [
    ("(12.5x) ttyACM0 B562", "bad timestamp"),
    ("(1700000000) ttyACM0 B562", "bad timestamp"),
    ("(1.000000) ttyACM0 B56", "odd-length hex"),
    ("(1.000000) ttyACM0 B5G2", "neither an NMEA sentence nor hex"),
    ("(1.000000) B56201", "expected '(seconds.micros) PORT PAYLOAD'"),
    ("1.000000 ttyACM0 B56201", "expected '(seconds.micros) PORT PAYLOAD'"),
])
def test_reader_errors_name_file_and_line(tmp_path, line, what):
    path = tmp_path / "bad.log"
    path.write_text("(0.500000) ttyACM0 $GNVTG,,T,,M,0.025,N,0.045,K,A*3B\n# comment\n" + line + "\n")
    it = read_gnss_log(path)
    assert next(it)[0] == 0.5  # lines before the bad one are delivered
    with pytest.raises(GnssLogError, match=rf"bad\.log:3: .*{re.escape(what)}"):
        next(it)


def test_reader_error_for_missing_file_and_non_ascii(tmp_path):
    with pytest.raises(GnssLogError, match="nope.log: cannot read GNSS log"):
        list(read_gnss_log(tmp_path / "nope.log"))
    path = tmp_path / "latin.log"
    path.write_bytes(b"(1.000000) ttyACM0 $GN\xe9\n")
    with pytest.raises(GnssLogError, match="latin.log:1: line is not ASCII"):
        list(read_gnss_log(path))


def test_a_raw_receiver_stream_is_named_as_such_with_what_replay_needs(tmp_path):
    """What a user saves from the receiver itself (``cat /dev/ttyACM0``, u-center's .ubx) has no
    receive times: one line saying so and what a capture is, not "expected (seconds.micros)"."""
    nmea = tmp_path / "drive.nmea"
    nmea.write_bytes(b"$GNRMC,080000.00,A,4808.21919,N,01134.50110,E,0.165,328.32,010624,,,A,V*0D\r\n"
                     b"$GNGGA,080000.00,4808.21919,N,01134.50110,E,1,14,0.90,520.6,M,0.0,M,,*73\r\n")
    ubx = tmp_path / "drive.ubx"  # NAV-PVT frames as the receiver sends them
    ubx.write_bytes(bytes.fromhex(
        "B56201075C0050E29D20E80706010800000714000000000000000301000E5034E606AE1FB11C40EF070040EF0700B0040000"
        "C409000048000000D3FFFFFF0C000000550000004BFAF4017800000056925300780000000000000000000000000000005336") * 3)
    for path, what in ((nmea, "NMEA sentences"), (ubx, "UBX frames")):
        with pytest.raises(GnssLogError) as e:
            list(read_gnss_log(path))
        msg = str(e.value)
        assert msg.startswith(f"{path}:1: a raw receiver stream ({what} without receive times)")
        assert "'(seconds.micros) PORT PAYLOAD'" in msg and "--record" in msg and "\n" not in msg


def test_writer_keeps_fragments_and_binary_exact(tmp_path):
    path = tmp_path / "w.log"
    with GnssLogWriter(path, port="ttyUSB0") as w:
        w.write(1.0, b"$GNRMC,12")            # cut-off sentence: hex, so no CR LF is invented
        w.write(2.0, b"$GNVTG,,T,,M,0.025,N,0.045,K,A*3B")  # whole sentence without line end: text
        w.write(3.0, b"\x00\xff$")
        w.write(4.0, b"")                     # nothing received: nothing written
    assert path.read_text().splitlines() == [
        "(1.000000) ttyUSB0 24474E524D432C3132",
        "(2.000000) ttyUSB0 $GNVTG,,T,,M,0.025,N,0.045,K,A*3B",
        "(3.000000) ttyUSB0 00FF24",
    ]
    assert [p for _, _, p in read_gnss_log(path)][0] == b"$GNRMC,12"
    with pytest.raises(ValueError, match="closed"):
        w.write(5.0, b"$")
    with pytest.raises(ValueError, match="whitespace"):
        GnssLogWriter(tmp_path / "x.log", port="tty ACM0")


def test_samples_from_log_uses_one_parser_per_port(tmp_path):
    """Two receivers in one log: their byte streams must not be mixed."""
    a = enc.nav_pvt(**enc.utc_fields(T0), lat_deg=1, lon_deg=2, vel_n_mps=1.0, vel_e_mps=0.0)
    b = enc.nav_pvt(**enc.utc_fields(T0), lat_deg=1, lon_deg=2, vel_n_mps=2.0, vel_e_mps=0.0)
    path = tmp_path / "two.log"
    path.write_text(f"(1.000000) ttyACM0 {a[:50].hex()}\n(1.000100) ttyACM1 {b[:30].hex()}\n"
                    f"(1.000200) ttyACM0 {a[50:].hex()}\n(1.000300) ttyACM1 {b[30:].hex()}\n")
    parsers = {}
    samples = list(samples_from_log(path, parsers=parsers))
    assert [(s.t, s.vel_n_mps) for s in samples] == [(1.0002, 1.0), (1.0003, 2.0)]
    assert set(parsers) == {"ttyACM0", "ttyACM1"}
    assert all(p.stats["garbage_bytes"] == 0 for p in parsers.values())


def test_parse_all_helper_agrees_with_log_replay(tmp_path):
    data = capture_bytes(PYUBX2 / "pygpsdata-MIXED3.log")
    path = tmp_path / "m.log"
    with GnssLogWriter(path) as w:
        GnssStreamParser(raw_sink=w.write).feed(5.0, data)
    assert [key(s) for s in samples_from_log(path)] == [key(s) for s in parse_all(data, t=5.0)[0]]


# ---------------------------------------------------------------------- gpsd's gpspipe -r -u / -uu

def test_a_gpspipe_capture_with_host_microseconds_is_read_on_the_host_clock(tmp_path):
    """gpspipe.c writes "%.24s%s: " before each line: strftime("%F %T") of CLOCK_REALTIME in UTC,
    then ".usec" (-u) or " sec.usec" (-uu); -Z makes it ISO 8601 (and -u then loses a digit to 'Z')."""
    rmc = "$GNRMC,080000.00,A,4808.21919,N,01134.50110,E,0.165,328.32,010624,,,A,V*0D"
    path = tmp_path / "pipe.log"
    path.write_bytes((f"2024-06-01 08:00:00.123456: {rmc}\r\n"
                      f"2024-06-01 08:00:00 1717228800.323456: {rmc}\r\n"
                      f"2024-06-01T08:00:00.52345Z: {rmc}\r\n").encode())
    got = list(read_gnss_log(path))
    assert [t for t, _, _ in got] == pytest.approx([1717228800.123456, 1717228800.323456, 1717228800.52345])
    assert {port for _, port, _ in got} == {"gpspipe"} and got[0][2] == rmc.encode() + b"\r\n"


@pytest.mark.parametrize("line, what", [
    ("2024-06-01 08:00:00: $GNRMC,080000.00,A*0D", "whole seconds (-t)"),
    ('2024-06-01 08:00:00.123456: {"class":"TPV","mode":3}', "gpspipe -w output"),
])
def test_gpspipe_captures_that_cannot_be_replayed_are_refused_with_the_command_that_can(tmp_path, line, what):
    path = tmp_path / "pipe.log"
    path.write_text(line + "\n")
    with pytest.raises(GnssLogError, match=rf"pipe\.log:1: .*{re.escape(what)}.*gpspipe -r -uu"):
        list(read_gnss_log(path))
