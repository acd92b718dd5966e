"""NMEA sentences -> GnssSample: one sample per epoch from RMC (and/or VTG), enriched by GGA and GST.

Framing and the ``*hh`` checksum are checked in ``stream.py``; this module gets whole sentences.
pynmea2 splits the fields, but three measured pynmea2 traps are avoided here
(``/work/shared/research/ecosystem.md`` finding 10):

* ``RMC.is_valid`` is False for every u-blox NMEA 4.1 RMC (nav-status field ``V``); validity is
  decided here from the status field and the FAA mode, ignoring nav status.
* A field that fails to convert is returned as the raw string (``'0.0x7'``), and an empty
  latitude becomes 0.0; every number is therefore checked here and a bad one rejects the
  sentence (counted as malformed) instead of flowing on as text or as a fake position.
* VTG knots are ``Decimal``; everything is converted to float.

Emission is driven by the velocity sentence so that no sample waits for later sentences of
the epoch (GGA/GST come after RMC on u-blox; at 9600 baud that would add ~0.1 s): an RMC
with a speed is emitted at once; an RMC without one waits for the VTG that follows it (only if
this stream sends VTG); a stream without RMC is served from VTG. GGA and GST
contribute fix quality, satellites and horizontal accuracy from the same or the previous
epoch (at most 1.5 s older).
"""
from __future__ import annotations

import calendar
import math
import re
from dataclasses import dataclass

import pynmea2

from ..samples import FIX_3D, FIX_DR, FIX_NONE, GnssSample

__all__ = ["MPS_PER_KNOT", "NmeaError", "NmeaEpochAssembler", "nmea_checksum_ok", "VELOCITY_KINDS",
           "USED_KINDS"]

MPS_PER_KNOT = 1852.0 / 3600.0
VELOCITY_KINDS = frozenset({"RMC", "VTG"})
USED_KINDS = frozenset({"RMC", "VTG", "GGA", "GST"})
#: GGA/GST older than this (relative to the RMC) are not used for the sample.
_AUX_MAX_AGE_MS = 1500
#: FAA mode indicators that mean a usable GNSS solution (A autonomous, D differential, P precise,
#: R RTK fixed, F RTK float). E is dead reckoning; N no fix; M manual and S simulator are not fixes.
_GNSS_MODES = frozenset("ADPRF")
_TIME = re.compile(r"^(\d\d)(\d\d)(\d\d)(\.\d+)?$")
_DM = re.compile(r"^(\d{1,3})(\d\d(?:\.\d*)?)$")


class NmeaError(ValueError):
    """A checksum-valid sentence whose content cannot be used (bad number, bad time, ...)."""


def nmea_checksum_ok(sentence: bytes) -> bool | None:
    """XOR checksum of ``$...*hh`` (no line ending). None when the sentence carries no checksum."""
    star = sentence.rfind(b"*")
    if star < 0 or len(sentence) - star != 3:
        return None
    try:
        want = int(sentence[star + 1:], 16)
    except ValueError:
        return False
    ck = 0
    for b in sentence[1:star]:
        ck ^= b
    return ck == want


# ------------------------------------------------------------------------------ field helpers

def _num(msg, name: str) -> float | None:
    """A numeric pynmea2 field as float, None when empty; raises on the raw-string fallback."""
    v = getattr(msg, name)
    if v is None or v == "":
        return None
    try:
        f = float(v)  # Decimal, float or (pynmea2 conversion failure) str
    except (TypeError, ValueError):
        raise NmeaError(f"{msg.sentence_type} {name} is not a number: {v!r}") from None
    if not math.isfinite(f):
        raise NmeaError(f"{msg.sentence_type} {name} is not finite: {v!r}")
    return f


def _tod_ms(msg) -> int | None:
    """Time of day of field 0 (hhmmss[.sss]) in ms; rounded, not pynmea2's truncating parse."""
    raw = msg.data[0] if msg.data else ""
    if raw == "":
        return None
    m = _TIME.match(raw)
    if not m or int(m[1]) > 23 or int(m[2]) > 59 or int(m[3]) > 60:
        raise NmeaError(f"{msg.sentence_type} time is not hhmmss.ss: {raw!r}")
    return (int(m[1]) * 3600 + int(m[2]) * 60 + int(m[3])) * 1000 + round(float(m[4] or 0) * 1000)


def _coord(value: str, hemi: str, limit: float, what: str) -> float:
    """ddmm.mmmm + hemisphere -> signed degrees; NaN when empty (pynmea2 would say 0.0)."""
    if value == "":
        return math.nan
    m = _DM.match(value)
    deg = int(m[1]) + float(m[2]) / 60.0 if m else math.inf
    if hemi not in ("N", "E", "S", "W") or not deg <= limit:
        raise NmeaError(f"{what} is not (d)ddmm.mmmm,{'NS' if limit == 90 else 'EW'}: {value!r},{hemi!r}")
    return -deg if hemi in ("S", "W") else deg


