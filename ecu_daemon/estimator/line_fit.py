"""Least squares ``d = k a + c b`` from running sums, ``c`` optionally held towards 0 by a prior.

Why one class: three checks fit the same two-parameter line against a witness, each with its own
sums before: the gyro-scale gate (``gyro_scale_gate.py``: the gyro against the rear axle's speed
difference and against ``ay / vx``, the offset held by a prior), the wheels' scale against the
gyro (``wheel_yaw_check.py``: no prior) and the wheel-offset fit of a re-seeded wheel scale
(``input_consistency.WheelScaleSeed``: raw wheel speed against GNSS speed, both centred, ``b =
1``, over a window it rebuilds the sums from). The normal equations, the determinant, the solve,
the residual and the covariance are written here once.

The prior is one more observation of ``c``: ``prior_weight`` (``lam``) is added to ``sum b^2``
(``lam = (noise / c_sd)^2``: the prior's weight with the residual at the noise ``noise``), so a
steady circle, where ``a`` and ``b`` stay in proportion, bounds ``k`` by what the prior allows of
``c`` instead of leaving it free. For the same reason the residual's degrees of freedom are
``n - 1`` with a prior and ``n - 2`` without.

The operations are those the gyro-scale gate and the wheel-yaw check did before, in the same
order (the same bits): the residual sum of squares is the data's own, ``|d - k a - c b|^2``
expanded in the sums; without a prior the normal equations reduce it to ``d'd - k a'd - c b'd``
(the same value, exactly, for the unpenalised solution), the form the wheels' check used. The
wheel-offset fit summed its centred products directly before: its slope, offset and offset std
now differ from those in the last bits (1e-16, 1e-14 m/s, 1e-12 relative on random windows).
"""
from __future__ import annotations

import math


class LineFit:
    """Running sums of ``a a, a b, b b, a d, b d, d d`` and their solve (module docstring)."""

    def __init__(self, prior_weight: float = 0.0):
        self.lam = prior_weight  # added to sum b^2: the prior on c (0: none)
        self.saa = self.sab = self.sbb = self.sad = self.sbd = self.sdd = 0.0
        self.n = 0
        self.k = math.nan  # the last solve's k and c
        self.c = math.nan
        self.det = math.nan  # its determinant and sum b^2 with the prior (k's variance: var sbb_p / det)
        self.sbb_p = math.nan

    def add(self, a: float, b: float, d: float) -> None:
        """One sample: ``a`` the regressor of ``k``, ``b`` that of ``c``, ``d`` the witness."""
        self.saa += a * a
        self.sab += a * b
        self.sbb += b * b
        self.sad += a * d
        self.sbd += b * d
        self.sdd += d * d
        self.n += 1

    def solve(self, min_det_rel: float = 0.0) -> bool:
        """Solve for ``k`` and ``c``; False (nothing changed) unless the determinant exceeds 0, or
        ``min_det_rel`` times ``sum a^2 sum b^2`` when that is given (the regressors nearly
        proportional: ``k`` and ``c`` cannot be told apart)."""
        sbb = self.sbb + self.lam
        det = self.saa * sbb - self.sab * self.sab
        if not det > (min_det_rel * self.saa * sbb if min_det_rel else 0.0):
            return False
        self.k = (self.sad * sbb - self.sbd * self.sab) / det
        self.c = (self.sbd * self.saa - self.sad * self.sab) / det
        self.det, self.sbb_p = det, sbb
        return True

    def rss(self) -> float:
        """The residual sum of squares of the last solve (data only, not the prior's term), >= 0."""
        k, c = self.k, self.c
        if self.lam == 0.0:  # the normal equations hold: d'd - beta' X'd
            return max(self.sdd - k * self.sad - c * self.sbd, 0.0)
        return max(self.sdd - 2.0 * (k * self.sad + c * self.sbd)
                   + k * k * self.saa + 2.0 * k * c * self.sab + c * c * self.sbb, 0.0)

    def residual_var(self, floor: float = 0.0) -> float:
        """The residual's variance per sample (``n - 1`` degrees of freedom with a prior, ``n - 2``
        without), never below ``floor`` squared."""
        dof = self.n - 1 if self.lam != 0.0 else self.n - 2
        return max(self.rss() / dof, floor * floor)

    def k_var(self, var: float) -> float:
        """``k``'s variance for a residual variance ``var``."""
        return var * self.sbb_p / self.det

    def c_var(self, var: float) -> float:
        """``c``'s variance for a residual variance ``var``."""
        return var * self.saa / self.det

    def kc_cov(self, var: float) -> float:
        """The covariance of ``k`` and ``c`` for a residual variance ``var``."""
        return -var * self.sab / self.det
