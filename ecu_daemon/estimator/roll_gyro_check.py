"""Is the roll-rate gyro mapped right? Its roll changes against the roll the lateral force drives.

Why: the roll filter (road.RollGyro) integrates the gyro and pulls the roll to the suspension
model ``roll = k f`` every few steps, so a gyro mapped wrong -- its sign flipped, a deg/s scale on
a signal already in rad/s (x0.0175), the yaw rate's signal mapped as roll rate -- is pulled back
between turns but wrong in every turn: slalom_dry_bank published roll 2.1, 1.7 and 5.6 deg off as
valid (74-97 % of the valid rows within 3 sigma). Nothing cross-checked the gyro.

Physics: body roll follows the lateral force through the suspension (quasi-static, a few deg/g,
``ROLL_LAG_S`` late), so over a short window the gyro's integral (its roll change) and the change
of the low-passed lateral force ``f`` must move together: their ratio is the car's roll gradient.
Over windows of ``RG_WINDOW_S``, weighted over ``RG_TAU_S``, this fits that gradient and the
correlation of the two changes. Only with enough evidence, the force changing well beyond ay's
noise (``RG_MIN_DF`` over ``RG_MIN_WINDOWS`` windows, weighted: a turn-in, a lane change; not a
steady circle), is there a verdict; between verdicts the last one stands. A right gyro has a gradient a car can
have (``RG_GRADIENT_RANGE``) and a correlation near 1 (a changing road bank, which the gyro sees
and the force does not, lowers it a little); a flipped one a negative gradient, a deg scale a
gradient 57x too small, the yaw rate a correlation near 0 (r is in phase with f, not with its
change). Passing verdicts for ``RG_OFF_S`` make the gyro :attr:`RollGyroCheck.trusted`; failing
ones for ``RG_ON_S`` make it :attr:`RollGyroCheck.wrong` (not trusted): its roll is then not
published, the suspension model's is (road.RoadAttitude.set_roll_gyro). Before the first
verdict a gyro is not taken on faith either (a flipped one was 1 deg off, 4 sigma, 0.4 s into
slalom_dry_bank's first turn-in, before any check could judge it): its roll's std also covers
its disagreement with the model until it is trusted.
"""
from __future__ import annotations

import math

from ..gravity import G

RG_EVERY = 5  # steps between samples (30 ms): the check is slow by design
RG_WINDOW_S = 0.3  # a slalom's force changes by its amplitude in a quarter period (0.5 Hz: 0.5 s)
RG_TAU_S = 3.0  # weighting of the windows: a couple of turns
RG_MIN_DF = 1.0  # m/s^2 change of f per window: well above ay's low-passed noise (0.1-0.3)
RG_MIN_WINDOWS = 10.0  # ... over this many (weighted) windows: 0.3 s of a turn-in at RG_MIN_DF
RG_GRADIENT_RANGE = (math.radians(0.5) / G, math.radians(15.0) / G)  # rad per m/s^2 (cars: 2-8 deg/g)
RG_MIN_CORR = 0.5  # road bank changes and suspension dynamics: a right gyro stays above 0.8
RG_ON_S = 0.3  # failing verdicts this long: wrong
RG_OFF_S = 0.6  # passing verdicts this long: trusted


class RollGyroCheck:
    """:attr:`wrong` while the gyro's roll changes do not follow the lateral force's (module doc)."""

    def __init__(self, dt: float):
        self.dt = dt
        self._n = max(2, int(round(RG_WINDOW_S / (RG_EVERY * dt))))
        self._ring_g = [math.nan] * self._n
        self._ring_f = [math.nan] * self._n
        self._j = 0
        self._k = 0
        self._cum = 0.0
        self._lam = math.exp(-RG_EVERY * dt / RG_TAU_S)
        self._s = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # weighted n, sum dg df, df^2, dg^2, df^2 of df > 0, of df < 0
        self._on = max(1, int(round(RG_ON_S / (RG_EVERY * dt))))
        self._off = max(1, int(round(RG_OFF_S / (RG_EVERY * dt))))
        self._bad = self._good = 0
        self.wrong = False
        self.trusted = False  # its roll is published (passing verdicts, RG_OFF_S)
        self.gradient = math.nan  # rad per m/s^2, the last verdict's fit
        self.corr = math.nan
        self.events = 0  # times it was found wrong

    def step(self, p: float, f: float) -> bool:
        """One step: ``p`` the gyro's bias-corrected roll rate (NaN: stale), ``f`` the low-passed
        lateral force (m/s^2). Returns :attr:`wrong` (see also :attr:`trusted`)."""
        if p != p or f != f:  # a gap: the windows restart
            self._ring_g = [math.nan] * self._n
            self._cum = 0.0
            return self.wrong
        self._cum += p * self.dt
        self._k += 1
        if self._k % RG_EVERY:
            return self.wrong
        j = self._j
        g_old, f_old = self._ring_g[j], self._ring_f[j]
        self._ring_g[j], self._ring_f[j] = self._cum, f
        self._j = (j + 1) % self._n
        if g_old != g_old:
            return self.wrong
        dg, df = self._cum - g_old, f - f_old
        s, lam = self._s, self._lam
        s[0] = lam * s[0] + 1.0
        s[1] = lam * s[1] + dg * df
        s[2] = lam * s[2] + df * df
        s[3] = lam * s[3] + dg * dg
        s[4] = lam * s[4] + (df * df if df > 0.0 else 0.0)
        s[5] = lam * s[5] + (df * df if df < 0.0 else 0.0)
        if s[2] < RG_MIN_DF * RG_MIN_DF * RG_MIN_WINDOWS:
            return self.wrong  # the force hardly changes: no verdict, the last one stands
        k = self.gradient = s[1] / s[2]
        c = self.corr = s[1] / math.sqrt(s[2] * s[3]) if s[3] > 0.0 else 0.0
        lo, hi = RG_GRADIENT_RANGE
        if not (lo <= k <= hi and c >= RG_MIN_CORR):
            self._bad += 1
            self._good = 0
            if not self.wrong and self._bad >= self._on:
                self.wrong = True
                self.trusted = False
                self.events += 1
        elif min(s[4], s[5]) >= 0.5 * RG_MIN_DF * RG_MIN_DF * RG_MIN_WINDOWS:
            # passing counts only with the force both rising and falling in the fit: over a turn-in
            # alone any signal that grows with the force (the yaw rate: in phase with it, not with
            # its change) has a roll change that rises with the force's
            self._good += 1
            self._bad = 0
            if not self.trusted and self._good >= self._off:
                self.wrong = False
                self.trusted = True
        return self.wrong

    def likely(self) -> str:
        """What the fit says the mapping error is (for the log line)."""
        k, c = self.gradient, self.corr
        if c < RG_MIN_CORR and abs(c) < 0.5:
            return "another signal (the yaw rate?) mapped as roll rate"
        if k < 0.0:
            return "sign flipped"
        lo, hi = RG_GRADIENT_RANGE
        good = math.radians(4.0) / G
        if k < lo:
            return f"scale {k / good:.3g}x too small (deg/s scale on a signal in rad/s?)"
        if k > hi:
            return f"scale {k / good:.3g}x too large (a rad/s scale on a signal in deg/s?)"
        return "unclear"