def _field(msg, i: int) -> str:
    return msg.data[i] if i < len(msg.data) else ""


@dataclass(slots=True)
class _Rmc:
    t: float
    talker: str
    tod_ms: int | None
    utc_s: float
    valid: bool
    mode: str
    lat: float
    lon: float
    speed: float | None  # m/s
    course: float | None  # deg true


@dataclass(slots=True)
class _Vtg:
    t: float
    speed: float | None
    course: float | None
    mode: str


def _decode_rmc(t: float, talker: str, msg) -> _Rmc:
    tod = _tod_ms(msg)
    utc = math.nan
    date = _field(msg, 8)
    if tod is not None and date:
        if not re.match(r"^\d{6}$", date):
            raise NmeaError(f"RMC date is not ddmmyy: {date!r}")
        yy = int(date[4:6])
        try:
            utc = calendar.timegm((2000 + yy if yy < 80 else 1900 + yy, int(date[2:4]), int(date[0:2]),
                                   0, 0, 0)) + tod / 1000.0
        except ValueError:
            raise NmeaError(f"RMC date is not ddmmyy: {date!r}") from None
    speed = _num(msg, "spd_over_grnd")
    valid = _field(msg, 1) == "A"
    try:
        lat = _coord(_field(msg, 2), _field(msg, 3), 90, "RMC latitude")
        lon = _coord(_field(msg, 4), _field(msg, 5), 180, "RMC longitude")
    except NmeaError:
        if valid:
            raise
        lat = lon = math.nan  # receivers print placeholders like 36000.0000 without a fix
    return _Rmc(t=t, talker=talker, tod_ms=tod, utc_s=utc, valid=valid, mode=_field(msg, 11),
                lat=lat, lon=lon, speed=None if speed is None else speed * MPS_PER_KNOT,
                course=_num(msg, "true_course"))


def _decode_vtg(t: float, msg) -> _Vtg:
    kn = _num(msg, "spd_over_grnd_kts")
    kmh = _num(msg, "spd_over_grnd_kmph")
    speed = kn * MPS_PER_KNOT if kn is not None else None if kmh is None else kmh / 3.6
    # pre-NMEA-2.3 VTG had no unit letters: "054.7,034.4,005.5,010.2"; pynmea2 maps that wrongly
    if _field(msg, 1) not in ("T", "") or _field(msg, 5) not in ("N", ""):
        raise NmeaError("VTG without T/N unit markers (NMEA 2.0 layout) is not supported")
    return _Vtg(t=t, speed=speed, course=_num(msg, "true_track"), mode=_field(msg, 8))


# ------------------------------------------------------------------------------ assembler

