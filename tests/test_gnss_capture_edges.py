"""Receiver captures as they come from other setups (robust25): u-blox 6/7/M8 with NAV-PVT off
sending NAV-VELNED before its NAV-STATUS (the order the user enabled them), serial captures that
start mid-sentence or end mid-line, and the NMEA leap second 23:59:60.

Before: the first gave no sample at all (replay exit 3, "no epoch could be dated"), the second was
refused whole (exit 2, ":1: payload is neither an NMEA sentence nor hex"), and the third stepped
``fix_time_utc_s`` back by 1 s."""
from __future__ import annotations

import csv
import math

import pytest
from pyubx2 import GET, UBXMessage

from ecu_daemon.cli import main as cli_main
from ecu_daemon.gnss import encode
from ecu_daemon.gnss.logfile import GnssLogError, read_gnss_log, samples_from_log
from ecu_daemon.gnss.stream import GnssStreamParser

#: 2024-06-01T08:00:00Z is GPS week 2317, time of week 6 d 8 h + 18 leap seconds
_ITOW0 = (6 * 86400 + 8 * 3600 + 18) * 1000
_UTC0 = 1717228800.0 + 8 * 3600


def _status(itow: int, fix_ok: bool = True) -> bytes:
    return UBXMessage("NAV", "NAV-STATUS", GET, iTOW=itow, gpsFix=3 if fix_ok else 0, gpsFixOk=int(fix_ok),
                      wknSet=1, towSet=1).serialize()


def _velned(itow: int, vn: float = 10.0) -> bytes:
    return encode.nav_velned(itow_ms=itow, vel_n_mps=vn, vel_e_mps=1.0, speed_acc_mps=0.3)


def _timeutc(itow: int, utc: float) -> bytes:
    f = encode.utc_fields(utc)
    return UBXMessage("NAV", "NAV-TIMEUTC", GET, iTOW=itow, tAcc=20, nano=f["nano"], year=f["year"],
                      month=f["month"], day=f["day"], hour=f["hour"], min=f["minute"], sec=f["second"],
                      validTOW=1, validWKN=1, validUTC=1).serialize()


def _capture(path, frames_by_t) -> None:
    with open(path, "w") as f:
        for t, frame in frames_by_t:
            f.write(f"({t:.6f}) ttyACM0 {frame.hex().upper()}\n")


def _parse(path):
    parsers = {}
    return list(samples_from_log(path, parsers=parsers)), parsers


# ---------------------------------------------------------------------- NAV-VELNED before NAV-STATUS

def test_nav_velned_before_its_nav_status_gives_every_epoch_with_that_epochs_fix_state(tmp_path):
    frames = []
    for k in range(10):  # 5 Hz; the receiver says "no fix" in epoch 4
        itow, t = _ITOW0 + 200 * k, 100.0 + 0.2 * k
        frames += [(t, _velned(itow, vn=10.0 + k)), (t + 0.003, _status(itow, fix_ok=k != 4))]
    _capture(tmp_path / "g.log", frames)
    samples, _ = _parse(tmp_path / "g.log")
    assert [s.vel_n_mps for s in samples] == [10.0 + k for k in range(10)]
    assert [s.fix_ok for s in samples] == [k != 4 for k in range(10)]
    assert [s.t for s in samples] == pytest.approx([100.0 + 0.2 * k for k in range(10)])  # the VELNED's own time


def test_nav_status_at_a_lower_rate_serves_the_epochs_up_to_1_s_after_it(tmp_path):
    frames = []
    for k in range(15):  # NAV-VELNED 5 Hz, NAV-STATUS 1 Hz after it; then NAV-STATUS stops
        itow, t = _ITOW0 + 200 * k, 100.0 + 0.2 * k
        frames.append((t, _velned(itow)))
        if k % 5 == 0 and k < 10:
            frames.append((t + 0.003, _status(itow)))
    _capture(tmp_path / "g.log", frames)
    samples, _ = _parse(tmp_path / "g.log")
    # epochs 0-9 have a status at most 0.8 s older, 10 exactly 1 s; 11-14 none: dropped
    assert [round((s.t - 100.0) / 0.2) for s in samples] == list(range(11))
    assert all(s.fix_ok for s in samples)


