"""Per-drive cornering stiffness from GNSS velocity and a gyro heading, not from the filter's vy.

The live learner (``single_track.AxleRls``) regresses the filter's vy, which the single-track
pseudo-measurement itself pulls towards the prior stiffness: it barely leaves its prior. This one
uses only quantities the stiffness does not influence. At each fused GNSS sample (at its time of
validity, from the ring buffer) the antenna's lateral velocity is the GNSS velocity projected on
the body y axis of a *gyro-integrated* heading psi_g::

    vy_g = V sin(psi_g - course) - r l_x                         (at the CG)

psi_g differs from the true heading by a slowly drifting error d_psi (yaw-rate bias and scale
residuals), which shifts vy_g by vx d_psi. The single-track axle relations (the regressors of
``SingleTrackFusion``; two-term tyre law k1 + k3 n^2 as in ``AxleRls``) then give, per axle::

    rear:   vy_g - lr r            = phi_r (k1 + k3 n^2) + vx d_psi - ay d_tau
    front:  vy_g + lf r - vx delta = phi_f (k1 + k3 n^2) + vx d_psi - ay d_tau - vx d0

with d_tau the error of the GNSS latency that placed the sample (the velocity vector turns at
ay / V, so a sample placed late by d_tau reads vy off by -ay d_tau) and d0 the steering offset.
A small Kalman filter per axle (:class:`AxleFilter`) estimates k1, k3 and the nuisances.
Observability is the physics of the relation: k1 separates from the heading error only when phi
changes faster than the heading error can (a corner entered or left, a slalom), and from the
latency only where phi is not proportional to ay (r_dot, speed changes); a steady circle or a
straight leaves k1 near its prior with a large variance. The result is only reported (learned
state ``kappa_r_drive``/``kappa_f_drive`` -> ``fleet calibrate``; the live model keeps its own
learner, so the estimates and Revs are unchanged): one independent estimate per drive with a std
scaled by the regression's own residuals, which the fleet's inverse-variance combination can trust.

Latency: the estimate leans on the GNSS latency the samples were placed by: a sample placed
d_tau late reads ay d_tau of lateral velocity, as large as the slip itself at ~0.15 s (front and
rear alike: ~0.006-0.009 rad of slip angle per m/s^2 at 20 m/s). A drive knows its latency to
0.01-0.03 s, so one drive's front or rear estimate moves 10-30 % with that error. ``learned_std``
therefore also gives, per axle, the slope d kappa / d tau (the considered state's
cross-covariance; replays with the latency fixed 0.02 s apart moved the estimate 0.4-1.4x the
slope), the std were the latency exact, and the latency the estimate is for:
``fleet/calibrate.py`` moves every drive to the vehicle's combined latency, known several times
better, and counts that latency's error once.

Gyro scale: psi_g also turns by the gyro's scale error times the angle turned (the sensor's, the
road's tilt). On a circle driven faster and faster that heading ramp grows with the slip's own
regressor and no residual shows it; it is *considered* like the latency (CONSIDER_GYRO_SCALE, its
1-sigma the estimator's ``yaw_scale_std``), so k1's std says how far it can move the estimate.
"""
from __future__ import annotations

import math

import numpy as np

from ..history import AUX_AY, AUX_DELTA, AUX_R, StepHistory
from ..kinematic import BR, PSI, VX

