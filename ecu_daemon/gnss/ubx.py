"""UBX frames -> samples: NAV-PVT, or for receivers without it NAV-SOL, HNR-PVT, NAV-VELNED (velocity);
NAV-RELPOSNED (dual-antenna heading: a u-blox F9P moving-base rover).

Framing and checksum checks happen in ``stream.py``; this module gets whole, checksum-verified
frames and turns the velocity messages into SI samples. pyubx2 decodes the payload, except
NAV-PVT's (the message every epoch of a modern receiver sends): one ``struct`` unpack with
pyubx2's scalings, held equal to the library by the tests.

NAV-PVT is the velocity source whenever a receiver sends it (u-blox 7's 84-byte version too: the
same fields but flags3 and the vehicle heading). Older receivers (u-blox 4-6, the timing series)
send NAV-SOL: an ECEF velocity, turned into north/east at the ECEF position
(pynmeagps' ``ecef2llh``), stamped with GPS week/time of week minus the leap seconds (NAV-TIMEGPS
when it says they are valid, else the IERS table below). HNR-PVT (u-blox 8 ADR/UDR high-rate
output) carries ground speed and course of motion. NAV-VELNED is paired with NAV-STATUS/NAV-SOL
of the same epoch (iTOW) in either order: receivers send the NAV messages in the order the user
enabled them, so a NAV-VELNED waits (at most until the next epoch's message, or
``stream.NAV_SOL_HOLD_S`` of receive time) for its status; one whose epoch has none (NAV-STATUS
at a lower rate) takes the fix state of the last status at most ``_STATUS_MAX_AGE_MS`` older. It is
dated by its own iTOW once any message told the GPS week (NAV-SOL, NAV-TIMEGPS, NAV-TIMEUTC).
One sample per epoch whichever of them come.

Unit traps handled here, once:
* NAV-PVT velN/velE/velD/gSpeed/sAcc are **mm/s**, hAcc mm; pyubx2 returns them unscaled.
* NAV-VELNED velN/velE/sAcc are **cm/s** (legacy message).
* pyubx2 returns headMot/headAcc/heading/cAcc already scaled to degrees.
* NAV-RELPOSNED: pyubx2 gives relPosHeading/accHeading in degrees, relPosN/E/D/Length in **cm** (the
  0.1 mm high-precision parts already added), accN/E/D/Length in **mm**. Only version 1 (64 bytes, F9P)
  carries a heading; the M8P's 40-byte version 0 has none and gives no sample.
"""
from __future__ import annotations

import calendar
import math
import struct
from dataclasses import replace
from itertools import accumulate

from pynmeagps import ecef2llh
from pyubx2 import GET, VALNONE, UBXReader
from pyubx2.ubxhelpers import calc_checksum
from pyubx2.ubxtypes_core import E1_N5, E1_N7, SCALROUND, UBX_CLASSES

from ..samples import GnssHeadingSample, GnssSample

__all__ = ["UBX_SYNC", "UBX_MAX_PAYLOAD", "UBX_CLASS_BYTES", "ubx_checksum", "UbxError", "nav_pvt_sample",
           "UbxDecoder", "NAV_PVT", "NAV_VELNED", "NAV_SOL", "HNR_PVT", "NAV_RELPOSNED"]

UBX_SYNC = b"\xb5\x62"
#: Longest payload we wait for. Real messages stay far below this (RXM-RAWX with 64 signals is
#: 2 KB); a corrupted length field above it is rejected at once instead of stalling the stream.
UBX_MAX_PAYLOAD = 8192
#: Class bytes pyubx2 knows; a sync pattern followed by anything else is not a frame.
UBX_CLASS_BYTES = frozenset(c[0] for c in UBX_CLASSES)

