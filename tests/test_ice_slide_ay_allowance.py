"""A car sliding on ice is not a road's bank: sideslip is not promised 17 deg off (issue 7: the worst defect).

Why (never-seen random drive 2254, stop 43: a double lane change on mu 0.21 dropping to 0.10, flat road,
the car slides out and spins): with bankay42's allowance (``fault_detection.AY_BANK_RATE_ALLOWANCE``: the
slow ay test widened by g x the bank a road may change within its window, 1.0 m/s^2 at 12 m/s) the
slide's ``ay - r vx`` (0.8 m/s^2, the sideslip's own rate, all the grip mu g the road has) fitted inside
the allowance, ay was not isolated, and the sideslip was published valid at -0.2..+0.4 deg +- 0.6 for a
true -17.6 deg (40 rows, t+44.3 s). Without the allowance (main before stop 42) ay is isolated there and
the sideslip withheld: 0 rows beyond 3 sigma. The allowance is off until it can tell a bank from a slide
(the same stop it added 884 heading rows beyond 3 sigma on 2175 and 215 sideslip rows on 2275).
"""
from __future__ import annotations

import math

import numpy as np

from tools_import import load_tool

SEED = 2254
DURATION_S = 47.0  # the slide's valid rows are at t+44.3-44.5 s


def test_sliding_on_ice_is_not_promised(tmp_path):
    rd = load_tool("random_drives")
    sc = rd.draw(SEED)
    assert sc.bank_rad == 0.0 and not sc.sensors.faults  # a flat road, no sensor fault: the slide is real
    d = rd.run_drive(SEED, str(tmp_path), DURATION_S)
    assert d["error"] is None, d["error"]
    out = tmp_path / d["name"]
    e = np.genfromtxt(out / "estimate.csv", delimiter=",", names=True,
                      usecols=("t", "sideslip_rad", "sideslip_std_rad", "sideslip_valid"))
    tr = np.genfromtxt(out / "truth.csv", delimiter=",", names=True, usecols=("t", "sideslip_rad"))
    valid = e["sideslip_valid"] == 1
    err = np.abs(e["sideslip_rad"] - np.interp(e["t"], tr["t"], tr["sideslip_rad"]))
    beyond = valid & (err > 3.0 * e["sideslip_std_rad"])
    assert valid.any()
    assert not beyond.any(), (f"{beyond.sum()} valid rows beyond 3 sigma, worst {math.degrees(err[beyond].max()):.1f} deg"
                              f" from t+{e['t'][beyond][0] - e['t'][0]:.1f} s")
