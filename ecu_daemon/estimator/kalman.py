"""Measurement updates shared by every aiding source (small functions, FilterPy-style).

Covariance updates are in Joseph form, ``P <- (I - K h') P (I - K h')' + K R K'``: it stays
symmetric and positive semi-definite under rounding, where ``P - K h' P`` can drift negative
over the millions of updates of a long drive. Each update also folds ``I - K h'`` into the
step's effective transition ``A`` (in place, as ``A -= K (h' A)``, cheaper than forming the
matrix); that is what lets a late GNSS correction be carried forward exactly through the later
updates (see ``history.py``).

These are the pure-Python (numpy) reference; ``backend.py`` swaps in the compiled ones under the
names without ``_reference``. Callers look them up on this module at call time (``kalman.x``).
"""
from __future__ import annotations

import numpy as np


def joseph(P: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """(I - K H) P (I - K H)' + K R K' for a vector measurement (K: n x m, H: m x n, R: m x m)."""
    B = P - K @ (H @ P)
    return B - (B @ H.T) @ K.T + K @ R @ K.T


def scalar_update_reference(x: np.ndarray, P: np.ndarray, innovation: float, h_row: np.ndarray, R: float,
                            gate_sigma: float = 0.0, A: np.ndarray | None = None) -> bool:
    """Fuse one scalar measurement in place (x, P, and A <- (I - K h') A). False if gated out."""
    Ph = P @ h_row
    S = float(h_row @ Ph) + R
    if not S > 0.0:
        return False
    if gate_sigma > 0.0 and innovation * innovation > gate_sigma * gate_sigma * S:
        return False
    K = Ph / S
    x += K * innovation
    # outer products as broadcast multiplies: what np.outer computes (the same ufunc on the same
    # operands, the same bits) without its Python-level wrapper, ~1/3 of this update's cost; the
    # road filters (road.py) run this at every fused sample
    Kc = K[:, None]
    P -= Kc * Ph  # (I - K h') P
    Bh = P @ h_row
    P -= Bh[:, None] * K
    P += R * (Kc * K)
    if A is not None:
        A -= Kc * (h_row @ A)
    return True


def index_update_reference(x: np.ndarray, P: np.ndarray, innovation: float, i: int, R: float,
                           gate_sigma: float = 0.0, A: np.ndarray | None = None) -> bool:
    """:func:`scalar_update_reference` for a direct measurement of state ``i`` (h = e_i), cheaper."""
    Pi = P[:, i].copy()
    S = Pi[i] + R
    if not S > 0.0:
        return False
    if gate_sigma > 0.0 and innovation * innovation > gate_sigma * gate_sigma * S:
        return False
    K = Pi / S
    x += K * innovation
    Kc = K[:, None]  # np.outer as a broadcast multiply (scalar_update_reference: the same bits)
    P -= Kc * Pi
    P -= P[:, i].copy()[:, None] * K
    P += R * (Kc * K)
    if A is not None:
        A -= Kc * A[i]
    return True


def late_update_reference(P: np.ndarray, H: np.ndarray, R: np.ndarray, y: np.ndarray, dx: np.ndarray,
                          M: np.ndarray) -> float:
    """A 1- or 2-D update at a stored step, not applied: dx <- K y, M <- P - Joseph(P) (for
    ``StepHistory.correct``); returns the normalised innovation squared (NaN: S not PD)."""
    PHt = P @ H.T
    S = H @ PHt
    S = 0.5 * (S + S.T) + R
    if not (S[0, 0] > 0.0 and np.linalg.det(S) > 0.0):
        return float("nan")
    Sinv = np.linalg.inv(S)
    K = PHt @ Sinv
    dx[:] = K @ y
    M[:] = P - joseph(P, K, H, R)
    symmetrize_reference(M)
    return float(y @ Sinv @ y)


def symmetrize_reference(P: np.ndarray) -> None:
    """P <- (P + P') / 2 in place: exactly symmetric."""
    P += P.T.copy()
    P *= 0.5


scalar_update = scalar_update_reference
index_update = index_update_reference
late_update = late_update_reference
symmetrize = symmetrize_reference