NAV_PVT = (0x01, 0x07)
NAV_VELNED = (0x01, 0x12)
NAV_SOL = (0x01, 0x06)
HNR_PVT = (0x28, 0x00)
NAV_RELPOSNED = (0x01, 0x3C)
_NAV_RELPOSNED_LEN = 64
_NAV_RELPOSNED_V0_LEN = 40
_NAV_STATUS = (0x01, 0x03)
_NAV_TIMEGPS = (0x01, 0x20)
_NAV_TIMEUTC = (0x01, 0x21)
#: A NAV-VELNED without a NAV-STATUS/NAV-SOL of its own epoch uses the last one at most this much older
#: (NAV-STATUS enabled at a lower rate than NAV-VELNED); older, the sample is dropped.
_STATUS_MAX_AGE_MS = 1000
_WEEK_MS = 604_800_000
_NAV_PVT_LEN = 92
#: u-blox 7 (protocol 14: NEO-7M and its many clones) sends NAV-PVT with 84 bytes: the same fields up to
#: pDOP, then reserved bytes, no flags3 (invalidLlh) and no headVeh/magDec/magAcc (PX4's driver takes both)
_NAV_PVT_LEN_UBX7 = 84
_GPS_EPOCH_POSIX = 315964800  # 1980-01-06T00:00:00Z
#: GPS - UTC in seconds from each leap second on (UTC posix time); used until NAV-TIMEGPS says.
_LEAP_SECONDS = ((1483228800, 18), (1435708800, 17), (1341100800, 16), (1230768000, 15),
                 (1136073600, 14), (915148800, 13), (867715200, 12), (820454400, 11))


class UbxError(ValueError):
    """A checksum-valid UBX frame whose content cannot be used (wrong length, undecodable)."""


def ubx_checksum(body: bytes | bytearray | memoryview) -> bytes:
    """8-bit Fletcher checksum over class, id, length and payload: pyubx2's ``calc_checksum``
    (tests/test_ubx_fast.py holds them equal) in C-level sums instead of a Python loop per byte
    (CK_A is the byte sum, CK_B the sum of its running sums)."""
    return bytes((sum(body) & 0xFF, sum(accumulate(body)) & 0xFF))


def ubx_checksum_reference(body: bytes | bytearray | memoryview) -> bytes:
    """pyubx2's own checksum: the reference of :func:`ubx_checksum`."""
    return calc_checksum(bytes(body))


#: NAV-PVT fields the sample needs, by offset in the 92-byte payload (u-blox interface
#: description): year, month, day, hour, min, sec, valid, nano, fixType, flags, numSV, lon, lat,
#: hAcc, velN, velE, velD, sAcc, headAcc, flags3
_NAV_PVT_FIELDS = struct.Struct("<4xHBBBBBB4xiBBxBii8xI4xiii8xII2xH")


def _leap_from_table(gps_posix: float) -> int:
    for since, leap in _LEAP_SECONDS:
        if gps_posix - leap >= since:
            return leap
    return 10  # before 1996: no receiver log of this project is that old


def _ecef_to_ne(vx: float, vy: float, vz: float, lat_deg: float, lon_deg: float) -> tuple[float, float]:
    """North and east components of an ECEF vector at a geodetic position."""
    la, lo = math.radians(lat_deg), math.radians(lon_deg)
    sla, cla, slo, clo = math.sin(la), math.cos(la), math.sin(lo), math.cos(lo)
    return -sla * clo * vx - sla * slo * vy + cla * vz, -slo * vx + clo * vy


def _utc_seconds(msg) -> float:
    """POSIX seconds of the NAV-PVT epoch, or NaN when the receiver says date/time are not valid."""
    return _utc_of(msg.validDate and msg.validTime, msg.year, msg.month, msg.day, msg.hour, msg.min,
                   msg.second, msg.nano)


def _utc_of(valid, year, month, day, hour, minute, second, nano) -> float:
    if not valid:
        return math.nan
    try:
        return calendar.timegm((year, month, day, hour, minute, second)) + nano * 1e-9
    except (ValueError, OverflowError):
        return math.nan


