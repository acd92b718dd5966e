"""The GNSS capture log: one received message per line, next to the candump-format CAN log.

Format (a public contract; the CAN log uses the same clock)::

    (1700000000.123456) ttyACM0 $GNRMC,221320.25,A,5107.40740,N,00145.92593,W,24.687,345.60,141123,,,A,V*20
    (1700000000.131002) ttyACM0 B56201075C00E8030000...

* ``(seconds.micros)``: host receive time of the message's last byte, as in candump ``-l``.
* ``PORT``: the serial device name (no whitespace).
* ``PAYLOAD``: an NMEA sentence as received, without its line ending; or anything else (a UBX
  or RTCM3 frame, bytes the parser could not frame) as uppercase hex of the raw bytes.
* Blank lines and lines starting with ``#`` are ignored.

``read_gnss_log`` gives payloads back as the raw bytes (NMEA text + CR LF, hex decoded), so
feeding them to a ``GnssStreamParser`` reproduces the original stream.

gpsd's ``gpspipe -r`` with host times (``-u``: ``2024-06-01 08:00:00.123456: $GPRMC,...``; ``-uu``: the
same with `` 1717228800.123456`` after the date; ``-Z``: ISO 8601) is read too, as port ``gpspipe``:
gpspipe stamps each line with the host's CLOCK_REALTIME in UTC, the clock candump uses. Whole
seconds (``-t`` alone) are refused: they cannot line GNSS up with CAN.

A capture of a serial port starts wherever the receiver is, and a logger killed mid-write leaves
its last line cut; other tools' captures also carry stray text. So the reader passes on, as raw
bytes for the parser to skip and count (``garbage_bytes``, one log line, exactly what the live
daemon does with the same bytes on the port): a payload that is the tail of an NMEA sentence
(printable text with a ``,`` or ``*``: ``N,01134.49981,E,...*5C``) when it is the first line of its
port or its port already gave a message; and a last line cut short (no line end). Anything else
that is not a capture line is still refused at its line, so a wrong file given as the capture (a
candump log, a CSV) is an error naming it, not a replay without GNSS.
"""
from __future__ import annotations

import calendar
import logging
import math
import os
import re
import time
from collections.abc import Iterator
from typing import IO

from ..samples import GnssSample
from .stream import GnssStreamParser

__all__ = ["GnssLogError", "read_gnss_log", "GnssLogWriter", "samples_from_log"]

_LINE = re.compile(r"^\((?P<t>[^)]*)\) (?P<port>\S+) (?P<payload>\S.*)$")
_TIME = re.compile(r"^\d+\.\d+$")
#: a gpspipe -t/-u/-uu/-Z line: date, time [.usec][Z] [ unix.usec]: payload (gpspipe.c's "%.24s%s: ")
_GPSPIPE = re.compile(r"^(?P<date>\d{4}-\d\d-\d\d)[ T](?P<time>\d\d:\d\d:\d\d)(?P<frac>\.\d{1,6})?Z?"
                      r"(?: (?P<unix>\d+\.\d{6}))?: (?P<payload>.*)$")
_HEX = re.compile(r"^[0-9A-Fa-f]+$")
_CHECKSUM_TAIL = re.compile(rb"\*[0-9A-Fa-f]{2}$")
#: the tail of an NMEA sentence: printable text with a field separator or the checksum star
_NMEA_TAIL = re.compile(r"^[\x20-\x7e]*[,*][\x20-\x7e]*$")

log = logging.getLogger("ecu_daemon.gnss")


#: What a receiver's own output saved as it came (``cat /dev/ttyACM0``, u-center's .ubx) lacks: the
#: host receive time of each message, on the CAN log's clock, which lines GNSS up with CAN (and
#: from which the latency is identified). Said instead of "expected (seconds.micros) ...".
_RAW_STREAM = ("a raw receiver stream ({} without receive times), not a GNSS capture log: replay needs each"
               " message's host receive time on the CAN log's clock, '(seconds.micros) PORT PAYLOAD'"
               " per line, as 'ecu-daemon run --record DIR' writes it")


