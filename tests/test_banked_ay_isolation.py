"""A fault-free lateral accelerometer on a banked road is not isolated (issue 7: invalid while right).

Why (avail42's census, tools/withheld.py, main b26daff on the never-seen drives 1681-1920): with an
IMU signal isolated the single-track model's vy bound is off and the sideslip is withheld on its
filter std. On fault-free banked drives that withheld 56,596 counted rows, 34,949 of them right
(1710, 1729, 1796, 1892, 1748, 1757). ``FaultDetector._yaw`` judges ay by
``r - (ay - lr rdot) / vx`` against ``YAW_SLOW_TOL + YAW_SLOW_TOL_REL |r|`` (0.02 rad/s + 0.12 |r|),
a tolerance for a flat road: the bank's gravity g sin(bank) / vx is at or beyond it at each onset
(1729: t+22.6 s, bank -0.022 rad at 6.5 m/s, 0.034 against 0.029 rad/s).

Fixed (bankay42): a road's bank changes by at most ``bank_rate.BANK_RATE_M`` per metre, and an ay
offset that changes no faster is followed by ``b_ay`` exactly as the bank is, so the slow ay test's
tolerance widens by what the bank may change within its window (``fault_detection.AY_BANK_RATE_ALLOWANCE``,
bank_rate.py). With the flag off this test fails (``ay isolated from t+22.9 s``); with it on it passes.
The suite's ay step faults (``fault_accel_y_*``) stay isolated as on main.

The allowance is off by default since stop 43 (it also passed cars sliding on ice as a bank: never-seen
drives 2254, 2175, 2275, 2356; README); this test keeps its mechanism checked with it on.
"""
from __future__ import annotations

import numpy as np

from tools_import import load_tool

SEED = 1729  # road course, mu 0.32, banks up to 8 %, no sensor fault
DURATION_S = 40.0  # ay isolated from t+22.6 s on main
ACCEL_Y_ISOLATED = 1 << 11


def test_fault_free_ay_on_a_banked_road_is_not_isolated(tmp_path, monkeypatch):
    from ecu_daemon.estimator import fault_detection
    monkeypatch.setattr(fault_detection, "AY_BANK_RATE_ALLOWANCE", True)
    rd = load_tool("random_drives")
    sc = rd.draw(SEED)
    assert not sc.sensors.faults and not sc.gnss.faults
    d = rd.run_drive(SEED, str(tmp_path), DURATION_S)
    assert d["error"] is None, d["error"]
    e = np.genfromtxt(tmp_path / d["name"] / "estimate.csv", delimiter=",", names=True, usecols=("t", "status"))
    isolated = (e["status"].astype(np.int64) & ACCEL_Y_ISOLATED) != 0
    assert not isolated.any(), f"ay isolated from t+{e['t'][isolated][0] - e['t'][0]:.1f} s"
