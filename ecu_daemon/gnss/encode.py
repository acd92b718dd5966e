"""Encoders for realistic receiver output: UBX NAV-PVT / NAV-RELPOSNED frames and NMEA RMC/VTG/GGA/GST/HDT/THS sentences.

Used by the vehicle simulator and by tests, so that everything downstream (parser, capture log,
estimator) sees byte streams shaped like a real u-blox receiver's. Inputs are SI (m/s, m,
degrees for angles as the protocols use them); the encoders do the protocol unit conversions
(mm/s, 1e-7 deg, 1e-5 deg, knots) exactly once, here.

UBX frames are built by pyubx2's ``UBXMessage`` (it does the packing and the Fletcher checksum).
One pyubx2 quirk is handled here: it converts scaled values with ``int(value / resolution)``,
which truncates (51.1234567 deg -> 511234566), so scaled fields are passed nudged by a quarter
of one resolution step away from zero, making the truncation land on the nearest integer.
NMEA sentences are rendered by pynmea2 (which appends the ``*hh`` checksum), without CR/LF.
"""
from __future__ import annotations

import calendar
import math
from datetime import datetime, timedelta, timezone

import pynmea2
from pyubx2 import GET, UBXMessage

from .nmea import THS  # noqa: F401  (registers THS with pynmea2 for rendering)

__all__ = [
    "GPS_LEAP_SECONDS",
    "KNOTS_PER_MPS",
    "utc_fields",
    "nav_pvt",
    "nav_velned",
    "nav_relposned",
    "nmea_hdt",
    "nmea_ths",
    "nmea_rmc",
    "nmea_vtg",
    "nmea_gga",
    "nmea_gst",
    "posix_from_fields",
]

#: GPS time minus UTC since 2017-01-01 (iTOW is GPS time of week).
GPS_LEAP_SECONDS = 18
#: 1 knot = 1852 m / 3600 s exactly.
KNOTS_PER_MPS = 3600.0 / 1852.0
_GPS_EPOCH = datetime(1980, 1, 6, tzinfo=timezone.utc)


def _as_datetime(utc: datetime | float) -> datetime:
    """UTC as an aware datetime; a number is POSIX seconds."""
    if isinstance(utc, datetime):
        return utc if utc.tzinfo else utc.replace(tzinfo=timezone.utc)
    return datetime(1970, 1, 1, tzinfo=timezone.utc) + timedelta(microseconds=round(float(utc) * 1e6))


def utc_fields(utc: datetime | float) -> dict:
    """The time keyword arguments of :func:`nav_pvt` for a UTC instant (datetime or POSIX seconds).

    ``itow_ms`` is GPS time of week (UTC + 18 leap seconds); ``nano`` carries the sub-second part
    so that ``second + nano * 1e-9`` is the exact UTC second, as u-blox reports it.
    """
    dt = _as_datetime(utc)
    gps = dt - _GPS_EPOCH + timedelta(seconds=GPS_LEAP_SECONDS)
    week_ms = (gps.days % 7) * 86_400_000 + gps.seconds * 1000 + gps.microseconds // 1000
    return dict(itow_ms=week_ms, year=dt.year, month=dt.month, day=dt.day, hour=dt.hour,
                minute=dt.minute, second=dt.second, nano=dt.microsecond * 1000)


def _scaled(value: float, resolution: float) -> float:
    """``value`` rounded to the ``resolution`` grid, nudged so pyubx2's int() truncation is exact."""
    n = round(value / resolution)
    return n * resolution + math.copysign(0.25 * resolution, n) if n else 0.0


