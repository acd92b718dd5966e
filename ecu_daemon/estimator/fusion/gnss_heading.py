"""Dual-antenna GNSS heading (u-blox moving base + rover NAV-RELPOSNED, NMEA HDT / THS), fused at
its time of validity.

Why a source of its own: the baseline between two antennas gives the heading directly, at any
speed and at standstill, instead of through the course of a moving car (which carries the
sideslip). With it the velocity's direction pins the sideslip: course - heading.

Quality first (the receiver's flags, its heading accuracy, the measured baseline against the
mounted one: a wrong carrier-phase fix shows as a wrong length before it shows as a wrong
heading), then the time of validity (same receiver, same latency as its velocity), then a scalar
innovation gate and the update at the stored step, shifted to the present
(``history.StepHistory.correct``). A heading the filter does not yet have (start-up, reset) is
set directly (:meth:`GnssHeadingFusion.align`). The latency's uncertainty turns into heading noise
while turning (r * delay std), as for the velocity.
"""
from __future__ import annotations

import math

import numpy as np

from ...samples import GnssHeadingSample
from .. import kalman
from ..history import AUX_R, StepHistory
from ..kinematic import NX, PSI, wrap_pi
from ..latency_consider import LatencyConsider
from .gnss_velocity import NOT_PD

# what happened to the last heading sample (EST_DIAG.GNSS_HEADING_STATE)
STATE_NONE = 0  # no heading received yet
STATE_FUSED = 1
STATE_INVALID = 2  # the receiver's flags or its accuracy say it is no good
STATE_BASELINE = 3  # measured baseline far from the mounted one
STATE_GATE = 4  # disagreed with the filter
STATE_STALE = 5  # none received for longer than the GNSS timeout (set by whoever knows the time)

HEADING_ACC_FLOOR_RAD = math.radians(0.05)  # below what any receiver's accHeading is honest about
#: the heading's time stamp against its velocity's (s): the receiver sends an epoch's messages one
#: after another (a NAV-PVT is ~9 ms at 115200 baud), so the two latencies differ by about this much
STAGGER_S = 0.01
#: consecutive gate rejections after which the filter, not the baseline, is taken to be wrong
REALIGN_REJECTS = 5


