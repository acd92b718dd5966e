"""GnssStreamParser behaviour: framing robustness, chunking invariance, units, NMEA epochs, logging."""
from __future__ import annotations

import logging
import math
from datetime import datetime, timezone

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from pyubx2 import GET, UBXMessage

from ecu_daemon.gnss import GnssStreamParser
from ecu_daemon.gnss import encode as enc
from ecu_daemon.samples import FIX_3D, FIX_DR, FIX_NONE
from test_gnss_captures import GPSD, PYUBX2, capture_bytes, key, parse_all

T0 = 1700000000.0  # 2023-11-14 22:13:20 UTC


def pvt(t_utc: float, vn: float, ve: float, **kw) -> bytes:
    return enc.nav_pvt(**enc.utc_fields(t_utc), lat_deg=48.1, lon_deg=11.5, vel_n_mps=vn, vel_e_mps=ve, **kw)


def ublox_nmea_epoch(t_utc: float, speed: float, course: float | None, **kw) -> list[str]:
    """One epoch as a u-blox 8/9 prints it: RMC, VTG, GGA, GSA, GSV, GST."""
    return [
        enc.nmea_rmc(utc=t_utc, lat_deg=48.1, lon_deg=11.5, speed_mps=speed, course_deg=course, **kw),
        enc.nmea_vtg(speed_mps=speed, course_deg=course, mode=kw.get("mode", "A")),
        enc.nmea_gga(utc=t_utc, lat_deg=48.1, lon_deg=11.5, num_sv=17),
        "$GNGSA,A,3,13,16,21,15,10,29,27,20,,,,,1.05,0.64,0.83,1*03",  # verbatim from a ZED-F9P
        "$GPGSV,3,3,12,26,04,276,,27,15,218,31,29,24,004,13,30,00,159,,1*69",
        enc.nmea_gst(utc=t_utc, std_lat_m=0.6, std_lon_m=0.8),
    ]


def lines(sentences) -> bytes:
    return b"".join(s.encode() + b"\r\n" for s in sentences)


def synthetic_stream() -> bytes:
    """Real captures and encoder output back to back: NMEA epochs, UBX+NMEA+RTCM3, NAV-PVT."""
    parts = [capture_bytes(GPSD / "ublox-zed-f9p-nmea.log")[:2500].rsplit(b"\r\n", 1)[0] + b"\r\n"]
    for k in range(6):
        epoch = ublox_nmea_epoch(T0 + 0.1 * k, 8.0 + k, 30.0 * k)
        if k == 3:
            epoch[2] = epoch[2][:-1] + ("0" if epoch[2][-1] != "0" else "1")  # GGA checksum error
        parts.append(lines(epoch))
    parts.append(capture_bytes(PYUBX2 / "pygpsdata-MIXED-RTCM3.log"))
    for k in range(6):
        parts.append(pvt(T0 + 1 + 0.1 * k, 3.0 * k, -2.0 * k))
        parts.append(lines([enc.nmea_gga(utc=T0 + 1 + 0.1 * k, lat_deg=1.0, lon_deg=2.0)]))
    return b"".join(parts)


STREAM = synthetic_stream()


def feed_chunks(data: bytes, cuts: list[int], **kw):
    """Feed ``data`` cut at ``cuts``; each chunk's t is the index of its last byte.

    t is in bytes here, so the "prefer UBX for 2 s" window is widened to cover the whole stream
    (its effect must not depend on the made-up timestamps).
    """
    kw.setdefault("prefer_ubx_s", 1e9)
    parser = GnssStreamParser(**kw)
    out, start = [], 0
    for end in sorted(set(cuts) | {len(data)}):
        if end > start:
            out += parser.feed(end - 1, data[start:end])
            start = end
    return out + parser.finish(), parser


@pytest.fixture(scope="module")
def bytewise():
    """Reference: one byte per read, so each sample's t is the index of its last byte."""
    return feed_chunks(STREAM, list(range(1, len(STREAM))))


