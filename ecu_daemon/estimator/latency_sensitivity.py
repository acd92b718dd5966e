"""How much of a latency error the filter's heading still carries: d x / d d per history slot.

A GNSS fix is fused at ``t_rx - delay``; with the delay off by ``d`` the course it gives is
turned by ``r d`` (``latency_consider.py``), the same on every fix of a turn: a bias, not noise.
Without a dual-antenna heading the filter cannot estimate ``d`` (only the lateral model would
separate it from a sideslip error, and it passes its own errors for one), so it fuses the course
with ``(r std)^2`` of white noise and publishes the bias on top of its heading std.

How large that bias is now is not a rule of thumb: it is linear in ``d``, ``x_err = S d``, and
``S`` follows the filter exactly (a consider analysis, Schmidt's, with ``d`` never estimated):
each step's effective transition carries it (``S_k = A_k S_{k-1}``, ``A = (I - K H) F`` with that
step's updates inside), and a late GNSS fix at stored step s, fused with gain ``K``, turns it into
``(I - K H) S + K h`` where ``h = dz/dd`` is what the latency error does to that fix (the antenna's
acceleration across the track, ``-a_perp``, for a velocity; ``r`` for a course alignment or a
dual-antenna heading). Mid-corner ``S_psi`` tends to the yaw rate (every course is turned by the
same ``r d``), as the old low-pass of ``|r|`` did; once the turn ends, the straight's courses
correct the heading at the rate the filter's own gain says, and ``S_psi`` falls with the error it
describes instead of over a fixed 5 s memory (the flying starts' heading stayed invalid 4-6 s
after a 40 deg/s corner ended while the filter had already taken the straight's courses in).
The published heading std is ``|S_psi| x latency std`` on top of the filter's own (``core.py``).

Used for the single receiver's velocity fixes while its latency error is not an augmented state;
the gain of a fix is the standard one from the stored covariance before the fix and the noise
it was fused with.
"""
from __future__ import annotations

import numpy as np

from .history import AUX_AX, AUX_AY, AUX_R, AUX_RDOT, StepHistory
from .kinematic import NX, PSI, VX, VY


def sideslip_rate(S, vx: float, vy: float) -> float:
    """|d beta / d e| of beta = atan2(vy, vx) from one step's sensitivity row S (d x / d e): the
    sideslip's share of a considered error e (this module's latency, scale_sensitivity's scale)."""
    return abs(vx * float(S[VY]) - vy * float(S[VX])) / (vx * vx + vy * vy)


class LatencySensitivity:
    """``S``: the state error per second of latency error, per history slot."""

    __slots__ = ("S", "Sr")

    def __init__(self, n: int) -> None:
        self.S = np.zeros((n, NX))
        self.Sr = list(self.S)  # per-slot row views (the per-step propagation is on the hot path)

    def step(self, i: int, ip: int, A: np.ndarray, predict: bool) -> None:
        """Carry S through step i's effective transition (after its updates)."""
        if predict:
            sens_step(A, self.Sr[ip], self.Sr[i])
        else:  # a fresh start: the initial state owes nothing to the latency
            self.Sr[i].fill(0.0)

    def heading(self, k: int) -> float:
        """|d psi / d d| at stored step k (rad per s of latency error)."""
        return abs(float(self.Sr[k % len(self.Sr)][PSI]))

    def sideslip(self, k: int, vx: float, vy: float) -> float:
        """|d beta / d d| at stored step k (rad per s of latency error), beta = atan2(vy, vx)."""
        return sideslip_rate(self.Sr[k % len(self.Sr)], vx, vy)

    def vy(self, k: int) -> float:
        """|d vy / d d| at stored step k (m/s per s of latency error)."""
        return abs(float(self.Sr[k % len(self.Sr)][VY]))

    def fused(self, hist: StepHistory, s: int, P: np.ndarray, H: np.ndarray, R: np.ndarray,
              h: np.ndarray) -> None:
        """A fix was fused at stored step s with Jacobian H and noise R against the covariance
        P it had before the fix; h = dz/dd. S at s becomes (I - K H) S + K h, carried to the present."""
        sens_fused(self.S, hist.A, P, H, R, h, s, hist.last)

    def set_heading(self, hist: StepHistory, idx: np.ndarray, J: np.ndarray, r: float) -> None:
        """The heading was set from a course at every slot idx as course + J x: the course's
        latency error r d plus what the states J reads carry."""
        self.S[idx, PSI] = np.einsum("ki,ki->k", J, self.S[idx]) + r

    def zero_heading(self, hist: StepHistory) -> None:
        """The heading was set from a source independent of the latency error (a dual-antenna align)."""
        self.S[np.arange(hist.oldest(), hist.last + 1) % hist.n, PSI] = 0.0


