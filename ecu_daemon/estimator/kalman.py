"""Measurement updates shared by every aiding source (one small function, FilterPy-style).

Each update also returns ``I - K H`` so the step history can fold it into the step's effective
transition; that is what lets a late GNSS correction be carried forward exactly through the later
updates (see ``history.py``).
"""
from __future__ import annotations

import numpy as np

from .kinematic import NX

_I = np.eye(NX)


def scalar_update(x: np.ndarray, P: np.ndarray, innovation: float, h_row: np.ndarray, R: float,
                  gate_sigma: float = 0.0) -> np.ndarray | None:
    """Fuse one scalar measurement in place. Returns I - K h (7x7), or None if gated out."""
    Ph = P @ h_row
    S = float(h_row @ Ph) + R
    if not S > 0.0:
        return None
    if gate_sigma > 0.0 and innovation * innovation > gate_sigma * gate_sigma * S:
        return None
    K = Ph / S
    x += K * innovation
    P -= np.outer(K, Ph)
    return _I - np.outer(K, h_row)


def index_update(x: np.ndarray, P: np.ndarray, innovation: float, i: int, R: float,
                 gate_sigma: float = 0.0) -> np.ndarray | None:
    """:func:`scalar_update` for a direct measurement of state ``i`` (h = e_i), cheaper."""
    Pi = P[:, i].copy()
    S = Pi[i] + R
    if not S > 0.0:
        return None
    if gate_sigma > 0.0 and innovation * innovation > gate_sigma * gate_sigma * S:
        return None
    K = Pi / S
    x += K * innovation
    P -= np.outer(K, Pi)
    IKH = _I.copy()
    IKH[:, i] -= K
    return IKH


def vector_update(x: np.ndarray, P: np.ndarray, innovation: np.ndarray, H: np.ndarray, R: np.ndarray):
    """Fuse a small vector measurement in place. Returns (I - K H, K, S)."""
    PHt = P @ H.T
    S = H @ PHt + R
    K = PHt @ np.linalg.inv(S)
    x += K @ innovation
    P -= K @ PHt.T
    return _I - K @ H, K, S


def symmetrize(P: np.ndarray) -> None:
    P += P.T
    P *= 0.5