def nav_pvt_sample(t: float, frame: bytes) -> GnssSample:
    """The sample of a whole NAV-PVT frame (92-byte payload, or u-blox 7's 84), read with one ``struct`` unpack.

    Why not pyubx2 here: it builds an attribute per field of every message (~120 us per NAV-PVT,
    a replay's biggest GNSS cost). The fields, scalings (pyubx2's own constants and rounding) and
    bit positions are the library's; ``tests/test_ubx_fast.py`` holds this equal to
    :meth:`UbxDecoder.nav_pvt_reference` on every capture and on random payloads. Any 92 bytes
    are a NAV-PVT for both (no field is variable), so nothing is left to the library here; other
    lengths never come (``UbxDecoder`` calls them malformed first). In u-blox 7's 84 bytes the
    flags3 position is reserved: its position is not declared invalid.
    """
    (year, month, day, hour, minute, second, valid, nano, fix_type, flags, num_sv, lon, lat, h_acc,
     vel_n, vel_e, vel_d, s_acc, head_acc, flags3) = _NAV_PVT_FIELDS.unpack_from(frame, 6)
    llh_ok = not flags3 & 1 or len(frame) != 8 + _NAV_PVT_LEN
    return GnssSample(
        t=t,
        vel_n_mps=vel_n / 1000,
        vel_e_mps=vel_e / 1000,
        vel_d_mps=vel_d / 1000,
        speed_acc_mps=s_acc / 1000,
        fix_type=fix_type,
        fix_ok=bool(flags & 1),
        num_sv=num_sv,
        protocol="ubx",
        fix_time_utc_s=_utc_of(valid & 1 and valid & 2, year, month, day, hour, minute, second, nano),
        head_acc_rad=math.radians(round(head_acc * E1_N5, SCALROUND)),
        lat_deg=float(round(lat * E1_N7, SCALROUND)) if llh_ok else math.nan,
        lon_deg=float(round(lon * E1_N7, SCALROUND)) if llh_ok else math.nan,
        h_acc_m=h_acc / 1000,
    )