def nav_pvt(*, itow_ms: int, year: int, month: int, day: int, hour: int, minute: int, second: int,
            nano: int = 0, fix_type: int = 3, fix_ok: bool = True, num_sv: int = 12,
            lat_deg: float, lon_deg: float, height_m: float = 0.0, hmsl_m: float | None = None,
            h_acc_m: float = 1.5, v_acc_m: float = 2.5,
            vel_n_mps: float, vel_e_mps: float, vel_d_mps: float = 0.0,
            speed_acc_mps: float = 0.3, head_mot_deg: float | None = None,
            head_acc_deg: float | None = None, p_dop: float = 1.2, t_acc_ns: int = 20,
            valid_date: bool = True, valid_time: bool = True, fully_resolved: bool = True,
            diff_soln: bool = False, carr_soln: int = 0, invalid_llh: bool = False,
            head_veh_deg: float = 0.0) -> bytes:
    """A complete UBX NAV-PVT frame (B5 62 01 07, 92-byte payload, checksum) as u-blox sends it.

    Units in: m/s, m, degrees. On the wire: velN/velE/velD/gSpeed/sAcc mm/s, lat/lon 1e-7 deg,
    height/hMSL/hAcc/vAcc mm, headMot/headAcc/headVeh 1e-5 deg, pDOP 0.01. ``gSpeed`` is the
    horizontal speed. ``head_mot_deg`` defaults to the course of (vel_n, vel_e) in [0, 360);
    ``head_acc_deg`` defaults to ``atan2(speed_acc, gSpeed)`` (large when nearly stationary, as
    real receivers report it).
    """
    g_speed = math.hypot(vel_n_mps, vel_e_mps)
    if head_mot_deg is None:
        head_mot_deg = round(math.degrees(math.atan2(vel_e_mps, vel_n_mps)) % 360.0, 5) % 360.0
    if head_acc_deg is None:
        head_acc_deg = min(180.0, math.degrees(math.atan2(speed_acc_mps, g_speed)))
    mm = lambda x: int(round(x * 1000.0))  # noqa: E731
    msg = UBXMessage(
        "NAV", "NAV-PVT", GET,
        iTOW=int(itow_ms), year=int(year), month=int(month), day=int(day), hour=int(hour),
        min=int(minute), second=int(second),
        validDate=int(valid_date), validTime=int(valid_time), fullyResolved=int(fully_resolved),
        tAcc=int(t_acc_ns), nano=int(nano), fixType=int(fix_type),
        gnssFixOk=int(fix_ok), diffSoln=int(diff_soln), carrSoln=int(carr_soln),
        numSV=int(num_sv),
        lon=_scaled(lon_deg, 1e-7), lat=_scaled(lat_deg, 1e-7),
        height=mm(height_m), hMSL=mm(height_m if hmsl_m is None else hmsl_m),
        hAcc=mm(h_acc_m), vAcc=mm(v_acc_m),
        velN=mm(vel_n_mps), velE=mm(vel_e_mps), velD=mm(vel_d_mps), gSpeed=mm(g_speed),
        headMot=_scaled(head_mot_deg, 1e-5), sAcc=mm(speed_acc_mps),
        headAcc=_scaled(head_acc_deg, 1e-5), pDOP=_scaled(p_dop, 1e-2),
        invalidLlh=int(invalid_llh), headVeh=_scaled(head_veh_deg, 1e-5),
    )
    return msg.serialize()


def nav_velned(*, itow_ms: int, vel_n_mps: float, vel_e_mps: float, vel_d_mps: float = 0.0,
               speed_acc_mps: float = 0.3, heading_deg: float | None = None,
               head_acc_deg: float = 5.0) -> bytes:
    """A UBX NAV-VELNED frame (01 12). Note the legacy units: velocities and sAcc in **cm/s**."""
    g_speed = math.hypot(vel_n_mps, vel_e_mps)
    if heading_deg is None:
        heading_deg = math.degrees(math.atan2(vel_e_mps, vel_n_mps)) % 360.0
    cm = lambda x: int(round(x * 100.0))  # noqa: E731
    msg = UBXMessage(
        "NAV", "NAV-VELNED", GET, iTOW=int(itow_ms), velN=cm(vel_n_mps), velE=cm(vel_e_mps),
        velD=cm(vel_d_mps), speed=cm(math.hypot(g_speed, vel_d_mps)), gSpeed=cm(g_speed),
        heading=_scaled(heading_deg, 1e-5), sAcc=cm(speed_acc_mps), cAcc=_scaled(head_acc_deg, 1e-5),
    )
    return msg.serialize()


# ---------------------------------------------------------------------------------------- NMEA

def _hms(dt: datetime) -> str:
    """hhmmss.ss with the centiseconds rounded (u-blox prints two decimals)."""
    cs = round((dt.hour * 3600 + dt.minute * 60 + dt.second + dt.microsecond * 1e-6) * 100)
    cs %= 8_640_000
    s, cs = divmod(cs, 100)
    return f"{s // 3600:02d}{s // 60 % 60:02d}{s % 60:02d}.{cs:02d}"