def test_reference_stream_is_what_we_think(bytewise):
    samples, parser = bytewise
    assert {s.protocol for s in samples} == {"ubx", "nmea"}
    assert parser.stats["rtcm_frames"] == 7 and parser.stats["checksum_errors"] == 1
    assert len(samples) == parser.stats["samples"] >= 6 + 6 + 1


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cuts=st.lists(st.integers(1, len(STREAM) - 1), max_size=200))
def test_any_chunking_gives_the_same_samples_and_counters(bytewise, cuts):
    ref, ref_parser = bytewise
    samples, parser = feed_chunks(STREAM, cuts)
    assert [key(s, with_t=False) for s in samples] == [key(s, with_t=False) for s in ref]
    ends = sorted(set(c - 1 for c in cuts) | {len(STREAM) - 1})
    # stamped with the read that completed the frame's last byte
    assert [s.t for s in samples] == [min(e for e in ends if e >= r.t) for r in ref]
    assert parser.stats == ref_parser.stats


def _frames_of(data: bytes) -> list[bytes]:
    frames: list[bytes] = []
    GnssStreamParser(raw_sink=lambda t, b: frames.append(b)).feed(0.0, data)
    assert b"".join(frames) == data
    return frames


STREAM_FRAMES = _frames_of(STREAM)
CLEAN = parse_all(STREAM, prefer_ubx_s=1e9)
JUNK = st.lists(st.sampled_from([b"\xb5", b"b", b"\xb5b\x01\x07", b"\xb5b\x06\x00\x20", b"$", b"$GNRMC,1",
                                 b"!", b"\xd3\x00", b"\xd3", b"*", b"\r", b"\n", b"\x00", b"\xff", b"G"]),
                max_size=6).map(b"".join)


@settings(max_examples=20, deadline=None)
@given(data=st.data())
def test_garbage_between_frames_loses_nothing(data):
    frames = STREAM_FRAMES
    noise = data.draw(st.lists(JUNK, min_size=len(frames) + 1, max_size=len(frames) + 1))
    stream = b"".join(n + f for n, f in zip(noise, frames + [b""]))
    cuts = data.draw(st.lists(st.integers(1, len(stream) - 1), max_size=30))
    samples, parser = feed_chunks(stream, cuts)
    clean, clean_parser = CLEAN
    assert [key(s, with_t=False) for s in samples] == [key(s, with_t=False) for s in clean]
    assert parser.stats["garbage_bytes"] == clean_parser.stats["garbage_bytes"] + sum(map(len, noise))
    assert parser.stats["ubx_frames"] == clean_parser.stats["ubx_frames"]
    assert parser.stats["nmea_sentences"] == clean_parser.stats["nmea_sentences"]


PVT_FRAMES = [pvt(T0 + 0.1 * i, float(i), -float(i)) for i in range(10)]
PVT_SAMPLES = parse_all(b"".join(PVT_FRAMES))[0]


@settings(max_examples=60, deadline=None)
@given(k=st.integers(0, 9), pos=st.integers(0, 99), xor=st.integers(1, 255))
def test_one_corrupted_byte_loses_only_that_frame(k, pos, xor):
    bad = bytearray(PVT_FRAMES[k])
    bad[pos] ^= xor
    samples, parser = parse_all(b"".join(PVT_FRAMES[:k] + [bytes(bad)] + PVT_FRAMES[k + 1:]))
    assert [key(s) for s in samples] == [key(s) for i, s in enumerate(PVT_SAMPLES) if i != k]
    assert parser.stats["checksum_errors"] + parser.stats["garbage_bytes"] + parser.stats["truncated"] > 0


# ------------------------------------------------------------------------------------ UBX content