def test_nav_velned_is_dated_by_its_own_itow_once_nav_timeutc_told_the_week(tmp_path):
    frames = []
    for k in range(5):
        itow, t = _ITOW0 + 200 * k, 100.0 + 0.2 * k
        frames += [(t, _velned(itow)), (t + 0.002, _status(itow))]
        if k == 1:
            frames.append((t + 0.004, _timeutc(itow, _UTC0 + 0.2 * k)))
    _capture(tmp_path / "g.log", frames)
    samples, _ = _parse(tmp_path / "g.log")
    assert len(samples) == 5 and all(math.isnan(s.fix_time_utc_s) for s in samples[:2])
    assert [s.fix_time_utc_s for s in samples[2:]] == pytest.approx([_UTC0 + 0.2 * k for k in (2, 3, 4)], abs=1e-6)


# ---------------------------------------------------------------------- captures cut anywhere

@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("drive")
    assert cli_main(["simulate", "--scenario", "straight_dry", "--duration", "20", "--out", str(d)]) == 0
    return d


def _replay(d, gnss, tmp_path, capsys):
    capsys.readouterr()
    rc = cli_main(["replay", "--config", str(d / "config.toml"), "--can", str(d / "drive.log"),
                   "--gnss", str(gnss), "--out-csv", str(tmp_path / "est.csv")])
    err = capsys.readouterr().err
    rows = list(csv.DictReader(open(tmp_path / "est.csv"))) if rc == 0 else []
    return rc, err, rows


def test_a_drive_whose_receiver_sends_nav_velned_first_replays_with_its_gnss_fused(drive, tmp_path, capsys):
    """NAV-PVT turned off, NAV-VELNED enabled before NAV-STATUS (u-blox 6/7/M8 send them in that order)."""
    from pyubx2 import UBXReader

    frames = []
    for t, _, frame in read_gnss_log(drive / "drive_gnss.log"):
        m = UBXReader.parse(frame)
        frames += [(t, encode.nav_velned(itow_ms=m.iTOW, vel_n_mps=m.velN / 1000, vel_e_mps=m.velE / 1000,
                                         vel_d_mps=m.velD / 1000, speed_acc_mps=m.sAcc / 1000)),
                   (t + 0.002, _status(m.iTOW))]
    _capture(tmp_path / "velned.log", frames)
    rc, err, rows = _replay(drive, tmp_path / "velned.log", tmp_path, capsys)
    assert rc == 0, err.strip().splitlines()[-1]
    assert int(rows[-1]["gnss_fused"]) >= 90 and int(rows[-1]["gnss_rejected"]) == 0


_TAIL = "N,01134.49981,E,0.165,327.99,010624,,,A,V*1D"  # what is left of a $GNRMC the capture began in


def test_a_capture_starting_mid_sentence_and_ending_mid_line_replays(drive, tmp_path, capsys):
    lines = open(drive / "drive_gnss.log").read().splitlines()
    t0 = float(lines[0][1:lines[0].index(")")])
    cut = [f"({t0 - 0.05:.6f}) ttyACM0 {_TAIL}"] + lines[:-1] + [lines[-1][:41]]  # no line end either
    (tmp_path / "g.log").write_text("\n".join(cut))
    samples, parsers = _parse(tmp_path / "g.log")
    whole, _ = _parse(drive / "drive_gnss.log")
    assert len(samples) == len(whole) - 1 and samples == whole[:-1]
    st = parsers["ttyACM0"].stats
    assert st["garbage_bytes"] >= len(_TAIL) and st["truncated"] == 1
    rc, err, rows = _replay(drive, tmp_path / "g.log", tmp_path, capsys)
    assert rc == 0, err.strip().splitlines()[-1]
    assert int(rows[-1]["gnss_fused"]) >= 90
    assert "skipped 46 bytes outside any valid frame (starting 4e 2c" in err  # the tail, said once


def test_a_last_line_cut_before_its_payload_is_skipped_with_one_line(tmp_path, caplog):
    path = tmp_path / "g.log"
    path.write_text("(1.000000) ttyACM0 $GNVTG,,T,,M,0.025,N,0.045,K,A*3B\n(1.2000")
    assert [t for t, _, _ in read_gnss_log(path)] == [1.0]
    assert "g.log:2: " in caplog.text and "the last line, cut short: skipped" in caplog.text


