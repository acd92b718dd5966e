"""The GNSS latency error as what it is: one unknown shared by every fix, a state of the filter.

A fix is fused at ``t_rx - delay``; with the latency estimate off by ``d`` (true minus
estimated) its true time of validity is ``d`` earlier, so the receiver reports
``v(t_s - d) = v(t_s) - a d`` (``a``: the antenna's acceleration over ground) and a dual-antenna
heading ``psi(t_s) + r d`` (heading clockwise, yaw rate counter-clockwise). ``d`` is the same on
every fix of a manoeuvre: in a steady circle the centripetal part turns every course by the same
``r d``. Added to each fix as white noise (``a^2 std^2``) it is believed averaged away over the
fixes where it is not (single antenna: 68 % of the sideslip errors inside 3 sigma,
``tests/test_latency_consider.py``), and where the velocity and the heading of one receiver
share it (course - heading = sideslip at any latency) the white treatment loses the
cancellation: the sideslip std stayed at 0.8 deg on a dual-antenna circle whose error was 0.1.

So ``d`` is augmented to the state, the minimal way: the filter's state stays as it is, and per
receiver this keeps ``d``'s estimate and variance and its cross-covariance with the state per
stored step, carried through the same effective transitions as the covariance
(``C_k = A_k C_{k-1}``, each step's updates included) and updated with every GNSS fix of that
receiver. What the filter learns about ``d`` comes from across the track only (course against
the gyro's heading, the baseline heading): along the track the timing error stays the
bias-weighted noise of ``gnss_velocity.py``, because the speed is what ``latency.py`` identifies
the latency from, and its std is ``d``'s prior (:meth:`LatencyConsider.sync`), so nothing counts
twice. ``latency.py``'s own algorithm is untouched; its delay stays the published one.

The core uses it for a receiver while that receiver's dual-antenna heading is fresh
(``Estimator._consider``): there the heading measures the ``r d`` the course carries. Without a
baseline only the lateral dynamics' model separates a latency error from a sideslip error, and
on the simulator's low-speed circles and on Revs it passed its own errors for one.
"""
from __future__ import annotations

import math

import numpy as np

from .history import StepHistory, positive_definite
from .kinematic import NX, PSI

RESCALE_TOL = 1e-3  # relative std change below which the history is not rescaled