def test_nav_pvt_units_mm_per_s_not_cm_per_s():
    (s,), _ = parse_all(pvt(T0 + 0.25, 12.345, -3.21, speed_acc_mps=0.27, h_acc_m=0.85, head_acc_deg=2.0))
    assert (s.vel_n_mps, s.vel_e_mps) == (12.345, -3.21)  # not 123.45 (cm/s) nor 0.012 (um/s)
    assert s.speed_acc_mps == 0.27 and s.h_acc_m == 0.85
    assert s.head_acc_rad == pytest.approx(math.radians(2.0))
    assert s.fix_time_utc_s == pytest.approx(T0 + 0.25, abs=1e-6)
    assert (s.fix_type, s.fix_ok, s.num_sv, s.protocol) == (FIX_3D, True, 12, "ubx")
    assert (s.lat_deg, s.lon_deg) == (48.1, 11.5)


def test_nav_velned_is_cm_per_s_and_needs_the_epoch_fix_state():
    status = UBXMessage("NAV", "NAV-STATUS", GET, iTOW=5000, gpsFix=3, gpsFixOk=1).serialize()
    vel = enc.nav_velned(itow_ms=5000, vel_n_mps=12.34, vel_e_mps=-5.67, speed_acc_mps=0.4)
    (s,), _ = parse_all(status + vel)
    assert (s.vel_n_mps, s.vel_e_mps, s.speed_acc_mps) == (12.34, -5.67, 0.4)
    assert s.fix_ok and s.fix_type == 3
    # a status more than 1 s older says nothing of this epoch's fix (ubx._STATUS_MAX_AGE_MS)
    other_epoch = enc.nav_velned(itow_ms=6200, vel_n_mps=1.0, vel_e_mps=0.0)
    assert parse_all(status + other_epoch)[0] == []
    # once NAV-PVT is seen, NAV-VELNED is redundant and ignored
    samples, _ = parse_all(pvt(T0, 1.0, 1.0) + status + vel)
    assert len(samples) == 1


def test_no_fix_and_invalid_time():
    (s,), _ = parse_all(pvt(T0, 0.0, 0.0, fix_type=0, fix_ok=False, valid_date=False, invalid_llh=True))
    assert not s.fix_ok and s.fix_type == FIX_NONE
    assert math.isnan(s.fix_time_utc_s) and math.isnan(s.lat_deg)


def test_checksum_valid_nav_pvt_of_wrong_length_is_malformed():
    # 84 bytes is u-blox 7's NAV-PVT and is decoded (test_ublox7_nav_pvt.py); 80 is no layout
    short = UBXMessage(b"\x01", b"\x07", GET, payload=bytes(80)).serialize()
    samples, parser = parse_all(short + pvt(T0, 1.0, 0.0))
    assert len(samples) == 1 and parser.stats["malformed"] == 1
    assert "NAV-PVT payload is 80 bytes" in parser.last_error


# ------------------------------------------------------------------------------------ NMEA epochs

def feed_lines(sentences, **kw):
    """Each sentence in its own read at t = its index; returns samples and the parser."""
    parser = GnssStreamParser(**kw)
    out = []
    for i, s in enumerate(sentences):
        out += parser.feed(float(i), s.encode() + b"\r\n")
    return out + parser.finish(), parser


def test_ublox_epochs_emit_at_rmc_with_gga_gst_of_the_previous_epoch():
    sentences = [s for k in range(3) for s in ublox_nmea_epoch(T0 + k, 20.0, 45.0)]
    samples, parser = feed_lines(sentences)
    assert [s.t for s in samples] == [0.0, 6.0, 12.0]  # the RMC's read, no waiting for GGA
    for k, s in enumerate(samples):
        assert s.vel_n_mps == pytest.approx(20 * math.cos(math.pi / 4), abs=3e-4)
        assert s.vel_e_mps == pytest.approx(20 * math.sin(math.pi / 4), abs=3e-4)
        assert math.isnan(s.speed_acc_mps) and s.fix_ok and s.fix_type == FIX_3D
        assert s.fix_time_utc_s == T0 + k and s.protocol == "nmea"
    assert samples[0].num_sv == 0 and [s.num_sv for s in samples[1:]] == [17, 17]
    assert samples[2].h_acc_m == pytest.approx(1.0)
    assert parser.stats["unsupported"] == 6  # GSA, GSV
    assert parser.stats["samples"] == 3 and parser.stats["nmea_sentences"] == 18


