"""NMEA sentences -> GnssSample: one sample per epoch from RMC and/or VTG, enriched by GGA, GNS and GST.

Framing and the ``*hh`` checksum are checked in ``stream.py``; this module gets whole sentences.
pynmea2 splits the fields, but three measured pynmea2 traps are avoided here
(``/work/shared/research/ecosystem.md`` finding 10):

* ``RMC.is_valid`` is False for every u-blox NMEA 4.1 RMC (nav-status field ``V``); validity is
  decided here from the status field and the FAA mode, ignoring nav status.
* A field that fails to convert is returned as the raw string (``'0.0x7'``), and an empty
  latitude becomes 0.0; every number is therefore checked here. A bad speed rejects the sentence
  (counted as malformed); a bad date, position or course drops only that field (reported through
  ``field_errors``) so one corrupt field does not throw away a valid velocity.
* VTG knots are ``Decimal``; everything is converted to float. The old VTG without unit letters
  (NMEA 1.5/2.0: course, course, knots, km/h) is mapped onto the lettered fields: it is read here.

Epochs are assembled by **time of day, whatever the talker**: receivers switch talker ids
between epochs (Trimble: GN -> GP -> GN) and some repeat an epoch per constellation (GPRMC +
GARMC); the first velocity sentence of an epoch is used, later copies are counted as duplicates.
Emission is driven by the velocity sentence so that no sample waits for later sentences of the
epoch (GGA/GST come after RMC on u-blox; at 9600 baud that would add ~0.1 s): an RMC with a
speed is emitted at once; an RMC without one waits for the VTG that follows it (only if this
stream sends VTG). A stream without RMC is served from VTG, which carries no time: the VTG
waits for the next timed sentence (GGA, GNS, GLL, ZDA, GST) and takes its epoch, unless that
sentence comes more than ``_VTG_EPOCH_GAP_S`` of receive time later (then the VTG ended the
previous epoch). The date comes from RMC or ZDA. GGA/GNS and GST contribute fix quality,
satellites and horizontal accuracy from the same or the previous epoch (at most 1.5 s older),
and the altitude with the time of its own epoch (GGA usually follows the RMC, so a sample carries the
previous epoch's height; the estimator differences heights at their own times, see
``estimator/altitude_grade.py``). An empty altitude, or one without a GNSS fix (quality 0, 6 dead
reckoning, 7 manual, 8 simulator), is NaN.

Heading sentences (dual-antenna receivers: HDT, THS) are not part of an epoch: each gives one
GnssHeadingSample at once (they carry no time; HDT no validity either, so an empty heading field is
the only "invalid" it has; THS is valid in modes A autonomous and D differential only).
pynmea2 has no THS class; the few lines below declare one the way pynmea2 declares its own.

An RMC/VTG with a speed but no course (receivers blank it when slow) gives a sample with
``course_known=False``: its speed is usable, its direction is not.
"""
from __future__ import annotations

import datetime
import math
import re
from dataclasses import dataclass

import pynmea2

from ..samples import FIX_3D, FIX_DR, FIX_NONE, GnssHeadingSample, GnssSample

__all__ = ["MPS_PER_KNOT", "NmeaError", "NmeaEpochAssembler", "nmea_checksum_ok", "VELOCITY_KINDS",
           "TIMED_KINDS", "HEADING_KINDS", "USED_KINDS"]

MPS_PER_KNOT = 1852.0 / 3600.0
VELOCITY_KINDS = frozenset({"RMC", "VTG"})
#: Sentences that carry the epoch's time of day (and, for ZDA, the date).
TIMED_KINDS = frozenset({"GGA", "GNS", "GLL", "ZDA", "GST"})
#: Dual-antenna heading sentences (true heading of the antenna baseline).
HEADING_KINDS = frozenset({"HDT", "THS"})
USED_KINDS = VELOCITY_KINDS | TIMED_KINDS | HEADING_KINDS
#: THS mode indicators of a measured heading (E estimated/dead reckoning, M manual, S simulator, V invalid).
_THS_VALID_MODES = frozenset("AD")
#: A VTG followed by a timed sentence more than this later (receive time) ended the previous epoch.
_VTG_EPOCH_GAP_S = 0.5
_DAY_MS = 86_400_000
_EPOCH_ORDINAL = datetime.date(1970, 1, 1).toordinal()
#: GGA/GST older than this (relative to the RMC) are not used for the sample.
_AUX_MAX_AGE_MS = 1500
#: FAA mode indicators that mean a usable GNSS solution (A autonomous, D differential, P precise,
#: R RTK fixed, F RTK float). E is dead reckoning; N no fix; M manual and S simulator are not fixes.
_GNSS_MODES = frozenset("ADPRF")
#: GGA qualities whose altitude is measured: GNSS, DGNSS, PPS, RTK fixed / float (not 0 none,
#: 6 dead reckoning, 7 manual, 8 simulator)
_ALT_QUALITIES = frozenset({1, 2, 3, 4, 5})
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


