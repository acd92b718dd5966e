"""CAN logs in and out: candump ``-L`` text (our own fast parser), ASC/BLF/... via python-can.

Why a hand-written candump parser: python-can's ``CanutilsLogReader`` reads an error frame only
when its class has the bus-error bit, so a bus-off frame ``20000040#...`` comes back as a data
frame with extended id 0x40; it is also ~5x slower. Here every line is checked against the
can-utils syntax (``(sec.frac) iface ID#DATA``, ``ID#R``, FD ``ID##<flags>DATA``, 3- or 8-digit
ids, error frames with CAN_ERR_FLAG) and a line that is not valid stops the read with ONE
message naming file:line and what is wrong, instead of being skipped silently.

Two views of the same reader: frames as tuples ``(t, arbitration_id, is_extended,
is_error_frame, data)`` (the estimator's input; for an error frame ``arbitration_id`` holds the
error class bits of linux/can/error.h; remote frames carry no data and are only counted), or,
with ``messages=True``, ``can.Message`` s carrying everything the log says (channel, CAN FD,
BRS/ESI, remote frames with their DLC, error frames). Either view can keep one channel only
(``channel=``), as ``canplayer`` does with ``can0=can1``: a log of two buses must not be mixed.

Time: ASC and BLF store times from the start of the measurement plus the start as a date;
python-can's ASC reader drops the date by default. Here the date is applied, so every format
comes out on the log's absolute clock (rounded to 1 us, the resolution candump and the
daemon's recordings have), and :attr:`CanLogReader.absolute_time` says when a log has no start
date (python-can's BLF writer stores none for times before 1990, e.g. monotonic/boot clocks);
``time_offset`` is added to every time, to line such a log up with a GNSS capture.
"""
from __future__ import annotations

import collections
import gzip
import io
import itertools
import logging
import math
import re
import zlib
from pathlib import Path
from typing import Iterator

import can

try:
    from ._candump import lines as _candump_lines  # setup.py builds it; optional
except ImportError:
    _candump_lines = None

log = logging.getLogger(__name__)

CAN_ERR_FLAG = 0x20000000
CAN_EFF_MASK = 0x1FFFFFFF
#: python-can's BLF writer stores a start date only for times from 1990 on (Unix time)
BLF_EARLIEST_START = 631152000.0
CANFD_BRS = 0x01
CANFD_ESI = 0x02
_FD_LENGTHS = frozenset((0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64))
#: suffixes read through python-can's LogReader; everything else is candump text
PYTHON_CAN_SUFFIXES = (".asc", ".blf", ".trc", ".csv", ".mf4", ".db")

Frame = tuple  # (t: float, arbitration_id: int, is_extended: bool, is_error_frame: bool, data: bytes)

_LINE = re.compile(
    r"[ \t]*\((\d+\.\d+)\)[ \t]+(\S+)[ \t]+([0-9A-Fa-f]{3}|[0-9A-Fa-f]{8})#"
    r"(?:(R)([0-8])?(?:_[0-9A-Fa-f])?|#([0-9A-Fa-f])([0-9A-Fa-f.]*)|([0-9A-Fa-f.]*)(?:_[0-9A-Fa-f])?)"
    r"(?:[ \t]+[RT])?[ \t]*\r?\n?")


class CanLogError(ValueError):
    """A CAN log that cannot be read, with file (and line) in the message."""


#: candump's screen output (``candump -ta can0 > x.txt``, what many captures are): ``(time)
#: iface [RX|TX flag flag] ID [len] XX XX ...`` with ``[8]`` for classic CAN and ``[08]`` for
#: CAN FD, ``remote request`` for a remote frame, ``'ascii'`` (``-a``) or ``ERRORFRAME ...``
#: (``-e``) after the data. Only ``-ta`` stamps are absolute (``%010llu``: 10 digits); ``-td``
#: / ``-tz`` (``%03llu``, relative), ``-tA`` (local date, no time zone) and no ``-t`` cannot be
#: put on the GNSS capture's clock and are refused with the command that records a usable log.
_SCREEN = re.compile(
    r"[ \t]*(?:\((?P<ts>[^)]*)\)[ \t]+)?(?P<iface>\S+)[ \t]+(?:(?P<dir>[RT]X)[ \t]+(?P<brs>[-B])[ \t]+"
    r"(?P<esi>[-E])[ \t]+)?(?P<id>[0-9A-Fa-f]{3}|[0-9A-Fa-f]{8})[ \t]+\[(?P<len>\d{1,2})\]"
    r"(?P<rest>(?:[ \t]+\S.*)?)[ \t]*\r?\n?")
