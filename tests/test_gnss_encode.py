"""The encoders produce what real receivers send: checked by decoding with pyubx2 / pynmea2 directly."""
from __future__ import annotations

import io
import math
import struct
from datetime import datetime, timezone

import pynmea2
import pytest
from hypothesis import given, settings, strategies as st
from pyubx2 import UBX_PROTOCOL, UBXReader

from ecu_daemon.gnss import encode


def _read_ubx(frame: bytes):
    raw, msg = UBXReader(io.BytesIO(frame), protfilter=UBX_PROTOCOL, quitonerror=2).read()
    assert raw == frame
    return msg


def test_utc_fields_gps_week_and_leap_seconds():
    f = encode.utc_fields(1700000000.25)  # Tue 2023-11-14 22:13:20.25 UTC
    assert (f["year"], f["month"], f["day"], f["hour"], f["minute"], f["second"]) == (2023, 11, 14, 22, 13, 20)
    assert f["nano"] == 250_000_000
    assert f["itow_ms"] == (2 * 86400 + 22 * 3600 + 13 * 60 + 20 + 18) * 1000 + 250
    assert encode.posix_from_fields(**{k: v for k, v in f.items() if k != "itow_ms"}) == pytest.approx(1700000000.25)


def test_nav_pvt_wire_units_are_mm_per_s_and_1e7_deg():
    frame = encode.nav_pvt(**encode.utc_fields(1700000000.0), lat_deg=51.1234567, lon_deg=-1.7654321,
                           height_m=123.456, vel_n_mps=12.345, vel_e_mps=-3.21, vel_d_mps=0.5,
                           speed_acc_mps=0.25, head_acc_deg=1.5, num_sv=17, h_acc_m=0.8)
    assert frame[:6] == b"\xb5\x62\x01\x07\x5c\x00" and len(frame) == 100
    payload = frame[6:-2]
    # the u-blox interface description offsets, independent of pyubx2
    lon, lat, height = struct.unpack_from("<iii", payload, 24)
    vel_n, vel_e, vel_d, g_speed, head_mot, s_acc, head_acc = struct.unpack_from("<iiiiiII", payload, 48)
    assert (lat, lon, height) == (511234567, -17654321, 123456)
    assert (vel_n, vel_e, vel_d) == (12345, -3210, 500)
    assert g_speed == round(math.hypot(12.345, 3.21) * 1000)
    assert s_acc == 250 and head_acc == 150000
    assert head_mot == round((math.degrees(math.atan2(-3.21, 12.345)) % 360) * 1e5)
    assert payload[20] == 3 and payload[21] & 1 and payload[23] == 17  # fixType, gnssFixOk, numSV


@settings(max_examples=60, deadline=None)
@given(lat=st.floats(-89.9, 89.9), lon=st.floats(-179.9, 179.9), vn=st.floats(-80, 80), ve=st.floats(-80, 80),
       sacc=st.floats(0.01, 5), fix=st.integers(0, 5), ok=st.booleans(), t=st.floats(1.3e9, 2.0e9))
def test_nav_pvt_round_trips_through_pyubx2(lat, lon, vn, ve, sacc, fix, ok, t):
    f = encode.utc_fields(t)
    msg = _read_ubx(encode.nav_pvt(**f, lat_deg=lat, lon_deg=lon, vel_n_mps=vn, vel_e_mps=ve,
                                   speed_acc_mps=sacc, fix_type=fix, fix_ok=ok))
    assert msg.identity == "NAV-PVT"
    assert msg.lat == pytest.approx(lat, abs=0.6e-7) and msg.lon == pytest.approx(lon, abs=0.6e-7)
    assert msg.velN == round(vn * 1000) and msg.velE == round(ve * 1000)
    assert msg.gSpeed == round(math.hypot(vn, ve) * 1000)
    assert msg.sAcc == round(sacc * 1000)
    assert msg.fixType == fix and msg.gnssFixOk == int(ok)
    assert msg.iTOW == f["itow_ms"] and msg.nano == f["nano"]
    assert 0 <= msg.headMot < 360.0


def test_nav_velned_is_centimetres_per_second():
    msg = _read_ubx(encode.nav_velned(itow_ms=1000, vel_n_mps=12.34, vel_e_mps=-5.67, speed_acc_mps=0.4))
    assert (msg.velN, msg.velE, msg.sAcc) == (1234, -567, 40)


def _nmea(sentence: str):
    assert not sentence.endswith(("\r", "\n"))
    return pynmea2.parse(sentence, check=True)


@settings(max_examples=60, deadline=None)
@given(lat=st.floats(-89.99, 89.99), lon=st.floats(-179.99, 179.99), v=st.floats(0, 90),
       course=st.floats(0, 359.99), t=st.floats(1.3e9, 2.0e9))
def test_rmc_vtg_round_trip(lat, lon, v, course, t):
    rmc = _nmea(encode.nmea_rmc(utc=t, lat_deg=lat, lon_deg=lon, speed_mps=v, course_deg=course))
    assert rmc.talker == "GN" and rmc.status == "A" and rmc.mode_indicator == "A" and rmc.nav_status == "V"
    assert rmc.spd_over_grnd / encode.KNOTS_PER_MPS == pytest.approx(v, abs=0.0003)  # 3 decimals of knots
    assert 0 <= rmc.true_course < 360
    assert math.remainder(rmc.true_course - course, 360) == pytest.approx(0, abs=0.0051)
    assert rmc.latitude == pytest.approx(lat, abs=1e-7) and rmc.longitude == pytest.approx(lon, abs=1e-7)
    rounded = round(t * 100) / 100
    got = datetime.combine(rmc.datestamp, rmc.timestamp).replace(tzinfo=timezone.utc).timestamp()
    assert got == pytest.approx(rounded, abs=1e-3)
    vtg = _nmea(encode.nmea_vtg(speed_mps=v, course_deg=course))
    assert float(vtg.spd_over_grnd_kts) / encode.KNOTS_PER_MPS == pytest.approx(v, abs=0.0003)
    assert vtg.spd_over_grnd_kmph / 3.6 == pytest.approx(v, abs=0.0002)
    assert vtg.faa_mode == "A"


def test_rmc_without_fix_has_empty_fields_and_rolls_date_with_rounding():
    s = encode.nmea_rmc(utc=datetime(2024, 2, 29, 23, 59, 59, 996000), lat_deg=None, lon_deg=None,
                        speed_mps=None, course_deg=None, valid=False, mode="N")
    assert s.startswith("$GNRMC,000000.00,V,,,,,,,010324,,,N,V*")
    msg = _nmea(s)
    assert msg.spd_over_grnd is None and msg.status == "V"


def test_gga_and_gst_round_trip():
    gga = _nmea(encode.nmea_gga(utc=1700000000.5, lat_deg=-33.5, lon_deg=151.25, quality=4, num_sv=23,
                                hdop=0.61, alt_m=41.2))
    assert (gga.gps_qual, gga.num_sats, gga.horizontal_dil) == (4, "23", "0.61")
    assert gga.latitude == pytest.approx(-33.5) and gga.longitude == pytest.approx(151.25)
    gst = _nmea(encode.nmea_gst(utc=1700000000.5, std_lat_m=0.7, std_lon_m=1.1, std_alt_m=1.9))
    assert (gst.std_dev_latitude, gst.std_dev_longitude, gst.std_dev_altitude) == (0.7, 1.1, 1.9)