def test_course_less_epoch_publishes_its_speed_with_an_unknown_course_not_a_zero_vector():
    (s,), _ = feed_lines(ublox_nmea_epoch(T0, 2.5, None))
    assert s.fix_ok and not s.course_known
    assert s.speed_mps == pytest.approx(2.5, abs=1e-3) and s.ground_speed_mps == s.speed_mps
    assert math.isnan(s.vel_n_mps) and math.isnan(s.vel_e_mps)  # no false direction (nor zero)
    assert s.fix_time_utc_s == T0
    (s,), _ = feed_lines(ublox_nmea_epoch(T0, 0.0, 90.0))
    assert abs(s.vel_n_mps) < 1e-12 and s.vel_e_mps == 0.0 and math.isnan(s.speed_acc_mps)


def test_rmc_without_speed_waits_for_the_vtg_that_follows():
    rmc = enc.nmea_rmc(utc=T0, lat_deg=1, lon_deg=2, speed_mps=None, course_deg=None)
    prev = ublox_nmea_epoch(T0 - 1, 5.0, 0.0)  # teaches the parser that this receiver sends VTG
    vtg = enc.nmea_vtg(speed_mps=5.0, course_deg=180.0)
    samples, _ = feed_lines(prev + [rmc, vtg])
    s = samples[-1]
    assert s.t == len(prev) + 1 and s.vel_n_mps == pytest.approx(-5.0, abs=3e-4) and s.fix_ok


def test_vtg_only_stream():
    sentences = []
    for k in range(3):
        sentences += [enc.nmea_gga(utc=T0 + k, lat_deg=1, lon_deg=2), enc.nmea_vtg(speed_mps=3.0, course_deg=270.0)]
    samples, _ = feed_lines(sentences)  # one sentence per second: the pause after each VTG ends its epoch
    assert len(samples) == 3 and all(s.fix_ok and s.vel_e_mps == pytest.approx(-3.0, abs=3e-4) for s in samples)
    assert all(math.isnan(s.fix_time_utc_s) for s in samples)  # neither VTG nor GGA carries the date
    assert [s.num_sv for s in samples] == [12, 12, 12]


@pytest.mark.parametrize("order", ["vtg_first", "vtg_last"])
def test_vtg_only_stream_takes_the_time_of_its_epoch_from_gga_and_zda(order):
    """VTG has no time field: the epoch's GGA/ZDA date it, whether VTG leads or ends the epoch."""
    sentences, times = [], []
    for k in range(3):
        utc = T0 + 86400 * 3 + k  # the ZDA date must be used, not a constant
        timed = [enc.nmea_gga(utc=utc, lat_deg=1, lon_deg=2), enc.nmea_zda(utc=utc)]
        vtg = enc.nmea_vtg(speed_mps=3.0 + k, course_deg=270.0)
        epoch = [vtg] + timed if order == "vtg_first" else timed + [vtg]
        # a burst per epoch: sentences 10 ms apart, epochs 1 s apart (receive time)
        sentences += epoch
        times += [k + 0.01 * i for i in range(len(epoch))]
    parser = GnssStreamParser()
    samples = [s for t, line in zip(times, sentences) for s in parser.feed(t, (line + "\r\n").encode())]
    samples += parser.finish()
    assert [round(s.speed_mps, 3) for s in samples] == [3.0, 4.0, 5.0]
    utc = [s.fix_time_utc_s for s in samples]
    if order == "vtg_first":  # emitted at the GGA: the very first epoch's ZDA has not come yet
        assert math.isnan(utc.pop(0)) and utc == [T0 + 86400 * 3 + k for k in (1, 2)]
    else:
        assert utc == [T0 + 86400 * 3 + k for k in range(3)]
    assert all(s.fix_ok and s.num_sv == 12 for s in samples)


