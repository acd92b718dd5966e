"""Online GNSS latency identification.

The receiver reports velocity some hundreds of ms after its time of validity. The delay shows
as a time shift between the GNSS speed and the speed from the wheel sensors. Yoon & Peng (003
§3; 000 §4.4.1.1) identify it offline by comparing the two during smooth acceleration; this is
the same idea online, as a regression per candidate delay:

    gnss_speed(t_rx)  ~  a * wheel_speed(t_rx - d) + b        for every d on the 6 ms grid

with exponentially forgotten sufficient statistics, so the scale a (wheel radius error, and the
sideslip's cos factor) and the offset b cannot bias the timing.

Known bias, not corrected: a braked wheel turns slower than the car by v * kappa with
kappa ~ ax * m / C_x, and since a time shift looks like -ax * d, that slip reads as a delay
error of about v * m / C_x in braking phases (simulated drives: +0.04 s at 25 m/s, +0.07 s at
50 m/s). Leaving braking fixes out removes it in the simulator but on the real RAV4 highway drive
moves the estimate from 0.15 to 0.11 s (truth ~0.20 s): there the wheel speeds themselves seem to
lag, which the braking bias happens to offset. Until that is understood, all fixes are used.

The residual sum of squares of each candidate is its cost; the minimum, refined by a parabola, is
the delay. It moves only when the data reject the current delay (a likelihood-ratio test on the
cost profile), with a slew limit; otherwise the prior (config ``delay_s``) stands, and nothing
drifts on a drive without speed changes.

Only the wheel speeds are used: they are independent of GNSS and of any vehicle model. (Course
changes against the integrated yaw rate would add lateral information, but they carry the
sideslip's own errors into the timing, which on real data biased it; measured on Revs and the
simulator.) ``std_s`` is the 1-sigma of the estimate, which the GNSS fusion turns into velocity
noise (|a| * std), so GNSS is de-weighted in hard manoeuvres until the delay is known.

A heading-only receiver (``role = "heading"``) has no speed to regress: its heading change
between two samples is regressed on the integrated yaw rate over the same interval delayed by
each candidate (:meth:`LatencyEstimator.observe_series`, fed by :class:`YawIntegral`), the
same statistics and decision rule; the integrated gyro, not the filter's heading, because the
filter's heading is pulled towards the receiver at the current latency estimate.
"""
from __future__ import annotations

import math

import numpy as np

from .history import AUX_WHEEL, StepHistory

MIN_SPEED = 3.0  # m/s: below walking pace wheel sensors read zero
MIN_UPDATES = 30  # informative fixes before the prior is left
LR_REJECT = 16.0  # likelihood ratio (4 sigma: GNSS and wheel errors are correlated over fixes)
MAX_SLEW_S = 0.004  # per fix (x4 for a very clear minimum)
PRIOR_STD_S = 0.15
FIXED_STD_S = 0.01
MIN_STD_S = 0.005  # the 6 ms candidate grid, refined by a parabola
STD_FALL = 0.98  # per informative fix: the std shrinks by e in ~10 s at 5 Hz
MIN_SPEED_SPREAD = 0.3  # m/s: the regression needs some speed variation in its memory