_SCREEN_BYTE = re.compile(r"[0-9A-Fa-f]{2}")
_SCREEN_FIX = ("record with 'candump -L' (or -l), or give its screen output with -ta (absolute times)")


def _screen_line_as_log_line(line: str) -> str | None:
    """The candump ``-L`` line for one line of candump's screen output (see ``_SCREEN``); None
    when ``line`` is not screen output. Raises :class:`ValueError` (the reason) for screen
    output that cannot be replayed: times that are not absolute, a length and data that differ."""
    m = _SCREEN.fullmatch(line)
    if m is None:
        return None
    ts = m["ts"]
    if ts is None:
        raise ValueError(f"candump screen output without times (no -t); {_SCREEN_FIX}")
    if not re.fullmatch(r"\d{10,}\.\d{6}", ts):
        kind = "local date and time without a time zone (-tA)" if "-" in ts else "relative times (-td/-tz)"
        raise ValueError(f"candump screen output with {kind}; {_SCREEN_FIX}")
    n, rest = int(m["len"]), m["rest"].strip()
    fd = len(m["len"]) == 2  # candump prints a CAN FD length with two digits, classic with one
    head = f"({ts}) {m['iface']} {m['id']}#"
    if rest.startswith("remote request"):
        return f"{head}R{n if 0 < n <= 8 else ''}"
    words = rest.split()
    data = list(itertools.takewhile(_SCREEN_BYTE.fullmatch, words[:n]))
    tail = words[len(data):]
    if len(data) != n or (tail and not tail[0].startswith(("'", "ERRORFRAME"))):
        raise ValueError(f"candump screen output: [{m['len']}] but {len(data)} data bytes")
    if fd:
        flags = (1 if m["brs"] == "B" else 0) | (2 if m["esi"] == "E" else 0)
        return f"{head}#{flags:X}{''.join(data)}"
    return head + "".join(data)


def _what_is_wrong(line: str) -> str:
    """Explain why a line did not match (only called for bad lines)."""
    parts = line.split()
    if not parts or not parts[0].startswith("("):
        return "expected '(timestamp) interface ID#DATA'"
    if not re.fullmatch(r"\(\d+\.\d+\)", parts[0]):
        return f"bad timestamp {parts[0]!r}"
    if len(parts) == 2 and "#" in parts[1]:
        return "no interface name before the frame (candump -L: '(timestamp) can0 ID#DATA')"
    if len(parts) < 3:
        return "missing interface or frame"
    if len(parts) > 4 or (len(parts) == 4 and parts[3] not in ("R", "T")):
        return "unexpected text after the frame"
    frame = parts[2]
    if "#" not in frame:
        return f"frame {frame!r} has no '#'"
    ident, _, rest = frame.partition("#")
    if not re.fullmatch(r"[0-9A-Fa-f]{3}|[0-9A-Fa-f]{8}", ident):
        return f"bad CAN id {ident!r} (3 hex digits for 11-bit, 8 for 29-bit ids)"
    if rest.startswith("#"):
        return f"bad CAN FD flags/data {rest[1:]!r}"
    return f"bad data {rest!r} (hex byte pairs expected)"


def _open_text(path: Path):
    if path.suffix.lower() == ".gz":
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding="ascii", errors="replace")
    return open(path, encoding="ascii", errors="replace")


