"""Measurement updates shared by every aiding source (one small function, FilterPy-style).

Each update also folds ``I - K h'`` into the step's effective transition ``A`` (in place, as
``A -= K (h' A)``, cheaper than forming the matrix); that is what lets a late GNSS correction be
carried forward exactly through the later updates (see ``history.py``).
"""
from __future__ import annotations

import numpy as np


def scalar_update(x: np.ndarray, P: np.ndarray, innovation: float, h_row: np.ndarray, R: float,
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
    P -= np.outer(K, Ph)
    if A is not None:
        A -= np.outer(K, h_row @ A)
    return True


def index_update(x: np.ndarray, P: np.ndarray, innovation: float, i: int, R: float,
                 gate_sigma: float = 0.0, A: np.ndarray | None = None) -> bool:
    """:func:`scalar_update` for a direct measurement of state ``i`` (h = e_i), cheaper."""
    Pi = P[:, i].copy()
    S = Pi[i] + R
    if not S > 0.0:
        return False
    if gate_sigma > 0.0 and innovation * innovation > gate_sigma * gate_sigma * S:
        return False
    K = Pi / S
    x += K * innovation
    P -= np.outer(K, Pi)
    if A is not None:
        A -= np.outer(K, A[i])
    return True
