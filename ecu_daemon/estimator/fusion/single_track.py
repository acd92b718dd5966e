"""Single-track (bicycle) model as an aiding source for the lateral velocity.

From the single-track force balance (Park 002 eqs. 8-13, signs corrected per the research notes
E1/E2), the rear-axle lateral force follows from measured signals alone::

    F_yr = (m lf ay - Iz r_dot) / L          alpha_r = (vy - lr r) / vx = -F_yr / C_r

so  vy_model = lr r - vx (m / C_r) (lf ay - (Iz/m) r_dot) / L.

It needs no steering angle (no steering ratio, offset or compliance) and no integration (no
drift); its error is the error of m/C_r, and tyre nonlinearity near the limit. The filter fuses
it as a pseudo-measurement of vy whose noise grows with (a) the uncertainty of m/C_r times the
regressor and (b) the normalised lateral force (Park's weighting factor idea, 002 §5.1): straight
and mildly dynamic driving lean on the model (where GNSS cannot separate heading from sideslip,
the yaw-rate observability rule of 000/003), hard cornering leans on the kinematic filter.

Cornering-stiffness adaptation: kappa = m / C_r is learned by recursive least squares at each
GNSS fusion, from the delayed, GNSS-corrected kinematic vy at that step (the best vy we ever have),
only while the regressor is large (cornering) and the tyres are in their linear range. The same is
done for the front axle (using the steering angle) to report C_f.

Tyre relaxation (``[vehicle] tyre_relaxation_length_m`` = sigma): a real tyre's force lags its
kinematic slip by sigma / vx, so the slip is the force's slip sigma / vx *ahead*:
alpha = (F + (sigma / vx) dF/dt) / C. With dF_yr/dt ~ m lf vx r_dot / L (ay ~ vx r in the linear
range) the lead is speed-independent, sigma m lf r_dot / L: the rear relation keeps its form with
the yaw-inertia term Iz/m - sigma lf, the front's with Iz/m + sigma lr (the r-double-dot part,
(sigma / vx) Iz r_ddot / L, is left out). With sigma = 0 (the default) both are Iz/m.
"""
from __future__ import annotations

import math

import numpy as np

from .. import kalman
from ..kinematic import VX, VY

G = 9.81
MIN_SPEED = 0.5  # m/s; at low speed the relation tends to slip-free kinematics, vy = lr r
CORNER_STEPS = 330.0  # 6 ms steps in ~2 s, the correlation time of parameter/nonlinearity errors
PRIOR_REL_STD = 0.4  # m / C of an unlearned configuration (1 sigma, relative): +-30 % is a usual error
PRIOR_REL_STD3 = 0.8  # the saturation term k3 (relative to k1): rarely known at all
MODEL_REL_STD = 0.3  # what the two-term law gets wrong beyond its parameters, before residuals say
MODEL_MIN_REL_STD = 0.05  # the law's error is never taken below this (relaxation, load transfer)
TAKE_MAX_REL_VAR = 0.25  # the drive estimate is taken once its std is half the prior's (a taught car)
LEARNED_MAX_N = 0.6  # the regression learns the law's error up to this lateral force (its MAX_N)
RESTORED_MIN_REL_STD = 0.03  # a restored stiffness is never trusted beyond this (wear, load, temperature)
LAW_HOLDS_SIGMA = 3.0  # the steering confirms the tyre law while it is within this many sigmas of it
# 1-sigma of the road-wheel angle beyond the two axles' law: the learned steering offset's residual
# and the steering system's compliance (stiffness_regression.STEER_OFFSET_RAD is the offset's prior)
STEER_ERR_RAD = math.radians(0.3)


def std_keys(name: str) -> tuple[str, str, str, str]:
    """Learned-state keys of an axle's uncertainty (``name``: kappa_r / kappa_f)."""
    return f"{name}_std", f"{name}3_std", f"{name}_corr", f"{name}_model_std"


def _restored_std(learned: dict, name: str) -> tuple:
    return tuple(learned.get(key) for key in std_keys(name))


