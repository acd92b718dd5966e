"""GNSS velocity (north/east of the antenna), fused at its time of validity.

Quality first (fix type, receiver validity, speed accuracy), then the time of validity
(receive time minus the latency estimate), then an innovation gate (normalised innovation
squared against chi-square), then the update at the stored step and the shift to the present
(``history.StepHistory.correct``).

Before the heading is known (after start-up or a reset) the velocity *direction* cannot be
fused linearly (through a heading with a variance of pi^2 it drags vx anywhere); then only the
speed is fused, and the heading is aligned from the GNSS course once the car moves fast enough
(course = heading - sideslip, clockwise-from-north convention). A run of consecutive gate
rejections (a real jump, or a diverged filter) is resolved by the core against the wheel
speeds: GNSS that agrees with the wheels re-aligns the heading, GNSS that does not stays
rejected (never a blind acceptance; the NIS lock-out the Yoon thesis warns about is avoided
without trusting a glitch).
"""
from __future__ import annotations

import math

import numpy as np

from ...samples import GnssSample
from ..gnss_noise import GnssNoiseLearner
from ..history import AUX_AX, AUX_AY, AUX_R, StepHistory
from ..kinematic import NX, VX, VY, antenna_velocity_ne, gnss_jacobian

ALIGN_SPEED = 5.0  # m/s: course is good to ~ sigma_v / v rad
MAX_CONSECUTIVE_REJECTS = 10
# A latency error is the same for every fix of a manoeuvre (~5 s of acceleration at 5 Hz), so its
# speed error ax * dd is a bias over that many fixes, not noise: weighted as one measurement per
# manoeuvre instead of one per fix (else a start-up acceleration with the latency 0.3 s off taught
# a wheel scale of 1.15 and vx 0.9 m/s off, valid).
TIMING_FIXES = 25.0
# chi-square, 2 degrees of freedom, for a gate of n sigma: exp(-g/2) = tail(n sigma, 1-D)
CHI2_2DOF = {3.0: 11.8, 4.0: 19.3, 5.0: 28.7, 6.0: 40.0}


#: a GNSS speed above this (m/s) is a receiver fault, not a car: rejected and reported to the FDI
MAX_PLAUSIBLE_SPEED = 150.0
IMPLAUSIBLE = "implausible velocity"