class GnssHeadingFusion:
    def __init__(self, mounts: list[tuple[float, float]], baseline_tol_m: float, max_acc_deg: float,
                 nmea_acc_deg: float, gate_sigma: float):
        """``mounts``: per receiver (``GnssHeadingSample.source``), the baseline's heading offset from
        the vehicle's (deg, clockwise) and its mounted length (m, 0: not checked)."""
        self.offsets = [math.radians(o) for o, _ in mounts]
        self.baselines = [b for _, b in mounts]
        self.baseline_tol_m = baseline_tol_m
        self.max_acc = math.radians(max_acc_deg)
        self.nmea_acc = math.radians(nmea_acc_deg)
        self.gate_sigma = gate_sigma
        self.fused = 0
        self.rejected = 0
        self.late = 0  # measured before the filter's first step: left out, never judged (core.BEFORE_START)
        self.consecutive_rejects = 0
        self.last_reason = ""
        self.state = STATE_NONE
        self.last: GnssHeadingSample | None = None  # the last sample received, usable or not
        # preallocated update operands (fusion is not re-entrant: one estimator, one thread)
        self._H = np.zeros((1, NX))
        self._H[0, PSI] = 1.0
        self._R, self._y = np.zeros((1, 1)), np.zeros(1)
        self._dx, self._M = np.zeros(NX), np.zeros((NX, NX))

    def sigma(self, g: GnssHeadingSample) -> float:
        acc = g.heading_acc_rad if math.isfinite(g.heading_acc_rad) else self.nmea_acc
        return max(acc, HEADING_ACC_FLOOR_RAD)

    def usable(self, g: GnssHeadingSample) -> bool:
        """The receiver's verdict, its accuracy and the baseline length; the reason in ``last_reason``."""
        self.last = g
        self.state = STATE_INVALID
        if not g.valid or not math.isfinite(g.heading_rad):
            self.last_reason = "no valid heading solution"
            return False
        if math.isfinite(g.heading_acc_rad) and g.heading_acc_rad > self.max_acc:
            self.last_reason = f"heading accuracy {math.degrees(g.heading_acc_rad):.2f} deg above limit"
            return False
        if not 0 <= g.source < len(self.offsets):
            self.last_reason = f"no receiver #{g.source + 1} configured"
            return False
        mounted = self.baselines[g.source]
        if mounted > 0.0 and math.isfinite(g.baseline_m) and abs(g.baseline_m - mounted) > self.baseline_tol_m:
            self.last_reason = (f"baseline {g.baseline_m:.3f} m, mounted {mounted:.3f} m"
                                " (wrong carrier fix)")
            self.state = STATE_BASELINE
            return False
        self.state = STATE_FUSED  # unless the gate says otherwise
        return True

    def vehicle_heading(self, g: GnssHeadingSample) -> float:
        """The vehicle's heading, clockwise from north in [0, 2pi), from the baseline's."""
        return (g.heading_rad - self.offsets[g.source]) % (2.0 * math.pi)

    def variance(self, hist: StepHistory, s: int, g: GnssHeadingSample, delay_std_s: float) -> float:
        r = hist.aux[hist.slot(s), AUX_R]
        return self.sigma(g) ** 2 + (r * delay_std_s) ** 2

    def fuse(self, hist: StepHistory, s: int, g: GnssHeadingSample, delay_std_s: float,
             consider: LatencyConsider | None = None, stagger_s: float = STAGGER_S) -> bool:
        """Scalar heading update at stored step s (Joseph form, through ``kalman.late_update`` as
        the velocity's); False (counted) when gated out, or when the corrected covariance would
        not be positive definite (``StepHistory.correct`` refuses it). With ``consider`` (the
        receiver's latency error, shared with its velocity) the heading reads ``psi + r d``
        (d psi / dt = -r) instead of carrying ``(r std)^2`` of white noise
        (``latency_consider.py``); only the stagger of its time stamp stays noise (``stagger_s``:
        0 when the heading is dated by its epoch's velocity fix, UBX RELPOSNED's iTOW)."""
        i = hist.slot(s)
        y = wrap_pi(self.vehicle_heading(g) - hist.X[i, PSI])
        self._R[0, 0] = self.variance(hist, s, g, stagger_s if consider is not None else delay_std_s)
        self._y[0] = y
        if consider is None:
            nis = kalman.late_update(hist.P[i], self._H, self._R, self._y, self._dx, self._M)
        else:
            nis, c = consider.late_update(hist.P[i], consider.Cr[i], self._H, np.array((hist.aux[i, AUX_R],)),
                                          self._R, self._y, self._dx, self._M)
        if not nis <= self.gate_sigma ** 2:  # NaN: no usable innovation covariance
            self.consecutive_rejects += 1
            self.rejected += 1
            self.last_reason = f"heading innovation gate ({math.degrees(y):+.2f} deg)"
            self.state = STATE_GATE
            return False
        if not hist.correct(s, self._dx, self._M):
            self.rejected += 1
            self.last_reason = NOT_PD
            return False
        if consider is not None:
            consider.commit(hist, s, c)
        self.consecutive_rejects = 0
        self.fused += 1
        return True

    def align(self, hist: StepHistory, s: int, g: GnssHeadingSample, delay_std_s: float, q_step: float) -> None:
        """Set the heading of every stored step from this measurement at step s.

        Each step keeps the heading change it integrated since s, so the history stays consistent
        for later (late) samples. The heading's variance is the measurement's, growing by the
        model's per-step process noise ``q_step`` after s (what propagating it through the stored
        transitions gives; a later sample's correction is carried forward on that assumption), and
        its correlation with the other states starts at zero: it came from none of them.
        """
        i = hist.slot(s)
        dpsi = self.vehicle_heading(g) - hist.X[i, PSI]
        var0 = self.variance(hist, s, g, delay_std_s)
        steps = np.arange(hist.oldest(), hist.last + 1)
        idx = steps % hist.n
        hist.X[idx, PSI] = (hist.X[idx, PSI] + dpsi) % (2.0 * math.pi)
        P = hist.P[idx]
        P[:, PSI, :] = 0.0
        P[:, :, PSI] = 0.0
        P[:, PSI, PSI] = var0 + q_step * np.maximum(steps - s, 0)
        hist.P[idx] = P
        self.consecutive_rejects = 0
        self.fused += 1