def rls_update_reference(k: np.ndarray, P: np.ndarray, P0: np.ndarray, phi: float, n2: float, y: float,
                         rv: float, lam: float) -> float:
    """One RLS step of :class:`AxleRls`'s [k1, k3] in place (regressor h = [phi, phi n2],
    measurement y, its variance rv, forgetting lam); returns the prediction error y - h'k before
    the step. The numpy reference; ``backend.py`` swaps in the compiled one as ``rls_update``."""
    h = np.array([phi, phi * n2])
    Ph = P @ h
    g = Ph / (h @ Ph + rv)
    e = float(y - h @ k)
    k += g * e
    P[:] = (P - np.outer(g, Ph)) / lam
    # forgetting must not inflate beyond the prior (no information -> back to the prior)
    if P[0, 0] > P0[0, 0] or P[1, 1] > P0[1, 1]:
        P[:] = np.minimum(P, P0) if np.all(np.linalg.eigvalsh(P) > 0) else P0
    return e


rls_update = rls_update_reference


class AxleRls:
    """Recursive least squares for one axle's slip compliance, with tyre saturation.

    alpha = -F_y / C with a secant stiffness that falls as the axle nears its friction limit:
    y = phi (k1 + k3 n^2), n = |ay| / g the normalised lateral force. k1 = m / C (the linear
    cornering compliance the config states) and k3 (how fast the tyre saturates, Park's
    normalised-stiffness change Delta C_n of 002 §3) are learned together; on the Revs race car
    data this two-term law fits sideslip to 0.39 deg where the best single stiffness gives 0.48.
    """

    def __init__(self, k1: float, k3: float | None = None, learned_std: tuple | None = None):
        self.k10 = k1
        self.k = np.array([k1, 0.6 * k1 if k3 is None else k3])
        # an unlearned configuration: m / C as a user states it, 40 % (1 sigma), the saturation 80 %
        self.P0 = np.diag([(PRIOR_REL_STD * k1) ** 2, (PRIOR_REL_STD3 * k1) ** 2])
        self.P = self.P0.copy()
        self.p00_prior = float(self.P0[0, 0])  # P0 is never changed: predict's every-step read, as a float
        self.updates = 0
        self.from_drive = False  # following the per-drive regression (SingleTrackFusion.take_drive_estimate)
        # what the two-term law still gets wrong, relative to its regressor (learned from residuals)
        self.rel_var = self.rel_var0 = (MODEL_REL_STD * k1) ** 2
        # the largest (|ay| / g)^2 at which a data-told vy (update) found the law within
        # LAW_HOLDS_SIGMA of its own uncertainty: the grip this drive has shown the law to hold at
        # (core.MODEL_BOUND_GRIP_SHOWN); not kept across drives (the road changes)
        self.n2_shown = 0.0
        if learned_std is not None:
            self.restore_std(*learned_std)

    def restore_std(self, s1: float | None, s3: float | None, corr: float | None, model: float | None) -> None:
        """Take the uncertainty an earlier drive left (the learned-state file): without it a
        restored stiffness would be trusted no more than the configuration's, and a restart
        mid-corner would wait for the corner to end. Never tighter than a floor (the tyres wear,
        warm up, the load changes between drives) nor wider than the prior; a file from before
        these keys (``None``) keeps the prior."""
        if s1 is None or s3 is None:
            return
        k = self.k10
        s1 = min(max(s1, RESTORED_MIN_REL_STD * k), math.sqrt(self.P0[0, 0]))
        s3 = min(max(s3, RESTORED_MIN_REL_STD * k), math.sqrt(self.P0[1, 1]))
        c = min(max(corr if corr is not None else 0.0, -0.99), 0.99)
        self.P = np.array([[s1 * s1, c * s1 * s3], [c * s1 * s3, s3 * s3]])
        if model is not None:
            self.rel_var = min(max(model, RESTORED_MIN_REL_STD * k), MODEL_REL_STD * k) ** 2

    def learned_std(self) -> tuple[float, float, float, float]:
        """(std of k1, std of k3, their correlation, the model-error std): what ``restore_std`` takes."""
        s1, s3 = math.sqrt(max(self.P[0, 0], 0.0)), math.sqrt(max(self.P[1, 1], 0.0))
        c = self.P[0, 1] / (s1 * s3) if s1 > 0.0 and s3 > 0.0 else 0.0
        return s1, s3, float(c), math.sqrt(self.rel_var)

    def predict(self, phi: float, n2: float, once: bool = False) -> tuple[float, float]:
        """(y, variance of y from the parameter uncertainty); ``once``: the law's error counted
        once with the prior (the published bound, see below), else on top of it (the filter's
        pseudo-measurement: :meth:`SingleTrackFusion.pseudo_measurement`)."""
        h0 = phi
        h1 = phi * n2
        # Python floats, not numpy scalar reads and numpy scalar arithmetic (issue 10: three calls a
        # step): the same IEEE operations on the same doubles in the same order, so the same bits
        (p00, p01), (_, p11) = self.P.tolist()
        k1, k3 = self.k.tolist()
        if n2 <= LEARNED_MAX_N ** 2 and once:
            # No double counting: the configuration's prior P0 is the error of the stated m / C
            # against the car's axle, and a stated stiffness is a fit to measured slip (tyre data,
            # a skidpad), the law's shape error included. The law's own error stands apart from k1's
            # only as the data fit k1 (they remove the parameter's error, never the shape's), so
            # together they never exceed the prior, but for what the residuals show beyond the law's
            # prior (rel_var above rel_var0). Stacked, an untaught axle had a 0.5 relative slip
            # error, 1.7x the usual +-30 % config error: low-speed circles (k1 unobservable there)
            # were invalid from ~0.4 g on while 0.1 deg right (issue 7 item 3).
            var1 = min(p00 + self.rel_var, self.p00_prior + max(self.rel_var - self.rel_var0, 0.0))
        elif n2 <= LEARNED_MAX_N ** 2:
            # The filter's pseudo-measurement keeps them stacked: its weight also sets the filter's vy
            # variance, which gates the live RLS (adapt_from); with the model counted once, a banked
            # circle's vy (the model's own, through a bank-biased ay) passed that gate and the RLS
            # learned C_r 93 % too stiff (sideslip RMS 0.29 -> 0.57 deg on the suite's bank_circle)
            var1 = p00 + self.rel_var
        else:
            # the law's error was learned below LEARNED_MAX_N at best: beyond, no better than the
            # prior's, and the law an extrapolation of the fitted range (kept on top of the prior)
            var1 = p00 + max(self.rel_var, self.rel_var0)
        return (h0 * k1 + h1 * k3,
                h0 * h0 * var1 + 2.0 * h0 * h1 * p01 + h1 * h1 * p11)

    def update(self, phi: float, n2: float, y: float, rv: float, lam: float = 0.999) -> None:
        if n2 > self.n2_shown:  # the law as it stood, against a vy the data told (before the step)
            y0, var0 = self.predict(phi, n2, True)
            if (y - y0) ** 2 <= LAW_HOLDS_SIGMA ** 2 * (var0 + rv):
                self.n2_shown = n2
        e = rls_update(self.k, self.P, self.P0, phi, n2, y, rv, lam)
        if phi * phi * self.k10 * self.k10 > rv:  # the slip stands out of the vy noise: a model error
            rel = max(e * e - rv, 0.0) / (phi * phi)
            self.rel_var += 0.02 * (rel - self.rel_var)
        lo, hi = 0.33 * self.k10, 3.0 * self.k10
        self.k[0] = min(max(self.k[0], lo), hi)
        self.k[1] = min(max(self.k[1], -self.k10), 4.0 * self.k10)
        self.updates += 1


