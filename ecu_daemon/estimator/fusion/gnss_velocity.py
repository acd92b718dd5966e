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
from .. import kalman
from ..gnss_noise import GnssNoiseLearner
from ..history import AUX_AX, AUX_AY, AUX_R, AUX_RDOT, StepHistory
from ..kinematic import NX, PSI, VX
from ..latency_consider import LatencyConsider, antenna_acceleration_ned

ALIGN_SPEED = 5.0  # m/s: the heading is aligned from a course at this speed or more; course is good to ~ sigma_v / v rad
# m/s: driving forwards (the filter's vx), already from this speed (core.Estimator._align). The
# alignment's variance carries the course's sigma_v / v, so a slow course aligns with the std it
# deserves and later fixes tighten it. 3 m/s, the speed above which sideslip may be promised at all
# (core.MIN_SPEED_SIDESLIP): a low-speed handling drive (launch to 5 m/s, then straight into a 10 m
# circle) aligned only inside the circle, where one course is heading + sideslip + yaw rate x the
# latency's error (0.5 rad/s x 0.15 s = 4.3 deg before the latency is known), and the heading stayed
# invalid for the whole circle (lowspeed_r10: 42 s after the first fix above 5 m/s). From the
# launch's straight (r ~ 0: no latency term, sideslip ~ 0) at 3-5 m/s it is valid before the
# turn-in. Forwards only: reversing (a gentle curve at 4 m/s), where the single-track sideslip does
# not hold, a re-alignment after a yaw-rate sign mistake put the heading 15-18 deg off with a 1.4 deg
# std for 8 s (tools/probe_wrong_config.py reversing yaw_sign: 649 -> 2081 heading rows beyond 3 sigma).
FORWARD_ALIGN_SPEED = 3.0

MAX_CONSECUTIVE_REJECTS = 10
# A latency error is the same for every fix of a manoeuvre (~5 s of acceleration at 5 Hz), so its
# speed error ax * dd is a bias over that many fixes, not noise: weighted as one measurement per
# manoeuvre instead of one per fix (else a start-up acceleration with the latency 0.3 s off taught
# a wheel scale of 1.15 and vx 0.9 m/s off, valid).
TIMING_FIXES = 25.0
# chi-square, 2 degrees of freedom, for a gate of n sigma: exp(-g/2) = tail(n sigma, 1-D)
CHI2_2DOF = {3.0: 11.8, 4.0: 19.3, 5.0: 28.7, 6.0: 40.0}


def align_speed_ok(speed: float, vx: float) -> bool:
    """Whether a course at GNSS speed ``speed`` (m/s) may align the heading, the filter's vx being
    ``vx``: ``ALIGN_SPEED`` either way, ``FORWARD_ALIGN_SPEED`` driving forwards."""
    return speed >= ALIGN_SPEED or (speed >= FORWARD_ALIGN_SPEED and vx >= FORWARD_ALIGN_SPEED)


