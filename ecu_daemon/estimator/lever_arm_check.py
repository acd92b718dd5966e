"""Is the configured GNSS antenna lever arm (x, along the car) consistent with the drive?

A single antenna moves at v_cg + r x lever: its course is the heading less the antenna's sideslip
atan2(vy + r x_a, vx - r y_a). With x_a configured dx too far forward the filter predicts a course
turned by r dx / vx (rad): on a steady circle of radius R that is dx / R, a constant the filter
cannot tell from a heading error and takes into the heading (lowspeed_r15, dx = 1.5 m: 5.9 deg
off while valid). It is observable against the gyro all the same: the heading a course implies,
course + predicted antenna sideslip, must follow the integrated yaw rate. Its difference from the
gyro's heading,

    z = course + beta_pred - psi_gyro = c0 + c1 t + dx (r / vx) + noise,

is a constant (the heading's offset; a new one after a gap), a drift (a residual yaw-rate bias)
and dx times r / vx, which changes at every corner entry and exit, every speed change on a
circle, every slalom. A least-squares fit (with a forgetting window, so old driving does not pin
them) gives dx and its standard deviation; the filter's own heading and vy are not the reference (both take
part of the error), the gyro is.

A GNSS latency error dd turns the course by r dd, which on a circle at one speed is the same
regressor as dx r / vx: it is a fourth unknown, with the latency estimator's std as its prior
(latency.py identifies it from speed changes), so only what the latency cannot explain is read as
a lever arm. That error is the one of the delay each fix was placed with: while the
identification moves the delay every fix in the fit is rebased on the current one
(``rebase_latency``), so the prior is about one error and the move is not read as dx. When the fit puts dx beyond LEVER_TOL_M by Z_FLAG of its standard deviations the
lever arm is flagged (sticky: a configuration does not fix itself; one log line); from Z_SUSPECT
on, ``heading_std`` gives the course error such a lever arm makes, |dx| |r| / vx, remembered over
TURN_MEMORY_S after the corner (the filter's heading keeps the error until straight-line GNSS
corrects it), which the core adds to the published heading std: the heading is not promised where
the wrong lever arm turns it. Straight driving is unaffected (r = 0), and so is every drive whose
lever arm is right (the fit's dx stays within the tolerance).

The y component of the lever arm turns the course only to second order; it changes the antenna's
speed by r dy instead, which ``LeverArmYCheck`` fits against the wheel speed (below).
"""
from __future__ import annotations

import math

import numpy as np

#: m: lever-arm x errors below this are not flagged. A measuring-tape error is centimetres; on the
#: tightest circles the suite drives (R = 9 m) 0.5 m turns the course by 3.2 deg, inside the 5 deg
#: a valid heading promises, and a CG that moves with the load moves by decimetres.
LEVER_TOL_M = 0.5
Z_FLAG = 3.0  # the fit's dx this many of its standard deviations beyond the tolerance: flagged
# ... this many: suspected (no log line; sticky, but the std it adds follows the fit's dx). The
# heading takes the course error within seconds of the corner entry, the fit needs ~15 s of the
# corner to reach Z_FLAG: while suspected, the heading std already covers the error the fit's dx
# makes (lowspeed_r15, dx = 1.5 m: the first rows 5 deg off came 1.6 s after the fit was 2 sigma
# beyond the tolerance, ~6 s before 3 sigma).
Z_SUSPECT = 2.0
# m/s: courses from this speed up (each weighted by its sigma_v / v): the straight before a corner
# is often slow (a start), and it is what anchors the heading offset the corner entry is read against
MIN_SPEED = 2.0
WINDOW_S = 60.0  # forgetting time of the fit: a drive's geometry is constant, a yaw-rate bias drifts
TURN_MEMORY_S = 5.0  # the heading keeps a course error this long after the corner (core.TURN_MEMORY_S)
# A fix whose residual is this many sigma from the fit's prediction (its noise plus the fit's own
# uncertainty there) is not the slow geometry this fits but a glitch (a GNSS velocity tripled for
# 5 s in gnss_glitch passed the core's checks for a few fixes and taught a lever arm y of 7.7 m):
# left out. A real lever-arm error is not: where the fit has not seen it yet, its uncertainty there
# (the corner's first r / vx or r) is large.
GATE_SIGMA = 5.0
# A lever arm is suspected or flagged only by a fit that can resolve it: its std below this many
# tolerances (an early, ill-conditioned fit of dy = 21 +- 7 m on latency_0.8 is no diagnosis)
MAX_FLAG_STD_FACTOR = 2.0
MAX_GAP_S = 2.0  # a gap this long (or a filter reset) restarts the gyro integral: a new offset c0
# Per-fix course noise the fit assumes besides the receiver's sigma_v / v: multipath and the
# filter's sideslip errors, both correlated over seconds, so counted as one fix per CORR_FIXES.
COURSE_NOISE_RAD = math.radians(0.5)
CORR_FIXES = 5.0
# prior of the drift column (rad per WINDOW_S): a yaw-rate bias the filter has not removed, up to
# 0.3 deg/s (a MEMS gyro's turn-on bias; the filter's b_r state takes most of it)
DRIFT_INFO = 1.0 / (math.radians(0.3) * WINDOW_S) ** 2



