"""vx at the friction limit: the wheels slip under ABS far beyond the linear slip law (issue 7, mode B).

Found by tools/random_drives.py (seeds 12, 64, 83, 159, 193, 210; report randdrive32): braking in a
corner on a road that rain has made slippery, the ABS holds the wheels ~13 % below the car (1.6 m/s
at 12 m/s) while the linear law (|ax| / (15 g) vx) allows 0.3 m/s, and vx stayed valid 1.5 m/s off
at a 0.25-0.5 m/s std (on integ32: 144 of 9122 valid rows beyond 3 sigma, worst 1.46 m/s).
Replayed end to end through the suite's own scoring (simulate, CAN/GNSS files, replay, evaluate).
"""
from __future__ import annotations

from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.suite import run_case


def test_braking_in_a_corner_after_rain_keeps_the_vx_promise(tmp_path):
    sc = Scenario("brake_turn_rain", "brake_turn", mu=0.78, mu_change=(21.2, 0.4))
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["vx_coverage_3sigma"] >= 0.99, row["vx_coverage_3sigma"]
    # the slip is not hidden by invalidity: the drive's vx stays published (the ABS' slip is bounded,
    # not unknown), and its worst valid error is the ABS slip, not more
    assert row["vx_worst_valid_mps"] <= 2.0, row["vx_worst_valid_mps"]