@pytest.mark.parametrize("kw, fix_type, fix_ok", [
    (dict(valid=True, mode="A"), FIX_3D, True),
    (dict(valid=True, mode="D"), FIX_3D, True),
    (dict(valid=True, mode="E"), FIX_DR, True),      # dead reckoning: min_fix_type decides
    (dict(valid=True, mode="N"), FIX_NONE, False),
    (dict(valid=False, mode="A"), FIX_NONE, False),
    (dict(valid=True, mode="S"), FIX_NONE, False),   # simulator
    (dict(valid=True, mode=None), FIX_3D, True),     # NMEA 2.2: no mode field
])
def test_rmc_validity_ignores_nav_status_and_uses_status_and_mode(kw, fix_type, fix_ok):
    (s,), _ = feed_lines([enc.nmea_rmc(utc=T0, lat_deg=1, lon_deg=2, speed_mps=1, course_deg=0, **kw)])
    assert (s.fix_type, s.fix_ok) == (fix_type, fix_ok)


def test_multi_talker_streams_give_one_sample_per_epoch():
    gp = [enc.nmea_rmc(utc=T0 + k, lat_deg=1, lon_deg=2, speed_mps=1, course_deg=0, talker="GP") for k in range(2)]
    ga = [enc.nmea_rmc(utc=T0 + k, lat_deg=1, lon_deg=2, speed_mps=9, course_deg=0, talker="GA") for k in range(2)]
    samples, parser = feed_lines([gp[0], ga[0], gp[1], ga[1]])
    assert [round(s.vel_n_mps, 3) for s in samples] == [1.0, 1.0] and parser.stats["ignored"] == 2


def test_talker_switching_receiver_keeps_every_epoch():
    """Trimble switches GN -> GP -> GN between epochs: epochs are assembled by time, not talker."""
    talkers = ["GN", "GP", "GP", "GN", "GL", "GN"]
    lines = [enc.nmea_rmc(utc=T0 + k, lat_deg=1, lon_deg=2, speed_mps=k, course_deg=0, talker=tk)
             for k, tk in enumerate(talkers)]
    samples, parser = feed_lines(lines)
    assert [round(s.vel_n_mps, 3) for s in samples] == list(range(6))
    assert [s.fix_time_utc_s for s in samples] == [T0 + k for k in range(6)] and parser.stats["ignored"] == 0


def _with_checksum(body: str) -> str:
    ck = 0
    for c in body[1:]:
        ck ^= ord(c)
    return f"{body}*{ck:02X}"


def test_checksum_valid_garbled_number_is_malformed_not_a_string_velocity():
    bad = _with_checksum("$GNRMC,221320.00,A,4807.03800,N,01131.00000,E,0.0x7,12.0,141123,,,A,V")
    good = enc.nmea_rmc(utc=T0 + 1, lat_deg=1, lon_deg=2, speed_mps=1, course_deg=0)
    samples, parser = feed_lines([bad, good])
    assert len(samples) == 1 and parser.stats["malformed"] == 1
    assert "spd_over_grnd" in parser.last_error and "0.0x7" in parser.last_error


def test_missing_and_wrong_nmea_checksums_are_counted():
    rmc = enc.nmea_rmc(utc=T0, lat_deg=1, lon_deg=2, speed_mps=1, course_deg=0)
    samples, parser = feed_lines([rmc[:-3], rmc[:-1] + ("0" if rmc[-1] != "0" else "1"), rmc])
    assert len(samples) == 1 and parser.stats["checksum_errors"] == 2
    assert parser.stats["garbage_bytes"] == len(rmc) - 3 + 2 + len(rmc) + 2


