"""3-axis magnetometer heading aid (an IMU that puts its magnetometer on CAN), after the thesis
(000, ch. 5): a tilt-compensated magnetic heading fused as a heading measurement, with the
thesis' disturbance detector in front of it.

Why each part:

* **Tilt compensation.** The field dips steeply (64 deg in Munich: the vertical part is twice the
  horizontal one), so a roll or pitch error of 1 deg turns the heading by up to tan(dip) = 2 deg.
  Roll and pitch come from the accelerometers' gravity part, which the filter already carries:
  ``ay_m - ay_kinematic = b_ay + g_ay * ay_m`` (bank, and body roll through the gain state) and
  ``ax_m - ax_kinematic = b_ax`` (grade); ``mag_tilt = "level"`` assumes a level car instead. What
  the accelerometers cannot tell from tilt (their own bias) is the ``mag_tilt_std_deg`` term.
* **Disturbance detector** (thesis 5.3.1: the heading error correlates 0.9 with the field norm's
  deviation). A passing truck, a steel bridge or a tram line changes the field's norm and its
  inclination before its heading error is large: a norm off its nominal value by more than
  ``mag_norm_tol`` (the thesis' 0.015), or an inclination off by more than ``mag_dip_tol_deg``,
  rejects the sample (the thesis' R inflated by eta^2 with eta >= 10 b_o / sigma, i.e. rejection)
  and keeps rejecting for ``HOLD_S`` after the field looks normal again (its edges). The nominal
  norm and inclination are learned from the undisturbed field itself (again after ``RELEARN_S``
  of uninterrupted disturbance: then the first samples were the disturbed ones, a steel garage).
* **Offset.** Mounting yaw and declination together: learned (a scalar filter) from the residual
  against the filter's heading while a good GNSS heading exists, its std added to the
  measurement noise. No heading is fused before it is learned.
* **Correlated error.** What is left (soft iron, residual tilt, offset) changes slowly, not from
  sample to sample: fused at 50 Hz as white noise it would be averaged into a heading far more
  certain than it is. Each sample's variance is therefore the white part plus the slow part times
  the samples in ``CORR_S`` (the filter averages over that time, no more), and the slow part is
  what the estimator publishes as the heading's floor while the magnetometer holds the heading.
* **Gate.** Its own innovation gate on the single sample's uninflated variance. While it rejects,
  the published heading is invalid (``consecutive_rejects``); when it has refused a clean field
  for ``LOCKOUT_S`` the filter's heading variance is widened to the disagreement (no lock-out).

The EKF state vector is untouched: a direct heading update through ``kalman.index_update``.
"""
from __future__ import annotations

import math

from ...gravity import G
from .. import kalman
from ..kinematic import PSI, wrap_pi

# what happened to the last magnetometer sample (EST_DIAG.MAG_STATE)
STATE_NONE = 0  # no sample yet
STATE_FUSED = 1
STATE_NORM = 2  # field norm off its nominal value: disturbed
STATE_DIP = 3  # inclination off its nominal value: disturbed
STATE_GATE = 4  # disagreed with the filter
STATE_LEARNING = 5  # nominal field or offset not learned yet (no GNSS heading so far)
STATE_STALE = 6  # none received for longer than its timeout (set by whoever knows the time)

NOMINAL_N = 50  # samples averaged for the first nominal field norm / inclination
NOMINAL_TAU_S = 60.0  # then followed this slowly, from undisturbed samples only
HOLD_S = 1.0  # rejection outlasts a detected disturbance by this much (its fading edges)
#: disturbed without a break for this long: the nominal field is what is wrong (learned in a steel
#: garage at start-up), so it is learned again; a disturbance this long is rejected until then
RELEARN_S = 60.0
CORR_S = 2.0  # the filter averages the slow heading error over no more than this (module docstring)
#: a clean field (the detector sees no disturbance) the gate keeps refusing for this long: the
#: filter's heading, not the magnetometer, has drifted (a gyro bias shift in a GNSS outage); the
#: heading's variance is widened to the disagreement and the sample fused (the thesis' argument
#: for the norm detector over an innovation gate, which locks out)
LOCKOUT_S = 2.0
OFFSET_WALK = math.radians(0.05)  # rad/sqrt(s): what the offset may drift (tilt bias with heading)
OFFSET_STD_MAX = math.radians(2.0)  # fused only once the offset is known this well
MAX_TILT = math.radians(30.0)


