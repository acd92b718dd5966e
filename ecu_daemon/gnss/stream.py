"""One serial byte stream (UBX + NMEA + RTCM3 interleaved, split anywhere, with garbage) -> GnssSamples
(velocity) and GnssHeadingSamples (dual-antenna heading: NAV-RELPOSNED, HDT, THS).

The framing is done here rather than by pyubx2's ``UBXReader`` because a reader that trusts a
corrupted length field swallows the good frames behind it. Rules:

* A frame candidate starts at ``B5 62`` (UBX), ``$`` or ``!`` (NMEA) or ``D3`` (RTCM3). A UBX/RTCM3
  candidate whose class, length or checksum is wrong is rejected by skipping **one** byte and
  rescanning, so any good frame inside or behind it is still found. An NMEA candidate ends at
  the first byte that is not printable ASCII; a sentence cut short that way is skipped whole
  (it cannot contain another frame start) and counted as truncated.
* Every byte that ends up in no accepted frame is counted in ``garbage_bytes``.
* Each byte carries the ``t`` of the ``feed`` call that delivered it; a frame is stamped with the
  time of its last byte (NMEA: its first line-ending byte), so the result does not depend on how
  the stream was chunked, even when a bogus length field makes the parser wait for more bytes.

Errors are counted in ``stats``, described in ``last_error`` and logged as one line per kind,
at most once per ``log_interval_s`` of stream time (with the count of suppressed repeats).
"""
from __future__ import annotations

import logging
import re
from collections import deque
from dataclasses import replace
from typing import Callable

import numpy as np

from ..io.logging_setup import RateLimitedLog
from ..samples import GnssHeadingSample, GnssSample
from .nmea import USED_KINDS, VELOCITY_KINDS, NmeaEpochAssembler, NmeaError, nmea_checksum_ok
from .ubx import (HNR_PVT, NAV_PVT, NAV_SOL, NAV_VELNED, UBX_CLASS_BYTES, UBX_MAX_PAYLOAD, UbxDecoder, UbxError,
                  ubx_checksum)

__all__ = ["GnssStreamParser", "STAT_KEYS", "crc24q", "sum_stats"]

log = logging.getLogger("ecu_daemon.gnss")

STAT_KEYS = ("ubx_frames", "nmea_sentences", "rtcm_frames", "samples", "checksum_errors",
             "garbage_bytes", "unsupported", "truncated", "malformed", "ignored", "suppressed")

#: NMEA 0183 allows 82 characters; proprietary sentences (PUBX,03, PSTM...) run longer.
NMEA_MAX_LEN = 1024
#: Longest a NAV-SOL sample waits (receive time) for the next frame before it is released anyway.
NAV_SOL_HOLD_S = 0.25
_START = re.compile(rb"[\xb5$!\xd3]")
_NMEA_BODY = re.compile(rb"[\x20\x22\x23\x25-\x7e]*")  # printable ASCII except the starts '$' and '!'
_SENTENCE_HEAD = re.compile(rb"[$!][A-Z0-9]{4}")  # what makes a cut-off fragment a "truncated" sentence
#: UBX messages a velocity sample comes from (ubx.py): NAV-PVT, or on older receivers NAV-SOL, HNR-PVT, NAV-VELNED
_UBX_VELOCITY = frozenset({NAV_PVT, NAV_SOL, HNR_PVT, NAV_VELNED})
_NAV_STATUS = (0x01, 0x03)
_NEED, _NOT, _BAD, _FRAG, _UBX, _NMEA, _RTCM = range(7)


def _crc24q_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 16
        for _ in range(8):
            crc = (crc << 1) ^ 0x1864CFB if crc & 0x800000 else crc << 1
        table.append(crc & 0xFFFFFF)
    return table


_CRC24Q = _crc24q_table()


def crc24q(data: bytes | bytearray | memoryview) -> int:
    """The RTCM3 CRC (Qualcomm CRC-24Q)."""
    crc = 0
    for b in data:
        crc = ((crc << 8) & 0xFFFFFF) ^ _CRC24Q[(crc >> 16) ^ b]
    return crc