def _regularised_cov(info: np.ndarray, prior_info: tuple[float, ...]) -> np.ndarray | None:
    """The fit's covariance: its information plus a diagonal prior (what keeps a fit the drive has
    not excited yet invertible); None if it still is singular (the fit keeps its last solution)."""
    try:
        return np.linalg.inv(info + np.diag(prior_info))
    except np.linalg.LinAlgError:
        return None


# The kernels every fix runs: numpy references here, swapped for the compiled ones (``_kernels.c``:
# the same math in one call each, the inverse by Gauss-Jordan; ``yaw_sum`` numpy's own bits, its
# pairwise summation) by ``backend.select``.

def fit_update_reference(info: np.ndarray, rhs: np.ndarray, h: np.ndarray, z: float, var: float,
                         prior: np.ndarray, theta: np.ndarray, cov: np.ndarray) -> bool:
    """Add a fix (regressors h, value z, noise variance var) to the information and solve the
    regularised fit into theta and cov, in place; False (theta, cov untouched) while singular."""
    info += np.outer(h, h) / var
    rhs += h * (z / var)
    c = _regularised_cov(info, prior)
    if c is None:
        return False
    theta[:] = c @ rhs
    cov[:] = c
    return True


def marginalise_offset(info: np.ndarray, rhs: np.ndarray) -> None:
    """Forget the fit's first unknown (a run's offset) in place, keeping what the data said about
    the others: the Schur complement of info[0, 0], then a zero row and column for the next run's."""
    a = info[0, 0]
    if a > 0.0:
        c = info[0].copy()
        info -= np.outer(c, c) / a
        rhs -= c * (rhs[0] / a)
    info[0, :] = 0.0
    info[:, 0] = 0.0
    rhs[0] = 0.0


def rebase_latency(info: np.ndarray, rhs: np.ndarray, theta: np.ndarray, j: int,
                   old: float | None, new: float | None) -> float | None:
    """The fit's latency-error unknown j is the error of the delay the fixes were placed with (``old``,
    None: none yet); this fix was placed with ``new`` (None: the fixes' delays are taken as one), so
    the delay moved by delta = new - old. Returns the delay the information is now about. Each fix already in the information was placed
    with the old delay, whose error is the new one's less delta: as a fixed linear change of unknown
    (theta_j' = theta_j + delta) it is exact in information form, rhs' = rhs + info[:, j] delta, and
    every fix, old and new, then shares one latency error, that of the current delay, which is what
    the prior (the latency estimator's std) is about. Without it a delay still being identified while
    the car circles leaves r x (its change) in the courses, which the fit reads as what else grows
    through the circle: a gyro scale of -2.8 % on a gyro with none (random drive 417: the delay moved
    0.32 -> 0.57 s in a 0.56 rad/s circle; the scale was applied and the heading moved 5.5 deg)."""
    if new is None:
        return old
    if old is not None and new != old:
        delta = new - old
        rhs += info[:, j] * delta
        theta[j] += delta
    return new


