"""The GNSS velocity noise as the wheels witness it, instead of the receiver's pessimistic sAcc.

Receivers report a speed accuracy (u-blox sAcc, or the configured NMEA figure) that is a
conservative bound, often several times the real scatter: the simulated receiver reports 0.12 m/s
for 0.05 m/s of noise, the Revs data 0.3 m/s for 0.05. Fused with that variance, every fix counts
for a fraction of what it is worth, so the lateral velocity (sideslip) lives on the IMU
integration between fixes and its standard deviation stays several times the real error (Revs:
98 % of the sideslip errors inside 1 sigma, where a calibrated filter has 68 %): honest in
direction but needlessly invalid.

Along the track, the filter's speed is the wheel speed (a 1-2 cm/s error at 83-100 Hz), so the
along-track innovation of a GNSS fix is the receiver's noise plus the filter's small speed error
(and a latency error times the acceleration): its mean square bounds the receiver's real
per-axis noise variance from above; receiver velocity noise is isotropic, so the same variance
holds across the track. The learned variance is used only below
the reported one (the receiver's figure stays a ceiling: a fix is never trusted more than the
receiver says unless the wheels have shown it is better), rises quickly when the scatter does
(multipath, a degraded fix) and falls slowly, and is never below ``FLOOR_MPS``.
"""
from __future__ import annotations

import math

FLOOR_MPS = 0.02  # below any receiver's velocity noise (Doppler at 5-10 Hz)
MIN_SAMPLES = 10  # fixes before the learned value is used
RISE = 0.2  # EMA weight of a sample above the estimate (scatter rising: believe it fast)
FALL = 0.04  # ... below it (~25 fixes: 5 s at 5 Hz)


class GnssNoiseLearner:
    __slots__ = ("var", "samples")

    def __init__(self) -> None:
        self.var = math.nan  # learned per-axis velocity noise variance (m^2/s^2)
        self.samples = 0

    def observe(self, innovation: float) -> None:
        """One along-track innovation (m/s). Its square is taken whole as receiver noise: the
        filter's own speed error and timing only add to it, so the estimate errs on the side of
        the receiver's figure, never below the real scatter."""
        if not math.isfinite(innovation):
            return
        sample = innovation * innovation
        if self.samples == 0:
            self.var = max(sample, FLOOR_MPS * FLOOR_MPS)
        else:
            self.var += (RISE if sample > self.var else FALL) * (sample - self.var)
        self.samples += 1

    def sigma(self, reported: float) -> float:
        """The noise (1-sigma, m/s) to fuse a fix with whose receiver reports ``reported``."""
        if self.samples < MIN_SAMPLES:
            return reported
        return min(reported, math.sqrt(max(self.var, FLOOR_MPS * FLOOR_MPS)))