class CanLogReader:
    """Iterator over the frames of a CAN log (see module doc); opens the file on construction.

    ``channel``: keep only the frames of this log channel (candump interface name, or the
    python-can channel of an ASC/BLF message as ``str``); ``None`` keeps all. ``channels``
    counts the frames seen per channel, kept or not.
    """

    def __init__(self, path: str | Path, *, channel: str | None = None, time_offset: float = 0.0,
                 messages: bool = False):
        self.path = Path(path)
        self.channel = channel
        self.time_offset = float(time_offset)
        self.messages = messages
        self.remote_frames = 0
        self.lines = 0
        self.channels: dict[str, int] = {}
        #: False for an ASC/BLF log without a start date: its times count from 0
        self.absolute_time = True
        self.format = "python-can" if _is_python_can(self.path) else "candump"
        try:
            if self.format == "candump":
                self._file = _open_text(self.path)
                self._it = self._candump(self._file)
            else:
                self._file = _python_can_reader(self.path)
                self._it = self._python_can(self._file)
        except OSError as e:
            raise CanLogError(f"cannot read CAN log {self.path}: {e.strerror or e}") from None
        except CanLogError:
            raise
        except Exception as e:  # python-can readers raise assorted types for a bad header
            raise CanLogError(f"cannot read CAN log {self.path}: {e}") from None

    def __iter__(self) -> Iterator[Frame]:
        return self

    def __next__(self) -> Frame:
        return next(self._it)

    def close(self) -> None:
        """Stop reading and release the file (done by itself when the iteration ends)."""
        it, self._it = self._it, iter(())
        it.close()  # runs the reader's ``finally``, which releases the file
        self._release()

    def _release(self) -> None:
        f, self._file = self._file, None
        if isinstance(f, io.IOBase):
            f.close()
        elif f is not None:
            f.stop()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _error(self, lineno: int, line: str) -> CanLogError:
        text = line.strip()
        shown = text if len(text) <= 80 else text[:77] + "..."
        return CanLogError(f"{self.path}:{lineno}: {_what_is_wrong(text)}: {shown!r}")

    def _candump(self, f) -> Iterator[Frame]:
        match = _LINE.fullmatch
        fromhex = bytes.fromhex
        want = self.channel
        seen = self.channels
        offset = self.time_offset
        messages = self.messages
        lineno = 0
        try:
            for line in f:
                lineno += 1
                m = match(line)
                if m is None:
                    s = line.strip()
                    if not s or s.startswith("#"):
                        continue  # blank lines and comments, as canplayer ignores them
                    try:
                        screen = _screen_line_as_log_line(line)
                    except ValueError as e:
                        raise CanLogError(f"{self.path}:{lineno}: {e}: {s[:77]!r}") from None
                    m = None if screen is None else match(screen)
                    if m is None:
                        raise self._error(lineno, line)
                ts, iface, ident, rtr, rdlc, fd_flags, fd_data, data = m.groups()
                seen[iface] = seen.get(iface, 0) + 1
                if want is not None and iface != want:
                    continue
                can_id = int(ident, 16)
                if rtr and not messages:
                    self.remote_frames += 1
                    continue
                try:
                    payload = b"" if rtr else fromhex((fd_data if fd_flags is not None else data).replace(".", ""))
                except ValueError:
                    raise self._error(lineno, line) from None
                if len(ident) == 3:
                    if can_id > 0x7FF:
                        raise CanLogError(f"{self.path}:{lineno}: 11-bit id 0x{can_id:03X} above 0x7FF")
                    is_ext, is_err = False, False
                elif can_id & CAN_ERR_FLAG:
                    if can_id & ~(CAN_ERR_FLAG | CAN_EFF_MASK):
                        raise CanLogError(f"{self.path}:{lineno}: bad error-frame id {ident}")
                    can_id &= CAN_EFF_MASK
                    is_ext, is_err = False, True
                elif can_id > CAN_EFF_MASK:
                    raise CanLogError(f"{self.path}:{lineno}: 29-bit id {ident} above 0x1FFFFFFF")
                else:
                    is_ext, is_err = True, False
                n = len(payload)
                if n > 8 and (fd_flags is None or n not in _FD_LENGTHS):
                    raise CanLogError(f"{self.path}:{lineno}: {n} data bytes is not a valid"
                                      f" {'CAN FD' if fd_flags is not None else 'classic CAN'} length")
                t = float(ts)
                if not math.isfinite(t):
                    raise CanLogError(f"{self.path}:{lineno}: timestamp {ts} out of range")
                if offset:
                    t = round(t + offset, 6)
                if messages:
                    flags = int(fd_flags, 16) if fd_flags is not None else 0
                    if rtr:
                        self.remote_frames += 1
                    yield can.Message(timestamp=t, arbitration_id=can_id, is_extended_id=is_ext,
                                      is_error_frame=is_err, is_remote_frame=bool(rtr),
                                      dlc=int(rdlc) if rdlc else n, data=payload, channel=iface,
                                      is_fd=fd_flags is not None, bitrate_switch=bool(flags & CANFD_BRS),
                                      error_state_indicator=bool(flags & CANFD_ESI), check=False)
                else:
                    yield (t, can_id, is_ext, is_err, payload)
        except (OSError, EOFError, zlib.error) as e:  # EOFError, zlib.error: a cut-off or corrupt .gz
            raise CanLogError(f"{self.path}:{lineno + 1}: read error: {e.strerror or e}"
                              if isinstance(e, OSError) else
                              f"{self.path}:{lineno + 1}: compressed data is cut off or corrupt ({e})") from None
        finally:
            self.lines = lineno
            self._release()

    def _python_can(self, reader) -> Iterator[Frame]:
        n = 0
        want = self.channel
        seen = self.channels
        try:
            it = iter(reader)
            first = next(it, None)  # ASC: the header (date, time format) is read with the first frame
            self.absolute_time = _has_start_date(reader)
            if getattr(reader, "timestamps_format", None) == "relative":
                raise CanLogError(f"{self.path}: 'timestamps relative' (each time since the previous event) is"
                                  " not supported; export the log with absolute timestamps")
            offset = self.time_offset
            for msg in itertools.chain((first,) if first is not None else (), it):
                n += 1
                name = "" if msg.channel is None else str(msg.channel)
                seen[name] = seen.get(name, 0) + 1
                if want is not None and name != want:
                    continue
                t = round(float(msg.timestamp) + offset, 6)
                if self.messages:
                    if msg.is_remote_frame:
                        self.remote_frames += 1
                    msg.timestamp = t
                    yield msg
                    continue
                if msg.is_remote_frame:
                    self.remote_frames += 1
                    continue
                yield (t, msg.arbitration_id, bool(msg.is_extended_id and not msg.is_error_frame),
                       bool(msg.is_error_frame), bytes(msg.data))
        except CanLogError:
            raise
        except Exception as e:  # a corrupt BLF/ASC: python-can raises assorted types
            raise CanLogError(f"{self.path}: unreadable after {n} frames: {e}") from None
        finally:
            self._release()