def fit_predict_reference(h: np.ndarray, theta: np.ndarray, cov: np.ndarray) -> tuple[float, float]:
    """The fit's prediction at regressors h and its variance there."""
    return float(h @ theta), float(h @ cov @ h)


def yaw_sum_reference(aux: np.ndarray, r_col: int, k0: int, k1: int, ring: np.ndarray | None) -> float:
    """The gyro turn the checks integrate between two fixes (per dt): the sum over the steps k0..k1
    of the ring buffer's aux[:, r_col], each divided by 1 - ring (the yaw-rate scale applied at
    that step) if ring is given."""
    idx = np.arange(k0, k1 + 1) % len(aux)
    r = aux[idx, r_col]
    if ring is not None:
        r = r / (1.0 - ring[idx])
    return float(np.sum(r))


fit_update = fit_update_reference
fit_predict = fit_predict_reference
yaw_sum = yaw_sum_reference


class LeverArmCheck:
    """One receiver's lever-arm consistency fit (information form, exponentially forgotten):
    unknowns [offset of the current run, drift, dx, latency error]."""

    def __init__(self, lever_x: float):
        self.lever_x = lever_x
        self.info = np.zeros((4, 4))
        self.rhs = np.zeros(4)
        self.t0 = None
        self.t_last = -math.inf
        self.psi_gyro = 0.0
        self.k_last = -1
        self.n = 0
        self.dx = 0.0
        self.dx_std = math.inf
        self.theta = np.zeros(4)
        self.cov = None  # of the last solve (None: no fit yet, or a new run since)
        self._cov = np.zeros((4, 4))  # where the solves write it
        self._prior = np.array((1e-9, DRIFT_INFO, 1e-6, 0.0))  # the last: the latency std's (_solve)
        self.gated = 0  # fixes left out as glitches
        self.flagged = False  # the lever arm is wrong (sticky: a configuration does not fix itself)
        self.suspected = False  # the fit has been heading for a flag (sticky; set before flagged)
        self.excess = 0.0  # |dx| the heading std covers while suspected
        self.turn = 0.0  # |r| / vx remembered over TURN_MEMORY_S
        self.turn_t = -math.inf
        self.delay_s = None  # the delay the fixes in the information were placed with (rebase_latency)

    def restart(self) -> None:
        """Forget the gyro integral (a filter reset): the next fix opens a new offset."""
        self.k_last = -1

    def observe(self, t: float, k: int, dt: float, r_sum: float | None, course: float, sigma_v: float,
                speed: float, vx: float, vy: float, r: float, lever_y: float, latency_std_s: float,
                delay_s: float | None = None) -> None:
        """A GNSS course of time of validity ``t`` at stored step ``k``, with the filter's vx, vy
        and the bias-corrected yaw rate r there; ``r_sum``: the sum of the bias-corrected yaw rates
        of the steps k_last+1 .. k (``yaw_sum``, np.sum's bits; None if the history no longer holds them);
        ``delay_s`` the delay the fix was placed with (``rebase_latency``; None: the fixes' delays are taken as one)."""
        self.delay_s = rebase_latency(self.info, self.rhs, self.theta, 3, self.delay_s, delay_s)
        if self.t0 is None:
            self.t0 = t
        ratio = r / vx if vx > 1.0 else 0.0
        self._remember_turn(t, abs(ratio))
        if speed < MIN_SPEED or vx < MIN_SPEED:
            self.k_last = -1
            return
        beta = math.atan2(vy + r * self.lever_x, vx - r * lever_y)
        new_run = self.k_last < 0 or r_sum is None or t - self.t_last > MAX_GAP_S or k <= self.k_last
        if new_run:
            self._new_run(course + beta)
        else:
            self.psi_gyro -= r_sum * dt  # clockwise, as the heading
        if self.n and t > self.t_last:  # forget: information decays as exp(-age / WINDOW_S)
            f = math.exp(-(t - self.t_last) / WINDOW_S)
            self.info *= f
            self.rhs *= f
        if t - self.t0 > WINDOW_S:
            self._shift_origin(t)
        self.k_last = k
        self.t_last = t
        z = math.remainder(course + beta - self.psi_gyro, 2.0 * math.pi)
        var = ((sigma_v / speed) ** 2 + COURSE_NOISE_RAD ** 2) * CORR_FIXES
        h = np.array((1.0, (t - self.t0) / WINDOW_S, ratio, -r))
        if not new_run and self.cov is not None:
            pred, spread = fit_predict(h, self.theta, self.cov)
            e = z - pred
            if e * e > GATE_SIGMA ** 2 * (var + spread):
                self.gated += 1
                return
        self.n += 1
        self._solve(latency_std_s, h, z, var)

    def _shift_origin(self, t: float) -> None:
        """Move the drift's time origin to t (a long drive keeps its regressor near 1, the fit well
        conditioned): the old regressors are h_old = M h_new with M = I + c e1 e0' (c the shift in
        windows), so the information becomes M' info M, the right-hand side M' rhs."""
        M = np.eye(4)
        M[1, 0] = (t - self.t0) / WINDOW_S
        self.info = M.T @ self.info @ M
        self.rhs = M.T @ self.rhs
        self.t0 = t

    def _new_run(self, psi0: float) -> None:
        """A new gyro integral (starting at this fix's heading, so z stays near 0, away from the
        wrap) and so a new unknown offset: the old one is marginalised out (Schur complement), the
        fit keeps its drift and dx information across the break."""
        self.psi_gyro = psi0
        self.cov = None
        marginalise_offset(self.info, self.rhs)

    def _solve(self, latency_std_s: float, h: np.ndarray | None = None, z: float = 0.0, var: float = 1.0) -> None:
        """Add a fix (regressors h, value z, noise variance var; None: none) and solve the fit again."""
        if h is None:
            h = np.zeros(4)  # adds exact zeros: the information as it stands
        # tiny priors keep a not-yet-excited fit invertible; the latency error's is the latency
        # estimator's std (latency.py): what a corner at one speed cannot tell from dx
        self._prior[3] = 1.0 / max(latency_std_s, 1e-3) ** 2
        if not fit_update(self.info, self.rhs, h, z, var, self._prior, self.theta, self._cov):
            return
        cov = self.cov = self._cov
        self.dx = float(self.theta[2])
        self.dx_std = math.sqrt(max(cov[2, 2], 0.0))
        if self.dx_std > MAX_FLAG_STD_FACTOR * LEVER_TOL_M:
            self.excess = abs(self.dx) if self.suspected else 0.0
            return
        if abs(self.dx) - Z_FLAG * self.dx_std > LEVER_TOL_M:
            self.flagged = True
        self.suspected = self.suspected or abs(self.dx) - Z_SUSPECT * self.dx_std > LEVER_TOL_M
        self.excess = abs(self.dx) if self.suspected else 0.0  # follows the fit (shrinks if it was noise)

    def _remember_turn(self, t: float, ratio: float) -> None:
        decayed = self.turn * math.exp(-(t - self.turn_t) / TURN_MEMORY_S) if self.turn_t > -math.inf else 0.0
        self.turn = max(ratio, decayed)
        self.turn_t = t

    def heading_std(self, t: float) -> float:
        """Course error (rad) a lever arm as wrong as the fit says makes now (0 unless suspected)."""
        if not self.suspected:
            return 0.0
        decayed = self.turn * math.exp(-max(t - self.turn_t, 0.0) / TURN_MEMORY_S)
        return self.excess * decayed


