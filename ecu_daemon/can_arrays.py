"""A whole CAN log as arrays (times, ids, flags) plus its payloads: what an offline replay reads.

Why: a replay used to pull frames one at a time through a generator chain (reader -> time
order -> merge), a few microseconds of Python per frame before any decoding. Here the log is read
once into arrays, in the same order and with the same checks as :func:`~ecu_daemon.canlog.read_can_log`
(which it uses, so every format and every error message stays the reader's), and the time-order
policy (:class:`~ecu_daemon.time_order.TimeOrder`) runs item by item only for a log that needs it:
a log that never goes back in time keeps every frame, so for it the check is one comparison of
arrays.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .canlog import read_can_log
from .signals import _EXTENDED_KEY
from .time_order import TimeOrder


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
    reader = read_can_log(path, channel=channel, time_offset=time_offset)
    frames = list(reader)
    n = len(frames)
    if n:
        t, fid, ext, err, data = zip(*frames)
        t = np.array(t, dtype=np.float64)
    else:
        t, fid, ext, err, data = np.zeros(0), (), (), (), ()
    if n > 1 and not bool(np.all(t[1:] >= t[:-1])):  # goes back somewhere: the item-by-item policy
        kept = [i for _, i in order((ti, i) for i, ti in enumerate(t.tolist()))]
        t = t[kept]
        fid = [fid[i] for i in kept]
        ext = [ext[i] for i in kept]
        err = [err[i] for i in kept]
        data = [data[i] for i in kept]
    else:
        order.items = n
    return CanArrays(t, np.array(fid, dtype=np.int64), np.array(ext, dtype=bool), np.array(err, dtype=bool),
                     list(data), reader.channels)