def _mulmod24(a: int, b: int) -> int:
    """a * b in GF(2)[x] modulo the CRC-24Q polynomial."""
    r = 0
    while b:
        if b & 1:
            r ^= a
        b >>= 1
        a <<= 1
        if a & 0x1000000:
            a ^= 0x1864CFB
    return r


def _zero_byte_powers(n: int) -> list[int]:
    """x^(8k) mod the CRC-24Q polynomial for k = 0..n: what k zero bytes do to a CRC register."""
    out = [1]
    for _ in range(n):
        out.append(_mulmod24(out[-1], 0x100))
    return out


_RTCM_MAX = 6 + 1023
_X8K = _zero_byte_powers(_RTCM_MAX)
#: a claimed frame longer than this is checked through the prefix sums of the whole buffer; up to
#: it directly (NAV-PVT's 96 checked bytes: building the prefix sums per frame cost ~25 us)
_LONG = 128


class _RangeChecks:
    """Fletcher-8 (UBX) and CRC-24Q (RTCM3) of any range of the buffer in O(1), after one O(n) pass.

    Why: garbage made of repeated frame headers (``B5 62 01 07 FF 1F`` ...) claims a long frame
    every few bytes; checking each candidate over its whole claimed length made resynchronising
    cost length x bytes (4 kB/s). Both checks are linear in the data, so a range follows from two
    prefixes: Fletcher from prefix sums, CRC-24Q (init 0, no final xor) from prefix CRCs as
    ``crc(B) = crc(A || B) ^ crc(A) * x^(8 |B|)``.
    """

    def __init__(self, buf: bytearray, n: int):
        a = np.frombuffer(bytes(buf[:n]), dtype=np.uint8).astype(np.int64)
        self.s = np.concatenate(([0], np.cumsum(a)))
        self.w = np.concatenate(([0], np.cumsum(a * np.arange(n, dtype=np.int64))))
        self.buf = buf
        self.n = n
        self._crc: list[int] | None = None

    def fletcher(self, a: int, b: int) -> bytes:
        """UBX checksum of buf[a:b]: byte i is added into CK_B (b - i) times."""
        sa = int(self.s[b] - self.s[a])
        return bytes((sa & 0xFF, (b * sa - int(self.w[b] - self.w[a])) & 0xFF))

    def crc24q(self, a: int, b: int) -> int:
        if self._crc is None:
            crc, table, p = 0, _CRC24Q, [0]
            for byte in self.buf[:self.n]:
                crc = ((crc << 8) & 0xFFFFFF) ^ table[(crc >> 16) ^ byte]
                p.append(crc)
            self._crc = p
        return self._crc[b] ^ _mulmod24(self._crc[a], _X8K[b - a])