# The y component: an antenna at y_a moves along the car at vx - r y_a, so with y_a configured dy
# too far left the filter predicts a GNSS speed r dy too low, and takes the difference into vx (lever
# arm y +1 m on lowspeed_r15: vx 0.31-0.37 m/s off, within 3 std 60-68 % of the rows). Against the
# wheels (not the filter's vx, which takes part of the error) the speed residual is
#     GNSS speed - |wheel velocity at the antenna| = (scale - 1) w + dy r + dd ax
# (a wheel radius error, the lever arm error, a latency error dd along the track), three regressors
# that a drive with straights, corners and speed changes separates (on a circle alone r = w / R).
SPEED_NOISE_FIXES = 5.0  # wheel slip and GNSS speed errors are correlated over ~1 s of fixes
# m: a lever arm y error this large moves the GNSS speed by 0.15 m/s at 0.6 rad/s (a 15 m circle at
# 9 m/s), about twice the vx std published there; flagging it costs only a wider vx std in corners
LEVER_Y_TOL_M = 0.25
SCALE_STD = 0.03  # prior of the wheel scale error: tyre wear and pressure, a few per cent (radius configured)
VX_MEMORY_S = 2.0  # the wheels pull vx back within ~1 s after the corner (core.SLIP_MEMORY_S), x2