class UbxDecoder:
    """Decodes whole UBX frames of one stream; keeps the little state NAV-VELNED pairing needs.

    ``decode(t, frame)`` returns the samples a frame completes (usually none or one;
    ``supported(cls_id)`` tells which frames count as unsupported), ``flush()`` a held one at end of
    stream. Raises UbxError for a frame of a supported type whose content is unusable.
    """

    def __init__(self) -> None:
        self.seen_nav_pvt = False
        self._status: tuple[int, int, bool, int] | None = None  # iTOW, fixType, fixOk, numSV
        self._leap_s: int | None = None  # GPS - UTC from NAV-TIMEGPS, when it says it is valid
        self._legacy_itow: int | None = None  # epoch of the last NAV-SOL / NAV-VELNED sample
        self._held: GnssSample | None = None  # NAV-SOL sample waiting to see whether NAV-PVT follows
        self._pvt_epoch: tuple[int, float] | None = None  # iTOW and UTC of the last NAV-PVT
        self._velned: tuple[float, object] | None = None  # NAV-VELNED (receive t, msg) waiting for its status
        self._tow_base: tuple[int, float] | None = None  # (iTOW, UTC s) of one epoch: dates any iTOW
        self._leap_end: float | None = None  # POSIX time at the end of a leap second NAV-PVT sent

    @staticmethod
    def supported(cls_id: tuple[int, int]) -> bool:
        return cls_id in (NAV_PVT, NAV_VELNED, _NAV_STATUS, NAV_SOL, _NAV_TIMEGPS, _NAV_TIMEUTC, HNR_PVT,
                          NAV_RELPOSNED)

    def decode(self, t: float, frame: bytes) -> list[GnssSample]:
        """The samples completed by this frame (any UBX frame: it may release a held NAV-SOL).

        A NAV-SOL sample is held until the next frame: a receiver that also sends NAV-PVT sends
        it right after NAV-SOL (u-blox orders an epoch's messages by id), and NAV-PVT replaces it.
        """
        held, self._held = self._held, None
        try:
            return self._decode(t, frame, held)
        except UbxError:
            self._held = held  # released by the next good frame
            raise

    def _decode(self, t: float, frame: bytes, held: GnssSample | None) -> list[GnssSample]:
        cls_id = (frame[2], frame[3])
        out: list[GnssSample] = []
        if cls_id == NAV_PVT:
            if len(frame) - 8 not in (_NAV_PVT_LEN, _NAV_PVT_LEN_UBX7):
                raise UbxError(f"NAV-PVT payload is {len(frame) - 8} bytes, expected {_NAV_PVT_LEN}"
                               f" (or {_NAV_PVT_LEN_UBX7}, u-blox 7)")
            self.seen_nav_pvt = True
            pvt = nav_pvt_sample(t, frame)
            if frame[16] == 60 or self._leap_end is not None:  # payload byte 10: sec
                pvt = self._leap_second(pvt, frame)
            self._pvt_epoch = (struct.unpack_from("<I", frame, 6)[0], pvt.fix_time_utc_s)  # payload's iTOW
            return out + [pvt]  # a held NAV-SOL of the same receiver is dropped
        if held is not None:
            out.append(held)
        if cls_id == NAV_RELPOSNED:
            if len(frame) == 8 + _NAV_RELPOSNED_V0_LEN:
                return out
            if len(frame) != 8 + _NAV_RELPOSNED_LEN:
                raise UbxError(f"NAV-RELPOSNED payload is {len(frame) - 8} bytes, expected {_NAV_RELPOSNED_LEN}"
                               " (version 1, with heading)")
            m = self._parse(frame)
            # the NAV-PVT of the same epoch (same iTOW) dates the heading: same time of validity
            ep = self._pvt_epoch
            return out + [self._nav_relposned(t, m, ep[1] if ep is not None and ep[0] == m.iTOW else math.nan)]
        if self.seen_nav_pvt or not self.supported(cls_id):
            return out  # the others are only used by receivers without NAV-PVT
        msg = self._parse(frame)
        if cls_id == _NAV_TIMEGPS:
            if msg.leapSValid:
                self._leap_s = int(msg.leapS)
            if msg.towValid and msg.weekValid:
                self._tow_base = (msg.iTOW, self._gps_to_utc(msg.week, msg.iTOW, msg.fTOW))
        elif cls_id == _NAV_TIMEUTC:
            if msg.validUTC and msg.sec < 60:  # POSIX has no 23:59:60: the next one dates the week
                self._tow_base = (msg.iTOW, _utc_of(True, msg.year, msg.month, msg.day, msg.hour, msg.min,
                                                    msg.sec, msg.nano))
        elif cls_id == HNR_PVT:
            out.append(self._hnr_pvt(t, msg))
        elif cls_id in (_NAV_STATUS, NAV_SOL):
            pending = self._velned
            if pending is not None and pending[1].iTOW != msg.iTOW:
                self._release_velned(out)  # its epoch's status never came: the last one (if fresh)
            ok = bool(msg.gpsFixOk if cls_id == _NAV_STATUS else msg.gpsfixOK)  # pyubx2 spells them so
            self._status = (msg.iTOW, int(msg.gpsFix), ok, int(getattr(msg, "numSV", 0)))
            if cls_id == NAV_SOL and msg.wknSet and msg.towSet:
                self._tow_base = (msg.iTOW, self._gps_to_utc(msg.week, msg.iTOW, msg.fTOW))
            self._release_velned(out)  # the NAV-VELNED of this epoch came first
            if cls_id == NAV_SOL:
                self._held = self._nav_sol(t, msg)
        else:  # NAV_VELNED
            self._release_velned(out)  # an earlier epoch's, never completed
            st = self._status
            if st is not None and st[0] == msg.iTOW:
                velned = self._nav_velned(t, msg, st)
                out += [velned] if velned is not None else []
            else:
                self._velned = (t, msg)  # its NAV-STATUS / NAV-SOL may follow
        return out

    def _release_velned(self, out: list) -> None:
        """The waiting NAV-VELNED with the status of its epoch, else with the last one if at most
        ``_STATUS_MAX_AGE_MS`` older; dropped otherwise (the fix state it needs is unknown)."""
        if self._velned is None:
            return
        (t, msg), self._velned = self._velned, None
        st = self._status
        if st is not None and 0 <= (msg.iTOW - st[0]) % _WEEK_MS <= _STATUS_MAX_AGE_MS:
            velned = self._nav_velned(t, msg, st)
            out += [velned] if velned is not None else []

    def _leap_second(self, pvt: GnssSample, frame: bytes) -> GnssSample:
        """NAV-PVT's sec is 60 in a leap second (23:59:60), which POSIX reads as the next day's
        00:00:00: kept in its place, and the later epochs of this stream 1 s ahead of POSIX, so
        fix times stay monotone with true differences (as ``nmea.py`` does)."""
        ft = pvt.fix_time_utc_s
        if not math.isfinite(ft):
            return pvt
        if frame[16] == 60:
            self._leap_end = ft - struct.unpack_from("<i", frame, 22)[0] * 1e-9  # payload's nano
            return pvt
        return replace(pvt, fix_time_utc_s=ft + 1.0) if ft >= self._leap_end - 1e-3 else pvt

    def flush(self, before: float = math.inf) -> list[GnssSample]:
        """The held NAV-SOL sample and the NAV-VELNED waiting for its status, if received before
        ``before`` (default: any; end of stream)."""
        out: list[GnssSample] = []
        if self._velned is not None and self._velned[0] < before:
            self._release_velned(out)
        if self._held is not None and self._held.t < before:
            held, self._held = self._held, None
            out.append(held)
        return sorted(out, key=lambda s: s.t) if len(out) > 1 else out

    @staticmethod
    def _parse(frame: bytes):
        try:
            return UBXReader.parse(frame, msgmode=GET, validate=VALNONE)
        except Exception as exc:  # pyubx2 raises several exception types for bad content
            raise UbxError(f"pyubx2 cannot decode {frame[2]:02X} {frame[3]:02X}: {exc}") from None

    @classmethod
    def nav_pvt_reference(cls, t: float, frame: bytes) -> GnssSample:
        """The NAV-PVT sample decoded by pyubx2: the reference of :func:`nav_pvt_sample`."""
        return cls._nav_pvt(t, cls._parse(frame), len(frame) - 8 == _NAV_PVT_LEN)

    @staticmethod
    def _nav_pvt(t: float, m, has_flags3: bool = True) -> GnssSample:
        llh_ok = not (has_flags3 and getattr(m, "invalidLlh", 0))
        return GnssSample(
            t=t,
            vel_n_mps=m.velN / 1000,
            vel_e_mps=m.velE / 1000,
            vel_d_mps=m.velD / 1000,
            speed_acc_mps=m.sAcc / 1000,
            fix_type=int(m.fixType),
            fix_ok=bool(m.gnssFixOk),
            num_sv=int(m.numSV),
            protocol="ubx",
            fix_time_utc_s=_utc_seconds(m),
            head_acc_rad=math.radians(m.headAcc),
            lat_deg=float(m.lat) if llh_ok else math.nan,
            lon_deg=float(m.lon) if llh_ok else math.nan,
            h_acc_m=m.hAcc / 1000,
        )

    @staticmethod
    def _nav_relposned(t: float, m, fix_time_utc_s: float = math.nan) -> GnssHeadingSample:
        """Moving-base heading: valid only when the receiver says the fix, the relative position
        and its heading are all valid (a float carrier solution stays valid; its accHeading says
        what it is worth). ``fix_time_utc_s``: the epoch of the NAV-PVT with the same iTOW."""
        valid = bool(m.gnssFixOK and m.relPosValid and m.relPosHeadingValid)
        vec = not m.relPosNormalized  # a normalised vector has no lengths (nor a usable accD)
        return GnssHeadingSample(
            t=t, heading_rad=math.radians(m.relPosHeading) % (2.0 * math.pi),
            heading_acc_rad=math.radians(m.accHeading),
            baseline_m=m.relPosLength / 100.0 if vec else math.nan,
            valid=valid, carr_soln=int(m.carrSoln), protocol="ubx", fix_time_utc_s=fix_time_utc_s,
            down_m=m.relPosD / 100.0 if vec else math.nan,
            horizontal_m=math.hypot(m.relPosN, m.relPosE) / 100.0 if vec else math.nan,
            down_acc_m=m.accD / 1000.0 if vec else math.nan,
        )

    def _gps_to_utc(self, week: int, itow_ms: int, ftow_ns: int) -> float:
        gps = _GPS_EPOCH_POSIX + week * 604800 + itow_ms / 1000 + ftow_ns * 1e-9
        return gps - (self._leap_s if self._leap_s is not None else _leap_from_table(gps))

    def _nav_sol(self, t: float, m) -> GnssSample | None:
        """u-blox 4-7 navigation solution: ECEF position (cm) and velocity (cm/s)."""
        if self._legacy_itow == m.iTOW:
            return None
        self._legacy_itow = m.iTOW
        known = bool(m.ecefX or m.ecefY or m.ecefZ)
        lat, lon, _ = ecef2llh(m.ecefX / 100, m.ecefY / 100, m.ecefZ / 100) if known else (math.nan,) * 3
        vn, ve = _ecef_to_ne(m.ecefVX / 100, m.ecefVY / 100, m.ecefVZ / 100, lat, lon) if known else (math.nan,) * 2
        return GnssSample(
            t=t, vel_n_mps=vn, vel_e_mps=ve, speed_acc_mps=m.sAcc / 100, fix_type=int(m.gpsFix),
            fix_ok=bool(m.gpsfixOK) and known, num_sv=int(m.numSV), protocol="ubx",
            fix_time_utc_s=self._gps_to_utc(m.week, m.iTOW, m.fTOW) if m.wknSet and m.towSet else math.nan,
            lat_deg=lat, lon_deg=lon,
        )

    @staticmethod
    def _hnr_pvt(t: float, m) -> GnssSample:
        """High-rate (sensor-fused) output: ground speed (mm/s) along the course of motion (deg)."""
        speed, c = m.gSpeed / 1000, math.radians(m.headMot)
        return GnssSample(
            t=t, vel_n_mps=speed * math.cos(c), vel_e_mps=speed * math.sin(c), speed_acc_mps=m.sAcc / 1000,
            fix_type=int(m.gpsFix), fix_ok=bool(m.GPSfixOK), protocol="ubx", fix_time_utc_s=_utc_seconds(m),
            head_acc_rad=math.radians(m.headAcc), lat_deg=float(m.lat), lon_deg=float(m.lon), h_acc_m=m.hAcc / 1000,
        )

    def _nav_velned(self, t: float, m, st: tuple[int, int, bool, int]) -> GnssSample | None:
        """Legacy velocity (cm/s) with the fix state ``st`` of a NAV-STATUS or NAV-SOL (None: this
        epoch already gave a sample)."""
        if self._legacy_itow == m.iTOW:
            return None
        self._legacy_itow = m.iTOW
        _, fix_type, fix_ok, num_sv = st
        return GnssSample(
            t=t, vel_n_mps=m.velN / 100, vel_e_mps=m.velE / 100, vel_d_mps=m.velD / 100,
            speed_acc_mps=m.sAcc / 100, fix_type=fix_type, fix_ok=fix_ok, num_sv=int(num_sv), protocol="ubx",
            head_acc_rad=math.radians(m.cAcc), fix_time_utc_s=self._utc_of_itow(m.iTOW),
        )

    def _utc_of_itow(self, itow_ms: int) -> float:
        """UTC seconds of a time of week, from the last message that dated one (NaN before any)."""
        if self._tow_base is None:
            return math.nan
        itow0, utc0 = self._tow_base
        d = (itow_ms - itow0) % _WEEK_MS
        return utc0 + (d - _WEEK_MS if d > _WEEK_MS // 2 else d) / 1000
