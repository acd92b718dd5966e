"""A whole CAN log decoded at once: :class:`SignalDecoder`'s results for every frame, in numpy.

Why: replay used to decode frame by frame in Python (~6 us a frame, ~11 us of every 6 ms step),
more than a bare Kalman filter's step. Offline the whole log is known up front, so each mapped
message's frames are decoded together with its precompiled bit layout (the same ``_layout`` the
frame-by-frame decoder uses), checksums (E2E profile 2, Toyota) and counter continuity
vectorised, and the samples are ready before the first step runs.

Same results, not similar ones: the arithmetic is the frame-by-frame decoder's in the same
order (``raw * scale + offset`` per DBC signal, then the mapping's), in float64 as Python does
it, and only for layouts where that holds exactly (integer signals of at most 48 bits in at most
8 bytes). A frame that does not decode cleanly (wrong length, checksum, counter, range), or a
message outside those limits, is handed to :meth:`SignalDecoder.decode` itself when its turn
comes -- with the counter checks' state set to what the frames before it left -- so its samples,
counts and log lines are the frame-by-frame ones. The health counters of the clean frames are
brought up to date lazily, to the frames handed over so far (:attr:`cursor`), whenever something
reads them (staleness, diagnostics, the end-of-replay table): what EST_DIAG carries is what the
frame-by-frame decoder would have counted at that step. ``tests/test_batch_decoder.py`` checks
samples and counters against :class:`SignalDecoder` on every frame of several logs.
"""
from __future__ import annotations

from bisect import bisect_left
from itertools import repeat

import numpy as np

from .checksums import FrameChecksum
from .integrity import CRC8H2F_TABLE
from .samples import InputSample
from .signals import _EXTENDED_KEY, SignalDecoder, _FramePlan

_new_tuple = tuple.__new__
#: widest DBC signal decoded in numpy: float64 holds its raw values and their sums exactly
MAX_BITS = 48
#: per frame, "decode me frame by frame" (see :meth:`BatchDecoder.take`)
DIRTY = object()
_T8 = np.frombuffer(CRC8H2F_TABLE, dtype=np.uint8)