class LeverArmYCheck:
    """One receiver's lever-arm y consistency fit against the wheel speed: unknowns
    [wheel scale - 1, dy, latency error], information form, exponentially forgotten."""

    def __init__(self, lever_x: float, lever_y: float):
        self.lever_x = lever_x
        self.lever_y = lever_y
        self.info = np.zeros((3, 3))
        self.rhs = np.zeros(3)
        self.t_last = -math.inf
        self.n = 0
        self.dy = 0.0
        self.dy_std = math.inf
        self.theta = np.zeros(3)
        self.cov = None
        self._cov = np.zeros((3, 3))  # where the solves write it
        self._prior = np.array((1.0 / SCALE_STD ** 2, 1e-6, 0.0))  # the last: the latency std's
        self.gated = 0
        self.flagged = False
        self.suspected = False
        self.excess = 0.0
        self.turn = 0.0  # |r| remembered over VX_MEMORY_S
        self.turn_t = -math.inf

    def observe(self, t: float, speed: float, sigma_v: float, wheel: float, vy: float, r: float, ax: float,
                latency_std_s: float) -> None:
        """A GNSS speed of time of validity ``t``; the wheel-derived speed, the filter's vy, the
        bias-corrected yaw rate and longitudinal acceleration at that step."""
        decayed = self.turn * math.exp(-(t - self.turn_t) / VX_MEMORY_S) if self.turn_t > -math.inf else 0.0
        self.turn = max(abs(r), decayed)
        self.turn_t = t
        if not (math.isfinite(wheel) and wheel >= MIN_SPEED and speed >= MIN_SPEED):
            return
        pred = math.hypot(wheel - r * self.lever_y, vy + r * self.lever_x)
        z = speed - pred
        var = sigma_v * sigma_v * SPEED_NOISE_FIXES
        if self.n and t > self.t_last:
            f = math.exp(-(t - self.t_last) / WINDOW_S)
            self.info *= f
            self.rhs *= f
        self.t_last = t
        h = np.array((wheel, r, ax))
        if self.cov is not None:
            pred, spread = fit_predict(h, self.theta, self.cov)
            e = z - pred
            if e * e > GATE_SIGMA ** 2 * (var + spread):
                self.gated += 1
                return
        self.n += 1
        self._prior[2] = 1.0 / max(latency_std_s, 1e-3) ** 2
        if not fit_update(self.info, self.rhs, h, z, var, self._prior, self.theta, self._cov):
            return
        cov = self.cov = self._cov
        self.dy = float(self.theta[1])
        self.dy_std = math.sqrt(max(cov[1, 1], 0.0))
        if self.dy_std > MAX_FLAG_STD_FACTOR * LEVER_Y_TOL_M:
            self.excess = abs(self.dy) if self.suspected else 0.0
            return
        if abs(self.dy) - Z_FLAG * self.dy_std > LEVER_Y_TOL_M:
            self.flagged = True
        # a wider vx std is all a suspicion costs here (velocity validity does not follow the std):
        # suspected as soon as dy is both beyond the tolerance and Z_SUSPECT sigma from zero
        self.suspected = self.suspected or abs(self.dy) > max(LEVER_Y_TOL_M, Z_SUSPECT * self.dy_std)
        self.excess = abs(self.dy) if self.suspected else 0.0  # follows the fit (shrinks if it was noise)

    def vx_std(self, t: float) -> float:
        """Speed error (m/s) a lever arm y as wrong as the fit says makes now (0 unless suspected)."""
        if not self.suspected:
            return 0.0
        return self.excess * self.turn * math.exp(-max(t - self.turn_t, 0.0) / VX_MEMORY_S)