def _tod_ms(msg, i: int = 0) -> int | None:
    """Time of day of field ``i`` (hhmmss[.sss]) in ms; rounded, not pynmea2's truncating parse."""
    raw = _field(msg, i)
    if raw == "":
        return None
    m = _TIME.match(raw)
    # second 60 only as a leap second, 23:59:60 (its time of day is then >= _DAY_MS)
    if not m or int(m[1]) > 23 or int(m[2]) > 59 or int(m[3]) > 60 or (int(m[3]) == 60 and raw[:4] != "2359"):
        raise NmeaError(f"{msg.sentence_type} time is not hhmmss.ss: {raw!r}")
    return (int(m[1]) * 3600 + int(m[2]) * 60 + int(m[3])) * 1000 + round(float(m[4] or 0) * 1000)


def _days(year: int, month: int, day: int) -> int:
    """Days since 1970-01-01; ValueError for an impossible date."""
    return datetime.date(year, month, day).toordinal() - _EPOCH_ORDINAL


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



def _optional(errors: list[str], fn, *args, default=None):
    """``fn(*args)``, or ``default`` with the reason appended to ``errors`` (one bad field only)."""
    try:
        return fn(*args)
    except NmeaError as exc:
        errors.append(str(exc))
        return default


@dataclass(slots=True)
class _Rmc:
    t: float
    tod_ms: int | None
    day: int | None  # days since 1970 (RMC date), None when absent or bad
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


def _rmc_day(msg) -> int | None:
    date = _field(msg, 8)
    if not date:
        return None
    if re.match(r"^\d{6}$", date):
        yy = int(date[4:6])
        try:
            return _days(2000 + yy if yy < 80 else 1900 + yy, int(date[2:4]), int(date[0:2]))
        except ValueError:
            pass
    raise NmeaError(f"RMC date is not ddmmyy: {date!r} (date dropped, rest of the sentence kept)")


def _decode_rmc(t: float, msg, errors: list[str]) -> _Rmc:
    speed = _num(msg, "spd_over_grnd")  # the one field without which the sentence is useless
    valid = _field(msg, 1) == "A"
    lat = lon = math.nan
    try:
        lat = _coord(_field(msg, 2), _field(msg, 3), 90, "RMC latitude")
        lon = _coord(_field(msg, 4), _field(msg, 5), 180, "RMC longitude")
    except NmeaError as exc:
        if valid:  # receivers print placeholders like 36000.0000 without a fix: not worth a word
            errors.append(f"{exc} (position dropped)")
        lat = lon = math.nan
    course = _optional(errors, _num, msg, "true_course")
    return _Rmc(t=t, tod_ms=_optional(errors, _tod_ms, msg), day=_optional(errors, _rmc_day, msg),
                valid=valid, mode=_field(msg, 11), lat=lat, lon=lon,
                speed=None if speed is None else speed * MPS_PER_KNOT, course=course)


def _decode_vtg(t: float, msg) -> _Vtg:
    if len(msg.data) == 4:  # NMEA 1.5/2.0 had no unit letters: "054.7,034.4,005.5,010.2"
        return _vtg_without_units(t, msg)
    kn = _num(msg, "spd_over_grnd_kts")
    kmh = _num(msg, "spd_over_grnd_kmph")
    speed = kn * MPS_PER_KNOT if kn is not None else None if kmh is None else kmh / 3.6
    if _field(msg, 1) not in ("T", "") or _field(msg, 5) not in ("N", ""):
        raise NmeaError(f"VTG fields are neither course,T,course,M,knots,N,km/h,K nor course,course,knots,km/h:"
                        f" {','.join(msg.data)[:40]!r}")
    return _Vtg(t=t, speed=speed, course=_num(msg, "true_track"), mode=_field(msg, 8))