def _is_python_can(path: Path) -> bool:
    return any(s.lower() in PYTHON_CAN_SUFFIXES for s in path.suffixes[-2:])


def _python_can_reader(path: Path):
    """python-can's reader for ``path``; ASC with its start date applied (absolute times), also
    gzipped (``.asc.gz``: python-can's LogReader would read it relative to the start and drop
    the date, so a dated log looked undated and could not be lined up with the GNSS capture)."""
    suffixes = [s.lower() for s in path.suffixes[-2:]]
    if suffixes[-1:] == [".asc"]:
        return _ASCReader(str(path), relative_timestamp=False)
    if suffixes == [".asc", ".gz"]:
        return _ASCReader(gzip.open(path, mode="rt", encoding="ascii", errors="replace"), relative_timestamp=False)
    return can.LogReader(str(path))


_ASC_SECONDS_FRACTION = re.compile(r":\d\d\.(\d+)\b")


class _ASCReader(can.ASCReader):
    """python-can's ASC reader, reading the start date as python-can's own writer meant it.

    python-can's ASCWriter (up to 4.6 at least) writes the milliseconds of the start date
    without leading zeros (``00:20:00.3`` for 3 ms), which its reader takes for 300 ms. Vector's
    tools always write three digits, so a shorter fraction can only be that writer's and is
    read as milliseconds.
    """

    @staticmethod
    def _datetime_to_timestamp(datetime_string: str) -> float:
        t = can.ASCReader._datetime_to_timestamp(datetime_string)
        m = _ASC_SECONDS_FRACTION.search(datetime_string)
        if m and len(m.group(1)) < 3:
            t += int(m.group(1)) / 1000.0 - float("0." + m.group(1))
        return t


class _ASCWriter(can.ASCWriter):
    """python-can's ASC writer with the start date's milliseconds in three digits (see above)."""

    FORMAT_DATE = "%a %b %d %H:%M:%S.{:03d} %Y"


def _has_start_date(reader) -> bool:
    """Whether python-can found the log's start date (else its times count from 0)."""
    if isinstance(reader, can.ASCReader):
        return reader.start_time != 0.0
    if isinstance(reader, can.BLFReader):
        return reader.start_timestamp != 0
    return True  # the other formats store each frame's time as recorded