class LatencyConsider:
    """The filter's share of one receiver's latency error: its estimate ``d`` (s, true minus
    ``latency.py``'s), variance ``var`` and cross-covariance with the state per history slot."""

    __slots__ = ("C", "Cr", "d", "var", "std", "delay")

    def __init__(self, n: int) -> None:
        self.C = np.zeros((n, NX))  # E[x_err * d_err] (state units x s)
        self.Cr = list(self.C)  # per-slot row views (the per-step propagation is on the hot path)
        self.d = 0.0  # estimated latency error (s)
        self.var = 0.0  # its variance (s^2); 0: not yet synchronised with latency.py
        self.std = 0.0  # latency.py's std (s) that var was built on
        self.delay = math.nan  # latency.py's delay (s) that d refers to

    def step(self, i: int, ip: int, A: np.ndarray, predict: bool) -> None:
        """Carry C through step i's effective transition (after its updates)."""
        if predict:
            np.dot(A, self.Cr[ip], out=self.Cr[i])
        else:  # a fresh start: the initial state owes nothing to the latency
            self.Cr[i].fill(0.0)

    def zero_heading(self, hist: StepHistory) -> None:
        """The heading was set from a source independent of the latency error (``GnssHeadingFusion.align``)."""
        self.C[np.arange(hist.oldest(), hist.last + 1) % hist.n, PSI] = 0.0

    def set_heading(self, idx: np.ndarray, J: np.ndarray) -> None:
        """The heading was set as J x (course alignment): its cross-covariance is J C."""
        self.C[idx, PSI] = np.einsum("ki,ki->k", J, self.C[idx])

    def sync(self, hist: StepHistory, delay: float, std: float) -> None:
        """Follow ``latency.py``: its delay moving by D moves the error by -D; its std is the prior
        of ``var``, which keeps the filter's own (lateral) information on top of it. A tighter
        prior conditions the whole augmented covariance (a zero-innovation measurement of d, so
        ``P`` and ``C`` shrink with it consistently); a wider one widens d alone."""
        if not (std > 0.0 and math.isfinite(delay)):
            return
        if self.var <= 0.0:
            self.d, self.var, self.std, self.delay = 0.0, std * std, std, delay
            return
        self.d -= delay - self.delay
        self.delay = delay
        old = self.std
        if abs(std / old - 1.0) < RESCALE_TOL:
            return
        self.std = std
        own = max(1.0 / self.var - 1.0 / (old * old), 0.0)  # the filter's information on d
        want = 1.0 / (own + 1.0 / (std * std))
        if want >= self.var:
            self.var = want
        else:
            rho = self.var * want / (self.var - want)  # the pseudo-measurement's variance
            idx = np.arange(hist.oldest(), hist.last + 1) % hist.n
            C = self.C[idx]
            P = hist.P[idx] - np.einsum("ki,kj->kij", C, C) / (self.var + rho)
            P += P.transpose(0, 2, 1).copy()
            P *= 0.5
            if positive_definite(P):
                hist.P[idx] = P
                self.C[idx] = C * (rho / (self.var + rho))
            self.var = want
        bound = 3.0 * std  # the filter's lateral view never outvotes latency.py by more than 3 sigma
        self.d = min(max(self.d, -bound), bound)

    def late_update(self, P: np.ndarray, c: np.ndarray, H: np.ndarray, h: np.ndarray, R: np.ndarray,
                    y: np.ndarray, dx: np.ndarray, M: np.ndarray) -> tuple[float, tuple]:
        """Update of the augmented state [x, d] at a stored step (state covariance P,
        cross-covariance c, measurement Jacobian H on the state and h on d, noise R, innovation y
        of the state alone), not applied: dx <- K y, M <- K S K' (the state's covariance
        reduction, for ``StepHistory.correct``); returns the normalised innovation squared (NaN:
        S not positive definite) and what :meth:`commit` applies once the correction went through."""
        var = self.var
        y = y - h * self.d
        Hc = H @ c
        zd = Hc + var * h  # cov(z, d)
        U = P @ H.T + np.outer(c, h)  # cov(x, z)
        S = H @ P @ H.T + np.outer(Hc, h) + np.outer(h, Hc) + var * np.outer(h, h) + R
        S = 0.5 * (S + S.T)
        if not (S[0, 0] > 0.0 and np.linalg.det(S) > 0.0):
            return math.nan, ()
        Sinv = np.linalg.inv(S)
        K = U @ Sinv
        kd = Sinv @ zd
        dx[:] = K @ y
        M[:] = K @ U.T
        M += M.T.copy()
        M *= 0.5
        return float(y @ Sinv @ y), (c - K @ zd, float(kd @ y), max(var - float(zd @ kd), 1e-12))

    def commit(self, hist: StepHistory, s: int, update: tuple) -> None:
        """After the correction at step s went through: d and its variance, and the new C at s
        carried to the present."""
        c, dd, self.var = update
        self.d += dd
        n = hist.n
        Cr = self.Cr
        Ar = hist.Ar
        Cr[s % n][:] = c
        for j in range(s + 1, hist.last + 1):
            np.dot(Ar[j % n], Cr[(j - 1) % n], out=Cr[j % n])


def antenna_acceleration_ned(psi: float, ax: float, ay: float, r: float, rdot: float,
                             lever_x: float, lever_y: float) -> tuple[float, float]:
    """The antenna's acceleration over ground [north, east] from the body's (bias-corrected
    specific force at the CG, yaw rate and yaw acceleration; heading clockwise from north, y left):
    the derivative of ``generated.gnss_velocity``."""
    bx = ax - rdot * lever_y - r * r * lever_x
    by = ay + rdot * lever_x - r * r * lever_y
    c, s = math.cos(psi), math.sin(psi)
    return bx * c + by * s, bx * s - by * c
