"""Online GNSS latency identification.

The receiver reports velocity some hundreds of ms after its time of validity. The delay shows
as a time shift between the GNSS speed and the speed from the wheel sensors. Yoon & Peng (003
§3; 000 §4.4.1.1) identify it offline by comparing the two during smooth acceleration; this is
the same idea online, as a regression per candidate delay:

    gnss_speed(t_rx)  ~  a * wheel_speed(t_rx - d) + b        for every d on the 6 ms grid

with exponentially forgotten sufficient statistics, so the scale a (wheel radius error, and the
sideslip's cos factor) and the offset b cannot bias the timing. The residual sum of squares of each
candidate is its cost; the minimum, refined by a parabola, is the delay. It moves only when the
cost has a clear minimum (enough speed variation to see a shift), with a slew limit; otherwise
the prior (config ``delay_s``) stands.

Only the wheel speeds are used: they are independent of GNSS and of any vehicle model. (Course
changes against the integrated yaw rate would add lateral information, but they carry the
sideslip's own errors into the timing, which on real data biased it; measured on Revs and the
simulator.) ``std_s`` is the 1-sigma of the estimate, which the GNSS fusion turns into velocity
noise (|a| * std), so GNSS is de-weighted in hard manoeuvres until the delay is known.
"""
from __future__ import annotations

import numpy as np

from .history import AUX_WHEEL, StepHistory

MIN_SPEED = 3.0  # m/s: below walking pace wheel sensors read zero
MIN_UPDATES = 30  # informative fixes before the prior is left
CLEAR_MINIMUM = 0.5  # cost at the minimum must be below this fraction of the median cost
MAX_SLEW_S = 0.004  # per fix (x4 for a very clear minimum)
PRIOR_STD_S = 0.15
FIXED_STD_S = 0.01
SETTLED_STD_S = 0.01
MIN_SPEED_SPREAD = 0.3  # m/s: the regression needs some speed variation in its memory


class LatencyEstimator:
    def __init__(self, dt: float, prior_s: float, max_s: float, enabled: bool = True,
                 forgetting: float = 0.995):
        self.dt = dt
        self.enabled = enabled
        self.delay_s = prior_s
        # a fixed (configured, not estimated) latency is taken as good to a few ms; an estimated
        # one starts uncertain and tightens as the identification settles
        self.std_s = PRIOR_STD_S if enabled else FIXED_STD_S
        self.max_steps = max(2, int(max_s / dt))
        n = self.max_steps + 1
        self.forgetting = forgetting
        # sufficient statistics of y = a x + b per candidate (x: delayed wheel speed, y: GNSS)
        self.s0 = np.zeros(n)
        self.sx = np.zeros(n)
        self.sy = np.zeros(n)
        self.sxx = np.zeros(n)
        self.sxy = np.zeros(n)
        self.syy = np.zeros(n)
        self.updates = 0
        self.cost = np.zeros(n)

    def observe(self, k_rx: int, speed: float, hist: StepHistory) -> None:
        """Feed one GNSS fix received just before step k_rx (history ends at k_rx - 1)."""
        if not self.enabled or speed < MIN_SPEED:
            return
        m = np.arange(self.max_steps + 1)
        cand = k_rx - 1 - m  # candidate validity steps: a delay of (m + 1) steps
        ok = cand >= hist.oldest()
        if not ok.all():
            return  # not enough history yet (start-up / after a reset)
        x = hist.aux[cand % hist.n, AUX_WHEEL]
        if not np.isfinite(x).all() or x.min() < MIN_SPEED:
            return
        lam = self.forgetting
        y = speed
        self.s0 = lam * self.s0 + 1.0
        self.sx = lam * self.sx + x
        self.sy = lam * self.sy + y
        self.sxx = lam * self.sxx + x * x
        self.sxy = lam * self.sxy + x * y
        self.syy = lam * self.syy + y * y
        self.updates += 1
        self._refine()

    def _refine(self) -> None:
        if self.updates < MIN_UPDATES:
            return
        n = self.s0
        cxx = self.sxx - self.sx * self.sx / n
        cxy = self.sxy - self.sx * self.sy / n
        cyy = self.syy - self.sy * self.sy / n
        if not (cxx.min() > MIN_SPEED_SPREAD ** 2 * n[0] * 0.1):
            return  # speed has hardly varied: no timing information
        c = np.maximum(cyy - cxy * cxy / cxx, 0.0)
        self.cost = c
        i = int(np.argmin(c))
        if i == 0 or i == len(c) - 1:
            return
        y0, y1, y2 = c[i - 1], c[i], c[i + 1]
        med = float(np.median(c))
        if not y1 < CLEAR_MINIMUM * med:
            return
        den = y0 - 2 * y1 + y2
        off = 0.5 * (y0 - y2) / den if den > 0 else 0.0
        est = (i + 1 + max(-0.5, min(0.5, off))) * self.dt  # candidate i is a delay of (i+1) steps
        # Slew-limited: a wrong step in the delay costs more than a slow convergence; a very
        # clear minimum may move faster.
        slew = MAX_SLEW_S * (4.0 if y1 < 0.2 * med else 1.0)
        self.delay_s += max(-slew, min(slew, 0.3 * (est - self.delay_s)))
        if abs(est - self.delay_s) < 0.02:  # settled: the minimum agrees with where we are
            self.std_s = max(SETTLED_STD_S, 0.95 * self.std_s)
        else:
            self.std_s = max(self.std_s, min(PRIOR_STD_S, abs(est - self.delay_s)))
