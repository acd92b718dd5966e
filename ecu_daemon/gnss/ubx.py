"""UBX frames -> GnssSample: NAV-PVT (and NAV-VELNED for receivers without NAV-PVT).

Framing and checksum checks happen in ``stream.py``; this module gets whole, checksum-verified
frames and turns the velocity messages into SI samples. pyubx2 decodes the payload.

Unit traps handled here, once:
* NAV-PVT velN/velE/velD/gSpeed/sAcc are **mm/s**, hAcc mm; pyubx2 returns them unscaled.
* NAV-VELNED velN/velE/sAcc are **cm/s** (legacy message).
* pyubx2 returns headMot/headAcc/heading/cAcc already scaled to degrees.
"""
from __future__ import annotations

import calendar
import math

from pyubx2 import GET, VALNONE, UBXReader
from pyubx2.ubxhelpers import calc_checksum
from pyubx2.ubxtypes_core import UBX_CLASSES

from ..samples import GnssSample

__all__ = ["UBX_SYNC", "UBX_MAX_PAYLOAD", "UBX_CLASS_BYTES", "ubx_checksum", "UbxError",
           "UbxDecoder", "NAV_PVT", "NAV_VELNED"]

UBX_SYNC = b"\xb5\x62"
#: Longest payload we wait for. Real messages stay far below this (RXM-RAWX with 64 signals is
#: 2 KB); a corrupted length field above it is rejected at once instead of stalling the stream.
UBX_MAX_PAYLOAD = 8192
#: Class bytes pyubx2 knows; a sync pattern followed by anything else is not a frame.
UBX_CLASS_BYTES = frozenset(c[0] for c in UBX_CLASSES)

NAV_PVT = (0x01, 0x07)
NAV_VELNED = (0x01, 0x12)
_NAV_STATUS = (0x01, 0x03)
_NAV_SOL = (0x01, 0x06)
_NAV_PVT_LEN = 92


class UbxError(ValueError):
    """A checksum-valid UBX frame whose content cannot be used (wrong length, undecodable)."""


def ubx_checksum(body: bytes | bytearray | memoryview) -> bytes:
    """8-bit Fletcher checksum over class, id, length and payload (pyubx2's implementation)."""
    return calc_checksum(bytes(body))


def _utc_seconds(msg) -> float:
    """POSIX seconds of the NAV-PVT epoch, or NaN when the receiver says date/time are not valid."""
    if not (msg.validDate and msg.validTime):
        return math.nan
    try:
        return calendar.timegm((msg.year, msg.month, msg.day, msg.hour, msg.min, msg.second)) + msg.nano * 1e-9
    except (ValueError, OverflowError):
        return math.nan


class UbxDecoder:
    """Decodes whole UBX frames of one stream; keeps the little state NAV-VELNED pairing needs.

    ``decode(t, frame)`` returns a GnssSample, or None for a frame that carries no velocity
    solution (``supported(frame)`` tells which ones count as unsupported). Raises UbxError for a
    frame of a supported type whose content is unusable.
    """

    def __init__(self) -> None:
        self.seen_nav_pvt = False
        self._status: tuple[int, int, bool, int] | None = None  # iTOW, fixType, fixOk, numSV

    @staticmethod
    def supported(cls_id: tuple[int, int]) -> bool:
        return cls_id in (NAV_PVT, NAV_VELNED, _NAV_STATUS, _NAV_SOL)

    def decode(self, t: float, frame: bytes) -> GnssSample | None:
        cls_id = (frame[2], frame[3])
        if cls_id == NAV_PVT:
            if len(frame) != 8 + _NAV_PVT_LEN:
                raise UbxError(f"NAV-PVT payload is {len(frame) - 8} bytes, expected {_NAV_PVT_LEN}")
            self.seen_nav_pvt = True
            return self._nav_pvt(t, self._parse(frame))
        if cls_id in (_NAV_STATUS, _NAV_SOL):
            if self.seen_nav_pvt:
                return None  # only needed to pair with NAV-VELNED
            msg = self._parse(frame)
            ok = bool(msg.gpsFixOk if cls_id == _NAV_STATUS else msg.gpsfixOK)  # pyubx2 spells them so
            self._status = (msg.iTOW, int(msg.gpsFix), ok, int(getattr(msg, "numSV", 0)))
            return None
        if cls_id == NAV_VELNED:
            return None if self.seen_nav_pvt else self._nav_velned(t, self._parse(frame))
        return None

    @staticmethod
    def _parse(frame: bytes):
        try:
            return UBXReader.parse(frame, msgmode=GET, validate=VALNONE)
        except Exception as exc:  # pyubx2 raises several exception types for bad content
            raise UbxError(f"pyubx2 cannot decode {frame[2]:02X} {frame[3]:02X}: {exc}") from None

    @staticmethod
    def _nav_pvt(t: float, m) -> GnssSample:
        llh_ok = not getattr(m, "invalidLlh", 0)
        return GnssSample(
            t=t,
            vel_n_mps=m.velN / 1000,
            vel_e_mps=m.velE / 1000,
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

    def _nav_velned(self, t: float, m) -> GnssSample | None:
        """Legacy velocity (cm/s); needs NAV-STATUS or NAV-SOL of the same epoch for the fix state."""
        st = self._status
        if st is None or st[0] != m.iTOW:
            return None
        _, fix_type, fix_ok, num_sv = st
        return GnssSample(
            t=t, vel_n_mps=m.velN / 100, vel_e_mps=m.velE / 100, speed_acc_mps=m.sAcc / 100,
            fix_type=fix_type, fix_ok=fix_ok, num_sv=int(num_sv), protocol="ubx", head_acc_rad=math.radians(m.cAcc),
        )