class LatencyEstimator:
    def __init__(self, dt: float, prior_s: float, max_s: float, enabled: bool = True,
                 forgetting: float = 0.995, prior_std_s: float = PRIOR_STD_S, min_spread: float = MIN_SPEED_SPREAD):
        self.dt = dt
        self.min_spread = min_spread  # of the regressor (its unit) for the timing to be informative
        self.enabled = enabled
        self.delay_s = prior_s
        # a fixed (configured, not estimated) latency is taken as good to a few ms; an estimated
        # one starts as uncertain as its prior (the config's, or the one identified before a
        # restart) and tightens as the identification settles
        self.prior_std_s = min(max(prior_std_s, MIN_STD_S), PRIOR_STD_S)
        self.std_s = self.prior_std_s if enabled else FIXED_STD_S
        self.max_steps = max(2, int(max_s / dt))
        n = self.max_steps + 1
        self.forgetting = forgetting
        # sufficient statistics of y = [x, 1] . theta per candidate (x: delayed wheel speed,
        # y: GNSS speed): Z'Z, Z'y and y'y
        self.zz = np.zeros((n, 2, 2))
        self.zy = np.zeros((n, 2))
        self.syy = 0.0
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
        slot = cand % hist.n
        x = hist.aux[slot, AUX_WHEEL]
        if not np.isfinite(x).all() or x.min() < MIN_SPEED:
            return
        self.observe_series(x, speed)

    def observe_series(self, x: np.ndarray, y: float) -> None:
        """One observation ``y ~ a * x[m] + b`` for every candidate m (``x[m]``: the reference
        signal at the candidate validity step, a delay of m + 1 steps)."""
        if not self.enabled:
            return
        z = np.stack((x, np.ones_like(x)), axis=1)
        lam = self.forgetting
        self.zz = lam * self.zz + z[:, :, None] * z[:, None, :]
        self.zy = lam * self.zy + z * y
        self.syy = lam * self.syy + y * y
        self.updates += 1
        self._refine()

    def _refine(self) -> None:
        if self.updates < MIN_UPDATES:
            return
        zz = self.zz
        n = zz[0, 1, 1]
        cxx = zz[:, 0, 0] - zz[:, 0, 1] ** 2 / n
        if not (cxx.min() > self.min_spread ** 2 * n * 0.1):
            return  # the regressor has hardly varied: no timing information
        # residual sum of squares of the least-squares fit per candidate
        theta = np.linalg.solve(zz, self.zy[:, :, None])[:, :, 0]
        c = np.maximum(self.syy - np.einsum("ki,ki->k", theta, self.zy), 0.0)
        self.cost = c
        i = int(np.argmin(c))
        if i == 0 or i == len(c) - 1:
            return
        # Likelihood-ratio statistic of every candidate against the best: RSS excess over the
        # residual variance per fix. Its profile gives both the decision (move only when the
        # data reject the current delay) and an honest std (the width of the set of delays the
        # data cannot reject; several near-equal minima, as a weakly excited drive has, make it
        # wide instead of picking one by noise).
        s2 = max(c[i], 1e-12) / max(n - 2.0, 1.0)
        lr = (c - c[i]) / s2
        y0, y1, y2 = c[i - 1], c[i], c[i + 1]
        den = y0 - 2 * y1 + y2
        off = 0.5 * (y0 - y2) / den if den > 0 else 0.0
        est = (i + 1 + max(-0.5, min(0.5, off))) * self.dt  # candidate i is a delay of (i+1) steps
        inside = np.flatnonzero(lr < LR_REJECT)
        width_std = 0.5 * (inside[-1] - inside[0] + 1) * self.dt / math.sqrt(LR_REJECT)
        cur = min(max(int(round(self.delay_s / self.dt)) - 1, 0), len(c) - 1)
        prior_std = self.prior_std_s
        if lr[cur] > LR_REJECT:
            # Slew-limited: a wrong step in the delay costs more than a slow convergence; a
            # very clear minimum may move faster. The prior is refuted: only the data count.
            slew = MAX_SLEW_S * (4.0 if y1 < 0.2 * float(np.median(c)) else 1.0)
            self.delay_s += max(-slew, min(slew, 0.3 * (est - self.delay_s)))
            prior_std = math.inf
        data_std = max(width_std, abs(est - self.delay_s))
        std = min(PRIOR_STD_S, max(MIN_STD_S, 1.0 / math.sqrt(prior_std ** -2 + data_std ** -2)))
        # rises at once, falls slowly: on real data (RAV4) the profile's second minimum comes
        # and goes from one fix to the next, and a std that followed it would promise too much
        self.std_s = max(std, STD_FALL * self.std_s)


HEADING_SPREAD_RAD = 0.01  # heading change between samples: turning, not straight-line noise
MAX_HEADING_GAP_S = 1.5  # two heading samples further apart than this are not paired


class YawIntegral:
    """The yaw rate integrated step by step (clockwise, as a heading), kept for the last
    ``n`` steps: the reference of a heading-only receiver's latency identification."""

    def __init__(self, dt: float, max_delay_s: float):
        self.dt = dt
        self.n = int(math.ceil((max_delay_s + MAX_HEADING_GAP_S) / dt)) + 4
        self.psi = np.zeros(self.n)
        self.total = 0.0
        self.last = -1  # last step stored
        self.first = 0  # first step of the current unbroken run
        self.prev: dict[int, tuple[int, float]] = {}  # receiver -> (step received, vehicle heading)

    def step(self, k: int, r: float) -> None:
        if k != self.last + 1:
            self.first = k
            self.prev.clear()
        self.total -= r * self.dt
        self.psi[k % self.n] = self.total
        self.last = k

    def pair(self, receiver: int, k_rx: int, heading: float, lat: LatencyEstimator) -> None:
        """A heading sample of ``receiver`` received just before step ``k_rx``: regress its change
        since the previous one on the gyro's over the same interval, delayed by each candidate."""
        prev = self.prev.get(receiver)
        self.prev[receiver] = (k_rx, heading)
        if prev is None:
            return
        k0, h0 = prev
        m = np.arange(lat.max_steps + 1)
        c1, c0 = k_rx - 1 - m, k0 - 1 - m
        if not (0 < (k_rx - k0) * self.dt <= MAX_HEADING_GAP_S and c0[-1] >= max(self.first, self.last - self.n + 1)
                and c1[0] <= self.last):
            return
        x = self.psi[c1 % self.n] - self.psi[c0 % self.n]
        y = math.remainder(heading - h0, 2.0 * math.pi)
        lat.observe_series(x, y)