def _vtg_without_units(t: float, msg) -> _Vtg:
    """The old VTG layout, course true, course magnetic, knots, km/h (no mode: pynmea2 maps it to
    the newer fields, so the speed would read as missing and the epoch as fix-less)."""
    def num(i: int, what: str) -> float | None:
        raw = _field(msg, i)
        try:
            v = float(raw) if raw else None
        except ValueError:
            v = math.inf
        if v is not None and not (math.isfinite(v) and v >= 0.0):
            raise NmeaError(f"VTG {what} is not a number: {raw!r}")
        return v
    kn, kmh = num(2, "speed (knots)"), num(3, "speed (km/h)")
    speed = kn * MPS_PER_KNOT if kn is not None else None if kmh is None else kmh / 3.6
    return _Vtg(t=t, speed=speed, course=num(0, "course"), mode="")


def _int_field(msg, i: int, what: str) -> int | None:
    v = _field(msg, i)
    if v == "":
        return None
    if not v.isdigit():
        raise NmeaError(f"{msg.sentence_type} {what} is not an integer: {v!r}")
    return int(v)


class THS(pynmea2.TalkerSentence):
    """True heading and status (NMEA 0183 v4): registered with pynmea2 by being defined."""

    fields = (("True heading", "heading"), ("Mode indicator", "mode"))


def _decode_heading(t: float, kind: str, msg) -> GnssHeadingSample:
    """HDT / THS -> a heading sample; an empty or non-numeric heading is an invalid sample."""
    h = _num(msg, "heading")
    mode_ok = kind == "HDT" or (getattr(msg, "mode", "") or "")[:1] in _THS_VALID_MODES
    ok = h is not None and 0.0 <= h <= 360.0 and mode_ok
    return GnssHeadingSample(t=t, heading_rad=math.radians(h) % (2.0 * math.pi) if ok else math.nan,
                             heading_acc_rad=math.nan, baseline_m=math.nan, valid=ok, protocol="nmea")


# ------------------------------------------------------------------------------ assembler