class GnssLogError(ValueError):
    """A GNSS capture log that cannot be read; the message is ``file:line: what is wrong``."""


def raw_capture_bytes(path: str | os.PathLike) -> bytes:
    """The receiver byte stream of a raw capture file (gpsd's test logs start with '#' comment lines)."""
    with open(path, "rb") as f:
        lines = f.read().splitlines(keepends=True)
    i = 0
    while i < len(lines) and lines[i].startswith(b"#"):
        i += 1
    return b"".join(lines[i:])


def read_gnss_log(path: str | os.PathLike) -> Iterator[tuple[float, str, bytes]]:
    """Yield ``(t, port, payload_bytes)`` per line; raises GnssLogError on the first bad line."""
    try:
        f = open(path, "rb")
    except OSError as exc:
        raise GnssLogError(f"{path}: cannot read GNSS log: {exc.strerror or exc}") from None
    with f:
        lineno = 0
        ports: dict[str, bool] = {}  # port -> it gave a whole message
        try:
            for lineno, raw in enumerate(f, 1):
                # only the last line can lack its line end: a capture's, once lines were read
                cut = not raw.endswith(b"\n") and any(ports.values())
                try:
                    item = _parse_line(path, lineno, raw, ports, cut)
                except GnssLogError as exc:
                    if not cut:
                        raise
                    log.warning("%s (the last line, cut short: skipped)", exc)
                    return
                if item is not None:
                    yield item
        except OSError as exc:
            raise GnssLogError(f"{path}:{lineno + 1}: read error: {exc.strerror or exc}") from None


def _parse_line(path, lineno: int, raw: bytes, ports: dict[str, bool] | None = None,
                cut: bool = False) -> tuple[float, str, bytes] | None:
    """One line's ``(t, port, payload)``, None for a comment; ``ports`` (updated) and ``cut`` (the
    line has no line end) decide whether a partial message is passed on (module doc) or refused."""
    line = raw.rstrip(b"\r\n")
    stripped = line.strip()
    if not stripped or stripped.startswith(b"#"):
        return None
    where = f"{path}:{lineno}"
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError:
        if b"\xb5b" in line:
            raise GnssLogError(f"{where}: {_RAW_STREAM.format('UBX frames')}") from None
        raise GnssLogError(f"{where}: line is not ASCII text") from None
    m = _LINE.match(text)
    if not m and (g := _GPSPIPE.match(text)):
        return _gpspipe_line(where, g, ports)
    if not m:
        if stripped[:1] in (b"$", b"!"):
            raise GnssLogError(f"{where}: {_RAW_STREAM.format('NMEA sentences')}")
        raise GnssLogError(f"{where}: expected '(seconds.micros) PORT PAYLOAD', got {text[:60]!r}")
    if not _TIME.match(m["t"]):
        raise GnssLogError(f"{where}: bad timestamp {m['t']!r} (expected seconds.micros)")
    payload, port = m["payload"], m["port"]
    whole = ports is None or ports.get(port)  # the port gave a message (None: no context given)
    if payload[0] in "$!":
        item = float(m["t"]), port, payload.encode("ascii") + b"\r\n"
    elif not _HEX.match(payload):
        if not (ports is not None and (cut or port not in ports or whole) and _NMEA_TAIL.match(payload)):
            raise GnssLogError(f"{where}: payload is neither an NMEA sentence nor hex: {payload[:40]!r}")
        ports.setdefault(port, False)
        return float(m["t"]), port, payload.encode("ascii") + b"\r\n"  # the parser skips and counts it
    elif len(payload) % 2:
        if not cut:
            raise GnssLogError(f"{where}: odd-length hex payload ({len(payload)} digits)")
        item = float(m["t"]), port, bytes.fromhex(payload[:-1])  # the parser counts the cut frame
    else:
        item = float(m["t"]), port, bytes.fromhex(payload)
    if ports is not None:
        ports[port] = True
    return item


