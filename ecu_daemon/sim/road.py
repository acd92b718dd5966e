"""Road profiles whose curvature, bank and grade vary with the distance driven, as real roads do.

The constant-bank / constant-grade planes of the other drives are not what a car meets on a real
road: straights carry ~2.5 % crossfall falling to the lane's outer edge (right-hand traffic: the
road falls to the right, a positive ISO bank), curves are superelevated *into* the turn (up to
6-8 %), and the crossfall is rotated from one to the other over the transition curve (a clothoid:
curvature linear in distance, tens of metres). Grade changes along the road too. A slow
lateral-acceleration-bias state that soaks up a constant bank cannot follow a bank that changes
every few seconds: these profiles are the drives that show it.

A :class:`RoadProfile` is three piecewise-linear functions of the distance ``s`` along the road:
curvature (1/m, positive = left turn), bank (rad, ISO: positive = left side up) and grade (rad,
positive = uphill). The vehicle model looks up bank and grade at the distance the car has travelled
(gravity in its accelerometers, its wheel loads); the driver follows the centreline built from the
curvature (:meth:`RoadProfile.centreline`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RoadProfile:
    """Knots ``(s, value)`` of curvature, bank and grade; linear between, held beyond the ends."""

    curvature: tuple
    bank: tuple
    grade: tuple

    def _at(self, knots: tuple, s):
        ks = [k[0] for k in knots]
        vs = [k[1] for k in knots]
        return np.interp(s, ks, vs)

    def bank_at(self, s):
        return self._at(self.bank, s)

    def grade_at(self, s):
        return self._at(self.grade, s)

    def curvature_at(self, s):
        return self._at(self.curvature, s)

    def centreline(self, length_m: float, step_m: float = 0.5) -> np.ndarray:
        """(x, y) of the centreline every ``step_m`` in the frame of its start (x along the start's
        course, y to the left), shape (n, 2): the heading is the integral of the curvature."""
        s = np.arange(0.0, length_m + step_m, step_m)
        k = self.curvature_at(s)
        yaw = np.concatenate(([0.0], np.cumsum(0.5 * (k[1:] + k[:-1]) * step_m)))
        # midpoint rule on the heading for the position
        ym = 0.5 * (yaw[1:] + yaw[:-1])
        x = np.concatenate(([0.0], np.cumsum(np.cos(ym) * step_m)))
        y = np.concatenate(([0.0], np.cumsum(np.sin(ym) * step_m)))
        return np.stack([x, y], axis=1)


def _pct(p: float) -> float:
    return math.atan(p / 100.0)


def build_profile(segments: list, crossfall_pct: float = 2.5, grade_pct: float = 0.0,
                  grade_wavelength_m: float = 600.0, grade_phase_m: float = 0.0) -> RoadProfile:
    """A road from ``segments``: ``("straight", length)`` or ``("curve", radius (+ left, - right),
    transition length, arc length, superelevation %)``. Straights fall to the right at
    ``crossfall_pct``; a curve's superelevation (into the turn) is reached linearly over its
    transition, as its curvature is; grade is a sine of ``grade_pct`` amplitude along the road."""
    cf = _pct(crossfall_pct)
    s = 0.0
    curv = [(0.0, 0.0)]
    bank = [(0.0, cf)]
    for seg in segments:
        if seg[0] == "straight":
            s += seg[1]
            curv.append((s, 0.0))
            bank.append((s, cf))
            continue
        _, radius, trans, arc, sup_pct = seg
        k = 1.0 / radius
        b = -math.copysign(_pct(sup_pct), radius)  # left curve (radius > 0): left side lower
        curv += [(s + trans, k), (s + trans + arc, k), (s + 2 * trans + arc, 0.0)]
        bank += [(s + trans, b), (s + trans + arc, b), (s + 2 * trans + arc, cf)]
        s += 2 * trans + arc
    end = s + 2000.0  # held straight beyond the last knot (the drive may run on)
    curv.append((end, 0.0))
    bank.append((end, cf))
    grade = []
    if grade_pct:
        for x in np.arange(0.0, end + 10.0, 10.0):
            grade.append((float(x), _pct(grade_pct) * math.sin(2 * math.pi * (x + grade_phase_m) / grade_wavelength_m)))
    else:
        grade = [(0.0, 0.0), (end, 0.0)]
    return RoadProfile(tuple(curv), tuple(bank), tuple(grade))


def country_road() -> RoadProfile:
    """About 3 km of two-lane country road: alternating curves of 120-250 m radius with 40-60 m
    transitions and 4-7 % superelevation, 2.5 % crossfall on the straights, grade +-5 % on a
    500 m wavelength (driven at 15-25 m/s: 2-4 m/s^2 in the curves)."""
    segs = [("straight", 330.0),
            ("curve", 180.0, 50.0, 120.0, 5.0), ("straight", 60.0),
            ("curve", -140.0, 50.0, 110.0, 6.0), ("straight", 120.0),
            ("curve", 250.0, 60.0, 150.0, 4.0),
            ("curve", -120.0, 40.0, 100.0, 7.0), ("straight", 80.0),
            ("curve", 150.0, 45.0, 130.0, 6.0), ("straight", 150.0),
            ("curve", -200.0, 55.0, 140.0, 5.0), ("straight", 400.0)]
    return build_profile(segs, crossfall_pct=2.5, grade_pct=5.0, grade_wavelength_m=500.0, grade_phase_m=-200.0)


def handling_course() -> RoadProfile:
    """A low-speed handling course (6-11 m/s): tight alternating curves of 25-45 m radius with
    short (15-25 m) transitions and 6-8 % superelevation, grade +-6 % on a 250 m wavelength."""
    segs = [("straight", 80.0),
            ("curve", 35.0, 20.0, 60.0, 8.0), ("straight", 25.0),
            ("curve", -28.0, 15.0, 50.0, 7.0), ("straight", 20.0),
            ("curve", 45.0, 25.0, 80.0, 6.0),
            ("curve", -25.0, 15.0, 45.0, 8.0), ("straight", 40.0),
            ("curve", 30.0, 20.0, 70.0, 8.0), ("straight", 30.0),
            ("curve", -40.0, 20.0, 60.0, 6.0), ("straight", 200.0)]
    return build_profile(segs, crossfall_pct=2.5, grade_pct=6.0, grade_wavelength_m=250.0, grade_phase_m=-60.0)


#: named profiles (``road_course(profile=...)``)
PROFILES = {"country": country_road, "handling": handling_course}