class NmeaEpochAssembler:
    """Turns the checksum-valid NMEA sentences of one stream into one GnssSample per epoch.

    ``add(t, sentence_text)`` returns the samples completed by that sentence (0, 1 or 2);
    ``flush()`` returns a held epoch at end of stream. ``duplicates`` counts velocity sentences
    of an epoch already emitted (another talker's copy); ``field_errors`` collects the reasons
    a field was dropped from an otherwise used sentence (the caller drains and reports them).
    NMEA samples carry NaN speed accuracy: the estimator applies its configured value.
    Raises NmeaError for unusable content (pynmea2.ParseError is converted too).
    """

    def __init__(self) -> None:
        self.duplicates = 0
        self.field_errors: list[str] = []
        self._sends_vtg = False
        self._sends_rmc = False
        self._held: _Rmc | None = None  # RMC without speed, waiting for its VTG
        self._vtg: _Vtg | None = None  # VTG of an RMC-less stream, waiting for its epoch's time
        self._vtg_tod_before: int | None = None  # time of the last timed sentence before that VTG
        self._done_tod: int | None = None  # epoch whose sample was emitted
        self._gga: tuple[int, int, int, float] | None = None  # tod_ms, quality, num_sv, altitude m (GGA or GNS)
        self._gst: tuple[int, float] | None = None  # tod_ms, horizontal 1-sigma m
        self._date: tuple[int, int] | None = None  # (days since 1970, tod_ms) of the last RMC/ZDA date
        self._last_tod: int | None = None
        self._leap_end: float | None = None  # POSIX time at the end of a leap second this stream sent

    def add(self, t: float, text: str) -> list[GnssSample]:
        kind = text[3:6]
        if kind not in USED_KINDS or text[1] == "P":
            return []
        try:
            msg = pynmea2.parse(text)
        except (pynmea2.ParseError, ValueError, TypeError, AttributeError, IndexError) as exc:
            raise NmeaError(f"pynmea2 cannot parse {text[:6]}: {exc}") from None
        out: list[GnssSample] = []
        if kind in HEADING_KINDS:
            out.append(_decode_heading(t, kind, msg))
        elif kind == "RMC":
            self._rmc(_decode_rmc(t, msg, self.field_errors), out)
        elif kind == "VTG":
            self._vtg_sentence(_decode_vtg(t, msg), out)
        else:
            self._timed(t, kind, msg, out)
        return out

    def flush(self) -> list[GnssSample]:
        """The held epoch, if any (end of stream)."""
        out: list[GnssSample] = []
        if self._held is not None:
            self._emit(self._held, None, self._held.tod_ms, out)
            self._held = None
        if self._vtg is not None:
            self._emit(None, self._vtg, self._vtg_tod_before, out)
            self._vtg = None
        return out

    # -------------------------------------------------------------------------------- internals

    def _rmc(self, rmc: _Rmc, out: list) -> None:
        self._sends_rmc = True
        if self._vtg is not None:  # the stream turned out to send RMC: the VTG before it is alone
            self._emit(None, self._vtg, self._vtg_tod_before, out)
            self._vtg = None
        if rmc.day is not None and rmc.tod_ms is not None:
            self._date = (rmc.day, rmc.tod_ms)
        if self._held is not None:
            if rmc.tod_ms is not None and rmc.tod_ms == self._held.tod_ms:
                self.duplicates += 1  # another talker's RMC of the held epoch
                return
            self._emit(self._held, None, self._held.tod_ms, out)
            self._held = None
        self._new_time(rmc.tod_ms)
        if rmc.tod_ms is not None and rmc.tod_ms == self._done_tod:
            self.duplicates += 1
            return
        if rmc.speed is None and self._sends_vtg and rmc.valid:
            self._held = rmc  # the VTG that follows may carry the speed this RMC lacks
        else:
            self._emit(rmc, None, rmc.tod_ms, out)

    def _vtg_sentence(self, vtg: _Vtg, out: list) -> None:
        self._sends_vtg = True
        if self._held is not None:
            self._emit(self._held, vtg, self._held.tod_ms, out)
            self._held = None
        elif not self._sends_rmc:
            if self._vtg is not None:  # two VTGs without a time between them
                self._emit(None, self._vtg, self._vtg_tod_before, out)
            self._vtg, self._vtg_tod_before = vtg, self._last_tod

    def _timed(self, t: float, kind: str, msg, out: list) -> None:
        """GGA, GNS, GLL, ZDA, GST: the epoch's time (and fix quality, accuracy, date)."""
        tod = _tod_ms(msg, 4 if kind == "GLL" else 0)
        vtg, before = self._vtg, self._vtg_tod_before
        if vtg is not None and tod is not None and before is not None and tod != before \
                and t - vtg.t > _VTG_EPOCH_GAP_S:
            self._vtg = None  # the pause before this sentence was the epoch boundary
            self._emit(None, vtg, before, out)
        if kind == "GGA":
            self._aux_fix(tod, _int_field(msg, 5, "quality"), _int_field(msg, 6, "satellites"),
                          self._altitude(msg, 8))
        elif kind == "GNS":
            mode = _field(msg, 5)
            qual = (1 if any(m in _GNSS_MODES for m in mode) else 6 if "E" in mode else 0) if mode else None
            self._aux_fix(tod, qual, _int_field(msg, 6, "satellites"), self._altitude(msg, 8))
        elif kind == "ZDA":
            day = _optional(self.field_errors, self._zda_day, msg)
            if tod is not None and day is not None:
                self._date = (day, tod)
        elif kind == "GST":
            sl, so = _num(msg, "std_dev_latitude"), _num(msg, "std_dev_longitude")
            if tod is not None and sl is not None and so is not None:
                self._gst = (tod, math.hypot(sl, so))
        if tod is None:
            return
        if self._held is not None and self._held.tod_ms != tod:
            self._emit(self._held, None, self._held.tod_ms, out)
            self._held = None
        self._new_time(tod)
        if self._vtg is not None:  # the VTG belongs to the epoch this sentence dates
            vtg, self._vtg = self._vtg, None
            self._emit(None, vtg, tod, out)

    @staticmethod
    def _zda_day(msg) -> int | None:
        d, m, y = _field(msg, 1), _field(msg, 2), _field(msg, 3)
        if not (d or m or y):
            return None
        try:
            return _days(int(y), int(m), int(d))
        except ValueError:
            raise NmeaError(f"ZDA date is not dd,mm,yyyy: {d!r},{m!r},{y!r} (date dropped)") from None

    def _altitude(self, msg, i: int) -> float:
        """Altitude above MSL (field i, metres); NaN when empty or not a number (dropped, reported)."""
        raw = _field(msg, i)
        if raw == "":
            return math.nan
        try:
            alt = float(raw)
        except ValueError:
            alt = math.nan
        if not (math.isfinite(alt) and -1000.0 < alt < 20000.0):
            self.field_errors.append(f"{msg.sentence_type} altitude is not a height in m: {raw!r} (altitude dropped)")
            return math.nan
        return alt

    def _aux_fix(self, tod: int | None, qual: int | None, nsv: int | None, alt: float = math.nan) -> None:
        # several talkers may send GGA (GPGGA + GLGGA): the first of the epoch wins
        if tod is not None and qual is not None and (self._gga is None or self._gga[0] != tod):
            self._gga = (tod, qual, nsv or 0, alt if qual in _ALT_QUALITIES else math.nan)

    def _new_time(self, tod: int | None) -> None:
        if tod is not None:
            self._last_tod = tod

    def _utc(self, tod: int | None) -> float:
        """UTC seconds of an epoch from its time of day and the last date seen (midnight-safe).

        A leap second (23:59:60.xx) has no POSIX time of its own: read plainly it is the next
        day's 00:00:00.xx, and the times would step back 1 s. It is put where it is (after
        23:59:59.xx) and the stream's later times run 1 s ahead of POSIX, so the times stay
        monotone and their differences (what the estimator uses: epoch matching, the distance
        between altitudes) stay true."""
        if tod is None or self._date is None:
            return math.nan
        day, date_tod = self._date
        diff = tod - date_tod
        day += 1 if diff < -_DAY_MS // 2 else -1 if diff > _DAY_MS // 2 else 0
        utc = day * 86400.0 + tod / 1000.0
        if tod >= _DAY_MS:  # 23:59:60.xx
            self._leap_end = day * 86400.0 + 86400.0
        elif self._leap_end is not None and utc >= self._leap_end:
            utc += 1.0
        return utc

    def _aux(self, tod: int | None):
        """GGA/GNS and GST of this epoch or the previous one (<= 1.5 s older), else None."""
        def fresh(rec):
            if rec is None or tod is None:
                return None
            age = tod - rec[0]
            if age < -_DAY_MS // 2:  # across midnight (from a leap second 23:59:60: 1 s more)
                age += _DAY_MS + (1000 if rec[0] >= _DAY_MS else 0)
            return rec if 0 <= age <= _AUX_MAX_AGE_MS else None
        return fresh(self._gga), fresh(self._gst)

    def _emit(self, rmc: _Rmc | None, vtg: _Vtg | None, tod: int | None, out: list) -> None:
        if tod is not None and tod == self._done_tod:
            self.duplicates += 1
            return
        if tod is not None:
            self._done_tod = tod
        out.append(self._sample(rmc, vtg, tod))

    def _sample(self, rmc: _Rmc | None, vtg: _Vtg | None, tod: int | None) -> GnssSample:
        speed = rmc.speed if rmc is not None and rmc.speed is not None else vtg.speed if vtg else None
        course = rmc.course if rmc is not None and rmc.course is not None else vtg.course if vtg else None
        modes = [m for m in ((rmc.mode if rmc else ""), (vtg.mode if vtg else "")) if m]
        valid = rmc.valid if rmc is not None else bool(modes) or speed is not None
        gga, gst = self._aux(tod)
        if not valid or "N" in modes or any(m not in _GNSS_MODES and m != "E" for m in modes) \
                or (rmc is None and not modes and gga is not None and gga[1] == 0):
            fix_type, fix_ok = FIX_NONE, False
        elif "E" in modes or (gga is not None and gga[1] == 6):
            fix_type, fix_ok = FIX_DR, True
        else:
            fix_type, fix_ok = FIX_3D, True
        vn = ve = ground = math.nan
        if speed is None:
            fix_ok = False  # invariant: fix_ok implies a finite speed
        elif course is None:
            ground = speed  # receivers blank the course when slow: the speed alone is still true
        else:
            c = math.radians(course)
            vn, ve = speed * math.cos(c), speed * math.sin(c)
        t = max(r.t for r in (rmc, vtg) if r is not None)
        return GnssSample(
            t=t, vel_n_mps=vn, vel_e_mps=ve, speed_acc_mps=math.nan, fix_type=fix_type, fix_ok=fix_ok,
            num_sv=gga[2] if gga else 0, protocol="nmea", fix_time_utc_s=self._utc(tod),
            lat_deg=rmc.lat if rmc is not None else math.nan,
            lon_deg=rmc.lon if rmc is not None else math.nan,
            h_acc_m=gst[1] if gst else math.nan,
            course_known=course is not None or speed is None, ground_speed_mps=ground,
            alt_m=gga[3] if gga else math.nan, alt_time_utc_s=self._utc(gga[0]) if gga else math.nan,
        )
