"""Real receiver captures through GnssStreamParser, checked against independent answer keys.

Oracles: gpsd's own decoding of the same logs (``*.tpv.jsonl``: the TPV lines of gpsd's
``.log.chk`` regression output) and pyubx2's ``UBXReader`` on the same bytes. Data provenance and
licences: ``tests/data/gnss/README.md``. The helpers at the top are shared by the other GNSS tests.
"""
from __future__ import annotations

import dataclasses
import io
import json
import math
from datetime import datetime
from pathlib import Path

import pytest
from pyubx2 import UBX_PROTOCOL, UBXReader

from ecu_daemon.gnss import GnssStreamParser
from ecu_daemon.gnss.logfile import raw_capture_bytes as capture_bytes
from ecu_daemon.samples import FIX_NONE

DATA = Path(__file__).parent / "data" / "gnss"
GPSD = DATA / "gpsd"
PYUBX2 = DATA / "pyubx2"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "gnss-captures"


# ------------------------------------------------------------------------------------ helpers

def parse_all(data: bytes, t: float = 0.0, **kwargs):
    parser = GnssStreamParser(**kwargs)
    samples = parser.feed(t, data) + parser.finish()
    return samples, parser


def tpv_by_time(path: Path) -> dict[float, dict]:
    """gpsd TPV reports with a time and a speed, keyed by UTC seconds (ms resolution)."""
    out = {}
    for line in path.read_text().splitlines():
        d = json.loads(line)
        if "time" in d and "speed" in d:
            out[round(datetime.fromisoformat(d["time"].replace("Z", "+00:00")).timestamp(), 3)] = d
    return out


def key(sample, *, with_t: bool = True) -> tuple:
    """A comparable, NaN-safe tuple of a GnssSample."""
    vals = dataclasses.astuple(sample)[0 if with_t else 1:]
    return tuple("nan" if isinstance(v, float) and math.isnan(v) else v for v in vals)


def pyubx2_messages(data: bytes):
    """What pyubx2 itself decodes from the stream (its own framing), for cross-checks."""
    rdr = UBXReader(io.BytesIO(data), protfilter=UBX_PROTOCOL, quitonerror=0)
    return [msg for _, msg in rdr if msg is not None]


# ------------------------------------------------------------------------------------ gpsd oracle

UBX_LOGS = ["navisys-gr8013", "ublox-neo-m8p", "ublox-zed-f9t-ubx_nmea_l5", "ublox-f9p-rtcm"]
NMEA_LOGS = ["firefly-II", "haicom-305N", "st-teseo-liv4f", "ublox-zed-f9p-nmea",
             "nmea-fuzzy-cases",  # Trimble: talker GP -> GN -> GP between epochs
             "ericsson-gru04"]  # VTG-only velocity, time and date from ZDA/GNS


@pytest.mark.parametrize("name", UBX_LOGS)
def test_ubx_logs_match_gpsd_speed_within_1mm_per_s(name):
    samples, parser = parse_all(capture_bytes(GPSD / f"{name}.log"))
    tpv = tpv_by_time(GPSD / f"{name}.tpv.jsonl")
    by_time = {round(s.fix_time_utc_s, 3): s for s in samples}
    assert tpv, "answer key is empty"
    assert all(s.protocol == "ubx" for s in samples)  # auto mode prefers UBX over the NMEA copy
    for when, d in tpv.items():
        s = by_time[when]  # every epoch gpsd reported, we reported
        # gpsd reports gSpeed (mm/s); we carry velN/velE (mm/s each): rounding <= ~1 mm/s
        assert math.hypot(s.vel_n_mps, s.vel_e_mps) == pytest.approx(d["speed"], abs=1.2e-3)
        assert s.fix_ok and s.fix_type == d["mode"]
    assert parser.stats["checksum_errors"] == 0


@pytest.mark.parametrize("name", NMEA_LOGS)
def test_nmea_logs_match_gpsd_speed(name):
    samples, parser = parse_all(capture_bytes(GPSD / f"{name}.log"))
    tpv = tpv_by_time(GPSD / f"{name}.tpv.jsonl")
    by_time = {round(s.fix_time_utc_s, 3): s for s in samples}
    assert tpv
    for when, d in tpv.items():
        s = by_time[when]
        assert s.protocol == "nmea" and s.fix_ok
        assert s.speed_mps == pytest.approx(d["speed"], abs=0.01)
        if s.course_known and d["speed"] > 1.0:  # course is meaningful only when moving
            track = math.degrees(math.atan2(s.vel_e_mps, s.vel_n_mps)) % 360
            assert abs((track - d["track"] + 180) % 360 - 180) < 0.01
        # u-blox blanks COG at standstill: speed only, no false direction
        assert s.course_known == ("track" in d) or d["speed"] < 1.0