def _gpspipe_line(where: str, g: re.Match, ports: dict[str, bool] | None) -> tuple[float, str, bytes]:
    """A line of ``gpspipe -r -u`` / ``-uu`` (module doc): its host time and NMEA sentence."""
    payload = g["payload"].rstrip("\r")
    if payload[:1] == "{":
        raise GnssLogError(f"{where}: gpspipe -w output (gpsd's JSON reports), not the receiver's sentences:"
                           " record with 'gpspipe -r -uu'")
    if g["unix"]:
        t = float(g["unix"])
    elif g["frac"]:
        t = calendar.timegm(time.strptime(f"{g['date']} {g['time']}", "%Y-%m-%d %H:%M:%S")) + float(g["frac"])
    else:
        raise GnssLogError(f"{where}: gpspipe time stamps in whole seconds (-t) cannot line GNSS up with CAN:"
                           " record with 'gpspipe -r -uu' (seconds.micros)")
    if payload[:1] not in ("$", "!"):
        raise GnssLogError(f"{where}: gpspipe line without an NMEA sentence (record with 'gpspipe -r -uu'):"
                           f" {payload[:40]!r}")
    if ports is not None:
        ports["gpspipe"] = True
    return t, "gpspipe", payload.encode("ascii") + b"\r\n"


def _nmea_text(payload: bytes) -> str | None:
    """The sentence text when ``payload`` is one whole NMEA sentence, else None (-> hex)."""
    if payload[:1] not in (b"$", b"!"):
        return None
    body = payload.rstrip(b"\r\n")
    ended = len(body) != len(payload)
    if len(body) < 2 or not all(0x20 <= b <= 0x7E for b in body):
        return None
    if body[-1:] == b" " or not (ended or _CHECKSUM_TAIL.search(body)):
        return None  # a fragment: keep the exact bytes
    return body.decode("ascii")


class GnssLogWriter:
    """Appends received messages to a GNSS capture log (see module docstring for the format).

    ``write(t, payload)`` takes one message's raw bytes -- ideally what ``GnssStreamParser``'s
    ``raw_sink`` hands over -- and decides NMEA text versus hex from the bytes. Lines are
    flushed on ``flush()``/``close()`` (call them from the SIGTERM path).
    """

    def __init__(self, path: str | os.PathLike, port: str = "ttyACM0", *, append: bool = False) -> None:
        port = os.path.basename(str(port)) or str(port)
        if not port or any(c.isspace() for c in port):
            raise ValueError(f"port name must be non-empty without whitespace, got {port!r}")
        self.path, self.port = path, port
        self._f: IO[str] | None = open(path, "a" if append else "w", encoding="ascii", newline="\n")

    def write(self, t: float, payload: bytes) -> None:
        if self._f is None:
            raise ValueError("GnssLogWriter is closed")
        if not payload:
            return
        if not math.isfinite(t) or t < 0:
            raise ValueError(f"timestamp must be finite and >= 0, got {t!r}")
        text = _nmea_text(payload)
        self._f.write(f"({t:.6f}) {self.port} {text if text is not None else payload.hex().upper()}\n")

    def flush(self) -> None:
        if self._f is not None:
            self._f.flush()

    def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None

    def __enter__(self) -> "GnssLogWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def samples_from_log(path: str | os.PathLike, parser_kwargs: dict | None = None, *,
                     parsers: dict[str, GnssStreamParser] | None = None) -> Iterator[GnssSample]:
    """Replay a capture log through one GnssStreamParser per port, each line at its timestamp.

    Pass a dict as ``parsers`` to get the parsers (and their ``stats``) back, keyed by port.
    """
    if parsers is None:
        parsers = {}
    for t, port, payload in read_gnss_log(path):
        parser = parsers.get(port)
        if parser is None:
            parser = parsers[port] = GnssStreamParser(**(parser_kwargs or {}))
        yield from parser.feed(t, payload)
    for parser in parsers.values():
        yield from parser.finish()