class GnssVelocityFusion:
    def __init__(self, lever_x: float, lever_y: float, min_fix_type: int, max_speed_acc: float,
                 nmea_speed_acc: float, gate_sigma: float):
        self.lever_x = lever_x
        self.lever_y = lever_y
        self.min_fix_type = min_fix_type
        self.max_speed_acc = max_speed_acc
        self.nmea_speed_acc = nmea_speed_acc
        self.gate = CHI2_2DOF.get(gate_sigma, gate_sigma * gate_sigma + 4.0)
        self.fused = 0
        self.rejected = 0
        self.late = 0
        self.consecutive_rejects = 0
        self.last_reason = ""
        self.noise = GnssNoiseLearner()

    def reported_sigma(self, g: GnssSample) -> float:
        acc = g.speed_acc_mps
        if not math.isfinite(acc):
            acc = self.nmea_speed_acc
        return max(acc, 0.02)

    def sigma(self, g: GnssSample) -> float:
        """Per-axis velocity noise of this fix: the receiver's figure, or less where the wheels
        have shown its scatter to be smaller (``gnss_noise``)."""
        return self.noise.sigma(self.reported_sigma(g))

    def usable(self, g: GnssSample) -> bool:
        if not (g.fix_ok and g.fix_type >= self.min_fix_type and g.fix_type != 5):
            self.last_reason = f"no usable fix (type {g.fix_type})"
            return False
        if not math.isfinite(g.speed_mps):  # speed only when the course is unknown (course_known)
            self.last_reason = "non-finite velocity"
            return False
        if g.speed_mps > MAX_PLAUSIBLE_SPEED:
            self.last_reason = IMPLAUSIBLE
            return False
        acc = g.speed_acc_mps
        if math.isfinite(acc) and acc > self.max_speed_acc:
            self.last_reason = f"speed accuracy {acc:.2f} m/s above limit"
            return False
        return True

    def fuse_speed(self, hist: StepHistory, s: int, g: GnssSample, delay_std_s: float = 0.0) -> bool:
        """Speed-only update (heading unknown, or the sample's course unknown): fuses |v| only; ``delay_std_s`` as in :meth:`fuse` (a start-up
        acceleration with the latency still unknown must not be read as a wheel-scale error)."""
        i = hist.slot(s)
        x = hist.X[i]
        P = hist.P[i]
        r = hist.aux[i, AUX_R]
        vax = x[VX] - r * self.lever_y
        vay = x[VY] + r * self.lever_x
        sp = math.hypot(vax, vay)
        zs = g.speed_mps
        if sp < 0.5:
            h = np.zeros(NX)
            h[VX] = 1.0
        else:
            h = np.zeros(NX)
            h[VX] = vax / sp
            h[VY] = vay / sp
        a = hist.aux[i]
        sig2 = self.sigma(g) ** 2 + TIMING_FIXES * a[AUX_AX] ** 2 * delay_std_s * delay_std_s
        Ph = P @ h
        S = float(h @ Ph) + sig2
        y = zs - (sp if sp >= 0.5 else x[VX])
        if y * y > 25.0 * S:
            self.consecutive_rejects += 1
            self.rejected += 1
            self.last_reason = "speed innovation gate"
            return False
        self.noise.observe(y)
        K = Ph / S
        hist.correct(s, K * y, np.outer(K, Ph))
        self.consecutive_rejects = 0
        self.fused += 1
        return True

    def fuse(self, hist: StepHistory, s: int, g: GnssSample, gate: bool = True,
             delay_std_s: float = 0.0) -> bool:
        """Full 2-D velocity update at stored step s. Returns False if gated out.

        ``delay_std_s``: uncertainty of the time of validity. A timing error dt looks like a
        velocity error of a dt (a = horizontal acceleration), so it is added to the noise:
        until the latency is identified, hard cornering de-weights GNSS instead of tearing the
        heading away (and the gate does not lock GNSS out). Along the track (speed, wheel
        scale) it is also weighted as the bias it is (``TIMING_FIXES``); across the track its
        effect on heading is published in the heading std by the core.
        """
        i = hist.slot(s)
        x = hist.X[i]
        P = hist.P[i]
        r = hist.aux[i, AUX_R]
        vn, ve = antenna_velocity_ne(x, r, self.lever_x, self.lever_y)
        H = gnss_jacobian(x, r, self.lever_x, self.lever_y)
        a = hist.aux[i]
        d2 = delay_std_s * delay_std_s
        sig2 = self.sigma(g) ** 2
        y = np.array([g.vel_n_mps - vn, g.vel_e_mps - ve])
        PHt = P @ H.T
        S = H @ PHt
        sp = math.hypot(vn, ve)
        u = (vn / sp, ve / sp) if sp > 0.5 else (1.0, 0.0)  # along-track unit vector
        iso = sig2 + (a[AUX_AX] ** 2 + a[AUX_AY] ** 2) * d2
        along = (TIMING_FIXES - 1.0) * a[AUX_AX] ** 2 * d2  # the along-track part as a bias
        S[0, 0] += iso + along * u[0] * u[0]
        S[1, 1] += iso + along * u[1] * u[1]
        S[0, 1] += along * u[0] * u[1]
        S[1, 0] = S[0, 1]
        Sinv = np.linalg.inv(S)
        nis = float(y @ Sinv @ y)
        if gate and nis > self.gate:
            self.consecutive_rejects += 1
            self.rejected += 1
            self.last_reason = f"innovation gate (NIS {nis:.1f})"
            return False
        self.noise.observe(u[0] * y[0] + u[1] * y[1])
        K = PHt @ Sinv
        hist.correct(s, K @ y, K @ PHt.T)
        self.consecutive_rejects = 0
        self.fused += 1
        return True

    @staticmethod
    def course(g: GnssSample) -> float:
        return math.atan2(g.vel_e_mps, g.vel_n_mps) % (2.0 * math.pi)