@pytest.mark.parametrize("text, line", [
    # a candump log given as the capture: refused at its first line, as before
    ("(1200.001000) can0 0B4#CB0059005700B100\n(1200.002000) can0 0B0#0008000800080008\n", 1),
    # two sentence tails and nothing else: not a capture that began mid-sentence
    ("(1.0) ttyACM0 N,01134.4,E*1D\n(1.2) ttyACM0 4,01134.49981,E,1,08*47\n", 2),
    # a line cut short is the last line only
    ("(1.000000) ttyACM0 $GNVTG,,T,,M,0.025,N,0.045,K,A*3B\n(1.100000) ttyACM0 B56\n(1.2) ttyACM0 B562\n", 2),
])
def test_a_file_that_is_not_a_gnss_capture_is_still_refused_at_its_line(tmp_path, text, line):
    path = tmp_path / "g.log"
    path.write_text(text)
    with pytest.raises(GnssLogError, match=rf"g\.log:{line}: "):
        list(read_gnss_log(path))


# ---------------------------------------------------------------------- NMEA leap second

def _sentence(body: str) -> bytes:
    ck = 0
    for c in body:
        ck ^= ord(c)
    return f"${body}*{ck:02X}\r\n".encode()


def test_an_nmea_leap_second_keeps_the_epoch_times_monotone_and_their_steps_true():
    """2016-12-31T23:59:60: a receiver sends 235959.80, 235960.00 ... 235960.80, 000000.00."""
    tods = ["235959.60", "235959.80"] + [f"235960.{k}0" for k in (0, 2, 4, 6, 8)] + ["000000.00", "000000.20"]
    p = GnssStreamParser("nmea")
    out = []
    for k, tod in enumerate(tods):
        date = "010117" if tod.startswith("00") else "311216"
        out += p.feed(10.0 + 0.2 * k, _sentence(f"GNRMC,{tod},A,4808.21919,N,01134.50110,E,20.0,45.0,{date},,,A,V"))
        out += p.feed(10.0 + 0.2 * k + 0.01, _sentence(
            f"GNGGA,{tod},4808.21919,N,01134.50110,E,1,12,0.9,520.{k},M,0.0,M,,"))
    out += p.finish()
    times = [s.fix_time_utc_s for s in out]
    assert len(times) == len(tods) and p.stats["malformed"] == 0
    assert [b - a for a, b in zip(times, times[1:])] == pytest.approx([0.2] * (len(tods) - 1), abs=1e-6)
    assert times[0] == pytest.approx(1483228799.6, abs=1e-6)  # POSIX before the leap second
    alt_times = [s.alt_time_utc_s for s in out[1:]]  # each sample carries the previous epoch's GGA
    assert [b - a for a, b in zip(alt_times, alt_times[1:])] == pytest.approx([0.2] * (len(tods) - 2), abs=1e-6)


def test_second_60_other_than_at_23_59_is_not_a_time():
    p = GnssStreamParser("nmea")
    p.feed(1.0, _sentence("GNRMC,120060.00,A,4808.21919,N,01134.50110,E,20.0,45.0,010624,,,A,V"))
    assert p.stats["malformed"] == 1 and "RMC time is not hhmmss.ss: '120060.00'" in p.last_error


# ---------------------------------------------------------------------- NMEA 1.5/2.0 VTG

def _vtg_gga_epochs(vtg_bodies, quality=1):
    p = GnssStreamParser("nmea")
    out = []
    for k, vtg in enumerate(vtg_bodies):
        out += p.feed(10.0 + k, _sentence(vtg))
        out += p.feed(10.0 + k + 0.01, _sentence(f"GPGGA,0800{k:02d}.00,4808.21919,N,01134.50110,E,{quality},08,0.9,520.0,M,0.0,M,,"))
    return out + p.finish(), p


