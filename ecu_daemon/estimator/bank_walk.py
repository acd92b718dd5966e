"""Process noise of the lateral-acceleration-bias state ``b_ay`` from the road, not the clock.

``b_ay`` holds the accelerometer's offset plus gravity's share of the road bank, ``g sin(bank)``.
Its time-driven walk (``accel_bias_walk``) covers a sensor's drift; a real road's bank changes
with *where* the car is: ~2.5 % crossfall on straights, superelevation into each curve (up to
6-8 %), rotated from one to the other over the transition curve as the curvature builds up. So
the bank moves where the road's curvature changes, and its walk is charged per change of
curvature: ``var(b_ay) += K |d kappa|``, ``kappa`` the path curvature ``r / vx`` low-passed over
``DISTANCE_M`` of travel (a lane change or a slalom swings the yaw rate without curving the
road, and mostly averages out). ``K``: entering a 30 m radius curve (d kappa 0.033) lets the bank
move by 0.32 m/s^2 (1.8 deg) at one sigma, a 150 m curve 0.14 m/s^2 (0.8 deg); the crossfall-to-
superelevation change of roads built to the usual design tables is 3-6 deg (sim/road.py drives
such roads; suite family ``road_profile``), which GNSS velocity then re-learns in the corner.
Larger K follows the bank faster but costs sideslip availability on every drive (K 5: three suite
rows, among them the banked circle's bank RMS, which the walk lets wander; K 10: eight).
"""
from __future__ import annotations

K_CURVATURE = 3.0  # (m/s^2)^2 per 1/m of curvature change: the bank's variance per curve entry
DISTANCE_M = 60.0  # the road's curvature, not the steering's: low-pass over this much travel
MIN_SPEED = 1.0  # m/s: below, r / vx is not a path curvature


class BankWalk:
    """Adds the road-driven variance to ``P[j, j]`` each step (``j`` = the b_ay index)."""

    def __init__(self, dt: float, k: float = K_CURVATURE, distance_m: float = DISTANCE_M):
        self.dt = dt
        self.k = k
        self.distance_m = distance_m
        self.kappa = 0.0
        self.total = 0.0  # (m/s^2)^2: all the variance added so far (road.py counts it in the roll)

    def step(self, P, j: int, vx: float, r: float) -> None:
        v = abs(vx)
        if v <= MIN_SPEED or self.k <= 0.0:
            return
        a = min(1.0, v * self.dt / self.distance_m)
        dk = a * (r / v - self.kappa)  # the yaw per metre travelled (either way)
        self.kappa += dk
        q = self.k * abs(dk)
        P[j, j] += q
        self.total += q