def _latlon(value: float | None, deg_digits: int, pos: str, neg: str) -> tuple[str, str]:
    """(d)ddmm.mmmmm and hemisphere, rounded in units of 1e-5 minute so 60.00000 never appears."""
    if value is None or not math.isfinite(value):
        return "", ""
    units = round(abs(value) * 60 * 100_000)
    deg, rem = divmod(units, 60 * 100_000)
    minutes, frac = divmod(rem, 100_000)
    return f"{deg:0{deg_digits}d}{minutes:02d}.{frac:05d}", (pos if value >= 0 else neg)


def _num(value: float | None, decimals: int) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value:.{decimals}f}"


def nav_relposned(*, itow_ms: int, heading_deg: float, baseline_m: float, head_acc_deg: float = 0.3,
                  length_acc_m: float = 0.01, fix_ok: bool = True, rel_pos_valid: bool = True,
                  heading_valid: bool = True, carr_soln: int = 2, down_m: float = 0.0,
                  down_acc_m: float | None = None) -> bytes:
    """A UBX NAV-RELPOSNED version 1 frame (01 3C, 64 bytes) as an F9P moving-base rover sends it.

    ``heading_deg``: baseline heading, clockwise from north; ``baseline_m`` its horizontal length
    (N/E components follow), ``down_m`` the rover antenna below the base (NED down) and
    ``down_acc_m`` its 1-sigma (accD; default ``length_acc_m`` as for N/E). On the wire: relPosN/E/D/Length cm + 0.1 mm high-precision parts,
    relPosHeading/accHeading 1e-5 deg, accLength 0.1 mm.
    """
    h = math.radians(heading_deg)
    cm = {}
    for key, v in (("N", baseline_m * math.cos(h)), ("E", baseline_m * math.sin(h)), ("D", down_m),
                   ("Length", math.hypot(baseline_m, down_m))):
        hp = round(v * 10000.0)  # 0.1 mm
        whole = int(hp / 100)  # toward zero: the high-precision part keeps the sign
        cm[f"relPos{key}"] = whole
        cm[f"_HPrelPos{key}"] = _scaled((hp - whole * 100) * 0.01, 0.01)
    msg = UBXMessage(
        "NAV", "NAV-RELPOSNED", GET, version=1, iTOW=int(itow_ms), **cm,
        relPosHeading=_scaled(heading_deg % 360.0, 1e-5), accHeading=_scaled(head_acc_deg, 1e-5),
        accN=_scaled(length_acc_m * 1000.0, 0.1), accE=_scaled(length_acc_m * 1000.0, 0.1),
        accD=_scaled((length_acc_m if down_acc_m is None else down_acc_m) * 1000.0, 0.1), accLength=_scaled(length_acc_m * 1000.0, 0.1),
        gnssFixOK=int(fix_ok), diffSoln=1, relPosValid=int(rel_pos_valid), carrSoln=int(carr_soln),
        isMoving=1, relPosHeadingValid=int(heading_valid),
    )
    return msg.serialize()


def nmea_hdt(*, heading_deg: float | None, talker: str = "GP") -> str:
    """``$GPHDT``: true heading (2 decimals); ``None`` gives the empty field of no solution."""
    return _render(talker, "HDT", [_num(None if heading_deg is None else heading_deg % 360.0, 2), "T"])


def nmea_ths(*, heading_deg: float | None, mode: str = "A", talker: str = "GN") -> str:
    """``$GNTHS``: true heading (2 decimals) and mode (A autonomous, E estimated, V invalid ...)."""
    return _render(talker, "THS", [_num(None if heading_deg is None else heading_deg % 360.0, 2), mode])


def _render(talker: str, kind: str, fields: list[str]) -> str:
    return pynmea2.TalkerSentence.sentence_types[kind](talker, kind, tuple(fields)).render()