G = 9.81
MIN_SPEED = 5.0  # m/s; below, the slip is a small part of vy (kinematic regime) and GNSS course is noisy
MAX_N = 0.6  # normalised lateral force beyond which the two-term tyre law is not trusted
WINDOW = 10  # steps each side of the time of validity for r, ay (mean) and r_dot (slope)
HEADING_INIT_RAD = math.radians(2.0)  # added to the filter's heading std when the gyro heading starts
MIN_LATENCY_STD = 0.01  # s; floor of the latency's considered std (the estimator's own floor is below)
STEER_OFFSET_RAD = math.radians(0.3)  # road-wheel steering offset prior (~4 deg at the steering wheel)
GYRO_SCALE_ERR = 0.005  # relative yaw-rate scale uncertainty (heading error per radian turned)
MODEL_ERR = 0.1  # relative slip error the two-term law and tyre relaxation leave (white part)
MIN_UPDATES = 20  # fewer samples: the residuals say too little about the noise level; the prior's std
MAX_RHO = 0.9  # residual autocorrelation cap (x19 variance)
# The gyro heading's scale error (the sensor's, the road's tilt: the estimator's yaw_scale_std) as a
# *considered* parameter: a constant scale error s turns psi_g by s x the angle turned, a heading
# ramp that on a circle driven faster and faster grows with the slip's own regressor (angle turned ~
# vx t, times vx: ~vx^2 ... vx^3, the slip phi ~ vx^3 / R), so no residual shows it. As the white
# random walk of GYRO_SCALE_ERR (kept) it counted 1/sqrt(N) of it over N samples: on the never-seen
# 2946 (accelerating 140 m circle, 3.3 deg bank) the gyro heading drifted 1.2 deg over 6 rad turned
# (scale and bias) and the rear k1 went to 0.23-0.39 of the truth with a claimed std of 0.11-0.16
# of it (4-5 sigma), which the live model took. Considered (never estimated, as the latency: the
# other states' gains allow for it), k1's std carries what such a scale moves it by
# (AxleFilter.scale_std; tests/test_stiffness_regression.py: a 0.4 % scale on a circle ramped
# 10 -> 30 m/s put k1 4-5 sigma off, considered within 1.1 sigma, its std 4x).
CONSIDER_GYRO_SCALE = True
# The residuals' noise level scales the information the samples gave k1, not k1's prior (issue 7,
# circle49; never-seen drive 3974: an AWD on a 77 m circle, speed rising, configured m / C_r 46 %
# of the car's too large). MIN_UPDATES fixes on the straight before the circle left k1's variance
# at its prior (0.5 k1: phi ~ 0, the samples say nothing of k1), but their residuals were small
# against the GNSS noise model (mean NIS 0.068), and scaling the whole noise part by them claimed
# k1 to 0.36 of the prior's std (3.78e-3 of 21.1e-3): below half the live model's prior, so
# ``SingleTrackFusion.take_drive_estimate`` took it as taught and stopped the live learner; the
# live law then went into the circle at 17 % of k1 (config 40 %) while 43 % off (k1 20.9e-3, the
# car's 14.6e-3), and the sideslip was published valid 0.9-1.2 deg off at 0.33 deg (185 rows).
# For a linear regression with prior variance p0 and data information J, a noise level s times the
# modelled one gives 1 / (1 / p0 + J / s): s scales J = 1 / noise - 1 / p0 and leaves p0 alone
# (no data: the prior; much data: s times the data's variance, as before). False: the noise part
# scaled whole (main's). Measured (circle49, pure Python, against the lead's rd48_integ = main's
# bits): 3974 185 -> 13 valid sideslip rows beyond 3 sigma (worst 1.16 -> 1.06 deg); the 28 steady
# circles of 3601-3840 0 -> 0, valid rows 234500 -> 233894 (3650's worst 0.97 -> 0.34 deg); all 40
# drives of 3601-3640 0 -> 0, valid rows 265328 -> 264435 (15 drives lose a little validity on
# right rows: a premature take had made them valid). Off: not free, and it alone does not close
# 3974 (the rest: the latency 6 sigma off and the model's bias counted every 2 s; report circle49).
SCALE_DATA_ONLY = False
SLIP_STANDS_OUT = 4.0  # slip^2 / (rest of the innovation variance) above which a residual measures the tyre law

# state of one axle's filter: compliances k1, k3, heading error, yaw-rate bias error, GNSS latency,
# road-wheel steering offset (front only)
K1, K3, DPSI, EB, TAU, D0 = range(6)
NS = 6


# ------------------------------------------------------------------------------------------------
# The numerical kernels, numpy reference. ``backend.py`` swaps in the compiled ones of
# ``_kernels.c`` (same math, within 1e-9: tests/test_kernels.py) under the names without
# ``_reference``; the methods below look them up on this module at call time.

def axle_propagate_reference(P: np.ndarray, c: float, q_psi: float, q_bias: float) -> None:
    """P <- F P F' with F = I + c e_dpsi e_eb' (the heading error grows by the bias error times
    the time c), plus the heading and bias random walks; in place."""
    F = np.eye(NS)
    F[DPSI, EB] = c
    P[:] = F @ P @ F.T
    P[DPSI, DPSI] += q_psi
    P[EB, EB] += q_bias