def read_can_log(path: str | Path, *, channel: str | None = None, time_offset: float = 0.0,
                 messages: bool = False) -> CanLogReader:
    """Frames ``(t, arbitration_id, is_extended, is_error_frame, data)`` of a candump ``-L`` log
    (``.log``, also ``.log.gz``) or any python-can format (``.asc``, ``.blf``, ...); with
    ``messages=True`` ``can.Message`` s with everything the log says. See :class:`CanLogReader`.

    Raises :class:`CanLogError` at once for a missing/unreadable file, and while iterating for a
    malformed line (message: ``file:line: what is wrong: 'the line'``).
    """
    return CanLogReader(path, channel=channel, time_offset=time_offset, messages=messages)


#: the channel of a candump line: the token between the time and the frame. A line without one
#: (``(t) 0B4#...``, which canplayer refuses too) names no channel: the reader reports it by line
_CANDUMP_CHANNEL = re.compile(rb"^[ \t]*\(\d+\.\d+\)[ \t]+(\S+)[ \t]+\S", re.M)


def log_channels(path: str | Path, max_frames: int | None = None) -> dict[str, int]:
    """Frames per channel of a CAN log (a quick scan; the lines themselves are checked on reading).

    Text candump is scanned whole (a regex over the bytes); other formats are read through
    python-can, so ``max_frames`` can bound that to the log's beginning.
    """
    p = Path(path)
    if _is_python_can(p) or p.suffix.lower() == ".gz":
        with CanLogReader(p) as r:
            for _ in itertools.islice(r, max_frames):
                pass
            return r.channels
    counts: collections.Counter = collections.Counter()
    try:
        with open(p, "rb") as f:
            tail = b""
            for chunk in iter(lambda: f.read(1 << 20), b""):
                chunk = tail + chunk
                cut = chunk.rfind(b"\n") + 1
                counts.update(_CANDUMP_CHANNEL.findall(chunk, 0, cut))
                tail = chunk[cut:]
            counts.update(_CANDUMP_CHANNEL.findall(tail))
    except OSError as e:
        raise CanLogError(f"cannot read CAN log {p}: {e.strerror or e}") from None
    return {k.decode("ascii", "replace"): v for k, v in counts.items()}