#: a GNSS speed above this (m/s) is a receiver fault, not a car: rejected and reported to the FDI
MAX_PLAUSIBLE_SPEED = 150.0
IMPLAUSIBLE = "implausible velocity"
NOT_PD = "covariance not positive definite after the correction"
# flat indices of the generated Jacobians' nonzero entries in the preallocated H
VELOCITY_H_FLAT = [i * NX + j for i, j in gen.GNSS_VELOCITY_H]
SPEED_H_FLAT = [i * NX + j for i, j in gen.GNSS_SPEED_H]


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
        # preallocated update operands (fusion is not re-entrant: one estimator, one thread)
        self._H1, self._H2 = np.zeros((1, NX)), np.zeros((2, NX))
        self._R1, self._R2 = np.zeros((1, 1)), np.zeros((2, 2))
        self._y1, self._y2 = np.zeros(1), np.zeros(2)
        self._dx, self._M = np.zeros(NX), np.zeros((NX, NX))
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

    def fuse_speed(self, hist: StepHistory, s: int, g: GnssSample, delay_std_s: float = 0.0,
                   along_std_s: float | None = None, along_accel: float | None = None) -> bool:
        """Speed-only update (heading unknown, or the sample's course unknown): fuses |v| only;
        ``delay_std_s``, ``along_std_s`` and ``along_accel`` as in :meth:`fuse` (a start-up
        acceleration with the latency still unknown must not be read as a wheel-scale error)."""
        if along_std_s is None:
            along_std_s = delay_std_s
        i = hist.slot(s)
        x = hist.X[i]
        a = hist.aux[i]
        args = (*x.tolist(), a[AUX_R], self.lever_x, self.lever_y)
        (sp,) = gen.gnss_speed(*args)
        H = self._H1
        H.fill(0.0)
        if sp < 0.5:  # the direction is noise: the speed is vx
            H[0, VX] = 1.0
            sp = x[VX]
        else:
            H.put(SPEED_H_FLAT, gen.gnss_speed_H(*args))
        ax = a[AUX_AX] if along_accel is None else along_accel
        self._R1[0, 0] = self.sigma(g) ** 2 + TIMING_FIXES * ax ** 2 * along_std_s * along_std_s
        self._y1[0] = g.speed_mps - sp
        nis = kalman.late_update(hist.P[i], H, self._R1, self._y1, self._dx, self._M)
        if not nis <= 25.0:  # 5 sigma (NaN: no usable innovation covariance)
            self.consecutive_rejects += 1
            self.rejected += 1
            self.last_reason = "speed innovation gate"
            return False
        self.noise.observe(float(self._y1[0]))
        if not self._correct(hist, s, self._dx, self._M):
            return False
        self.consecutive_rejects = 0
        self.fused += 1
        return True

    def fuse(self, hist: StepHistory, s: int, g: GnssSample, gate: bool = True,
             delay_std_s: float = 0.0, consider: LatencyConsider | None = None,
             along_std_s: float | None = None, along_accel: float | None = None) -> bool:
        """Full 2-D velocity update at stored step s. Returns False if gated out.

        ``delay_std_s``: uncertainty of the time of validity. A timing error dt looks like a
        velocity error of a dt (a = horizontal acceleration), so it is added to the noise:
        until the latency is identified, hard cornering de-weights GNSS instead of tearing the
        heading away (and the gate does not lock GNSS out). Along the track (speed, wheel
        scale) it is also weighted as the bias it is (``TIMING_FIXES``). With ``consider`` (the
        receiver's :class:`~ecu_daemon.estimator.latency_consider.LatencyConsider`) the timing
        error across the track is not noise but the shared latency error, an augmented state
        (``latency_consider.py``); along the track (the speed, which ``latency.py`` identifies
        the latency from) it stays the bias-weighted noise above, so no information counts twice.

        ``along_std_s`` (default ``delay_std_s``): the timing std of the along-track term alone,
        wider than the latency's std while the data have not identified the latency, and
        ``along_accel`` (default: the stored ax) the along-track acceleration it multiplies, the
        secant over the instants the fix may be from (``timing_trust.py``: a configured prior far
        off must not teach the wheel scale).
        """
        if along_std_s is None:
            along_std_s = delay_std_s
        i = hist.slot(s)
        # the stored row and state as Python floats (tolist): the velocity, noise and timing terms
        # below in float arithmetic, not numpy scalar arithmetic (issue 10; the same doubles)
        a = hist.aux[i].tolist()
        xs = hist.X[i].tolist()
        ax = a[AUX_AX] if along_accel is None else along_accel
        args = (*xs, a[AUX_R], self.lever_x, self.lever_y)
        vn, ve = gen.gnss_velocity(*args)
        H = self._H2
        H.put(VELOCITY_H_FLAT, gen.gnss_velocity_H(*args))
        d2 = delay_std_s * delay_std_s
        # what the along-track term adds beyond the latency's own std: 0 once it is identified
        wide = TIMING_FIXES * (ax * ax * (along_std_s * along_std_s) - a[AUX_AX] ** 2 * d2)
        sp = math.hypot(vn, ve)
        u0, u1 = (vn / sp, ve / sp) if sp > 0.5 else (1.0, 0.0)  # along-track unit vector
        if consider is None:
            iso = self.sigma(g) ** 2 + (a[AUX_AX] ** 2 + a[AUX_AY] ** 2) * d2
            along = (TIMING_FIXES - 1.0) * a[AUX_AX] ** 2 * d2 + wide  # the along-track part as a bias
        else:  # across the track the latency error is the augmented state; along it, as before
            iso = self.sigma(g) ** 2
            along = TIMING_FIXES * a[AUX_AX] ** 2 * d2 + wide
        R = self._R2
        R.flat = (iso + along * u0 * u0, along * u0 * u1, along * u0 * u1, iso + along * u1 * u1)
        self._y2.flat = (g.vel_n_mps - vn, g.vel_e_mps - ve)
        if consider is None:
            nis = kalman.late_update(hist.P[i], H, R, self._y2, self._dx, self._M)
        else:
            an, ae = antenna_acceleration_ned(xs[PSI], a[AUX_AX], a[AUX_AY], a[AUX_R], a[AUX_RDOT],
                                              self.lever_x, self.lever_y)
            across = u1 * an - u0 * ae  # the acceleration's part normal to the track (v(t_s - d) = v - a d)
            nis, c = consider.late_update(hist.P[i], consider.Cr[i], H, np.array((-across * u1, across * u0)),
                                          R, self._y2, self._dx, self._M)
        if not nis == nis or (gate and nis > self.gate):  # NaN: no usable innovation covariance
            self.consecutive_rejects += 1
            self.rejected += 1
            self.last_reason = f"innovation gate (NIS {nis:.1f})"
            return False
        y0, y1 = self._y2.tolist()
        self.noise.observe(u0 * y0 + u1 * y1)
        if not self._correct(hist, s, self._dx, self._M):
            return False
        if consider is not None:
            consider.commit(hist, s, c)
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