class NmeaEpochAssembler:
    """Turns the checksum-valid NMEA sentences of one stream into one GnssSample per epoch.

    ``add(t, sentence_text)`` returns the samples completed by that sentence (0 or 1, 2 when a
    held epoch is flushed by the next one); ``flush()`` returns a held epoch at end of stream.
    ``nominal_speed_acc_mps`` is used only to derive the accuracy of course-less epochs (see
    ``_sample``); other NMEA samples carry NaN and the estimator applies its configured value.
    Raises NmeaError for unusable content (pynmea2.ParseError is converted too).
    """

    def __init__(self, nominal_speed_acc_mps: float | None = 0.15) -> None:
        self.nominal_speed_acc = math.nan if nominal_speed_acc_mps is None else float(nominal_speed_acc_mps)
        self.talker: str | None = None  # the talker whose RMC/VTG we use (first RMC talker, GN preferred)
        self.other_talker_sentences = 0
        self._rmc_talker_locked = False
        self._sends_vtg = False
        self._sends_rmc = False
        self._held: _Rmc | None = None
        self._gga: tuple[int, int, int] | None = None  # tod_ms, quality, num_sv
        self._gst: tuple[int, float] | None = None  # tod_ms, horizontal 1-sigma m
        self._last_tod: int | None = None

    def add(self, t: float, text: str) -> list[GnssSample]:
        talker, kind = text[1:3], text[3:6]
        if kind not in USED_KINDS or text[1] == "P":
            return []
        try:
            msg = pynmea2.parse(text)
        except (pynmea2.ParseError, ValueError, TypeError, AttributeError, IndexError) as exc:
            raise NmeaError(f"pynmea2 cannot parse {text[:6]}: {exc}") from None
        out: list[GnssSample] = []
        if kind == "GGA":
            tod = _tod_ms(msg)
            qual, nsv = _field(msg, 5), _field(msg, 6)
            if (qual and not qual.isdigit()) or (nsv and not nsv.isdigit()):
                raise NmeaError(f"GGA quality/satellites are not integers: {qual!r}, {nsv!r}")
            self._flush_if_new_epoch(tod, out)
            if tod is not None and qual:
                # several talkers may send GGA (GPGGA + GLGGA): first of the epoch, or ours, wins
                if self._gga is None or self._gga[0] != tod or talker == self.talker:
                    self._gga = (tod, int(qual), int(nsv or 0))
        elif kind == "GST":
            tod = _tod_ms(msg)
            self._flush_if_new_epoch(tod, out)
            sl, so = _num(msg, "std_dev_latitude"), _num(msg, "std_dev_longitude")
            if tod is not None and sl is not None and so is not None:
                self._gst = (tod, math.hypot(sl, so))
        elif kind == "RMC":
            if not self._accept_talker(talker, is_rmc=True):
                return out
            rmc = _decode_rmc(t, talker, msg)
            self._sends_rmc = True
            if self._held is not None:
                out.append(self._sample(self._held, None))
                self._held = None
            self._flush_if_new_epoch(rmc.tod_ms, out)
            if rmc.speed is None and self._sends_vtg and rmc.valid:
                self._held = rmc  # the VTG that follows may carry the speed this RMC lacks
            else:
                out.append(self._sample(rmc, None))
        else:  # VTG
            if not self._accept_talker(talker, is_rmc=False):
                return out
            vtg = _decode_vtg(t, msg)
            self._sends_vtg = True
            if self._held is not None:
                out.append(self._sample(self._held, vtg))
                self._held = None
            elif not self._sends_rmc:
                out.append(self._sample(None, vtg))
        return out

    def flush(self) -> list[GnssSample]:
        """The held epoch, if any (end of stream)."""
        out: list[GnssSample] = []
        if self._held is not None:
            out.append(self._sample(self._held, None))
            self._held = None
        return out

    # -------------------------------------------------------------------------------- internals

    def _accept_talker(self, talker: str, is_rmc: bool) -> bool:
        """Use one talker's velocity only (multi-talker streams repeat or differ per constellation).

        The first RMC talker wins (a VTG talker only until an RMC shows up); a GN (combined
        constellations) RMC takes over from a single-constellation one.
        """
        if is_rmc and (not self._rmc_talker_locked or (talker == "GN" and self.talker != "GN")):
            self.talker, self._rmc_talker_locked = talker, True
        elif self.talker is None:
            self.talker = talker
        if talker != self.talker:
            self.other_talker_sentences += 1
            return False
        return True

    def _flush_if_new_epoch(self, tod: int | None, out: list) -> None:
        if tod is None:
            return
        if self._held is not None and self._held.tod_ms != tod:
            out.append(self._sample(self._held, None))
            self._held = None
        self._last_tod = tod

    def _aux(self, tod: int | None):
        """GGA and GST of this epoch or the previous one (<= 1.5 s older), else None."""
        def fresh(rec):
            if rec is None:
                return None
            if tod is None:
                return rec if rec[0] == self._last_tod else None
            age = (tod - rec[0]) % 86_400_000
            return rec if age <= _AUX_MAX_AGE_MS else None
        return fresh(self._gga), fresh(self._gst)

    def _sample(self, rmc: _Rmc | None, vtg: _Vtg | None) -> GnssSample:
        speed = rmc.speed if rmc is not None and rmc.speed is not None else vtg.speed if vtg else None
        course = rmc.course if rmc is not None and rmc.course is not None else vtg.course if vtg else None
        modes = [m for m in ((rmc.mode if rmc else ""), (vtg.mode if vtg else "")) if m]
        valid = rmc.valid if rmc is not None else bool(modes) or speed is not None
        tod = rmc.tod_ms if rmc is not None else self._last_tod
        gga, gst = self._aux(tod)
        if not valid or "N" in modes or any(m not in _GNSS_MODES and m != "E" for m in modes):
            fix_type, fix_ok = FIX_NONE, False
        elif "E" in modes or (gga is not None and gga[1] == 6):
            fix_type, fix_ok = FIX_DR, True
        else:
            fix_type, fix_ok = FIX_3D, True
        speed_acc = math.nan
        if speed is None:
            vn = ve = math.nan
            fix_ok = False  # invariant: fix_ok implies finite velocity
        elif course is None:
            # receivers blank the course when nearly stationary; the vector is then known only to
            # lie within `speed` of zero, which is folded into the accuracy
            vn = ve = 0.0
            speed_acc = math.hypot(self.nominal_speed_acc, speed)
            if not math.isfinite(speed_acc):
                speed_acc = math.nan
        else:
            c = math.radians(course)
            vn, ve = speed * math.cos(c), speed * math.sin(c)
        t = max(r.t for r in (rmc, vtg) if r is not None)
        return GnssSample(
            t=t, vel_n_mps=vn, vel_e_mps=ve, speed_acc_mps=speed_acc, fix_type=fix_type, fix_ok=fix_ok,
            num_sv=gga[2] if gga else 0, protocol="nmea",
            fix_time_utc_s=rmc.utc_s if rmc is not None else math.nan,
            lat_deg=rmc.lat if rmc is not None else math.nan,
            lon_deg=rmc.lon if rmc is not None else math.nan,
            h_acc_m=gst[1] if gst else math.nan,
        )
