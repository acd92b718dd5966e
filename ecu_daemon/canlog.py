"""CAN logs in and out: candump ``-L`` text (our own fast parser), ASC/BLF/... via python-can.

Why a hand-written candump parser: python-can's ``CanutilsLogReader`` reads an error frame only
when its class has the bus-error bit, so a bus-off frame ``20000040#...`` comes back as a data
frame with extended id 0x40; it is also ~5x slower. Here every line is checked against the
can-utils syntax (``(sec.frac) iface ID#DATA``, ``ID#R``, FD ``ID##<flags>DATA``, 3- or 8-digit
ids, error frames with CAN_ERR_FLAG) and a line that is not valid stops the read with ONE
message naming file:line and what is wrong, instead of being skipped silently.

Frames come out as tuples ``(t, arbitration_id, is_extended, is_error_frame, data)``; for an error
frame ``arbitration_id`` holds the error class bits (linux/can/error.h). Remote frames carry no
data and are skipped (counted in :attr:`CanLogReader.remote_frames`).
"""
from __future__ import annotations

import gzip
import io
import math
import re
import zlib
from pathlib import Path
from typing import Iterator

import can

CAN_ERR_FLAG = 0x20000000
CAN_EFF_MASK = 0x1FFFFFFF
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


def _what_is_wrong(line: str) -> str:
    """Explain why a line did not match (only called for bad lines)."""
    parts = line.split()
    if not parts or not parts[0].startswith("("):
        return "expected '(timestamp) interface ID#DATA'"
    if not re.fullmatch(r"\(\d+\.\d+\)", parts[0]):
        return f"bad timestamp {parts[0]!r}"
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
    """Iterator over the frames of a CAN log (see module doc); opens the file on construction."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.remote_frames = 0
        self.lines = 0
        suffixes = [s.lower() for s in self.path.suffixes[-2:]]
        self.format = "python-can" if any(s in PYTHON_CAN_SUFFIXES for s in suffixes) else "candump"
        try:
            if self.format == "candump":
                self._file = _open_text(self.path)
                self._it = self._candump(self._file)
            else:
                self._file = can.LogReader(str(self.path))
                self._it = self._python_can(self._file)
        except OSError as e:
            raise CanLogError(f"cannot read CAN log {self.path}: {e.strerror or e}") from None
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
        lineno = 0
        try:
            for line in f:
                lineno += 1
                m = match(line)
                if m is None:
                    s = line.strip()
                    if not s or s.startswith("#"):
                        continue  # blank lines and comments, as canplayer ignores them
                    raise self._error(lineno, line)
                ts, _iface, ident, rtr, _rdlc, fd_flags, fd_data, data = m.groups()
                can_id = int(ident, 16)
                if rtr:
                    self.remote_frames += 1
                    continue
                try:
                    payload = fromhex((fd_data if fd_flags is not None else data).replace(".", ""))
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
        try:
            for msg in reader:
                n += 1
                if msg.is_remote_frame:
                    self.remote_frames += 1
                    continue
                yield (float(msg.timestamp), msg.arbitration_id, bool(msg.is_extended_id and not msg.is_error_frame),
                       bool(msg.is_error_frame), bytes(msg.data))
        except CanLogError:
            raise
        except Exception as e:  # a corrupt BLF/ASC: python-can raises assorted types
            raise CanLogError(f"{self.path}: unreadable after {n} frames: {e}") from None
        finally:
            self._release()


def read_can_log(path: str | Path) -> CanLogReader:
    """Frames ``(t, arbitration_id, is_extended, is_error_frame, data)`` of a candump ``-L`` log
    (``.log``, also ``.log.gz``) or any python-can format (``.asc``, ``.blf``, ...).

    Raises :class:`CanLogError` at once for a missing/unreadable file, and while iterating for a
    malformed line (message: ``file:line: what is wrong: 'the line'``).
    """
    return CanLogReader(path)


class CandumpWriter:
    """Writes frames as candump ``-L`` lines that canplayer accepts: ``(%.6f) can0 ID#DATA``."""

    def __init__(self, path: str | Path, channel: str = "can0"):
        self.path = Path(path)
        if not channel or any(c.isspace() for c in channel):
            raise ValueError(f"bad channel name {channel!r}")
        self.channel = channel
        self.frames = 0
        try:
            self._f = open(self.path, "w", encoding="ascii", newline="\n")
        except OSError as e:
            raise CanLogError(f"cannot write CAN log {self.path}: {e.strerror or e}") from None

    def write(self, msg: can.Message) -> None:
        """Append one python-can message (data, remote, error or CAN FD frame)."""
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