def nmea_rmc(*, utc: datetime | float, lat_deg: float | None, lon_deg: float | None,
             speed_mps: float | None, course_deg: float | None, valid: bool = True,
             mode: str | None = "A", nav_status: str | None = "V", talker: str = "GN") -> str:
    """``$GNRMC`` (NMEA 4.1 layout, as u-blox 8/9/10) with ``*hh`` checksum and no CR/LF.

    Speed goes out in knots with 3 decimals, course in degrees true with 2 decimals; ``None``
    gives an empty field (what receivers print without a fix). ``mode=None`` / ``nav_status=None``
    drop those trailing fields (NMEA 2.x layouts). u-blox always prints nav status ``V``.
    """
    dt = _as_datetime(utc)
    dt_c = dt + timedelta(microseconds=5000)  # date of the rounded time (23:59:59.996 -> next day)
    lat, ns = _latlon(lat_deg, 2, "N", "S")
    lon, ew = _latlon(lon_deg, 3, "E", "W")
    kn = None if speed_mps is None else speed_mps * KNOTS_PER_MPS
    course = None if course_deg is None else round(course_deg % 360.0, 2) % 360.0
    fields = [_hms(dt), "A" if valid else "V", lat, ns, lon, ew, _num(kn, 3), _num(course, 2),
              dt_c.strftime("%d%m%y"), "", ""]
    if mode is not None:
        fields.append(mode)
        if nav_status is not None:
            fields.append(nav_status)
    return _render(talker, "RMC", fields)


def nmea_vtg(*, speed_mps: float | None, course_deg: float | None, mode: str | None = "A",
             talker: str = "GN") -> str:
    """``$GNVTG``: course true (2 decimals), magnetic empty, speed in knots and km/h (3 decimals)."""
    course = None if course_deg is None else round(course_deg % 360.0, 2) % 360.0
    kn = None if speed_mps is None else speed_mps * KNOTS_PER_MPS
    kmh = None if speed_mps is None else speed_mps * 3.6
    fields = [_num(course, 2), "T", "", "M", _num(kn, 3), "N", _num(kmh, 3), "K"]
    if mode is not None:
        fields.append(mode)
    return _render(talker, "VTG", fields)


def nmea_gga(*, utc: datetime | float, lat_deg: float | None, lon_deg: float | None,
             quality: int = 1, num_sv: int = 12, hdop: float | None = 0.9, alt_m: float | None = 0.0,
             geoid_sep_m: float | None = 0.0, talker: str = "GN") -> str:
    """``$GNGGA``: quality 0 none, 1 GNSS, 2 DGNSS, 4 RTK fixed, 5 RTK float, 6 dead reckoning."""
    lat, ns = _latlon(lat_deg, 2, "N", "S")
    lon, ew = _latlon(lon_deg, 3, "E", "W")
    fields = [_hms(_as_datetime(utc)), lat, ns, lon, ew, str(int(quality)), f"{int(num_sv):02d}",
              _num(hdop, 2), _num(alt_m, 1), "M", _num(geoid_sep_m, 1), "M", "", ""]
    return _render(talker, "GGA", fields)


def nmea_gst(*, utc: datetime | float, rms_m: float | None = 10.0, std_major_m: float | None = 1.5,
             std_minor_m: float | None = 1.0, orient_deg: float | None = 0.0,
             std_lat_m: float | None = 1.0, std_lon_m: float | None = 1.0,
             std_alt_m: float | None = 2.0, talker: str = "GN") -> str:
    """``$GNGST``: pseudorange error statistics; std_lat/std_lon are 1-sigma position errors in m."""
    fields = [_hms(_as_datetime(utc)), _num(rms_m, 1), _num(std_major_m, 1), _num(std_minor_m, 1),
              _num(orient_deg, 1), _num(std_lat_m, 1), _num(std_lon_m, 1), _num(std_alt_m, 1)]
    return _render(talker, "GST", fields)


def nmea_zda(*, utc: datetime | float, talker: str = "GN") -> str:
    """``$GNZDA``: time and date (day, month, 4-digit year), local zone fields 00."""
    dt = _as_datetime(utc)
    dt_c = dt + timedelta(microseconds=5000)  # date of the rounded time
    return _render(talker, "ZDA", [_hms(dt), f"{dt_c.day:02d}", f"{dt_c.month:02d}", f"{dt_c.year:04d}", "00", "00"])


def posix_from_fields(year: int, month: int, day: int, hour: int, minute: int, second: int,
                      nano: int = 0) -> float:
    """POSIX seconds of a NAV-PVT date/time (inverse of :func:`utc_fields`, for tests)."""
    return calendar.timegm((year, month, day, hour, minute, second)) + nano * 1e-9
