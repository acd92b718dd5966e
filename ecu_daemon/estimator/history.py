"""Ring buffer of past filter steps, and the "measurement shift" for late measurements.

Every 6 ms step stores its posterior state and covariance, the *effective* transition that step
applied (``A = (I - K H) F``: the prediction followed by whatever was fused at that step) and a few
inputs. A GNSS sample that arrives late is fused against the stored step at its time of validity
``s``; the correction (dx, and the covariance reduction ``M = K H P_s``) is then carried forward to
every later step, and so to the present, through the stored transitions::

    x_j += Phi_j dx          P_j -= Phi_j M Phi_j'        Phi_j = A_j A_{j-1} ... A_{s+1}

This is the re-filtering of Yoon (000 §3.3.1) and Larsen et al. done with stored linearisations: it
is exact for the linearised system (the later measurement updates are inside ``A``), costs one
8x8 product per step of delay, and leaves the whole history consistent, so the next late sample
(GNSS at 5 Hz with 0.4 s latency has two in flight) is fused against corrected states.

Every corrected covariance is made exactly symmetric and checked positive definite (Cholesky);
if one is not, the correction is undone and refused: a filter that believes a variance <= 0 is
valid-while-wrong from then on. ``correct_reference`` is the numpy version; ``backend.py``
swaps in the compiled one (the same math, carried step by step, M = K S K' through its low-rank
factor K) as ``correct``.
"""
from __future__ import annotations

import math

import numpy as np

from .kinematic import NX, PSI

# auxiliary per-step values (columns of ``aux``)
AUX_R = 0  # bias-corrected yaw rate, rad/s
AUX_AY = 1  # bias-corrected lateral acceleration, m/s^2
AUX_RDOT = 2  # low-passed yaw acceleration, rad/s^2
AUX_WHEEL = 3  # wheel-derived speed (raw, configured radius), m/s; NaN if unknown
AUX_DELTA = 4  # road-wheel steering angle, offset-corrected, rad
AUX_AX = 5  # bias-corrected longitudinal acceleration, m/s^2
NAUX = 6


class StepHistory:
    def __init__(self, length: int):
        self.n = length
        self.X = np.zeros((length, NX))
        self.P = np.zeros((length, NX, NX))
        self.A = np.zeros((length, NX, NX))
        self.aux = np.zeros((length, NAUX))
        # per-slot row views (list indexing is several times cheaper than numpy's, per step)
        self.Xr = list(self.X)
        self.Pr = list(self.P)
        self.Ar = list(self.A)
        self.auxr = list(self.aux)
        self.first = 0  # first step index stored since the last reset
        self.last = -1  # last step index stored

    def reset(self, first_step: int) -> None:
        self.first = first_step
        self.last = first_step - 1

    def oldest(self) -> int:
        return max(self.first, self.last - self.n + 1)

    def slot(self, k: int) -> int:
        return k % self.n

    def clamp_step(self, k: int) -> tuple[int, bool]:
        """The stored step nearest to k; second value True if k was older than the buffer."""
        old = self.oldest()
        if k < old:
            return old, True
        if k > self.last:
            return self.last, False
        return k, False

    def correct_reference(self, s: int, dx: np.ndarray, M: np.ndarray) -> bool:
        """Apply a correction computed at stored step s and carry it to every later step.

        False (and nothing changed) if a corrected covariance would not be positive definite."""
        n = self.n
        idx = np.arange(s, self.last + 1) % n
        X = self.X[idx]  # copies: written back only once every covariance checks out
        P = self.P[idx]
        X[0] += dx
        P[0] -= M
        if len(idx) > 1:
            # Prefix products Phi_j = A_j ... A_{s+1} by doubling (Hillis-Steele scan): log2(count)
            # whole-array matmuls instead of count small ones (~4x faster here; same bits each run).
            phis = self.A[idx[1:]]
            d = 1
            while d < len(phis):
                phis[d:] = phis[d:] @ phis[:-d]
                d *= 2
            X[1:] += phis @ dx
            P[1:] -= phis @ M @ phis.transpose(0, 2, 1)
        P += P.transpose(0, 2, 1).copy()
        P *= 0.5
        if not positive_definite(P):
            return False
        X[:, PSI] %= 2.0 * math.pi
        self.X[idx] = X
        self.P[idx] = P
        return True

    correct = correct_reference


def positive_definite(P: np.ndarray) -> bool:
    """True if every matrix of the stack P is (numerically) positive definite and finite."""
    if not np.isfinite(P).all():
        return False
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return False
    return True