class LaggedModelInputs:
    """The model's yaw rate and lateral acceleration at the lag of its yaw acceleration, and the
    change of vy over that lag (timing of the samples, issue 7 "low-speed accuracy").

    The yaw acceleration is the slope of the low-passed yaw rate, itself low-passed (the
    estimator's ``_lp_r`` then ``_lp_rdot``: 0.03 + 0.05 s of lag; a gyro's derivative needs
    them), while the model took r and ay as they came: at a turn-in the yaw-inertia term came
    0.08 s after the lateral-force term. On the demo's 0.8 g turn-in (rdot 1.7 rad/s^2) the
    model's vy was 0.4 deg off for those 0.1 s, on a linear car's 0.25 g turn-in 0.2 deg
    (tests/test_fusion_modules.py). Here r and ay pass the same two low-passes, so the model gives
    vy as it was one lag ago from consistent inputs, and ``shift``, the vy the IMU integrated over
    that lag (``ay - r vx`` high-passed by the same two stages: the part the low-passes have not
    passed on yet), carries it to the present step, as a late GNSS sample is carried by the stored
    transitions: a complementary filter, the model for the slow part and the IMU for the last
    0.08 s. The accelerometer's noise reaches the model low-passed too (Revs: 1.5 m/s^2 a sample).
    """

    def __init__(self, a1: float, a2: float, dt: float):
        self.a1 = a1  # the first low-pass' gain per step (the yaw rate's, r_lp)
        self.a2 = a2  # the second's (the yaw acceleration's)
        self.dt = dt
        self.start(0.0, 0.0)

    def start(self, r: float, ay: float) -> None:
        """Steady state at yaw rate ``r`` and lateral acceleration ``ay`` (a filter (re)start)."""
        self.r = r
        self.ay1 = self.ay = ay
        self.vy1 = self.vy2 = 0.0

    def step(self, r_lp: float, r: float, ay: float, vx: float) -> tuple[float, float, float]:
        """One step: ``r_lp`` the yaw rate after the first low-pass, ``r``, ``ay`` (bias-corrected)
        and ``vx`` as the filter predicts with them; returns (r, ay, shift) for the model."""
        a1 = self.a1
        a2 = self.a2
        r_c = self.r = self.r + a2 * (r_lp - self.r)
        ay1 = self.ay1 = self.ay1 + a1 * (ay - self.ay1)
        ay_c = self.ay = self.ay + a2 * (ay1 - self.ay)
        # vy's integral k: vy1 = k - LP1(k), vy2 = k - LP2(LP1(k)), kept as differences (no drift)
        dv = (ay - r * vx) * self.dt
        e1 = self.vy1 = (self.vy1 + dv) * (1.0 - a1)
        e2 = self.vy2 + dv
        shift = self.vy2 = e2 - a2 * (e2 - e1)
        return r_c, ay_c, shift


