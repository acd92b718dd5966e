"""A whole CAN log as arrays (times, ids, flags) plus its payloads: what an offline replay reads.

Why: a replay used to pull frames one at a time through a generator chain (reader -> time
order -> merge), a few microseconds of Python per frame before any decoding. Here the log is read
once into arrays, in the same order and with the same checks as :func:`~ecu_daemon.canlog.read_can_log`
(candump text that ``_candump.c`` takes whole is parsed there in one pass; anything else, every
other format and every error message stay the reader's), and the time-order
policy (:class:`~ecu_daemon.time_order.TimeOrder`) runs item by item only for a log that needs it:
a log that never goes back in time keeps every frame, so for it the check is one comparison of
arrays.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .canlog import _is_python_can, read_can_log
from .signals import _EXTENDED_KEY
from .time_order import TimeOrder

try:
    from . import _candump  # setup.py builds it; optional
except ImportError:
    _candump = None


@dataclass
class CanArrays:
    t: np.ndarray  # float64, s, non-decreasing
    fid: np.ndarray  # int64 arbitration id (error frames: their error class bits)
    ext: np.ndarray  # bool, 29-bit id
    err: np.ndarray  # bool, error frame
    data: list  # bytes per frame
    channels: dict  # frames per log channel, replayed or not (the reader's count)

    def __len__(self) -> int:
        return len(self.data)

    def finite(self) -> "CanArrays":
        """The frames with a finite time (the readers refuse others; a python-can format might not)."""
        ok = np.isfinite(self.t)
        if bool(np.all(ok)):
            return self
        keep = np.flatnonzero(ok)
        return CanArrays(self.t[keep], self.fid[keep], self.ext[keep], self.err[keep],
                         [self.data[i] for i in keep.tolist()], self.channels)

    def keys(self) -> np.ndarray:
        """The decoder's frame keys (``_EXTENDED_KEY`` set for 29-bit ids); -1 for error frames,
        which are counted, never decoded."""
        k = np.where(self.ext, self.fid | _EXTENDED_KEY, self.fid)
        return np.where(self.err, -1, k)


def read_can_arrays(path: str, order: TimeOrder, channel: str | None = None,
                    time_offset: float = 0.0) -> CanArrays:
    """Every frame of the log that a replay hands over, in order (see the module docstring).
    Raises :class:`~ecu_daemon.canlog.CanLogError` and :class:`~ecu_daemon.time_order.TimeOrderError`
    as reading frame by frame does."""
    fast = _parse_candump(path, channel, time_offset)
    if fast is not None:
        return _ordered(fast, order)
    reader = read_can_log(path, channel=channel, time_offset=time_offset)
    frames = list(reader)
    n = len(frames)
    if n:
        t, fid, ext, err, data = zip(*frames)
        t = np.array(t, dtype=np.float64)
    else:
        t, fid, ext, err, data = np.zeros(0), (), (), (), ()
    return _ordered(CanArrays(t, np.array(fid, dtype=np.int64), np.array(ext, dtype=bool),
                              np.array(err, dtype=bool), list(data), reader.channels), order)


def _ordered(can: CanArrays, order: TimeOrder) -> CanArrays:
    """``can`` as the time-order policy lets it through (all of it, unless it goes back in time)."""
    t = can.t
    n = len(t)
    if n > 1 and not bool(np.all(t[1:] >= t[:-1])):  # goes back somewhere: the item-by-item policy
        kept = np.array([i for _, i in order((ti, i) for i, ti in enumerate(t.tolist()))], dtype=np.int64)
        return CanArrays(t[kept], can.fid[kept], can.ext[kept], can.err[kept],
                         [can.data[i] for i in kept.tolist()], can.channels)
    order.items = n
    return can


def _parse_candump(path: str, channel: str | None, time_offset: float) -> CanArrays | None:
    """The log through ``_candump.parse`` when it is candump text that parser takes whole; None
    otherwise (no extension, another format, an unreadable file, a line it leaves to the reader)."""
    if _candump is None or _is_python_can(Path(path)) or Path(path).suffix.lower() == ".gz":
        return None
    try:
        text = Path(path).read_bytes()
    except OSError:
        return None  # the reader says what is wrong
    parsed = _candump.parse(text, channel)
    if parsed is None:
        return None
    times, ids, flags, data, channels = parsed
    t = np.frombuffer(times, dtype=np.float64).copy()
    if time_offset:  # as the reader: round(t + offset, 6), frame by frame
        t = np.array([round(x + time_offset, 6) for x in t.tolist()], dtype=np.float64)
    f = np.frombuffer(flags, dtype=np.uint8)
    return CanArrays(t, np.frombuffer(ids, dtype=np.int64).copy(), (f & 1).astype(bool), (f & 2).astype(bool),
                     data, channels)