class BatchDecoder(SignalDecoder):
    """:class:`SignalDecoder` over a whole log: :meth:`prepare` once, then :meth:`take` per frame
    in log order (``cursor``: how many frames were handed over)."""

    def prepare(self, t: np.ndarray, keys: np.ndarray, data: list) -> list:
        """Decode every frame (``keys``: frame id, with ``_EXTENDED_KEY`` for 29-bit ids, -1 for
        frames not to decode, e.g. error frames). Returns per frame its samples (a tuple), None
        (nothing mapped) or :data:`DIRTY`."""
        self._t = t
        self._data = data
        self.cursor = 0
        self._synced = 0
        self._clean: list[list] = []  # [plan, clean frame indices (list), their times (list), taken]
        self._prev: dict[int, dict] = {}  # dirty frame -> {counter: value before it, or None}
        out: list = [None] * len(t)
        for key, plan in self._plans.items():
            idx = np.flatnonzero(keys == key)
            if idx.size:
                self._prepare_plan(plan, idx, out)
        return out

    def _prepare_plan(self, plan: _FramePlan, idx: np.ndarray, out: list) -> None:
        data = self._data
        L = plan.length
        layout = plan.layout
        if layout is None or L > 8 or any(mask >> MAX_BITS for _, _, _, mask, _, _, _ in layout):
            for j in idx.tolist():
                out[j] = DIRTY
            return
        lens = np.fromiter((len(data[j]) for j in idx.tolist()), dtype=np.int64, count=idx.size)
        good = idx[lens == L]
        n = good.size
        D = np.frombuffer(b"".join([data[j] for j in good.tolist()]), dtype=np.uint8).reshape(n, L)
        intact = self._intact(plan, D, good)
        le = np.zeros(n, dtype=np.uint64)
        be = np.zeros(n, dtype=np.uint64)
        for i in range(L):
            col = D[:, i].astype(np.uint64)
            le |= col << np.uint64(8 * i)
            be |= col << np.uint64(8 * (L - 1 - i))
        phys = {}
        for name, little, shift, mask, sign, scale, offset in layout:
            raw = (((le if little else be) >> np.uint64(shift)) & np.uint64(mask)).astype(np.int64)
            if sign:
                raw = np.where(raw & sign, raw - (sign << 1), raw)
            phys[name] = raw.astype(np.float64) * float(scale) + float(offset)
        # counters: the state each frame leaves (-1: none, re-synchronise) and the errors
        before: dict[str, np.ndarray] = {}
        after: dict[str, np.ndarray] = {}
        cerr: dict[str, np.ndarray] = {}
        for cname, (chk, sc, off) in plan.counters.items():
            raw = (phys[cname] - off) / sc
            in_range = (raw >= -0.5) & (raw < chk.mask + 0.5)
            rawi = np.where(in_range, np.rint(np.where(in_range, raw, 0.0)), -1).astype(np.int64)
            after[cname] = a = np.where(intact & in_range, rawi, -1)
            before[cname] = prev = np.concatenate((np.array([-1], dtype=np.int64), a[:-1]))
            cerr[cname] = intact & (~in_range | ((prev >= 0) & (rawi != ((prev + 1) & chk.mask))))
        dirty = ~intact
        values = []
        for b, h, sig1, scale, offset, lo, hi, index, checked, sign in plan.fast:
            if sign is not None or sig1 is None:
                mag = 0.0 + phys[b.signals[0]]
                for s in b.signals[1:]:
                    mag = mag + phys[s]
                if sign is not None:
                    mag = np.where(phys[sign] != 0, -mag, mag)
                v = mag * scale + offset
            else:
                v = phys[sig1] * scale + offset
            dirty = dirty | ~((v >= lo) & (v <= hi))
            if b.counter is not None:
                dirty = dirty | cerr[b.counter]
            values.append((index, v))
        # frames of the wrong length and frames with any failure: frame by frame, later
        bad = idx[lens != L].tolist()
        bad_good = np.flatnonzero(dirty)
        for j in bad:
            out[j] = DIRTY
        if plan.counters:
            # a wrong-length frame leaves the counters alone: the state before it is the one the
            # last right-length frame left
            last_good = (np.searchsorted(good, np.asarray(bad, dtype=np.int64)) - 1).tolist()
            for j, g in zip(bad, last_good):
                self._prev[j] = {c: (None if g < 0 or a[g] < 0 else int(a[g])) for c, a in after.items()}
            for f in bad_good.tolist():
                self._prev[int(good[f])] = {c: (None if p[f] < 0 else int(p[f])) for c, p in before.items()}
        for f in bad_good.tolist():
            out[int(good[f])] = DIRTY
        clean = np.flatnonzero(~dirty)
        gi = good[clean].tolist()
        ts = self._t[good[clean]].tolist()
        # the samples, made in C loops (map, zip): one Python object per sample is the floor
        nb = len(values)
        if nb:
            m = len(gi)
            col_t = np.repeat(self._t[good[clean]], nb).tolist()
            col_i = [index for index, _ in values] * m
            col_v = np.stack([v[clean] for _, v in values], axis=1).ravel().tolist()
            flat = list(map(_new_tuple, repeat(InputSample, m * nb), zip(col_t, col_i, col_v)))
            for j, s in zip(gi, zip(*[iter(flat)] * nb)):
                out[j] = s
        self._clean.append([plan, gi, ts, 0])

    @staticmethod
    def _intact(plan: _FramePlan, D: np.ndarray, good: np.ndarray) -> np.ndarray:
        """Per right-length frame: its checksum holds (all True without one)."""
        ck: FrameChecksum | None = plan.checksum
        n, L = D.shape
        if ck is None:
            return np.ones(n, dtype=bool)
        if ck.scheme == "e2e_p2" and L >= 2:
            r = np.full(n, 0xFF, dtype=np.uint8)
            for i in range(1, L):
                r = _T8[r ^ D[:, i]]
            ids = np.asarray(ck.data_ids, dtype=np.uint8)
            did = ids[0] if ids.size == 1 else ids[D[:, 1] & 0x0F]
            return D[:, 0] == (_T8[r ^ did] ^ 0xFF)
        if ck.scheme == "toyota" and L >= 1:
            s = L + sum((ck.frame_id >> (8 * i)) & 0xFF for i in range(4))
            s = (s + D[:, :-1].astype(np.int64).sum(axis=1)) & 0xFF
            return D[:, -1] == s
        return np.fromiter((ck.check(bytes(row)) for row in D), dtype=bool, count=n)

    # ------------------------------------------------------------------------ hand-over
    def take(self, j: int, t: float, arbitration_id: int, data, is_extended: bool) -> list:
        """Frame ``j`` (marked :data:`DIRTY`) decoded frame by frame, after the clean frames before it."""
        self.cursor = j
        self.sync()
        prev = self._prev.get(j)
        if prev:
            plan = self._plans[arbitration_id | _EXTENDED_KEY if is_extended else arbitration_id]
            for c, v in prev.items():
                plan.counters[c][0].prev = v
        out = self.decode(t, arbitration_id, data, is_extended)
        self.cursor = self._synced = j + 1
        return out

    def sync(self) -> None:
        """Count the clean frames handed over (before :attr:`cursor`) into :attr:`health`."""
        c = self.cursor
        if c == self._synced:
            return
        self._synced = c
        for entry in self._clean:
            plan, gi, ts, done = entry
            pos = bisect_left(gi, c)
            new = pos - done
            if new > 0:
                entry[3] = pos
                t = ts[pos - 1]
                for b in plan.bindings:
                    h = b.health
                    h.frames += new
                    h.samples += new
                    h.last_t = t

    def check_stale(self, t: float) -> list[str]:
        self.sync()
        return super().check_stale(t)

    def input_diagnostics(self, t: float):
        self.sync()
        return super().input_diagnostics(t)