def _excess_beyond_law(e: float, var: float) -> float:
    """The understeer misfit ``e`` (m/s, variance ``var``) beyond LAW_HOLDS_SIGMA of it, squared
    (:meth:`SingleTrackFusion.law_excess_var`)."""
    a = abs(e)
    lim = LAW_HOLDS_SIGMA * math.sqrt(var)
    return (a - lim) ** 2 if a > lim else 0.0


def _oversteer_side(e: float, var: float, ay: float) -> float:
    """The misfit in its own sigmas, signed by the corner's side ``ay`` (non-zero)
    (:meth:`SingleTrackFusion.oversteer_sigmas`)."""
    return (e if ay > 0.0 else -e) / math.sqrt(var)


class SingleTrackFusion:
    def __init__(self, mass: float, yaw_inertia: float, lf: float, lr: float, cf: float, cr: float,
                 adapt: bool, learned: dict | None = None, relaxation_length: float = 0.0):
        learned = learned or {}
        self.lf = lf
        self.lr = lr
        self.L = lf + lr
        self.iz_m = yaw_inertia / mass
        # the axles' yaw-inertia terms with the tyres' relaxation lead (module doc)
        self.iz_r = self.iz_m - relaxation_length * lf
        self.iz_f = self.iz_m + relaxation_length * lr
        self.mass = mass
        self.rear = AxleRls(learned.get("kappa_r", mass / cr), learned.get("kappa_r3"),
                            _restored_std(learned, "kappa_r"))
        self.front = AxleRls(learned.get("kappa_f", mass / cf), learned.get("kappa_f3"),
                             _restored_std(learned, "kappa_f"))
        self.rear.k10 = mass / cr
        self.front.k10 = mass / cf
        self.adapt = adapt
        self.base_sigma_beta = math.radians(0.25)

    def regressor_rear(self, vx: float, ay: float, rdot: float) -> float:
        return -vx * (self.lf * ay - self.iz_r * rdot) / self.L

    def regressor_front(self, vx: float, ay: float, rdot: float) -> float:
        return -vx * (self.lr * ay + self.iz_f * rdot) / self.L

    def force_var(self, vx: float, force_var: float) -> float:
        """Variance (m/s)^2 of the rear law's vy from a variance ``force_var`` (m/s^2)^2 of the lateral
        force it is given (core.MODEL_TYRE_FORCE: the sensor offset's, road.py's bank split): the
        law's d vy / d ay = vx kappa_r lf / L, the softer of the configured and learned compliance."""
        d = vx * max(float(self.rear.k[0]), self.rear.k10) * self.lf / self.L
        return d * d * force_var

    def split_var(self, vx: float, offset_var: float, ratio: float, law_force: bool) -> float:
        """Variance (m/s)^2 of the slip-ratio rule's excess from the bank/offset split's doubt
        ``offset_var`` (m/s^2)^2 (core.SLIP_RATIO_TYRE_FORCE). The tyres' force is the specific force
        less the sensor's offset, and the offset is known to its std on a flat road as on a bank: no
        sensor tells a standing offset from a bank (road.py), so a flat road's offset may sit in the
        split's bank and the tyres' force be off by it (random drive 1481, no bank: the -0.29 m/s^2
        offset read as a 1.6 deg bank, the force 0.28 m/s^2 off). At the limit the angle a force takes
        is ``ratio`` times the linear one, so the tyres' angle is doubted by ratio^2 times
        :meth:`force_var`, on a flat road too. The kinematic ay's law carries none of that doubt;
        the tyres' force's law (``law_force``, core.MODEL_TYRE_FORCE) carries 1x of it already, fused
        with the law: the excess then carries the rest, ratio^2 - 1, and the two sum to the angle's."""
        return self.force_var(vx, offset_var) * (ratio ** 2 - (1.0 if law_force else 0.0))

    def pseudo_measurement(self, vx: float, r: float, ay: float, rdot: float) -> tuple[float, float]:
        """(vy_model, variance per 6 ms fusion) for the rear-axle relation at this instant.

        The model's errors are not white: a wrong m/C_r or a saturating tyre is a bias for the
        whole corner. Fusing it every step as if independent would make the filter believe it
        hundreds of times over, so each error term is inflated by the number of steps in its
        correlation time: ~0.1 s for the small unmodelled dynamics (the floor), ~2 s for the
        parameter and nonlinearity terms. On a straight the model then anchors heading (the
        fallback of 000/003); in a corner GNSS course and the gyro carry sideslip.
        """
        phi = self.regressor_rear(vx, ay, rdot)
        n = abs(ay) / G
        y, var_par = self.rear.predict(phi, n * n)
        vy = self.lr * r + y
        # beyond ~0.8 g the two-term tyre law is an extrapolation
        nl = 0.0 if n < 0.8 else (n - 0.8) * math.radians(3.0)
        var = 16.0 * (self.base_sigma_beta * vx) ** 2 + CORNER_STEPS * (var_par + (nl * vx) ** 2)
        return vy, var

    def model_error(self, vx: float, r: float, ay: float, rdot: float) -> tuple[float, float]:
        """(vy_model, std of its error): :meth:`pseudo_measurement`'s vy and what it gets wrong at
        this instant, *not* inflated for fusion: the parameter and tyre-law uncertainty (a bias
        for the whole corner; the law's error counted once with the prior, ``AxleRls.predict``),
        the saturation term, and the unmodelled dynamics' floor once.
        ``core.Estimator`` bounds the published vy std by it (``MODEL_BOUND``)."""
        phi = self.regressor_rear(vx, ay, rdot)
        n = abs(ay) / G
        y, var_par = self.rear.predict(phi, n * n, True)
        nl = 0.0 if n < 0.8 else (n - 0.8) * math.radians(3.0)
        return self.lr * r + y, math.sqrt(var_par + (nl * vx) ** 2 + (self.base_sigma_beta * vx) ** 2)

    def bias_std(self, vx: float, r: float, ay: float, rdot: float) -> float:
        """std (m/s) of the part of :meth:`model_error` that is a bias for the whole corner: the
        parameter and tyre-law uncertainty and the saturation term, the terms
        :meth:`pseudo_measurement` inflates by CORNER_STEPS and so lets count again every 2 s. The
        unmodelled dynamics' floor is left out: it decorrelates in ~0.1 s, the filter may average it
        (``core.MODEL_BIAS_FLOOR``)."""
        phi = self.regressor_rear(vx, ay, rdot)
        n = abs(ay) / G
        _, var_par = self.rear.predict(phi, n * n, True)
        nl = 0.0 if n < 0.8 else (n - 0.8) * math.radians(3.0)
        return math.sqrt(var_par + (nl * vx) ** 2)

    def law_holds(self, vx: float, r: float, ay: float, rdot: float, delta: float) -> bool:
        """Whether the steering confirms both axles' tyre law, with no vy and no GNSS: the difference
        of the axle relations is L r - vx delta = k_f phi_f - k_r phi_r (the understeer relation),
        within LAW_HOLDS_SIGMA of both laws' uncertainty (counted once, as :meth:`model_error`) and
        the steering's. An axle at its friction limit (a low-friction road the lateral force
        normalised by g does not reveal) slips degrees beyond its law: the front of an understeering
        car first (mu 0.5 at 0.48 g: 22 deg); a rear at its limit moves the difference the other way.
        Only both axles leaving the law alike (a neutral car at its limit) would pass unseen.
        False without a steering angle (``delta`` NaN) or below MIN_SPEED."""
        if not vx >= MIN_SPEED or not math.isfinite(delta):
            return False
        e, var = self._understeer_misfit(vx, r, ay, rdot, delta)
        return e * e <= LAW_HOLDS_SIGMA ** 2 * var

    def _understeer_misfit(self, vx: float, r: float, ay: float, rdot: float, delta: float) -> tuple[float, float]:
        """(misfit, its variance) of the understeer relation: ``L r - vx delta - (y_f - y_r)`` (m/s),
        and both laws' uncertainty (counted once) plus the steering's; the one quantity
        :meth:`law_holds` tests and :meth:`law_excess_var` measures beyond its 3 sigma."""
        n2 = (ay / G) ** 2
        y_r, var_r = self.rear.predict(self.regressor_rear(vx, ay, rdot), n2, True)
        y_f, var_f = self.front.predict(self.regressor_front(vx, ay, rdot), n2, True)
        return self.L * r - vx * delta - (y_f - y_r), var_f + var_r + (STEER_ERR_RAD * vx) ** 2

    def law_excess_var(self, vx: float, r: float, ay: float, rdot: float, delta: float) -> float:
        """Variance (m/s)^2 the rear law's vy may be off by beyond its own uncertainty, from the
        steering: the part of the understeer relation's misfit (:meth:`law_holds`) beyond
        LAW_HOLDS_SIGMA of both laws and the steering, squared (0 while the law holds, and without
        a steering angle). Why the misfit bounds the rear's error too: the lateral force is
        normalised by g, not by the road's friction, so on a low-friction road an axle at its
        combined-slip limit (braking or power in a corner) slips degrees beyond a law that calls the
        force linear, and the misfit is the only signal of it that needs no vy. It cannot say which
        axle left its law (a ploughing front alone leaves the rear's vy intact), so it is an upper
        bound: ``core.Estimator`` widens the pseudo-measurement by it only with fresh GNSS
        (``core.LAW_EXCESS``), where the model's vy would otherwise be vouched for by the heading."""
        if not vx >= MIN_SPEED or not math.isfinite(delta):
            return 0.0
        return _excess_beyond_law(*self._understeer_misfit(vx, r, ay, rdot, delta))

    def law_excess_and_oversteer(self, vx: float, r: float, ay: float, rdot: float,
                                 delta: float) -> tuple[float, float]:
        """(:meth:`law_excess_var`, :meth:`oversteer_sigmas`) from one :meth:`_understeer_misfit`:
        the step wants both when ``core.FRICTION_REAR`` is on, and the misfit (two axle laws'
        predictions) is the costly part of each (~13 k instructions, callgrind); the same
        operations in the same order as the two methods, so the same bits."""
        if not vx >= MIN_SPEED or not math.isfinite(delta):
            return 0.0, math.nan
        e, var = self._understeer_misfit(vx, r, ay, rdot, delta)
        return _excess_beyond_law(e, var), (math.nan if ay == 0.0 else _oversteer_side(e, var, ay))

    def oversteer_sigmas(self, vx: float, r: float, ay: float, rdot: float, delta: float) -> float:
        """The understeer relation's misfit (:meth:`law_holds`) on the oversteer side, in its own
        sigmas: > 0 when the car yaws more than the two laws and the steering say (the rear beyond
        its law more than the front), < 0 when less (the front: a plough); NaN without a steering
        angle, below MIN_SPEED or without a lateral acceleration to give the corner its side.
        Signed by ay: in a corner to the right (ay < 0) a ploughing front makes the misfit
        ``L r - vx delta - (y_f - y_r)`` positive (random drive 3791: +3.4 deg of slip at -2.8 m/s^2),
        in one to the left negative."""
        if not vx >= MIN_SPEED or not math.isfinite(delta) or ay == 0.0:
            return math.nan
        e, var = self._understeer_misfit(vx, r, ay, rdot, delta)
        return _oversteer_side(e, var, ay)

    def drive_excess_var(self, vx: float, ay: float, rdot: float, alpha: float) -> float:
        """Variance (m/s)^2 the rear law's vy is off by when the driven rear axle is on its friction
        limit and slips ``alpha`` (rad, magnitude; ``drive_slip.DriveSlip``): the slip beyond the
        law's own (counted once, as :meth:`model_error`), as a speed, squared; 0 when ``alpha`` is
        not beyond it. Why the whole difference and not its part beyond 3 sigma
        (:meth:`law_excess_var`): the limit is already established by the wheels, and what the law
        misses there is the angle, not a noise around it."""
        if not vx >= MIN_SPEED or not alpha > 0.0:
            return 0.0
        y, _ = self.rear.predict(self.regressor_rear(vx, ay, rdot), (ay / G) ** 2, True)
        e = vx * math.tan(alpha) - abs(y)
        return e * e if e > 0.0 else 0.0

    def brake_excess_var(self, vx: float, ay: float, rdot: float, ratio: float, law_ay: float | None = None) -> float:
        """Variance (m/s)^2 the rear law's vy may be off by while the rear axle brakes in a corner:
        its linear angle (the softer of the configured and the learned compliance) times ``ratio``
        (``brake_grip.BrakeGrip``: the brush tyre's slip over its linear angle at the rear's lateral
        utilisation bound), beyond the law's own angle (counted once, as :meth:`model_error`), as a
        speed, squared; 0 when it is not beyond it. ``law_ay``: the force the law is fused with when it
        is not ``ay`` (core.SLIP_RATIO_TYRE_FORCE: ``ay`` the tyres' force, the law the kinematic ay's):
        the excess is then the tyres' angle less that law's, signed."""
        if not vx >= MIN_SPEED or not ratio > 1.0:
            return 0.0
        phi = self.regressor_rear(vx, ay, rdot)
        if law_ay is None:
            y, _ = self.rear.predict(phi, (ay / G) ** 2, True)
            e = abs(phi) * max(float(self.rear.k[0]), self.rear.k10) * ratio - abs(y)
            return e * e if e > 0.0 else 0.0
        y, _ = self.rear.predict(self.regressor_rear(vx, law_ay, rdot), (law_ay / G) ** 2, True)
        e = phi * max(float(self.rear.k[0]), self.rear.k10) * ratio - y
        return e * e

    def substitute_vy_rate(self, vx: float, rdot: float) -> float:
        """|d vy / dt| the single-track model expects from the yaw acceleration ``rdot``: what an
        ay substituted by r vx (which says vy is steady) leaves out. In the steady state,
        vy = lr r - kappa_r vx (lf ay) / L with ay = r vx, so vy moves with r by the sideslip
        gradient lr - kappa_r vx^2 lf / L (the understeer term), twice the linear law's for the
        saturation (k3) and the stiffness error (a lane change at 22 m/s: ~1.3 m/s^2 per rad/s^2)."""
        k = self.rear.k[0]
        return 2.0 * abs((self.lr - k * vx * vx * self.lf / self.L) * rdot)

    def model_vy(self, vx: float, r: float, ay: float, rdot: float) -> float:
        """:meth:`pseudo_measurement`'s vy alone (the same arithmetic; the fault detector's lateral
        check needs no variance, and it runs every step)."""
        phi = self.regressor_rear(vx, ay, rdot)
        n = abs(ay) / G
        k1, k3 = self.rear.k.tolist()
        return self.lr * r + (phi * k1 + phi * (n * n) * k3)

    def fuse(self, x: np.ndarray, P: np.ndarray, r: float, ay: float, rdot: float, A=None,
             every: int = 1, var_scale: float = 1.0, shift: float = 0.0, law_var: float = 0.0) -> bool:
        """Fuse the pseudo-measurement; ``every``: it is fused every n-th step (noise scaled);
        ``var_scale``: its variance widened (an input is a coarse substitute); ``shift``: what vy
        did since the instant the inputs describe (inputs lagged alike, :class:`LaggedModelInputs`)."""
        vx = x.item(VX)  # a Python float: the model's arithmetic below in floats, not numpy scalars (issue 10)
        if vx < MIN_SPEED:
            return False
        vy_m, var = self.pseudo_measurement(vx, r, ay, rdot)
        if law_var > 0.0:
            var += CORNER_STEPS * law_var
        return kalman.index_update(x, P, vy_m + shift - x[VY], VY, var * var_scale / every, 0.0, A)

    def adapt_from(self, vx: float, vy: float, var_vy: float, r: float, ay: float, rdot: float,
                   delta: float, seen_by_data: bool = True) -> None:
        """RLS step for both axles from a well-estimated (GNSS-fused) kinematic vy;
        ``seen_by_data``: the caller's word that the data, not this model, told vy (core.py
        LEARN_EXCITE_FIXES): the variance alone cannot say, as this model's pseudo-measurement
        narrows it too."""
        # Learn only from a sideslip the kinematic filter really observes: a steady circle with
        # free accelerometer biases is not (heading error and rotated biases trade off).
        if not self.adapt or not seen_by_data or vx < 8.0 or var_vy > 0.06 ** 2:
            return
        n2 = (ay / G) ** 2
        rv = var_vy + 0.05 ** 2
        phi = self.regressor_rear(vx, ay, rdot)
        if abs(phi) > 0.05 and not self.rear.from_drive:
            self.rear.update(phi, n2, vy - self.lr * r, rv)
        if not math.isfinite(delta):
            return
        phf = self.regressor_front(vx, ay, rdot)
        if abs(phf) > 0.05 and not self.front.from_drive:
            # alpha_f = (vy + lf r)/vx - delta = -F_yf / C_f  ->  vy + lf r - vx delta = kappa_f phf
            self.front.update(phf, n2, vy + self.lf * r - vx * delta, rv)

    def take_drive_estimate(self, estimates) -> None:
        """Adopt the per-drive regression's compliances (``StiffnessRegression.model_parameters``:
        per axle None or ((k1, k3), their 2x2 covariance, the law's relative error variance)) where
        it is the more certain, and clearly taught (half the prior's std: on a banked circle an
        honest 35 % moved the estimate within its std, and the sideslip RMS doubled); from then on
        the model follows it, and this RLS stops (its own updates pulled Revs' k_r 7 % off the
        regression's, with a std that then kept the regression out). That
        regression sees the stiffness through GNSS and a gyro heading, which the model does not
        pull, so its uncertainty is what the drive has taught; this RLS learns only from the filter's
        vy, which the model itself holds near the prior in every corner (it barely moves off it)."""
        if not self.adapt:
            return
        for axle, est in zip((self.rear, self.front), estimates):
            if est is None:
                continue
            k, P, rel = est
            if not (P[0, 0] < TAKE_MAX_REL_VAR * axle.P0[0, 0] and (axle.from_drive or P[0, 0] < axle.P[0, 0])):
                continue
            axle.from_drive = True
            axle.k[0] = min(max(k[0], 0.33 * axle.k10), 3.0 * axle.k10)
            axle.k[1] = min(max(k[1], -axle.k10), 4.0 * axle.k10)
            axle.P = np.array(P, dtype=float)
            if rel is not None:  # what the law got wrong on this drive, where the slip stood out
                axle.rel_var = max(rel, MODEL_MIN_REL_STD ** 2) * axle.k[0] ** 2

    def learned(self) -> dict:
        out = {"kappa_r": float(self.rear.k[0]), "kappa_r3": float(self.rear.k[1]),
               "kappa_f": float(self.front.k[0]), "kappa_f3": float(self.front.k[1])}
        for name, axle in (("kappa_r", self.rear), ("kappa_f", self.front)):
            out.update(zip(std_keys(name), axle.learned_std()))
        return out

    @property
    def cornering_stiffness_rear(self) -> float:
        return self.mass / self.rear.k[0]

    @property
    def cornering_stiffness_front(self) -> float:
        return self.mass / self.front.k[0]
