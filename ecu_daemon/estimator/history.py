"""Ring buffer of past filter steps, and the "measurement shift" for late measurements.

Every 6 ms step stores its posterior state and covariance, the *effective* transition that step
applied (``A = (I - K H) F``: the prediction followed by whatever was fused at that step) and a few
inputs. A GNSS sample that arrives late is fused against the stored step at its time of validity
``s``; the correction (dx, and the covariance reduction ``M = K H P_s``) is then carried forward to
every later step, and so to the present, through the stored transitions::

    x_j += Phi_j dx          P_j -= Phi_j M Phi_j'        Phi_j = A_j A_{j-1} ... A_{s+1}

This is the re-filtering of Yoon (000 §3.3.1) and Larsen et al. done with stored linearisations: it
is exact for the linearised system (the later measurement updates are inside ``A``), costs one
7x7 product per step of delay, and leaves the whole history consistent, so the next late sample
(GNSS at 5 Hz with 0.4 s latency has two in flight) is fused against corrected states.
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

    def correct(self, s: int, dx: np.ndarray, M: np.ndarray) -> None:
        """Apply a correction computed at stored step s and carry it to every later step."""
        n = self.n
        i = s % n
        self.X[i] += dx
        self.P[i] -= M
        count = self.last - s
        if count <= 0:
            self._wrap(np.array([i]))
            return
        idx = np.arange(s + 1, self.last + 1) % n
        # Prefix products Phi_j = A_j ... A_{s+1} by doubling (Hillis-Steele scan): log2(count)
        # whole-array matmuls instead of count small ones (~4x faster here; same bits each run).
        phis = self.A[idx]
        d = 1
        while d < count:
            phis[d:] = phis[d:] @ phis[:-d]
            d *= 2
        self.X[idx] += phis @ dx
        self.P[idx] -= phis @ M @ phis.transpose(0, 2, 1)
        self._wrap(np.append(idx, i))

    def _wrap(self, idx: np.ndarray) -> None:
        self.X[idx, PSI] %= 2.0 * math.pi