def axle_update_reference(x: np.ndarray, P: np.ndarray, z: float, h: np.ndarray, rv: float) -> float:
    """Scalar update of x, P in place, tau considered (its gain zero; Joseph form, the covariance
    then stays that of the suboptimal gain); returns the normalised innovation."""
    Ph = P @ h
    s = float(h @ Ph) + rv
    e = z - float(h @ x)
    g = Ph / s
    g[TAU] = 0.0
    x += g * e
    IKH = np.eye(NS) - np.outer(g, h)
    P[:] = IKH @ P @ IKH.T + rv * np.outer(g, g)
    P[:] = 0.5 * (P + P.T)
    return e / math.sqrt(s)


def axle_latency_reference(x: np.ndarray, P: np.ndarray, tau: float, var: float) -> None:
    """The considered latency moved to tau with variance var, in place: every state moves with
    it by its regression on tau (P[:, tau] / P[tau, tau]), and its share of every variance is
    rescaled."""
    p = P[:, TAU].copy()
    x += p / p[TAU] * (tau - x[TAU])
    P -= (1.0 - var / p[TAU]) * np.outer(p, p) / p[TAU]
    P[:] = 0.5 * (P + P.T)


def gyro_sum_reference(aux: np.ndarray, r_col: int, X: np.ndarray, br_col: int, k0: int, k1: int) -> float:
    """Sum over the steps k0..k1 of the ring buffers of aux[:, r_col] + X[:, br_col]."""
    idx = np.arange(k0, k1 + 1) % len(aux)
    return float(np.sum(aux[idx, r_col] + X[idx, br_col]))


def window_fit_reference(aux: np.ndarray, r_col: int, ay_col: int, lo: int, hi: int, s: int,
                         dt: float) -> tuple[float, float, float, float]:
    """Over the steps lo..hi of the ring buffer: the least-squares line of aux[:, r_col] against
    t = (k - s) dt (slope r_dot, value r at s), the mean of aux[:, ay_col] and the standard error
    of that mean."""
    idx = np.arange(lo, hi + 1) % len(aux)
    ayw = aux[idx, ay_col]
    rdot, r = np.polyfit((np.arange(lo, hi + 1) - s) * dt, aux[idx, r_col], 1)
    return float(rdot), float(r), float(np.mean(ayw)), float(np.std(ayw)) / math.sqrt(len(ayw))


axle_propagate = axle_propagate_reference
axle_update = axle_update_reference
axle_latency = axle_latency_reference
gyro_sum = gyro_sum_reference
window_fit = window_fit_reference