def test_firefly_bad_gga_checksums_are_counted_and_every_rmc_still_parses():
    samples, parser = parse_all(capture_bytes(GPSD / "firefly-II.log"))
    assert parser.stats["checksum_errors"] == 23  # every GPGGA of this receiver is corrupt
    assert len(samples) == 23 and all(s.fix_ok for s in samples)
    assert "checksum" in parser.last_error


def test_proprietary_and_doubled_dollar_sentences_do_not_disturb():
    samples, parser = parse_all(capture_bytes(GPSD / "st-teseo-liv4f.log"))
    assert len(samples) == 12
    assert parser.stats["unsupported"] > 100  # $PSTM... sentences: framed, checked, not used


def test_u_blox_nmea41_rmc_is_valid_despite_nav_status_v():
    data = capture_bytes(GPSD / "ublox-zed-f9p-nmea.log")
    assert b",A,V*" in data  # status A, mode A, nav status V: pynmea2's is_valid says False
    samples, _ = parse_all(data)
    assert len(samples) == 29 and all(s.fix_ok and s.fix_type == 3 for s in samples)
    # GGA/GST follow RMC on u-blox: the sample (emitted at RMC) takes them from the previous epoch
    assert samples[0].num_sv == 0 and math.isnan(samples[0].h_acc_m)
    assert all(s.num_sv == 12 for s in samples[1:])
    assert all(s.h_acc_m == pytest.approx(math.hypot(2.3, 3.5), abs=1.5) for s in samples[1:])


@pytest.mark.parametrize("path, expect", [
    (GPSD / "ublox-lea-5q.log", 10),                      # RMC status V, mode N, empty fields
    (PYUBX2 / "2023-4-17_82912_serial-COM3.ubx", 90),    # u-blox session without a fix
    (GPSD / "garmin-geko201.log", 18),                    # mode S: the receiver's simulator
])
def test_sessions_without_a_fix_give_invalid_samples(path, expect):
    samples, _ = parse_all(capture_bytes(path))
    assert len(samples) == expect
    assert not any(s.fix_ok for s in samples) and all(s.fix_type == FIX_NONE for s in samples)


# ------------------------------------------------------------------------------------ pyubx2 oracle

def test_mixed_capture_matches_pyubx2_field_by_field_in_si_units():
    data = capture_bytes(PYUBX2 / "pygpsdata-MIXED.log")
    samples, parser = parse_all(data)
    pvts = [m for m in pyubx2_messages(data) if m.identity == "NAV-PVT"]
    assert len(samples) == len(pvts) == 39
    for s, m in zip(samples, pvts):
        assert s.vel_n_mps == m.velN / 1000 and s.vel_e_mps == m.velE / 1000  # mm/s -> m/s
        assert s.speed_acc_mps == m.sAcc / 1000 and s.h_acc_m == m.hAcc / 1000
        assert s.head_acc_rad == pytest.approx(math.radians(m.headAcc))
        assert (s.fix_type, s.fix_ok, s.num_sv) == (m.fixType, bool(m.gnssFixOk), m.numSV)
        assert (s.lat_deg, s.lon_deg) == (m.lat, m.lon)
    assert parser.stats["garbage_bytes"] == 0 and parser.stats["checksum_errors"] == 0


@pytest.mark.parametrize("name, pvt, errors", [
    ("pygpsdata-BADCK2.log", 1, "checksum_errors"),
    ("pygpsdata-MIXED3BADCK.log", 1, "checksum_errors"),
    ("pygpsdata-BADEOF1.log", 1, "truncated"),
    ("pygpsdata-BADEOF2.log", 1, "truncated"),
    ("pygpsdata-BADEOF3.log", 1, "truncated"),
    ("pygpsdata-BADNMEAEOF.log", 2, "truncated"),
    ("pygpsdata-MIXED-RTCM3BADCRC.log", 1, "checksum_errors"),
])
def test_damaged_captures_count_the_damage_and_keep_every_good_frame(name, pvt, errors):
    data = capture_bytes(PYUBX2 / name)
    samples, parser = parse_all(data)
    good = [m for m in pyubx2_messages(data) if m.identity == "NAV-PVT"]
    assert len(samples) == len(good) == pvt
    assert parser.stats[errors] >= 1 and parser.last_error