class GnssStreamParser:
    """Incremental parser for one receiver byte stream.

    ``protocol``: ``"auto"`` (UBX and NMEA both used; while UBX velocities keep arriving -- within
    ``prefer_ubx_s`` -- NMEA samples are dropped and counted as ``suppressed`` so one receiver
    emitting both does not double every epoch), ``"ubx"`` or ``"nmea"`` (frames of the other
    protocol are framed and counted as ``ignored``). RTCM3 frames are always skipped.

    ``source``: the receiver's index in the config, stamped on every sample (``GnssSample.source``).

    ``raw_sink(t, data)``: optional; receives every accepted frame (NMEA with its line ending when
    present) and every run of rejected bytes, in stream order -- what ``GnssLogWriter`` records.
    """

    def __init__(self, protocol: str = "auto", *,
                 name: str = "gnss", raw_sink: Callable[[float, bytes], None] | None = None,
                 log_interval_s: float = 10.0, prefer_ubx_s: float = 2.0, source: int = 0) -> None:
        if protocol not in ("auto", "ubx", "nmea"):
            raise ValueError(f"protocol must be auto, ubx or nmea, got {protocol!r}")
        self.protocol = protocol
        self.source = source
        self.stats: dict[str, int] = dict.fromkeys(STAT_KEYS, 0)
        self.last_error = ""
        self._name = name
        self._report = RateLimitedLog(log, log_interval_s)
        self._sink = raw_sink
        self._prefer_ubx_s = prefer_ubx_s
        self._ubx = UbxDecoder()
        self._nmea = NmeaEpochAssembler()
        self._buf = bytearray()
        self._base = 0  # absolute stream offset of _buf[0]
        self._marks: deque[tuple[int, float]] = deque()  # (absolute end offset, t) per feed
        self._skip_lf = 0  # previous sentence ended in CR at the end of a read (2: it was rejected)
        self._junk = bytearray()  # rejected bytes not yet handed to raw_sink
        self._junk_t = 0.0
        self._last_pvt_t: float | None = None
        self._last_ubx_heading_t: float | None = None
        self._checks: _RangeChecks | None = None
        # what the stream carried, for why_unusable(): UBX (class, id) and NMEA sentence kinds seen,
        # velocity samples whose receiver reported a fix
        self.seen_ubx: dict[tuple[int, int], int] = {}
        self.seen_nmea: dict[str, int] = {}
        self.fixes = 0

    # ------------------------------------------------------------------------------ public API

    def feed(self, t: float, data: bytes) -> list[GnssSample]:
        """Add bytes received at host time ``t``; return the samples they completed."""
        if not data:
            return []
        self._buf += data
        self._marks.append((self._base + len(self._buf), float(t)))
        out: list[GnssSample] = []
        # a NAV-SOL waits for a NAV-PVT of its epoch; at 9600 baud that follows within ~0.1 s
        self._emit_ubx(self._ubx.flush(before=t - NAV_SOL_HOLD_S), out)
        self._scan(out, final=False)
        return out

    def finish(self) -> list[GnssSample]:
        """End of stream (or the port closed): resolve what is pending, count a cut-off frame.

        The parser stays usable; the next ``feed`` starts from an empty buffer.
        """
        out: list[GnssSample] = []
        self._scan(out, final=True)
        self._emit_ubx(self._ubx.flush(), out)
        self._emit_nmea(self._nmea.flush(), out)
        self._flush_junk()
        self._skip_lf = 0
        return out

    # ------------------------------------------------------------------------------ framing

    def _scan(self, out: list, final: bool) -> None:
        buf, n, pos = self._buf, len(self._buf), 0
        self._checks = None  # _RangeChecks of buf[:n], built when a long candidate needs it
        if self._skip_lf and n:
            if buf[0] == 0x0A:
                pos = 1
                if self._skip_lf == 2:  # the LF of a rejected sentence is rejected with it
                    self._account_reject(1)
            self._skip_lf = 0
        truncated_counted = False
        while pos < n:
            m = _START.search(buf, pos)
            s = m.start() if m else n
            if s > pos:
                self._reject(pos, s)
            if m is None:
                pos = n
                break
            kind, end = self._frame_at(buf, s, n)
            if kind == _NEED and final:
                if not truncated_counted:
                    truncated_counted = True
                    self._error(self._t_at(n - 1), "truncated", "truncated",
                                f"stream ended inside a frame ({n - s} bytes pending)")
                kind, end = (_FRAG, n) if buf[s] in (0x24, 0x21) else (_NOT, s + 1)
            if kind == _NEED:
                pos = s
                break
            if kind == _NOT or kind == _BAD:
                self._reject(s, s + 1)
                pos = s + 1
            elif kind == _FRAG:
                if (end < n or not final) and _SENTENCE_HEAD.match(buf, s):
                    self._error(self._t_at(end - 1), "truncated", "truncated",
                                f"NMEA sentence cut off after {end - s} bytes")
                self._reject(s, end)
                pos = end
            else:
                self._flush_junk()
                pos = self._dispatch(kind, s, end, out)
        del buf[:pos]
        self._base += pos
        marks = self._marks
        while marks and marks[0][0] <= self._base:
            marks.popleft()
        if final and self._junk:
            self._flush_junk()

    def _frame_at(self, buf: bytearray, s: int, n: int) -> tuple[int, int]:
        """Classify the candidate at ``s``: (_NEED | _NOT | _BAD | _FRAG | _UBX | _NMEA | _RTCM, end)."""
        c = buf[s]
        avail = n - s
        if c == 0x24 or c == 0x21:  # '$' or '!' (encapsulation sentences, e.g. AIS)
            e = _NMEA_BODY.match(buf, s + 1).end()
            if e - s > NMEA_MAX_LEN:
                return _FRAG, e
            if e == n:
                return _NEED, 0
            term = buf[e]
            if term != 0x0D and term != 0x0A:
                return _FRAG, e
            return _NMEA, e
        if c == 0xB5:
            if avail < 2:
                return _NEED, 0
            if buf[s + 1] != 0x62:
                return _NOT, 0
            if avail < 3:
                return _NEED, 0
            if buf[s + 2] not in UBX_CLASS_BYTES:
                return _NOT, 0
            if avail < 6:
                return _NEED, 0
            length = buf[s + 4] | buf[s + 5] << 8
            if length > UBX_MAX_PAYLOAD:
                return _NOT, 0
            end = s + 8 + length
            if end > n:
                return _NEED, 0
            ck = ubx_checksum(buf[s + 2:end - 2]) if length <= _LONG else self._range_checks(buf, n).fletcher(s + 2, end - 2)
            if ck != buf[end - 2:end]:
                self._error(self._t_at(end - 1), "checksum", "checksum_errors",
                            f"UBX {buf[s + 2]:02X} {buf[s + 3]:02X} checksum error ({length} byte payload)")
                return _BAD, 0
            return _UBX, end
        # 0xD3: RTCM3 -- 6 reserved bits zero, 10-bit length, payload, CRC-24Q
        if avail < 3:
            return _NEED, 0
        if buf[s + 1] & 0xFC:
            return _NOT, 0
        end = s + 6 + ((buf[s + 1] & 0x03) << 8 | buf[s + 2])
        if end > n:
            return _NEED, 0
        crc = crc24q(buf[s:end - 3]) if end - s <= _LONG else self._range_checks(buf, n).crc24q(s, end - 3)
        if crc != int.from_bytes(buf[end - 3:end], "big"):
            self._error(self._t_at(end - 1), "checksum", "checksum_errors", "RTCM3 CRC error")
            return _BAD, 0
        return _RTCM, end

    def _range_checks(self, buf: bytearray, n: int) -> _RangeChecks:
        if self._checks is None:
            self._checks = _RangeChecks(buf, n)
        return self._checks

    # ------------------------------------------------------------------------------ dispatch

    def _dispatch(self, kind: int, s: int, end: int, out: list) -> int:
        """Handle the accepted frame at [s, end); return where the scan continues."""
        buf = self._buf
        if kind == _NMEA:
            e = end  # index of the first line-ending byte
            t = self._t_at(e)
            end = e + 1
            cr_at_end = False
            if buf[e] == 0x0D:
                if end < len(buf):
                    end += buf[end] == 0x0A
                else:
                    cr_at_end = True  # its LF, if any, arrives with the next read
            if self._sink:
                self._sink(t, bytes(buf[s:end]))
            accepted = self._nmea_sentence(t, bytes(buf[s:e]).rstrip(b" "), out)
            if not accepted:
                self._account_reject(end - s)
            if cr_at_end:
                self._skip_lf = 1 if accepted else 2
            return end
        t = self._t_at(end - 1)
        if self._sink:
            self._sink(t, bytes(buf[s:end]))
        if kind == _RTCM:
            self.stats["rtcm_frames"] += 1
        else:
            self.stats["ubx_frames"] += 1
            self._ubx_frame(t, bytes(buf[s:end]), out)
        return end

    def _ubx_frame(self, t: float, frame: bytes, out: list) -> None:
        cls_id = (frame[2], frame[3])
        self.seen_ubx[cls_id] = self.seen_ubx.get(cls_id, 0) + 1
        if self.protocol == "nmea":
            self.stats["ignored"] += 1
            return
        if not UbxDecoder.supported(cls_id):
            self.stats["unsupported"] += 1
        try:
            samples = self._ubx.decode(t, frame)
        except UbxError as exc:
            self._error(t, "malformed", "malformed", str(exc))
            return
        self._emit_ubx(samples, out)

    def _emit_ubx(self, samples: list[GnssSample], out: list) -> None:
        for sample in samples:
            # a UBX velocity (heading): the same receiver's NMEA copy of it is not used
            if type(sample) is GnssHeadingSample:
                self._last_ubx_heading_t = sample.t
            else:
                self._last_pvt_t = sample.t
                self.fixes += sample.fix_ok
            self.stats["samples"] += 1
            out.append(replace(sample, source=self.source) if self.source else sample)

    def _nmea_sentence(self, t: float, sentence: bytes, out: list) -> bool:
        """Check and use one sentence; False when its checksum rejects it."""
        ok = nmea_checksum_ok(sentence)
        if not ok:
            what = "without *hh checksum" if ok is None else "checksum error"
            self._error(t, "checksum", "checksum_errors", f"NMEA {what}: {sentence[:16].decode('ascii')}...")
            return False
        self.stats["nmea_sentences"] += 1
        text = sentence.decode("ascii")
        kind = "P" + text[2:5] if text[1] == "P" else text[3:6]  # PUBX, PSTM..., else GGA, RMC...
        self.seen_nmea[kind] = self.seen_nmea.get(kind, 0) + 1
        if self.protocol == "ubx":
            self.stats["ignored"] += 1
            return True
        if text[1] == "P" or text[3:6] not in USED_KINDS:
            self.stats["unsupported"] += 1
            return True
        nmea = self._nmea
        duplicates = nmea.duplicates
        try:
            samples = nmea.add(t, text)
        except NmeaError as exc:
            self._error(t, "malformed", "malformed", str(exc))
            return True
        finally:
            for text in nmea.field_errors:  # a field dropped, the rest of the sentence used
                self._error(t, "malformed", "malformed", text)
            nmea.field_errors.clear()
        if nmea.duplicates != duplicates:
            self.stats["ignored"] += 1
        self._emit_nmea(samples, out)
        return True

    def _emit_nmea(self, samples: list[GnssSample], out: list) -> None:
        for smp in samples:
            last_ubx = self._last_ubx_heading_t if type(smp) is GnssHeadingSample else self._last_pvt_t
            if (self.protocol == "auto" and last_ubx is not None
                    and abs(smp.t - last_ubx) <= self._prefer_ubx_s):
                self.stats["suppressed"] += 1
                continue
            self.stats["samples"] += 1
            if type(smp) is not GnssHeadingSample:
                self.fixes += smp.fix_ok
            out.append(replace(smp, source=self.source) if self.source else smp)

    def why_unusable(self) -> str | None:
        """Why the stream gave no velocity with a fix, in a few words for one line; None if it did.

        Why: a capture from a receiver set up for something else (raw measurements only, NMEA
        without RMC/VTG, no fix all drive long) otherwise ends a replay with "gnss (0 of 553 frames
        used)" or, worse, runs to the end with nothing fused and nothing said.
        """
        if self.fixes:
            return None
        st = self.stats
        if not st["ubx_frames"] and not st["nmea_sentences"]:
            return (f"no NMEA sentence or UBX frame in it ({st['garbage_bytes']} bytes skipped"
                    f"{', ' + str(st['checksum_errors']) + ' checksum errors' if st['checksum_errors'] else ''})")
        nmea = sum(self.seen_nmea.get(k, 0) for k in VELOCITY_KINDS)
        ubx = sum(n for cls_id, n in self.seen_ubx.items() if cls_id in _UBX_VELOCITY)
        other = {"ubx": ("nmea", nmea, "NMEA RMC/VTG"), "nmea": ("ubx", ubx, "UBX velocity messages")}.get(self.protocol)
        if other and other[1] and not (ubx if self.protocol == "ubx" else nmea):
            return (f"protocol = \"{self.protocol}\" in [gnss], but the receiver sent its velocity as {other[2]}"
                    f" ({other[1]} ignored); set protocol = \"auto\" (or \"{other[0]}\")")
        velocity = nmea + ubx
        if velocity and st["samples"]:
            return (f"no usable fix in any of its {st['samples']} epochs (the receiver said no fix, or an"
                    " estimated / simulated one)")
        if velocity and st["malformed"] >= velocity:
            return (f"none of its {velocity} velocity messages could be decoded ({st['malformed']} malformed;"
                    f" the last: {self.last_error})")
        velned = self.seen_ubx.get(NAV_VELNED, 0)
        if velned and not self.seen_ubx.get(_NAV_STATUS) and not self.seen_ubx.get(NAV_SOL):
            return (f"{velned} NAV-VELNED without a NAV-STATUS or NAV-SOL of the same epoch (the fix state it"
                    " needs); enable NAV-STATUS, or NAV-PVT")
        if velocity:
            return (f"{velocity} velocity messages but no epoch could be dated (NMEA VTG needs GGA/GNS/ZDA"
                    " and a date from RMC or ZDA; UBX NAV-VELNED needs NAV-STATUS or NAV-SOL of its epoch, or one at most 1 s older)")
        seen = sorted(((n, _ubx_name(k)) for k, n in self.seen_ubx.items()), reverse=True)
        seen += sorted(((n, k) for k, n in self.seen_nmea.items()), reverse=True)
        listed = ", ".join(f"{name} x{n}" for n, name in seen[:4]) + (", ..." if len(seen) > 4 else "")
        return (f"no velocity message: none of UBX NAV-PVT, NAV-SOL, HNR-PVT, NAV-VELNED or NMEA RMC, VTG"
                f" among its {st['ubx_frames'] + st['nmea_sentences']} messages ({listed});"
                " enable one on the receiver")

    # ------------------------------------------------------------------------------ bookkeeping

    def _t_at(self, i: int) -> float:
        """Receive time of buffer index ``i`` (the feed that delivered that byte)."""
        a = self._base + i
        for end, t in self._marks:
            if a < end:
                return t
        return self._marks[-1][1]

    def _reject(self, s: int, e: int) -> None:
        """Bytes [s, e) belong to no frame: count them, keep them for raw_sink, report the run."""
        self._account_reject(e - s)
        self._junk += self._buf[s:e]
        self._junk_t = self._t_at(e - 1)

    def _account_reject(self, n: int) -> None:
        self.stats["garbage_bytes"] += n

    def _flush_junk(self) -> None:
        """A run of rejected bytes ended: report it once and hand it to raw_sink."""
        if self._junk:
            n = len(self._junk)
            self._error(self._junk_t, "garbage", None,
                        f"skipped {n} byte{'s' if n > 1 else ''} outside any valid frame"
                        f" (starting {bytes(self._junk[:8]).hex(' ')})")
            if self._sink:
                self._sink(self._junk_t, bytes(self._junk))
            self._junk.clear()

    def _error(self, t: float, kind: str, counter: str | None, text: str) -> None:
        if counter:
            self.stats[counter] += 1
        self.last_error = text
        self._report.report(kind, logging.WARNING, f"{self._name}: {text}", now=t)


def _ubx_name(cls_id: tuple[int, int]) -> str:
    """u-blox's name of a UBX message (pyubx2's table), else its class and id in hex."""
    from pyubx2 import UBX_MSGIDS

    return UBX_MSGIDS.get(bytes(cls_id), f"UBX 0x{cls_id[0]:02X} 0x{cls_id[1]:02X}")


def sum_stats(parsers) -> dict:
    """GNSS parser counters summed over parsers (a dict: its values), e.g. every port of every
    capture, or the daemon's receivers."""
    ps = list(parsers.values() if isinstance(parsers, dict) else parsers)
    if len(ps) == 1:  # the usual case, read with every EST_DIAG update
        return dict(ps[0].stats)
    total: dict = {}
    for p in ps:
        for k, v in p.stats.items():
            total[k] = total.get(k, 0) + v
    return total
