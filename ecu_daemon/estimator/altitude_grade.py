"""Road grade from a receiver's altitude (NMEA GGA), differenced over the distance travelled.

Why: NMEA has no vertical velocity, but GGA has the antenna's altitude. Over a segment of the
drive ``tan(grade) = dh / ds`` (``ds`` the horizontal distance, the receiver's own speeds integrated
between the two epochs). Both ends are taken at the epochs the receiver dated them (GGA follows the
RMC, so its height is usually the previous epoch's): the latency does not enter.

Noise of ``dh`` (honest for a standalone receiver):

* the 0.1 m resolution GGA prints (uniform: ``0.1 / sqrt(12)`` per end) and a small white part;
* the receiver's height error wanders (atmosphere, geometry): a Gauss-Markov error of a metre or
  two with a correlation time of tens of seconds, i.e. short-term a random walk of about
  ``ALT_WALK`` m/sqrt(s). Successive segments share no walk, so they are independent
  measurements; the white part they share at a common end only makes the sum's variance smaller
  than the count assumes (conservative).

Segments are at least ``SEGMENT_MIN_S`` long and ``SEGMENT_MIN_M`` long, so that quantisation does
not dominate. The grade measured is the mean over the segment, some time ago: the road grade's
walk over that time is added to the noise. A chain of speeds with a gap (no fix for more than
``MAX_GAP_S``) or a reversing car starts again: the distance would be guessed there.
"""
from __future__ import annotations

import math
from collections import deque

ALT_RESOLUTION_M = 0.1  # GGA prints altitude with one decimal
ALT_WHITE_M = 0.03  # receiver's epoch-to-epoch height noise besides the walk
ALT_WALK = 0.35  # m/sqrt(s): short-term wander of a standalone receiver's height error
SEGMENT_MIN_S = 1.0
SEGMENT_MIN_M = 5.0
MAX_GAP_S = 1.1  # between two speed epochs (a 1 Hz receiver's epochs, plus margin)
ALT_GATE_SIGMA = 4.0  # a height jump (satellite set change) is not a grade
_SAME_EPOCH_S = 5e-4


class AltitudeGrade:
    """Keeps the distance travelled per receiver epoch and turns altitudes into grade measurements."""

    def __init__(self, angle_walk: float):
        self.angle_walk = angle_walk  # rad/sqrt(s): the road grade's own wander (road.py's)
        self._dist: deque[tuple[float, float]] = deque(maxlen=32)  # (epoch UTC s, distance m)
        self._anchor: tuple[float, float, float] | None = None  # (UTC s, altitude m, distance m)
        self._last_alt_t = math.nan
        self._speed0 = math.nan

    def restart(self) -> None:
        """Forget the chain (a gap, a reverse, a rejected fix): the next altitude is a new anchor."""
        self._dist.clear()
        self._anchor = None

    def speed(self, utc_s: float, speed_mps: float, forward: bool) -> None:
        """A fused fix's horizontal speed at its epoch: the distance travelled grows by the trapezoid."""
        if not (math.isfinite(utc_s) and math.isfinite(speed_mps)) or not forward:
            self.restart()
            return
        if self._dist:
            t0, d0 = self._dist[-1]
            if utc_s <= t0 + _SAME_EPOCH_S:
                return
            if utc_s - t0 > MAX_GAP_S:
                self.restart()
            else:
                self._dist.append((utc_s, d0 + 0.5 * (self._speed0 + speed_mps) * (utc_s - t0)))
                self._speed0 = speed_mps
                return
        self._dist.append((utc_s, 0.0))
        self._speed0 = speed_mps

    def _distance_at(self, utc_s: float) -> float:
        for t, d in reversed(self._dist):
            if abs(t - utc_s) <= _SAME_EPOCH_S:
                return d
        return math.nan

    def measure(self, alt_m: float, alt_utc_s: float) -> tuple[float, float] | None:
        """The grade (rad) over the segment that ends at this altitude and its variance, or None
        (no anchor yet, segment too short, an epoch whose distance is not known, a repeat)."""
        if not (math.isfinite(alt_m) and math.isfinite(alt_utc_s)) or abs(alt_utc_s - self._last_alt_t) <= _SAME_EPOCH_S:
            return None
        self._last_alt_t = alt_utc_s
        d = self._distance_at(alt_utc_s)
        if not math.isfinite(d):
            self._anchor = None
            return None
        a = self._anchor
        if a is None or a[2] > d or alt_utc_s < a[0]:
            self._anchor = (alt_utc_s, alt_m, d)
            return None
        T, ds, dh = alt_utc_s - a[0], d - a[2], alt_m - a[1]
        if T < SEGMENT_MIN_S or ds < SEGMENT_MIN_M:
            return None
        self._anchor = (alt_utc_s, alt_m, d)
        var_dh = 2.0 * (ALT_RESOLUTION_M ** 2 / 12.0 + ALT_WHITE_M ** 2) + ALT_WALK ** 2 * T
        z = math.atan2(dh, ds)
        c2 = math.cos(z) ** 2
        return z, var_dh * (c2 / ds) ** 2 + self.angle_walk ** 2 * T