def test_rtcm3_frames_are_skipped_whole():
    samples, parser = parse_all(capture_bytes(PYUBX2 / "pygpsdata-MIXED-RTCM3.log"))
    assert parser.stats["rtcm_frames"] == 7 and parser.stats["garbage_bytes"] == 0
    assert len(samples) == 1 and samples[0].protocol == "ubx"


def test_protocol_filter():
    data = capture_bytes(GPSD / "ublox-zed-f9t-ubx_nmea_l5.log")
    ubx, p1 = parse_all(data, protocol="ubx")
    nmea, p2 = parse_all(data, protocol="nmea")
    assert len(ubx) == len(nmea) == 9
    assert {s.protocol for s in ubx} == {"ubx"} and {s.protocol for s in nmea} == {"nmea"}
    assert p1.stats["ignored"] == p1.stats["nmea_sentences"] and p2.stats["ignored"] == p2.stats["ubx_frames"]
    # the two protocols describe the same epochs: same velocities to NMEA's 3 decimals of knots
    for a, b in zip(ubx, nmea):
        assert a.fix_time_utc_s == pytest.approx(b.fix_time_utc_s, abs=1e-3)  # UBX nano is -119 us
        assert a.speed_mps == pytest.approx(b.speed_mps, abs=0.16)


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} not present")
def test_every_shared_capture_parses_without_exceptions():
    """All staged captures (72 gpsd, 12 pyubx2): no exception, and NMEA/UBX get framed."""
    n = 0
    for path in sorted(SHARED.glob("*/*")):
        if path.suffix in (".chk", ".csv") or "LICENSE" in path.name:
            continue
        samples, parser = parse_all(capture_bytes(path))
        assert parser.stats["ubx_frames"] + parser.stats["nmea_sentences"] > 0, path.name
        assert all(not s.fix_ok or math.isfinite(s.speed_mps) for s in samples), path.name
        assert all(math.isfinite(s.vel_n_mps + s.vel_e_mps) == s.course_known for s in samples if s.fix_ok), path.name
        n += 1
    assert n >= 80


# ------------------------------------------------------------------------------------ receivers without NAV-PVT

def test_nav_sol_receiver_velocity_matches_gpsd_at_every_epoch():
    """u-blox 8 timing (NAV-SOL only): ECEF velocity -> north/east at the ECEF position, GPS time -> UTC."""
    samples, parser = parse_all(capture_bytes(GPSD / "ublox-8-time.log"))
    tpv = tpv_by_time(GPSD / "ublox-8-time.tpv.jsonl")
    by_time = {round(s.fix_time_utc_s, 2): s for s in samples}
    assert len(tpv) == 89 and all(s.protocol == "ubx" for s in samples)
    for when, d in tpv.items():
        s = by_time[round(when, 2)]  # NAV-SOL's fTOW puts the epoch 0.1 ms before the second
        assert s.fix_ok and s.fix_type == d["mode"]
        assert s.speed_mps == pytest.approx(d["speed"], abs=0.011)  # cm/s resolution per axis
        assert s.lat_deg == pytest.approx(45.2185, abs=1e-3) and s.lon_deg == pytest.approx(5.8072, abs=1e-3)


def test_hnr_pvt_gives_velocity_when_no_nav_pvt_comes():
    """u-blox M8L: HNR-PVT at 10 Hz; with the NAV-PVT frames removed it is the velocity source."""
    data = capture_bytes(GPSD / "ublox-neo-m8l.log")
    frames = [raw for raw, m in UBXReader(io.BytesIO(data), protfilter=UBX_PROTOCOL, quitonerror=0)
              if m is not None and m.identity != "NAV-PVT"]
    samples, _ = parse_all(b"".join(frames))
    gpsd: dict[float, list[float]] = {}  # gpsd reports an HNR and a NAV TPV at some epochs
    for line in (GPSD / "ublox-neo-m8l.tpv.jsonl").read_text().splitlines():
        d = json.loads(line)
        if "time" in d and "speed" in d:
            when = datetime.fromisoformat(d["time"].replace("Z", "+00:00")).timestamp()
            gpsd.setdefault(round(when, 3), []).append(d["speed"])
    assert len(samples) == 189 and all(s.fix_ok and s.protocol == "ubx" for s in samples)
    for s in samples:  # every HNR epoch is one gpsd reported, at its speed (6 cm/s: HNR/NAV mix)
        assert min(abs(v - s.speed_mps) for v in gpsd[round(s.fix_time_utc_s, 3)]) <= 0.06