def test_auto_prefers_ubx_when_one_receiver_sends_both():
    stream = b""
    for k in range(3):
        stream += pvt(T0 + k, 1.0, 0.0) + lines(ublox_nmea_epoch(T0 + k, 1.0, 0.0))
    samples, parser = feed_chunks(stream, [])
    assert [s.protocol for s in samples] == ["ubx"] * 3 and parser.stats["suppressed"] == 3


# ------------------------------------------------------------------------------------ logging, state

def test_one_log_line_per_error_kind_rate_limited(caplog):
    good = pvt(T0, 1.0, 0.0)
    bad = good[:-1] + bytes([good[-1] ^ 0xFF])
    parser = GnssStreamParser(name="gnss ttyACM0")
    with caplog.at_level(logging.WARNING, logger="ecu_daemon.gnss"):
        for i in range(50):
            parser.feed(i * 0.1, bad + good)
        parser.feed(11.0, bad + good)
    assert parser.stats["checksum_errors"] == 51 and parser.stats["samples"] == 51
    checksum_lines = [r.getMessage() for r in caplog.records if "checksum" in r.getMessage()]
    assert len(checksum_lines) == 2
    assert checksum_lines[0].startswith("gnss ttyACM0: UBX 01 07 checksum error")
    assert "+49 more" in checksum_lines[1]
    assert all("\n" not in r.getMessage() and r.exc_info is None for r in caplog.records)


def test_finish_resolves_a_bogus_length_and_parser_stays_usable():
    good = pvt(T0, 1.0, 0.0)
    bogus = b"\xb5\x62\x01\x07\x00\x10"  # claims a 4096-byte payload
    parser = GnssStreamParser()
    assert parser.feed(1.0, bogus + good) == []  # waits: the header might be real
    samples = parser.finish()
    assert len(samples) == 1 and samples[0].t == 1.0 and parser.stats["truncated"] == 1
    assert len(parser.feed(2.0, good)) == 1


def test_bogus_length_resolves_by_itself_once_enough_bytes_arrive():
    good = [pvt(T0 + k, float(k), 0.0) for k in range(3)]
    bogus = b"\xb5\x62\x01\x07\x20\x00"  # claims 32 bytes: shorter than the good frames behind it
    parser = GnssStreamParser()
    out = parser.feed(1.0, bogus + good[0]) + parser.feed(2.0, good[1]) + parser.feed(3.0, good[2])
    assert [s.t for s in out] == [1.0, 2.0, 3.0]
    assert parser.stats["checksum_errors"] == 1 and parser.stats["garbage_bytes"] == len(bogus)


def test_invalid_protocol_is_rejected():
    with pytest.raises(ValueError, match="protocol"):
        GnssStreamParser(protocol="sirf")


def test_rmc_date_and_time_give_the_utc_epoch():
    when = datetime(2024, 2, 29, 23, 59, 58, 500000, tzinfo=timezone.utc)
    (s,), _ = feed_lines([enc.nmea_rmc(utc=when, lat_deg=-33.5, lon_deg=151.25, speed_mps=1, course_deg=0)])
    assert s.fix_time_utc_s == pytest.approx(when.timestamp(), abs=1e-6)
    assert (s.lat_deg, s.lon_deg) == (pytest.approx(-33.5), pytest.approx(151.25))


FIELD = st.text(alphabet="0123456789.-+ABCDEFNSEWVTMKxyz", max_size=12)


@settings(max_examples=100, deadline=None)
@given(kind=st.sampled_from(["GNRMC", "GPVTG", "GNGGA", "GNGST", "GPRMC"]),
       fields=st.lists(FIELD, max_size=15))