class AxleFilter:
    """Kalman filter of one axle's two-term slip compliance [k1, k3] (``AxleRls``'s tyre law) with
    the nuisances of its relation: d_psi the gyro heading's error, e_b the error of the yaw-rate
    bias it removes (a drift: d_psi grows by e_b dt), tau the GNSS latency (*considered*: see
    :meth:`latency`) and, for the front, d0 the steering offset. d_psi and e_b are reset into
    ``psi``/``bias`` after each update (error state), so the measurement stays linear.

    The two axles are deliberately separate filters: together, their difference is the
    understeer relation L r - vx delta = k_f phi_f - k_r phi_r with no GNSS noise in it, which pins
    only the understeer gradient and lets its small systematic errors (steering timing, the tyre
    law) drive k1 and k3 apart with a tiny variance (tried: both axles 30-40 % off at 1 % std)."""

    def __init__(self, k1: float, steer_offset_var: float):
        self.x = np.array([k1, 0.6 * k1, 0.0, 0.0, 0.0, 0.0])
        self.P = np.diag([(0.5 * k1) ** 2, (0.8 * k1) ** 2, 0.0, 0.0, 0.0, steer_offset_var])
        self.p0_k1 = float(self.P[K1, K1])  # k1's prior variance (SCALE_DATA_ONLY)
        self.psi = 0.0  # gyro heading (clockwise from north), rad
        self.bias = 0.0  # the yaw-rate bias it removes, rad/s
        self.latency_started = False
        self.nis_sum = 0.0
        self.lag_sum = 0.0  # sum of products of consecutive normalised innovations
        self.last_nu = 0.0
        self.updates = 0
        self.model_sum = 0.0  # residual variance beyond every modelled term, relative to slip^2
        self.model_n = 0
        # the considered gyro-scale error s (CONSIDER_GYRO_SCALE): S = d x_error / d s, its variance.
        # The states' covariance with s is S x var_s; P holds its share var_s S S' (tau is never
        # updated, so S[TAU] stays 0 and :meth:`latency` leaves both alone)
        self.S = np.zeros(NS)
        self.var_s = 0.0

    def start_heading(self, psi: float, var_psi: float, bias: float, var_bias: float) -> None:
        self.psi, self.bias = psi, bias
        self.x[DPSI] = self.x[EB] = 0.0
        for j, v in ((DPSI, var_psi), (EB, var_bias)):
            self.P[j, :] = 0.0
            self.P[:, j] = 0.0
            self.P[j, j] = v
            self.S[j] = 0.0

    def scale_std(self, std: float) -> None:
        """Follow the gyro-scale error's 1-sigma (considered, like the latency): its share of every
        variance, var_s S S', rescaled."""
        var = std * std
        self.P += (var - self.var_s) * np.outer(self.S, self.S)
        self.var_s = var

    def latency(self, tau: float, std: float) -> None:
        """Follow the latency estimator: tau is a *considered* state (Schmidt): this regression never
        updates it (here tau trades with k1 whenever speed is steady: V r tau and phi ~ vx^2 r look
        alike), but carries how its estimate depends on it (the cross-covariance, S = P[:, tau] /
        P[tau, tau] per second of latency error). When the estimator's tau moves, the estimate
        moves by S dtau; when its std changes, so does the share of tau in every variance."""
        var = max(std, MIN_LATENCY_STD) ** 2
        if not self.latency_started:
            self.x[TAU] = tau
            self.P[TAU, :] = 0.0
            self.P[:, TAU] = 0.0
            self.P[TAU, TAU] = var
            self.latency_started = True
            return
        axle_latency(self.x, self.P, tau, var)

    def propagate(self, r_sum: float, steps: int, dt: float, q_psi: float, q_bias: float) -> None:
        """Integrate ``steps`` raw yaw-rate samples (their sum ``r_sum``) into the heading."""
        turned = (r_sum - steps * self.bias) * dt
        self.psi -= turned  # yaw rate positive left, heading clockwise
        if self.var_s > 0.0:
            # the heading error grows by s x the angle turned: F = I + turned e_dpsi e_s' on [x, s]
            S0 = self.S.copy()
            self.S[DPSI] += turned
            self.P += self.var_s * (np.outer(self.S, self.S) - np.outer(S0, S0))
        axle_propagate(self.P, steps * dt, q_psi, q_bias)
        if self.var_s > 0.0:
            self.S[DPSI] += steps * dt * self.S[EB]  # ... and by the bias error's (F of axle_propagate)

    def update(self, z: float, h: np.ndarray, rv: float, model_var: float = 0.0) -> None:
        """Scalar update, tau considered (its gain zero; Joseph form, the covariance then stays
        that of the suboptimal gain). ``model_var``: the two-term law's share of ``rv``; where the
        slip stands out of the rest, the residual says how wrong the law is (:meth:`model_rel_var`)."""
        slip = float(h[K1] * self.x[K1] + h[K3] * self.x[K3])
        Ph = self.P @ h
        rest = float(h @ Ph) + rv - model_var
        if self.var_s > 0.0:  # the considered scale: S <- (I - g h') S, g the update's gain
            g = Ph / (rest + model_var)
            g[TAU] = 0.0
            self.S -= g * float(h @ self.S)
        nu = axle_update(self.x, self.P, z, h, rv)
        if slip * slip > SLIP_STANDS_OUT * rest:
            self.model_sum += max(nu * nu * (rest + model_var) - rest, 0.0) / (slip * slip)
            self.model_n += 1
        self.nis_sum += nu * nu
        self.lag_sum += nu * self.last_nu
        self.last_nu = nu
        self.updates += 1
        self.psi -= float(self.x[DPSI])
        self.bias -= float(self.x[EB])
        self.x[DPSI] = self.x[EB] = 0.0

    def model_rel_var(self) -> float | None:
        """The two-term law's error variance relative to the slip, from the residuals where the
        slip stood out (None before MIN_UPDATES of them): their mean, raised by two standard
        errors of a mean of that many squares (as if independent, less their autocorrelation)."""
        if self.model_n < MIN_UPDATES:
            return None
        rho = min(max(self.lag_sum / self.nis_sum, 0.0), MAX_RHO) if self.nis_sum > 0 else 0.0
        n_eff = self.model_n * (1.0 - rho) / (1.0 + rho)
        return self.model_sum / self.model_n * (1.0 + 2.0 * math.sqrt(2.0 / max(n_eff, 1.0)))

    def k1_per_latency(self) -> float:
        """d k1 / d tau: how the estimate moves per second of latency error (the considered
        state's cross-covariance; 0 before the latency is known)."""
        return float(self.P[K1, TAU] / self.P[TAU, TAU]) if self.P[TAU, TAU] > 0 else 0.0

    def k1_std(self) -> float:
        """1-sigma of k1: its noise-driven part with the noise level the residuals show (the
        least-squares estimate of the residual variance, the mean normalised innovation squared:
        the noise model only has to be right in shape) and their time correlation (lag-1
        autocorrelation rho: a sample then carries (1 - rho) / (1 + rho) of an independent one's
        information); plus, unscaled, the part the latency's uncertainty leaves (a bias common to
        every sample, which no residual shows)."""
        noise, lat = self._k1_var_parts()
        return math.sqrt(noise + lat)

    def k1_std_given_latency(self) -> float:
        """1-sigma of k1 were the latency exactly ``x[TAU]``: the noise-driven part of
        :meth:`k1_std` and the gyro scale's (CONSIDER_GYRO_SCALE: one drive's own). What a fleet combines per drive once it knows the vehicle's latency
        better than one drive does (the latency part is common to all its drives: it does not
        average out, ``fleet/calibrate.py`` adds it back once)."""
        return math.sqrt(self._k1_var_parts()[0])

    def _k1_var_parts(self) -> tuple[float, float]:
        var = max(float(self.P[K1, K1]), 0.0)
        lat = self.P[K1, TAU] ** 2 / self.P[TAU, TAU] if self.P[TAU, TAU] > 0 else 0.0
        # the considered gyro scale's share (CONSIDER_GYRO_SCALE): as the latency's, no residual shows
        # it; unlike it, common to nothing beyond this drive (in the first part, unscaled)
        scl = min(self.var_s * self.S[K1] ** 2, max(var - lat, 0.0))
        noise = max(var - lat - scl, 0.0)
        if self.updates < MIN_UPDATES:
            return noise + scl, var - noise - scl
        nis = self.nis_sum / self.updates
        rho = min(max(self.lag_sum / self.nis_sum, 0.0), MAX_RHO) if self.nis_sum > 0 else 0.0
        s = nis * (1.0 + rho) / (1.0 - rho)
        if SCALE_DATA_ONLY and noise > 0.0 and s > 0.0:
            # the residuals' level scales the samples' information on k1, not its prior (SCALE_DATA_ONLY)
            p0 = self.p0_k1
            info = max(1.0 / noise - 1.0 / p0, 0.0)
            return 1.0 / (1.0 / p0 + info / s) + scl, lat
        return noise * s + scl, lat