@pytest.mark.skipif(not (SHARED / "gpsd").is_dir(), reason=f"{SHARED / 'gpsd'} not present")
def test_share_of_gpsd_speed_epochs_matched_over_all_shared_captures():
    """tools/score_gnss_captures.py: 74.4 % before issue 9's GNSS items (1244 of 1671 with the same
    definition), 85.9 % after; the rest is gpsd's own speed (quectel, boat), HNR/NAV mixing (M8L)."""
    from tools_import import load_tool
    score = load_tool("score_gnss_captures")
    scores = score.score_dir(SHARED / "gpsd")
    total, hit = sum(n for n, _ in scores.values()), sum(m for _, m in scores.values())
    assert len(scores) == 72 and total == 1671
    assert hit / total >= 0.85
    assert scores["nmea-fuzzy-cases"] == (14, 14) and scores["ublox-8-time"] == (89, 89)


# ------------------------------------------------------------------------------------ why no velocity

@pytest.mark.parametrize("path, why", [
    (GPSD / "ublox-lea-5q.log", "no usable fix in any of its 10 epochs"),                # RMC status V
    (GPSD / "garmin-geko201.log", "no usable fix in any of its 18 epochs"),              # mode S: simulator
    (PYUBX2 / "2023-4-17_82912_serial-COM3.ubx", "no usable fix in any of its 90 epochs"),
])
def test_a_capture_without_a_fix_says_so(path, why):
    _, parser = parse_all(capture_bytes(path))
    assert parser.fixes == 0 and parser.why_unusable().startswith(why)


@pytest.mark.skipif(not (SHARED / "gpsd").is_dir(), reason=f"{SHARED / 'gpsd'} not present")
@pytest.mark.parametrize("name, listed", [
    ("ublox-ned-m8t-sbfrx3.log", "(RXM-SFRBX x165)"),                  # raw subframes only
    ("ublox-x20p.log", "(RXM-SFRBX x408, NAV-TIMEGPS x29"),            # satellites and time, no solution
    ("ublox-zoe-m8b-logretrieve.log", "LOG-RETRIEVEPOS x34)"),         # a log read back, not a live fix
])
def test_a_receiver_sending_no_velocity_message_is_told_which_to_enable(name, listed):
    """Before: nothing to say but "0 of 553 frames used"."""
    samples, parser = parse_all(capture_bytes(SHARED / "gpsd" / name))
    why = parser.why_unusable()
    assert not samples and why.startswith("no velocity message: none of UBX NAV-PVT, NAV-SOL, HNR-PVT, NAV-VELNED"
                                          " or NMEA RMC, VTG among its")
    assert listed in why and why.endswith("enable one on the receiver")


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} not present")
def test_every_shared_capture_yields_a_fix_or_says_why_not():
    said = {}
    for path in sorted(SHARED.glob("*/*")):
        if path.suffix in (".chk", ".csv") or "LICENSE" in path.name:
            continue
        samples, parser = parse_all(capture_bytes(path))
        fixes = sum(1 for s in samples if getattr(s, "speed_mps", None) is not None and s.fix_ok)
        assert parser.fixes == fixes, path.name
        assert (parser.why_unusable() is None) == (fixes > 0), path.name
        if not fixes:
            said[path.name] = parser.why_unusable()
    assert len(said) == 9 and all(len(w) < 300 and "\n" not in w for w in said.values()), said


def test_nav_velned_without_its_fix_state_says_which_message_to_enable():
    """A u-blox 6/7 set up for NAV-VELNED alone: the velocity is there, its fix state is not (NAV-STATUS
    or NAV-SOL of the same epoch); with NAV-STATUS each epoch gives a sample."""
    from pyubx2 import GET, UBXMessage

    def velned(itow):
        return UBXMessage("NAV", "NAV-VELNED", GET, iTOW=itow, velN=1000, velE=200, velD=0, speed=1020,
                          gSpeed=1020, heading=11.3, sAcc=30, cAcc=1.0).serialize()

    alone = b"".join(velned(1000 * k) for k in range(5))
    samples, parser = parse_all(alone)
    assert not samples and parser.why_unusable() == (
        "5 NAV-VELNED without a NAV-STATUS or NAV-SOL of the same epoch (the fix state it needs);"
        " enable NAV-STATUS, or NAV-PVT")
    paired = b"".join(UBXMessage("NAV", "NAV-STATUS", GET, iTOW=1000 * k, gpsFix=3, gpsFixOk=1).serialize()
                      + velned(1000 * k) for k in range(5))
    samples, parser = parse_all(paired)
    assert len(samples) == 5 and all(s.fix_ok and s.vel_n_mps == 10.0 for s in samples)
    assert parser.why_unusable() is None