class MagnetometerFusion:
    def __init__(self, tilt: str, noise_deg: float, bias_deg: float, tilt_std_deg: float,
                 norm_tol: float, dip_tol_deg: float, gate_sigma: float):
        self.tilt = tilt
        self.white = math.radians(noise_deg) ** 2
        self.bias2 = math.radians(bias_deg) ** 2
        self.tilt_std = math.radians(tilt_std_deg)
        self.norm_tol = norm_tol
        self.dip_tol = math.radians(dip_tol_deg)
        self.gate_sigma = gate_sigma
        self.state = STATE_NONE
        self.fused = 0
        self.rejected = 0
        self.last_reason = ""
        self.last_t = -math.inf  # receive time of the last sample
        self.last_fused_t = -math.inf
        self.disturbed_t = -math.inf  # last time a disturbance was seen
        self._disturbed_since = math.inf  # first of the current unbroken run of disturbed samples
        self.norm = math.nan  # of the last sample (T)
        self.dip = math.nan  # inclination of the last sample (rad, positive down)
        self.nominal_norm = math.nan
        self.nominal_dip = math.nan
        self._n = 0
        self.offset = math.nan  # magnetic heading - vehicle heading (mounting yaw - declination)
        self.offset_var = math.inf
        self._offset_t = -math.inf
        self.period = 0.02  # s between samples, measured
        self.last_slow_var = 0.0  # slow error variance of the last fused sample (the published floor)
        self.consecutive_rejects = 0  # gate rejections in a row
        self._gate_t = math.inf  # first of the current run of gate rejections

    # ----------------------------------------------------------------------------------------
    def tilt_angles(self, b_ax: float, b_ay: float, g_ay: float, ay_m: float) -> tuple[float, float]:
        """(roll, pitch) in ISO 8855 (roll + = left side up, pitch + = nose down) from the
        accelerometers' gravity part as the filter carries it; (0, 0) for ``tilt = "level"``."""
        if self.tilt == "level":
            return 0.0, 0.0
        gy = max(-1.0, min(1.0, (b_ay + g_ay * ay_m) / G))
        gx = max(-1.0, min(1.0, b_ax / G))
        roll = max(-MAX_TILT, min(MAX_TILT, math.asin(gy)))
        pitch = max(-MAX_TILT, min(MAX_TILT, -math.asin(gx)))
        return roll, pitch

    @staticmethod
    def level_field(mx: float, my: float, mz: float, roll: float, pitch: float) -> tuple[float, float, float]:
        """The body-axis field rotated into the level frame (x forward, y left, z up):
        Ry(pitch) Rx(roll) m."""
        cr, sr = math.cos(roll), math.sin(roll)
        cp, sp = math.cos(pitch), math.sin(pitch)
        y1 = cr * my - sr * mz
        z1 = sr * my + cr * mz
        return cp * mx + sp * z1, y1, -sp * mx + cp * z1

    def measure(self, t: float, mx: float, my: float, mz: float, roll: float, pitch: float) -> float:
        """The magnetic heading (clockwise from magnetic north, before the offset) of one sample;
        sets its norm and inclination."""
        if math.isfinite(self.last_t) and 0.0 < t - self.last_t < 1.0:
            self.period += 0.05 * (t - self.last_t - self.period)
        self.last_t = t
        lx, ly, lz = self.level_field(mx, my, mz, roll, pitch)
        h = math.hypot(lx, ly)
        self.norm = math.sqrt(mx * mx + my * my + mz * mz)
        self.dip = math.atan2(-lz, h)
        return math.atan2(ly, lx)

    def undisturbed(self, t: float) -> bool:
        """The thesis' detector on the last measured sample: norm and inclination against their
        nominal values (learned here from the field while it looks undisturbed)."""
        norm, dip = self.norm, self.dip
        if not (math.isfinite(norm) and norm > 0.0):
            self.state, self.last_reason = STATE_NORM, "no field"
            return False
        if self._n < NOMINAL_N:  # the first samples set the nominal field
            self._n += 1
            self.nominal_norm = norm if self._n == 1 else self.nominal_norm + (norm - self.nominal_norm) / self._n
            self.nominal_dip = dip if self._n == 1 else self.nominal_dip + (dip - self.nominal_dip) / self._n
            self.state, self.last_reason = STATE_LEARNING, "learning the nominal field"
            return False
        rel = norm / self.nominal_norm - 1.0
        ddip = dip - self.nominal_dip
        if abs(rel) > self.norm_tol or abs(ddip) > self.dip_tol:
            if abs(rel) > self.norm_tol:
                self.state, self.last_reason = STATE_NORM, f"field norm {rel:+.3f} off nominal"
            else:
                self.state, self.last_reason = STATE_DIP, f"inclination {math.degrees(ddip):+.2f} deg off nominal"
            self.disturbed_t = t
            self._disturbed_since = min(self._disturbed_since, t)
            if t - self._disturbed_since > RELEARN_S:
                self._n = 0  # learn the nominal field again from the next samples
                self._disturbed_since = math.inf
            return False
        self._disturbed_since = math.inf
        a = self.period / NOMINAL_TAU_S
        self.nominal_norm += a * (norm - self.nominal_norm)
        self.nominal_dip += a * ddip
        if t - self.disturbed_t < HOLD_S:
            self.state, self.last_reason = STATE_NORM, "just after a disturbance"
            return False
        return True

    # ----------------------------------------------------------------------------------------
    def tilt_heading_std(self, tilt_std: float) -> float:
        """Heading error (rad) a tilt error ``tilt_std`` causes at the nominal inclination."""
        dip = self.nominal_dip if math.isfinite(self.nominal_dip) else math.radians(60.0)
        return math.tan(min(abs(dip), math.radians(85.0))) * tilt_std

    def slow_var(self, filter_tilt_std: float) -> float:
        """Variance of the slowly varying heading error: residual bias, offset, tilt."""
        tilt = math.hypot(self.tilt_std, filter_tilt_std) if self.tilt != "level" else self.tilt_std
        off = self.offset_var if math.isfinite(self.offset_var) else 0.0
        return self.bias2 + off + self.tilt_heading_std(tilt) ** 2

    def learn_offset(self, t: float, psi_mag: float, psi: float, psi_var: float, slow_var: float) -> None:
        """The residual against a GNSS-backed filter heading: a scalar filter for the offset
        (random walk ``OFFSET_WALK``), each residual worth what the slow error lets it be."""
        e = wrap_pi(psi_mag - psi)
        R = self.white + (slow_var - (self.offset_var if math.isfinite(self.offset_var) else 0.0)) \
            * CORR_S / max(self.period, 1e-3) + psi_var
        if not math.isfinite(self.offset):
            self.offset, self.offset_var, self._offset_t = e, self.white + slow_var + psi_var, t
            return
        self.offset_var += OFFSET_WALK ** 2 * max(t - self._offset_t, 0.0)
        self._offset_t = t
        k = self.offset_var / (self.offset_var + R)
        self.offset = wrap_pi(self.offset + k * wrap_pi(e - self.offset))
        self.offset_var *= 1.0 - k

    def offset_known(self, t: float) -> bool:
        if not math.isfinite(self.offset):
            return False
        var = self.offset_var + OFFSET_WALK ** 2 * max(t - self._offset_t, 0.0)
        return var <= OFFSET_STD_MAX ** 2

    def fuse(self, t: float, x, P, A, psi_mag: float, slow_var: float, may_widen: bool = True) -> bool:
        """One heading update at the current step (the magnetometer has no latency worth the
        history); False (counted) when gated out. ``may_widen``: no other heading source is
        fresh, so a lock-out means the filter drifted (never while GNSS backs the heading)."""
        off_var = self.offset_var + OFFSET_WALK ** 2 * max(t - self._offset_t, 0.0)
        slow = slow_var - (self.offset_var if math.isfinite(self.offset_var) else 0.0) + off_var
        y = wrap_pi(psi_mag - self.offset - x[PSI])
        S1 = P[PSI, PSI] + self.white + slow
        if y * y > self.gate_sigma ** 2 * S1:
            self._gate_t = min(self._gate_t, t)
            if t - self._gate_t < LOCKOUT_S or not may_widen:
                self.state = STATE_GATE
                self.last_reason = f"heading innovation gate ({math.degrees(y):+.2f} deg)"
                self.rejected += 1
                self.consecutive_rejects += 1
                return False
            P[PSI, PSI] += y * y  # locked out on a clean field: the filter's heading has drifted
        self._gate_t = math.inf
        self.consecutive_rejects = 0
        R = self.white + slow * CORR_S / max(self.period, 1e-3)
        self.last_slow_var = slow
        kalman.index_update(x, P, y, PSI, R, 0.0, A)
        x[PSI] %= 2.0 * math.pi
        self.state = STATE_FUSED
        self.fused += 1
        self.last_fused_t = t
        return True
