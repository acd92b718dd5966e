"""Two never-seen breakers traced in reinit44 (issue 7): 2225 fixed in stop 50, 2286 in stop 49.

2225 (double lane change, FWD, mu 0.95, bank -3.97 deg): on the straight before the lane change (1212-1220 s,
22 m/s, MODEL_FALLBACK) the tyres carry m g sin(bank) (true rear slip -0.38 deg), b_ay holds that gravity
share correctly, and the single-track pseudo-measurement takes ay with b_ay removed: "no lateral force,
vy = 0" at the model's straight-line std (0.05 m/s). Sideslip valid -0.41..-0.44 deg off at 0.14 deg, 88
rows beyond 3 sigma (main d1a0953). The drive-slip rule already takes the force bank in
(fusion/tyre_lateral_force.py); the model does since core.MODEL_TYRE_FORCE is on (stop 50: this test's
strict xfail XPASSed).

2286 (steady circle, RWD, mu 1.10 -> 0.62): ploughing (front slip -20 deg) and braking from 1262 s, one
wheel isolated; the GNSS latency estimate runs 0.207 -> 0.283 s (true 0.167) over 1260-1263 s: braked,
slipping wheels read low while the speed falls, which the identification (GNSS speed on the wheels) takes
for a longer delay. 0.116 s x r 0.32 rad/s = 2.1 deg of course, taken into the sideslip: valid -2.57 deg
off at 0.66 deg (84 rows beyond 3 sigma). The model is not involved (its excess is 3-16 (m/s)^2 there).
Fixed by latency.TIMING_INFORMATION (stop 49): a refutation of the current delay needs the information to
make it; worst valid sideslip 2.28 deg with it off, 0.85 with it on (lead, `tog.py --pure`, integ49).
"""
from __future__ import annotations

import math

import pytest
from tools_import import load_tool


def test_2225_sideslip_on_a_banked_straight_within_3_sigma(tmp_path):
    rd = load_tool("random_drives")
    d = rd.run_drive(2225, str(tmp_path), None)
    assert d["error"] is None, d["error"]
    assert d["figures"]["sideslip"]["beyond_3sigma"] == 0, d["figures"]["sideslip"]["beyond_3sigma"]


def test_2286_sideslip_while_braking_a_ploughing_circle_within_2_deg(tmp_path):
    rd = load_tool("random_drives")
    d = rd.run_drive(2286, str(tmp_path), None)
    assert d["error"] is None, d["error"]
    assert d["figures"]["sideslip"]["worst_error_valid"] < math.radians(2.0), \
        math.degrees(d["figures"]["sideslip"]["worst_error_valid"])
