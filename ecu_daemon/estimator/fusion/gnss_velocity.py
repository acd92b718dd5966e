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
from .. import generated as gen
from ..history import AUX_AX, AUX_AY, AUX_R, StepHistory
from ..kalman import joseph
from ..kinematic import NX, VX, jacobian

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
NOT_PD = "covariance not positive definite after the correction"


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

    def sigma(self, g: GnssSample) -> float:
        acc = g.speed_acc_mps
        if not math.isfinite(acc):
            acc = self.nmea_speed_acc
        return max(acc, 0.02)

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
        args = (*x.tolist(), hist.aux[i, AUX_R], self.lever_x, self.lever_y)
        (sp,) = gen.gnss_speed(*args)
        zs = g.speed_mps
        if sp < 0.5:  # the direction is noise: the speed is vx
            h = np.zeros(NX)
            h[VX] = 1.0
            sp = x[VX]
        else:
            h = jacobian(gen.GNSS_SPEED_H, gen.gnss_speed_H(*args), 1)[0]
        a = hist.aux[i]
        sig2 = self.sigma(g) ** 2 + TIMING_FIXES * a[AUX_AX] ** 2 * delay_std_s * delay_std_s
        Ph = P @ h
        S = float(h @ Ph) + sig2
        y = zs - sp
        if y * y > 25.0 * S:
            self.consecutive_rejects += 1
            self.rejected += 1
            self.last_reason = "speed innovation gate"
            return False
        K = Ph / S
        if not self._correct(hist, s, K * y, P - joseph(P, K[:, None], h[None, :], np.array([[sig2]]))):
            return False
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
        args = (*x.tolist(), hist.aux[i, AUX_R], self.lever_x, self.lever_y)
        vn, ve = gen.gnss_velocity(*args)
        H = jacobian(gen.GNSS_VELOCITY_H, gen.gnss_velocity_H(*args), 2)
        a = hist.aux[i]
        d2 = delay_std_s * delay_std_s
        sig2 = self.sigma(g) ** 2
        y = np.array([g.vel_n_mps - vn, g.vel_e_mps - ve])
        PHt = P @ H.T
        sp = math.hypot(vn, ve)
        u0, u1 = (vn / sp, ve / sp) if sp > 0.5 else (1.0, 0.0)  # along-track unit vector
        iso = sig2 + (a[AUX_AX] ** 2 + a[AUX_AY] ** 2) * d2
        along = (TIMING_FIXES - 1.0) * a[AUX_AX] ** 2 * d2  # the along-track part as a bias
        R = np.array([[iso + along * u0 * u0, along * u0 * u1], [along * u0 * u1, iso + along * u1 * u1]])
        S = H @ PHt
        S += S.T.copy()
        S *= 0.5
        S += R
        Sinv = np.linalg.inv(S)
        nis = float(y @ Sinv @ y)
        if gate and nis > self.gate:
            self.consecutive_rejects += 1
            self.rejected += 1
            self.last_reason = f"innovation gate (NIS {nis:.1f})"
            return False
        K = PHt @ Sinv
        if not self._correct(hist, s, K @ y, P - joseph(P, K, H, R)):
            return False
        self.consecutive_rejects = 0
        self.fused += 1
        return True

    def _correct(self, hist: StepHistory, s: int, dx: np.ndarray, M: np.ndarray) -> bool:
        """Apply the correction through the history; a covariance that would lose positive
        definiteness (rounding, or a model gone wrong) rejects the fix instead."""
        if hist.correct(s, dx, M):
            return True
        self.rejected += 1
        self.last_reason = NOT_PD
        return False

    @staticmethod
    def course(g: GnssSample) -> float:
        return math.atan2(g.vel_e_mps, g.vel_n_mps) % (2.0 * math.pi)