def test_checksum_valid_nonsense_never_raises_and_never_gives_a_valid_nan(kind, fields):
    """Whatever a receiver (or a bug) puts in the fields: a counted error or a sane sample."""
    good = enc.nmea_rmc(utc=T0, lat_deg=1, lon_deg=2, speed_mps=1, course_deg=0)
    samples, parser = feed_lines([_with_checksum("$" + ",".join([kind] + fields)), good])
    assert parser.stats["nmea_sentences"] == 2
    assert samples[-1].fix_time_utc_s == T0  # the good sentence after it still parses
    for s in samples:  # a speed without a course is a course-less epoch: its ground speed is the number
        assert not s.fix_ok or (math.isfinite(s.vel_n_mps) and math.isfinite(s.vel_e_mps)) or (
            not s.course_known and math.isfinite(s.ground_speed_mps))


@pytest.mark.parametrize("bad_date", ["310219", "1A0320", "000000"])
def test_one_bad_rmc_field_drops_that_field_not_the_velocity(bad_date):
    """A corrupt date (or position) is reported once; the epoch's velocity is still published."""
    good = enc.nmea_rmc(utc=T0, lat_deg=1, lon_deg=2, speed_mps=5, course_deg=90)
    f = enc.nmea_rmc(utc=T0 + 1, lat_deg=1, lon_deg=2, speed_mps=6, course_deg=90)[1:-3].split(",")
    f[9] = bad_date
    f[3] = "99x9.0"  # and a latitude that is no number
    samples, parser = feed_lines([good, _with_checksum("$" + ",".join(f))])
    assert [round(s.vel_e_mps, 3) for s in samples] == [5.0, 6.0] and all(s.fix_ok for s in samples)
    assert samples[1].fix_time_utc_s == T0 + 1  # the date of the previous epoch, the sentence's time
    assert math.isnan(samples[1].lat_deg) and math.isnan(samples[1].lon_deg)
    assert parser.stats["malformed"] == 2 and "date dropped" in parser.last_error  # position, then date


def test_nav_sol_is_released_by_time_when_no_frame_follows_it():
    """A receiver whose epoch ends with NAV-SOL: the sample does not wait for the next epoch."""
    from pyubx2 import GET, UBXMessage

    lon = math.atan2(45537294, 447748408)  # a real u-blox 8 position (ublox-8-time), cm
    sol = UBXMessage("NAV", "NAV-SOL", GET, iTOW=1000, week=2300, gpsFix=3, gpsfixOK=1, wknSet=1, towSet=1,
                     ecefX=447748408, ecefY=45537294, ecefZ=450468730, ecefVX=round(-math.sin(lon) * 300),
                     ecefVY=round(math.cos(lon) * 300), ecefVZ=0, sAcc=20, numSV=9).serialize()  # 3 m/s east
    parser = GnssStreamParser()
    assert parser.feed(10.0, sol) == []  # held: a NAV-PVT of this epoch may follow
    assert parser.feed(10.1, b"\x00") == []
    (s,) = parser.feed(10.3, b"\x00")  # 0.3 s later, nothing came: released
    assert s.t == 10.0 and s.fix_ok and s.num_sv == 9 and s.speed_acc_mps == pytest.approx(0.2)
    assert s.vel_e_mps == pytest.approx(3.0, abs=0.01) and s.vel_n_mps == pytest.approx(0.0, abs=0.01)
    assert s.fix_time_utc_s == 315964800 + 2300 * 604800 + 1.0 - 18


def test_a_vtg_with_a_speed_and_no_course_is_a_course_less_epoch_not_a_nan_velocity():
    """Hypothesis found ``$GPVTG,,,,,0``: a valid speed, a blank course. The sample is usable for its
    speed (course_known False, ground speed 0) and never claims a direction."""
    good = enc.nmea_rmc(utc=T0, lat_deg=1, lon_deg=2, speed_mps=1, course_deg=0)
    samples, _ = feed_lines([_with_checksum("$GPVTG,,,,,0"), good])
    s = samples[0]
    assert s.fix_ok and not s.course_known and s.ground_speed_mps == 0.0
    assert math.isnan(s.vel_n_mps) and math.isnan(s.vel_e_mps)