def test_a_vtg_without_unit_letters_is_read_as_course_course_knots_kmh():
    """Older receivers (NMEA 1.5/2.0) send '$GPVTG,054.7,034.4,005.5,010.2': pynmea2 maps it onto the
    lettered layout, so the speed read as missing and every epoch as "no fix"."""
    out, p = _vtg_gga_epochs(["GPVTG,054.7,034.4,005.5,010.2", "GPVTG,090.0,,019.4,036.0", "GPVTG,,,,"])
    assert p.stats["malformed"] == 0 and len(out) == 3
    a, b, c = out
    assert a.fix_ok and math.hypot(a.vel_n_mps, a.vel_e_mps) == pytest.approx(5.5 * 1852 / 3600)
    assert math.degrees(math.atan2(a.vel_e_mps, a.vel_n_mps)) == pytest.approx(54.7)
    assert b.fix_ok and b.vel_e_mps == pytest.approx(19.4 * 1852 / 3600) and abs(b.vel_n_mps) < 1e-9
    assert not c.fix_ok  # no fix: empty fields
    out, _ = _vtg_gga_epochs(["GPVTG,054.7,034.4,005.5,010.2"], quality=0)
    assert not out[0].fix_ok  # GGA says no fix


def test_a_vtg_of_neither_layout_is_malformed_with_its_fields():
    _, p = _vtg_gga_epochs(["GPVTG,054.7,X,,M,005.5,N,010.2,K,A"])
    assert p.stats["malformed"] == 1 and "VTG fields are neither" in p.last_error


# ---------------------------------------------------------------------- logger clock stepped back

def test_a_drive_whose_logger_clock_stepped_back_2_s_replays_past_the_step(drive, tmp_path, capsys):
    """NTP steps the host clock back mid-drive: both logs jump back 2 s at the same instant. Before:
    refused whole as "not in time order ... sort it" (sorting would interleave the two stretches)."""
    can = (drive / "drive.log").read_text().splitlines()
    t_step = float(can[len(can) // 2][1:can[len(can) // 2].index(")")])

    def stepped(lines):
        out = []
        for line in lines:
            t = float(line[1:line.index(")")])
            out.append(f"({t - 2.0 if t >= t_step else t:.6f}){line[line.index(')') + 1:]}")
        return "\n".join(out) + "\n"

    (tmp_path / "can.log").write_text(stepped(can))
    (tmp_path / "g.log").write_text(stepped((drive / "drive_gnss.log").read_text().splitlines()))
    capsys.readouterr()
    rc = cli_main(["replay", "--config", str(drive / "config.toml"), "--can", str(tmp_path / "can.log"),
                   "--gnss", str(tmp_path / "g.log"), "--out-csv", str(tmp_path / "est.csv")])
    err = capsys.readouterr().err
    assert rc == 0, err.strip().splitlines()[-1]
    assert "1 jump(s) back: a clock stepped back" in err
    rows = list(csv.DictReader(open(tmp_path / "est.csv")))
    assert float(rows[-1]["t"]) > t_step + 5.0 and int(rows[-1]["gnss_fused"]) >= 80


def test_a_nav_pvt_leap_second_keeps_the_epoch_times_monotone_and_their_steps_true():
    """u-blox NAV-PVT counts sec to 60 in a leap second; the RELPOSNED of each epoch takes its date."""
    epochs = [(23, 59, 59, 600), (23, 59, 59, 800)] + [(23, 59, 60, ms) for ms in (0, 200, 400, 600, 800)] \
        + [(0, 0, 0, 0), (0, 0, 0, 200)]
    data = b""
    for k, (h, mi, sec, ms) in enumerate(epochs):
        day = (2017, 1, 1) if h == 0 else (2016, 12, 31)
        itow = 100_000 + 200 * k
        data += encode.nav_pvt(itow_ms=itow, year=day[0], month=day[1], day=day[2], hour=h, minute=mi,
                               second=sec, nano=ms * 1_000_000, lat_deg=48.1, lon_deg=11.5, vel_n_mps=10.0,
                               vel_e_mps=0.0)
        data += encode.nav_relposned(itow_ms=itow, heading_deg=10.0, baseline_m=1.0)
    p = GnssStreamParser("ubx")
    out = p.feed(1.0, data) + p.finish()
    vel = [s.fix_time_utc_s for s in out if hasattr(s, "vel_n_mps")]
    head = [s.fix_time_utc_s for s in out if not hasattr(s, "vel_n_mps")]
    assert len(vel) == len(epochs) and head == vel
    assert [b - a for a, b in zip(vel, vel[1:])] == pytest.approx([0.2] * (len(epochs) - 1), abs=1e-6)
    assert vel[0] == pytest.approx(1483228799.6, abs=1e-6)
