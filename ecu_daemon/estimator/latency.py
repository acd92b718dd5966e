"""Online GNSS latency identification.

The receiver reports velocity some hundreds of ms after its time of validity. The delay shows
as a time shift between GNSS signals and the same signals from the CAN sensors. Following the
offline method of Yoon & Peng (003, §3; 000 §4.4.1.1: wheel speed vs GPS speed during smooth
acceleration) we do it online and with both axes of motion:

* longitudinal: the change of GNSS speed between consecutive fixes vs the change of wheel speed
  over the same interval shifted back by a candidate delay d;
* lateral: the change of GNSS course times speed vs the change of integrated yaw rate.

Differences cancel constant errors (wheel-radius scale is a small gain error, heading offset
vanishes), so only the timing remains. For every candidate d on the 6 ms grid we keep an
exponentially-forgotten sum of squared residuals; its minimum (refined by a parabola) is the delay.
The estimate only moves when the cost has a clear minimum, i.e. when there was enough
acceleration or yaw motion to see a shift; otherwise the prior (config ``delay_s``) stands.
"""
from __future__ import annotations

import math

import numpy as np

from .history import AUX_R, AUX_THETA, AUX_WHEEL, StepHistory
from .kinematic import VX, VY


MIN_SPEED = 3.0  # m/s, both fixes
MIN_SPREAD = 2e-3  # (m/s)^2: the residual must depend on the candidate delay by at least this
MIN_UPDATES = 40  # informative fix pairs before the prior is left
MAX_SLEW_S = 0.004  # per fix


class LatencyEstimator:
    def __init__(self, dt: float, prior_s: float, max_s: float, enabled: bool = True,
                 forgetting: float = 0.995, lever_arm: tuple[float, float] = (0.0, 0.0)):
        self.dt = dt
        self.lever = lever_arm
        self.enabled = enabled
        self.delay_s = prior_s
        self.max_steps = max(2, int(max_s / dt))
        self.cost = np.zeros(self.max_steps + 1)
        self.weight = 0.0
        self.forgetting = forgetting
        self._prev = None  # (step index at receive, speed, course, theta-history-free)
        self.updates = 0

    def observe(self, k_rx: int, speed: float, course: float, hist: StepHistory) -> None:
        """Feed one GNSS fix received at step k_rx (speed m/s, course rad clockwise from north)."""
        if not self.enabled:
            return
        prev = self._prev
        self._prev = (k_rx, speed, course)
        if prev is None:
            return
        k0, s0, c0 = prev
        gap = k_rx - k0
        # below walking pace wheel sensors read zero and GNSS course is noise: no timing there
        if gap <= 0 or gap > 0.6 / self.dt or min(speed, s0) < MIN_SPEED:
            return
        m = np.arange(self.max_steps + 1)
        a = k_rx - 1 - m  # candidate validity steps of this fix (history ends at k_rx - 1)
        b = a - gap
        old = hist.oldest()
        ok = b >= old
        if not ok.any():
            return
        a = a[ok] % hist.n
        b = b[ok] % hist.n
        aux = hist.aux
        dsw = aux[a, AUX_WHEEL] - aux[b, AUX_WHEEL]
        res_long = (speed - s0) - dsw
        vmean = 0.5 * (speed + s0)
        if vmean > 3.0:
            dcourse = math.remainder(course - c0, 2.0 * math.pi)
            # yaw angle is CCW-positive, course clockwise: course change = -theta change (+ dbeta)
            dth = aux[a, AUX_THETA] - aux[b, AUX_THETA]
            X = hist.X
            # sideslip of the antenna (lever arm), whose course the receiver reports
            lx, ly = self.lever
            ra = aux[a, AUX_R]
            rb = aux[b, AUX_R]
            dbeta = (np.arctan2(X[a, VY] + ra * lx, X[a, VX] - ra * ly)
                     - np.arctan2(X[b, VY] + rb * lx, X[b, VX] - rb * ly))
            res_lat = vmean * (dcourse + dth + dbeta)
        else:
            res_lat = 0.0
        r2 = res_long * res_long + res_lat * res_lat
        r2 = np.where(np.isfinite(r2), r2, np.nan)
        if np.isnan(r2).all():
            return
        full = np.full(self.max_steps + 1, np.nan)
        full[ok] = r2
        # Only informative if the residual depends on the candidate delay.
        spread = np.nanmax(full) - np.nanmin(full)
        if not spread > MIN_SPREAD:
            return
        full = np.where(np.isnan(full), np.nanmax(full), full)
        self.cost = self.forgetting * self.cost + full
        self.weight = self.forgetting * self.weight + spread
        self.updates += 1
        self._refine()

    def _refine(self) -> None:
        if self.updates < MIN_UPDATES or self.weight < 1.0:
            return
        c = self.cost
        i = int(np.argmin(c))
        if i == 0 or i == len(c) - 1:
            return
        y0, y1, y2 = c[i - 1], c[i], c[i + 1]
        den = y0 - 2 * y1 + y2
        off = 0.5 * (y0 - y2) / den if den > 0 else 0.0
        # A clear minimum: the cost well below its median over the candidates.
        if not y1 < 0.5 * float(np.median(c)):
            return
        est = (i + 1 + max(-0.5, min(0.5, off))) * self.dt  # candidate i is a delay of (i+1) steps
        # Slew-limited: a wrong step in the delay costs more than a slow convergence.
        step = max(-MAX_SLEW_S, min(MAX_SLEW_S, 0.2 * (est - self.delay_s)))
        self.delay_s += step