def timing_secant(y: np.ndarray, i0: int, dt: float, span: float, slope: float) -> float:
    """d y / d t as a latency error sees it: the largest secant (y_j - y_i0) / (t_j - t_i0) over
    the steps ``y`` holds (those the fix's true time of validity may lie in; ``i0``: the step it
    is fused at), or the tangent ``slope`` there if that is larger. Lags beyond ``span`` (3
    latency sigmas: a latency not identified yet may be anywhere in the receiver's range) count
    as ``span``, so that 3 published sigmas still reach their change.

    Why: a fix is fused with ``h = dz/dd`` linearised at its assumed step, but what it carries is
    the whole change between the assumed and the true instant. At a turn-in the yaw rate and the
    acceleration across the track grow within the window: lowspeed_r15 with a latency 0.3-0.7 s
    off aligned and fused its first corner courses at steps still on the straight (r 0.01 rad/s),
    took 4 deg into the heading and published 0.1 deg of it. Steady turning gives the tangent."""
    lag = (np.arange(len(y)) - i0) * dt
    cap = np.sign(lag) * np.minimum(np.abs(lag), span)
    cap[i0] = 1.0  # y[i0] - y[i0] = 0: the step itself is the tangent's
    sec = (y - y[i0]) / cap
    j = int(np.argmax(np.abs(sec)))
    return float(sec[j]) if abs(sec[j]) > abs(slope) else float(slope)


def across_secant_reference(aux: np.ndarray, c: np.ndarray, sn: np.ndarray, u0: float, u1: float,
                            lever_x: float, lever_y: float, dt: float, i0: int, span: float,
                            slope: float) -> float:
    """The antenna's acceleration across the track (unit vector (u0, u1) north / east) over the
    stored rows aux (the history's aux rows of the fix's timing window; c, sn: cos / sin of their
    headings), integrated to a velocity change, and its ``timing_secant`` about row i0: what a
    velocity fix at row i0 carries of a latency error (``core.Estimator._sensitivity_fused``)."""
    rr, rd = aux[:, AUX_R], aux[:, AUX_RDOT]
    bx = aux[:, AUX_AX] - rd * lever_y - rr * rr * lever_x
    by = aux[:, AUX_AY] + rd * lever_x - rr * rr * lever_y
    a_across = u1 * (bx * c + by * sn) - u0 * (bx * sn - by * c)
    return timing_secant(np.cumsum(a_across) * dt, i0, dt, span, slope)


# The kernels: numpy references here, swapped for the compiled ones (``_kernels.c``: ``sens_step``,
# ``sens_fused``; the same math, summed in index order; ``prefix_doubling``: numpy's own bits,
# checked; ``across_secant``: elementwise, the same bits) by ``backend.select``.

def sens_step_reference(A: np.ndarray, S_prev: np.ndarray, S_out: np.ndarray) -> None:
    """S_out = A S_prev: the sensitivity through one step's effective transition."""
    np.dot(A, S_prev, out=S_out)


def sens_fused_reference(S: np.ndarray, A: np.ndarray, P: np.ndarray, H: np.ndarray, R: np.ndarray,
                         h: np.ndarray, s: int, last: int) -> None:
    """S (one row per history slot, ring of len(S)) after a fix fused at step s with Jacobian H and
    noise R against the covariance P it had before: S_s <- S_s - K (H S_s - h), K the standard
    gain, then carried through the stored transitions A to step ``last``."""
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    n = len(S)
    i = s % n
    S[i] = S[i] - K @ (H @ S[i] - h)
    carry_reference(S, A, s, last)


def prefix_products(A: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """A_j ... A_{s+1} for every slot j of idx (the steps after s, in order), by doubling as
    StepHistory.correct_reference does (log2(count) whole-array matmuls instead of a rewind's
    ~80 small ones; the same bits every run)."""
    phis = A[idx]
    prefix_doubling(phis)
    return phis


def prefix_doubling_reference(phis: np.ndarray) -> None:
    """phis[j] <- phis[j] ... phis[0] in place: for d = 1, 2, 4, ...: phis[d:] = phis[d:] @ phis[:-d]."""
    d = 1
    while d < len(phis):
        phis[d:] = phis[d:] @ phis[:-d]
        d *= 2


def carry_reference(S: np.ndarray, A: np.ndarray, s: int, last: int) -> None:
    """S at every step after s from S at s: S_j = A_j ... A_{s+1} S_s."""
    n = len(S)
    idx = np.arange(s + 1, last + 1) % n
    if len(idx) == 0:
        return
    S[idx] = prefix_products(A, idx) @ S[s % n]


sens_step = sens_step_reference
sens_fused = sens_fused_reference
prefix_doubling = prefix_doubling_reference
across_secant = across_secant_reference
