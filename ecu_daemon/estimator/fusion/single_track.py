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
"""
from __future__ import annotations

import math

import numpy as np

from .. import kalman
from ..kinematic import VX, VY

G = 9.81
MIN_SPEED = 0.5  # m/s; at low speed the relation tends to slip-free kinematics, vy = lr r
CORNER_STEPS = 330.0  # 6 ms steps in ~2 s, the correlation time of parameter/nonlinearity errors


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

    def __init__(self, k1: float, k3: float | None = None):
        self.k10 = k1
        self.k = np.array([k1, 0.6 * k1 if k3 is None else k3])
        self.P0 = np.diag([(0.4 * k1) ** 2, (0.8 * k1) ** 2])
        self.P = self.P0.copy()
        self.updates = 0
        # what the two-term law still gets wrong, relative to its regressor (learned from residuals)
        self.rel_var = (0.3 * k1) ** 2

    def predict(self, phi: float, n2: float) -> tuple[float, float]:
        """(y, variance of y from the parameter uncertainty)."""
        h0 = phi
        h1 = phi * n2
        P = self.P
        return (h0 * self.k[0] + h1 * self.k[1],
                h0 * h0 * (P[0, 0] + self.rel_var) + 2.0 * h0 * h1 * P[0, 1] + h1 * h1 * P[1, 1])

    def update(self, phi: float, n2: float, y: float, rv: float, lam: float = 0.999) -> None:
        e = rls_update(self.k, self.P, self.P0, phi, n2, y, rv, lam)
        if phi * phi * self.k10 * self.k10 > rv:  # the slip stands out of the vy noise: a model error
            rel = max(e * e - rv, 0.0) / (phi * phi)
            self.rel_var += 0.02 * (rel - self.rel_var)
        lo, hi = 0.33 * self.k10, 3.0 * self.k10
        self.k[0] = min(max(self.k[0], lo), hi)
        self.k[1] = min(max(self.k[1], -self.k10), 4.0 * self.k10)
        self.updates += 1


class SingleTrackFusion:
    def __init__(self, mass: float, yaw_inertia: float, lf: float, lr: float, cf: float, cr: float,
                 adapt: bool, learned: dict | None = None):
        learned = learned or {}
        self.lf = lf
        self.lr = lr
        self.L = lf + lr
        self.iz_m = yaw_inertia / mass
        self.mass = mass
        self.rear = AxleRls(learned.get("kappa_r", mass / cr), learned.get("kappa_r3"))
        self.front = AxleRls(learned.get("kappa_f", mass / cf), learned.get("kappa_f3"))
        self.rear.k10 = mass / cr
        self.front.k10 = mass / cf
        self.adapt = adapt
        self.base_sigma_beta = math.radians(0.25)

    def regressor_rear(self, vx: float, ay: float, rdot: float) -> float:
        return -vx * (self.lf * ay - self.iz_m * rdot) / self.L

    def regressor_front(self, vx: float, ay: float, rdot: float) -> float:
        return -vx * (self.lr * ay + self.iz_m * rdot) / self.L

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

    def model_vy(self, vx: float, r: float, ay: float, rdot: float) -> float:
        """:meth:`pseudo_measurement`'s vy alone (the same arithmetic; the fault detector's lateral
        check needs no variance, and it runs every step)."""
        phi = self.regressor_rear(vx, ay, rdot)
        n = abs(ay) / G
        k1, k3 = self.rear.k.tolist()
        return self.lr * r + (phi * k1 + phi * (n * n) * k3)

    def fuse(self, x: np.ndarray, P: np.ndarray, r: float, ay: float, rdot: float, A=None,
             every: int = 1, var_scale: float = 1.0) -> bool:
        """Fuse the pseudo-measurement; ``every``: it is fused every n-th step (noise scaled);
        ``var_scale``: its variance widened (an input is a coarse substitute)."""
        vx = x[VX]
        if vx < MIN_SPEED:
            return False
        vy_m, var = self.pseudo_measurement(vx, r, ay, rdot)
        return kalman.index_update(x, P, vy_m - x[VY], VY, var * var_scale / every, 0.0, A)

    def adapt_from(self, vx: float, vy: float, var_vy: float, r: float, ay: float, rdot: float,
                   delta: float) -> None:
        """RLS step for both axles from a well-estimated (GNSS-fused) kinematic vy."""
        # Learn only from a sideslip the kinematic filter really observes: a steady circle with
        # free accelerometer biases is not (heading error and rotated biases trade off).
        if not self.adapt or vx < 8.0 or var_vy > 0.06 ** 2:
            return
        n2 = (ay / G) ** 2
        rv = var_vy + 0.05 ** 2
        phi = self.regressor_rear(vx, ay, rdot)
        if abs(phi) > 0.05:
            self.rear.update(phi, n2, vy - self.lr * r, rv)
        if not math.isfinite(delta):
            return
        phf = self.regressor_front(vx, ay, rdot)
        if abs(phf) > 0.05:
            # alpha_f = (vy + lf r)/vx - delta = -F_yf / C_f  ->  vy + lf r - vx delta = kappa_f phf
            self.front.update(phf, n2, vy + self.lf * r - vx * delta, rv)

    def learned(self) -> dict:
        return {"kappa_r": float(self.rear.k[0]), "kappa_r3": float(self.rear.k[1]),
                "kappa_f": float(self.front.k[0]), "kappa_f3": float(self.front.k[1])}

    @property
    def cornering_stiffness_rear(self) -> float:
        return self.mass / self.rear.k[0]

    @property
    def cornering_stiffness_front(self) -> float:
        return self.mass / self.front.k[0]