class StiffnessRegression:
    """Both axles' filters, fed from the fused GNSS samples and the ring buffer."""

    def __init__(self, mass: float, yaw_inertia: float, lf: float, lr: float, cf: float, cr: float,
                 yaw_rate_noise: float, yaw_rate_bias_walk: float, dt: float, relaxation_length: float = 0.0):
        self.dt = dt
        self.lf, self.lr, self.L = lf, lr, lf + lr
        self.iz_m = yaw_inertia / mass
        # per axle (rear, front): the yaw-inertia term with the tyres' relaxation lead (single_track.py)
        self.iz_axle = (self.iz_m - relaxation_length * lf, self.iz_m + relaxation_length * lr)
        self.rear = AxleFilter(mass / cr, 0.0)
        self.front = AxleFilter(mass / cf, STEER_OFFSET_RAD ** 2)
        self.arw = yaw_rate_noise
        self.bias_walk = yaw_rate_bias_walk
        self.last_s: int | None = None  # step up to which the gyro headings are integrated

    def observe(self, h: StepHistory, s: int, course: float, speed: float, sigma_v: float,
                lever_x: float, latency: float, latency_std: float, steer_offset: float,
                scale_std: float = 0.0, force_shift: float = 0.0) -> None:
        """Use one fused GNSS velocity (course, speed; per-axis 1-sigma ``sigma_v``) valid at step s
        by the latency estimator's ``latency`` (+- ``latency_std``). ``steer_offset``: the road-wheel
        angle offset the estimator currently removes from the steering (added back: d0 is the true,
        constant offset, not the learner's slowly moving one). ``scale_std``: the gyro's scale error
        1-sigma (considered, CONSIDER_GYRO_SCALE). ``force_shift`` (m/s^2): the tyres' lateral force
        less the kinematic ay the history holds (core.MODEL_TYRE_FORCE: the bank's share of b_ay), in
        the tyre law's regressor only; the latency term stays kinematic (the velocity vector turns
        at the kinematic ay)."""
        i = h.slot(s)
        if self.last_s is not None and s <= self.last_s:
            return  # out of order (a second receiver): the headings only move forward
        axles = (self.rear, self.front)
        if self.last_s is None or self.last_s < h.oldest():
            # (re)start from the filter's heading and bias, with their uncertainty
            for ax in axles:
                ax.start_heading(float(h.X[i, PSI]), float(h.P[i][PSI, PSI]) + HEADING_INIT_RAD ** 2,
                                 float(h.X[i, BR]), float(h.P[i][BR, BR]))
        else:
            r_sum = gyro_sum(h.aux, AUX_R, h.X, BR, self.last_s + 1, s)  # the gyro's own reading
            steps = s - self.last_s
            q_psi = self.arw ** 2 * steps * self.dt + (GYRO_SCALE_ERR * r_sum * self.dt) ** 2
            q_bias = self.bias_walk ** 2 * steps * self.dt
            for ax in axles:
                ax.propagate(r_sum, steps, self.dt, q_psi, q_bias)
        self.last_s = s
        for ax in axles:
            ax.latency(latency, latency_std)
            if CONSIDER_GYRO_SCALE:
                ax.scale_std(scale_std)
        vx = float(h.X[i, VX])
        lo, hi = max(h.oldest(), s - WINDOW), min(h.last, s + WINDOW)
        if hi - lo < 2:
            return
        rdot, r, ay, sig_ay = window_fit(h.aux, AUX_R, AUX_AY, lo, hi, s, self.dt)
        fy = ay + force_shift
        n = abs(fy) / G
        if vx < MIN_SPEED or n > MAX_N:
            return
        n2 = n * n
        delta = float(h.aux[i, AUX_DELTA]) + steer_offset
        for ax, arm, sign, iz in ((self.rear, self.lf, 1.0, self.iz_axle[0]), (self.front, self.lr, -1.0, self.iz_axle[1])):
            rel = ax.psi - course
            vax = speed * math.cos(rel)
            if vax < MIN_SPEED or (ax is self.front and not math.isfinite(delta)):
                continue
            # measured lateral velocity at the CG, as if the sample were placed by tau
            vy = speed * math.sin(rel) - r * lever_x - ay * latency
            phi = -vx * (arm * fy - sign * iz * rdot) / self.L
            z = vy - self.lr * r if ax is self.rear else vy + self.lf * r - vx * delta
            hv = np.array([phi, phi * n2, vax, 0.0, -ay, 0.0 if ax is self.rear else -vx])
            # noise: GNSS, the regressor's own (ay noise), what the two-term tyre law leaves
            k1 = ax.x[K1]
            rv = sigma_v ** 2 + (k1 * vx * arm * sig_ay / self.L) ** 2 + (MODEL_ERR * k1 * phi) ** 2
            ax.update(z, hv, rv, (MODEL_ERR * k1 * phi) ** 2)

    def model_parameters(self) -> tuple:
        """Per axle (rear, front): None before MIN_UPDATES samples, else ((k1, k3), their 2x2
        covariance scaled as :meth:`AxleFilter.k1_std` scales k1's, the law's relative error
        variance or None) for the live single-track model."""
        out = []
        for ax in (self.rear, self.front):
            p11 = float(ax.P[K1, K1])
            if ax.updates < MIN_UPDATES or not p11 > 0.0:
                out.append(None)
                continue
            scale = ax.k1_std() ** 2 / p11
            out.append(((float(ax.x[K1]), float(ax.x[K3])), ax.P[:2, :2] * scale, ax.model_rel_var()))
        return tuple(out)

    def learned(self) -> dict:
        return {"kappa_r_drive": float(self.rear.x[K1]), "kappa_f_drive": float(self.front.x[K1])}

    def learned_std(self) -> dict:
        """The 1-sigmas, and what a fleet needs to move each drive's estimate to a better latency:
        ``*_per_latency_s`` (d kappa / d tau), ``*_given_latency`` (the std without the latency's
        part) and ``kappa_drive_latency_s`` (the latency the estimates are for)."""
        out = {"kappa_drive_latency_s": float(self.rear.x[TAU])}
        for key, ax in (("kappa_r_drive", self.rear), ("kappa_f_drive", self.front)):
            out.update({key: ax.k1_std(), f"{key}_given_latency": ax.k1_std_given_latency(),
                        f"{key}_per_latency_s": ax.k1_per_latency()})
        return out
