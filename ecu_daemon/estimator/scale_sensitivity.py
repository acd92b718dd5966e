"""How much of a gyro scale error the filter's heading still carries: d x / d s per history slot.

A yaw rate read with a scale error ``s`` turns the integrated heading by ``s r dt`` every step:
a bias the filter does not estimate until ``yaw_scale_check.py`` has selected and applied a scale
and realigned the state. Until then the published heading std carries it. How large it is now is
not a fixed memory of the rotation (gyro17 forgot the signed rotation over 20 s): it is linear in
``s``, ``x_err = S s``, and ``S`` follows the filter exactly as ``latency_sensitivity.py`` follows
a latency error (Schmidt's consider analysis, ``s`` never estimated):

- each step ``S_k = A_k S_{k-1} + e_psi r_k dt`` (``A = (I - K H) F``, that step's model and wheel
  updates inside; the scale error enters the heading's integration of ``r``);
- a GNSS fix fused at stored step s with gain ``K`` (``dz/ds = 0``: courses do not read the gyro)
  turns ``S_s`` into ``(I - K H) S_s``; the later steps change by the same linear map carried
  through their transitions (the inputs ``r dt`` they added are unchanged);
- a course alignment sets the heading from the course: ``S_psi = J S`` (what the states the
  course reads carry), a dual-antenna alignment zeroes it.

Why it matters: in a long corner the courses read heading + sideslip and the single-track model
pulls vy, and with it the heading, only over tens of seconds, so ``S_psi`` stays near the
rotation; on a straight at speed the sideslip is model-anchored near zero and each course takes
the heading back at the filter's own gain, so ``S_psi`` falls with the error it describes (the
flying starts' heading stayed invalid ~12 s after their corner ended under the 20 s memory).
"""
from __future__ import annotations

import numpy as np

from .history import StepHistory
from .kinematic import NX, PSI, VY
from .latency_sensitivity import prefix_products, sideslip_rate


class ScaleSensitivity:
    """``S``: the state error per unit (1.0 = 100 %) of yaw-rate scale error, per history slot."""

    __slots__ = ("S", "Sr", "dt")

    def __init__(self, n: int, dt: float) -> None:
        self.S = np.zeros((n, NX))
        self.Sr = list(self.S)
        self.dt = dt

    def step(self, i: int, ip: int, A: np.ndarray, predict: bool, r: float) -> None:
        """Carry S through step i's effective transition and add this step's r dt to the heading."""
        if predict:
            scale_step(A, self.Sr[ip], self.Sr[i], PSI, r * self.dt)
        else:  # a fresh start: the initial heading owes nothing to the scale yet
            self.Sr[i].fill(0.0)

    def heading(self, k: int) -> float:
        """|d psi / d s| at stored step k (rad per unit scale error)."""
        return abs(float(self.Sr[k % len(self.Sr)][PSI]))

    def sideslip(self, k: int, vx: float, vy: float) -> float:
        """|d beta / d s| at stored step k (rad per unit scale error), beta = atan2(vy, vx): in a
        corner the courses keep heading - sideslip right, so this follows :meth:`heading`."""
        return sideslip_rate(self.Sr[k % len(self.Sr)], vx, vy)

    def vy(self, k: int) -> float:
        """|d vy / d s| at stored step k (m/s per unit scale error)."""
        return abs(float(self.Sr[k % len(self.Sr)][VY]))

    def fused(self, hist: StepHistory, s: int, P: np.ndarray, H: np.ndarray, R: np.ndarray) -> None:
        """A fix was fused at stored step s with Jacobian H and noise R against the covariance P it
        had before: S_s -= K H S_s, and every later step by the same change carried forward."""
        scale_fused(self.S, hist.A, P, H, R, s, hist.last)

    def set_heading(self, idx: np.ndarray, J: np.ndarray) -> None:
        """The heading was set from a course at every slot idx as course + J x."""
        self.S[idx, PSI] = np.einsum("ki,ki->k", J, self.S[idx])

    def zero_heading(self, hist: StepHistory) -> None:
        """The heading was set from a source independent of the gyro (a dual-antenna align)."""
        self.S[np.arange(hist.oldest(), hist.last + 1) % hist.n, PSI] = 0.0


# The kernels: numpy references here, swapped for the compiled ones by ``backend.select``
# (``_kernels.c``): ``scale_step`` / ``carry_change`` the same products with numpy's own bits,
# installed only where a probe shows they are; ``scale_fused`` the same math in one call (the gain
# summed in index order, the change carried one step at a time: not numpy's last bits; perfg23).

def scale_step_reference(A: np.ndarray, S_prev: np.ndarray, S_out: np.ndarray, i: int, r_dt: float) -> None:
    """S_out = A S_prev, then S_out[i] += r_dt (i: the heading's index)."""
    np.dot(A, S_prev, out=S_out)
    S_out[i] += r_dt


def scale_fused_reference(S: np.ndarray, A: np.ndarray, P: np.ndarray, H: np.ndarray, R: np.ndarray,
                          s: int, last: int) -> None:
    """``ScaleSensitivity.fused``'s math: with K = P H' (H P H' + R)^-1, S_s += delta = -K H S_s and
    every later step (ring of len(S) slots, up to step last) by the same change carried forward."""
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    i = s % len(S)
    delta = -(K @ (H @ S[i]))
    S[i] += delta
    # the change, not S_s, is carried: unlike the latency's, every later step added its own r dt
    carry_change(S, A, s, last, delta)


def carry_change_reference(S: np.ndarray, A: np.ndarray, s: int, last: int, delta: np.ndarray) -> None:
    """S at every step after s (a ring of len(S) slots, up to step last) += A_j ... A_{s+1} delta."""
    idx = np.arange(s + 1, last + 1) % len(S)
    if len(idx) == 0:
        return
    S[idx] += prefix_products(A, idx) @ delta


scale_step = scale_step_reference
carry_change = carry_change_reference
scale_fused = scale_fused_reference