class CandumpWriter:
    """Writes frames as candump ``-L`` lines that canplayer accepts: ``(%.6f) can0 ID#DATA``."""

    def __init__(self, path: str | Path, channel: str = "can0", name: str | Path | None = None):
        self.path = Path(path)
        self.name = Path(name) if name is not None else self.path  # what messages call it
        if not channel or any(c.isspace() for c in channel):
            raise ValueError(f"bad channel name {channel!r}")
        self.channel = channel
        self.frames = 0
        try:
            self._f = open(self.path, "w", encoding="ascii", newline="\n")
        except OSError as e:
            raise CanLogError(f"cannot write CAN log {self.name}: {e.strerror or e}") from None

    def write(self, msg: can.Message) -> None:
        """Append one python-can message (data, remote, error or CAN FD frame)."""
        if not (msg.is_error_frame or msg.is_extended_id or msg.is_remote_frame or msg.is_fd):
            # the common case (every output frame) in one formatting step
            if self._f is None:
                raise ValueError("CandumpWriter is closed")
            self._f.write(f"({msg.timestamp:.6f}) {self.channel} {msg.arbitration_id:03X}#{msg.data.hex().upper()}\n")
            self.frames += 1
            return
        if msg.is_error_frame:
            head = f"{CAN_ERR_FLAG | (msg.arbitration_id & CAN_EFF_MASK):08X}#"
        elif msg.is_extended_id:
            head = f"{msg.arbitration_id:08X}#"
        else:
            head = f"{msg.arbitration_id:03X}#"
        if msg.is_remote_frame and not msg.is_error_frame:
            body = "R" + (f"{msg.dlc:X}" if 0 < msg.dlc <= 8 else "")
        elif msg.is_fd:
            body = f"#{(1 if msg.bitrate_switch else 0) | (2 if msg.error_state_indicator else 0):X}" + bytes(msg.data).hex().upper()
        else:
            body = bytes(msg.data).hex().upper()
        self._line(msg.timestamp, head + body)

    def write_payloads(self, t: float, frames: list) -> None:
        """Append ``(11-bit id, payload)`` pairs stamped ``t``, in one write: what :meth:`write`
        writes for the same frames as ``can.Message`` s (an output encoder's frames)."""
        if self._f is None:
            raise ValueError("CandumpWriter is closed")
        self._f.write(self._lines_reference(self.channel, t, frames))
        self.frames += len(frames)

    @staticmethod
    def _lines_reference(channel: str, t: float, frames: list) -> str:
        head = f"({t:.6f}) {channel} "
        return "".join([f"{head}{fid:03X}#{bytes(data).hex().upper()}\n" for fid, data in frames])

    def write_steps(self, steps: list) -> None:
        """:meth:`write_payloads` for ``[(t, frames), ...]`` at once, formatted in C where built
        (``_candump.lines``; it hands anything but float times, 11-bit ids and byte payloads back
        to the Python formatting)."""
        if self._f is None:
            raise ValueError("CandumpWriter is closed")
        text = NotImplemented if _candump_lines is None else _candump_lines(self.channel, steps)
        if text is NotImplemented:
            text = "".join([self._lines_reference(self.channel, t, frames) for t, frames in steps])
        self._f.write(text)
        self.frames += sum(len(frames) for _, frames in steps)

    def write_frame(self, t: float, arbitration_id: int, data: bytes, is_extended: bool = False,
                    is_error_frame: bool = False) -> None:
        """Append one frame given as the fields :func:`read_can_log` yields."""
        if is_error_frame:
            head = f"{CAN_ERR_FLAG | (arbitration_id & CAN_EFF_MASK):08X}#"
        else:
            head = f"{arbitration_id:08X}#" if is_extended else f"{arbitration_id:03X}#"
        if len(data) > 8:
            self._line(t, head + "#0" + bytes(data).hex().upper())
        else:
            self._line(t, head + bytes(data).hex().upper())

    def _line(self, t: float, frame: str) -> None:
        if self._f is None:
            raise ValueError("CandumpWriter is closed")
        self._f.write(f"({t:.6f}) {self.channel} {frame}\n")
        self.frames += 1

    def flush(self) -> None:
        if self._f is not None:
            self._f.flush()

    def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class PythonCanWriter:
    """The writer python-can picks for the file's extension (``can.Logger``: .asc, .blf, ...),
    with :class:`CandumpWriter`'s interface. ``name``: what messages call the file (the target
    a temporary ``path`` will be renamed to; default ``path``)."""

    def __init__(self, path: str | Path, name: str | Path | None = None):
        self.path = Path(path)
        self.name = Path(name) if name is not None else self.path
        self.frames = 0
        try:
            asc = self.path.suffix.lower() == ".asc"
            self._w = _ASCWriter(str(self.path)) if asc else can.Logger(str(self.path))
        except OSError as e:
            raise CanLogError(f"cannot write CAN log {self.name}: {e.strerror or e}") from None
        except (ValueError, ImportError) as e:  # an extension python-can has no writer (or library) for
            raise CanLogError(f"cannot write CAN log {self.name}: {e}") from None

    def write(self, msg: can.Message) -> None:
        if self._w is None:
            raise ValueError("PythonCanWriter is closed")
        if not self.frames and self.path.suffix.lower() == ".blf" and msg.timestamp < BLF_EARLIEST_START:
            log.warning("%s: times before 1990 (%.6f s: a monotonic or boot clock?) have no BLF start date;"
                        " read back, they count from the first frame's millisecond", self.name, msg.timestamp)
        self._w.on_message_received(msg)
        self.frames += 1

    def write_payloads(self, t: float, frames: list) -> None:
        """:meth:`CandumpWriter.write_payloads`, through ``can.Message`` s."""
        for fid, data in frames:
            self.write(can.Message(timestamp=t, arbitration_id=fid, is_extended_id=False, data=data, check=False))

    def write_steps(self, steps: list) -> None:
        """:meth:`CandumpWriter.write_steps`, through ``can.Message`` s."""
        for t, frames in steps:
            self.write_payloads(t, frames)

    def close(self) -> None:
        if self._w is not None:
            self._w.stop()
            self._w = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_can_writer(path: str | Path, channel: str = "can0", name: str | Path | None = None):
    """A writer for the format the file name says: candump ``-L`` text for ``.log`` (and any name
    python-can does not know), python-can's writer for ``.asc``, ``.blf``, ``.trc``, ...
    ``name``: what messages call the file (the target of a temporary ``path``)."""
    p = Path(path)
    return PythonCanWriter(p, name) if _is_python_can(p) else CandumpWriter(p, channel, name)
