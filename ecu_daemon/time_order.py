"""Time order of one input log: what a replay does with timestamps that go back or leap ahead.

A replay merges its logs by time and steps the estimator on that time, so each log must go
forward. What real logs get wrong, and the policy:

* **A line stamped before the previous one** (a capture of two interfaces slightly out of step,
  a hand-edited log) is dropped and counted (``backwards``): the estimator has already run the
  steps it belonged to. A log in which that is not the exception -- at least
  :data:`MAX_BACKWARDS` lines and more than :data:`MAX_BACKWARDS_FRACTION` of those read each
  going back from the line before it (a reversed or unsorted log) -- is refused with one line
  saying how to sort it. A logger's clock stepped back (NTP) is one jump back, after which the
  lines go forward again: the lines stamped before the last one replayed are dropped (as many as
  the step is long) and the replay goes on, with the jump named in the summary; sorting such a log
  would interleave the two stretches. Lines that stay behind for more than :data:`MAX_STEP_BACK_S`
  are not a clock step (logs concatenated out of order): refused.
* **A single line far ahead** (a typo'd digit: 3000 s, 1e7 s) would otherwise make every line
  after it "go back": a line more than ``gap_s`` after the previous one is held until the next
  arrives, and dropped as an ``outlier`` when the next one is back more than ``gap_s`` before
  it. When the next one follows it, it is a real gap, left to the estimator (which skips it).

Pure bookkeeping on ``(t, ...)`` tuples, so it is tested on its own and shared by CAN and GNSS.
"""
from __future__ import annotations

import math
from typing import Iterable, Iterator

MAX_BACKWARDS = 100
MAX_BACKWARDS_FRACTION = 0.01
#: A jump back whose lines stay behind the last one replayed for longer than this (their own time) is
#: not a clock step (NTP steps a running logger by seconds) but logs put together out of order.
MAX_STEP_BACK_S = 60.0


class TimeOrderError(ValueError):
    """A log that is not in time order; the message is one line for the user."""


class TimeOrder:
    """Filter for the items ``(t, ...)`` of one log; counts what it drops (see the module doc)."""

    def __init__(self, what: str, gap_s: float):
        self.what = what
        self.gap_s = gap_s
        self.items = 0
        self.backwards = 0
        self.jumps = 0  # lines stamped before the line read just before them (a step back starts)
        self.outliers = 0
        self.first_problem = ""

    def _note(self, text: str) -> None:
        if not self.first_problem:
            self.first_problem = text

    def __call__(self, items: Iterable[tuple]) -> Iterator[tuple]:
        last = -math.inf
        prev = -math.inf  # the line read before this one (not a stray stamp far ahead)
        behind_since, run = math.inf, 0  # the line that jumped back, and the lines behind since (forward)
        pending = None
        gap = self.gap_s
        for item in items:
            self.items += 1
            t = item[0]
            if pending is not None:
                if t < pending[0] - gap:
                    self.outliers += 1
                    self._note(f"entry {self.items - 1} stamped {pending[0]:.6f}, {pending[0] - last:.6g} s"
                               f" after the one before it and {pending[0] - t:.6g} s after the one behind it")
                    prev = last
                else:
                    last = prev = pending[0]
                    yield pending
                pending = None
            jump, prev = t < prev, t
            if t < last:
                self.backwards += 1
                self.jumps += jump
                if jump:
                    behind_since, run = t, 0
                run += 1
                if run > MAX_BACKWARDS and t - behind_since > MAX_STEP_BACK_S:  # going forward, still behind
                    raise TimeOrderError(
                        f"{self.what} goes back {last - behind_since:.6g} s and stays behind for more than"
                        f" {MAX_STEP_BACK_S:g} s (first: {self.first_problem}): logs put together out of"
                        " order? sort it by timestamp (a candump -L log: sort -s -k1,1)")
                self._note(f"entry {self.items} stamped {t:.6f}, {last - t:.6g} s before the one before it")
                if self.jumps >= MAX_BACKWARDS and self.jumps > MAX_BACKWARDS_FRACTION * self.items:
                    raise TimeOrderError(
                        f"{self.what} is not in time order: {self.backwards} of its first {self.items} lines"
                        f" go back in time (first: {self.first_problem}); sort it by timestamp"
                        " (a candump -L log: sort -s -k1,1)")
                continue
            if t - last > gap and last > -math.inf:
                pending = item
                continue
            last = t
            yield item
        if pending is not None:
            yield pending

    def summary(self) -> str:
        """One line, empty when nothing was dropped."""
        if not (self.backwards or self.outliers):
            return ""
        step = (f"; {self.jumps} jump(s) back: a clock stepped back loses the lines until it is past the"
                " last one replayed" if self.backwards > 2 * self.jumps else "")
        return (f"{self.what}: dropped {self.backwards} line(s) stamped before the one before them and"
                f" {self.outliers} stray timestamp(s) far ahead (first: {self.first_problem}){step}")
