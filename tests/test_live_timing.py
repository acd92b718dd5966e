"""Input timing a live run does not control must not decide the sideslip (issues 7 and 10).

A live daemon starts at an arbitrary phase of its 6 ms step grid, and reads the GNSS port when its
loop gets round to it (the pty/serial read time is the receive time: 0.2 ms late at the median,
34-43 ms at p99 on a loaded machine, live49's four demo runs). Neither changes the drive. Yet the
demo drive replayed offline by the time rule at six grid phases (c0 = 1000 s + 0..5 ms,
``tools/grid_phase.py``) gave sideslip RMS 0.092-0.229 deg, and four live runs 0.096-0.186 while
their recordings replayed to the same bits (tests/test_daemon_replay.py).

Mechanism (traced, live49): the GNSS latency identification. Each candidate delay reads one stored
wheel sample; the wheels come at 100 Hz onto the 6 ms grid, so which candidate reads which sample
(and which noise) depends on the phase, and the likelihood ratio of the right delay (0.4 s, the
prior) wanders about LR_REJECT = 16 in the 0.8 g circle (40-60 s). Where it crosses, the delay
walks to 0.41-0.42 s, and a fix dated 12-18 ms off in a circle at r = 0.49 rad/s turns the GNSS
course by r * d = 0.35-0.5 deg: the circle's sideslip bin goes 0.18 -> 0.36-0.52 deg RMS. With
the latency held at its (true) prior the six phases give 0.118-0.125; with the wheels' profile
averaged over 0.1 s (``latency.WHEEL_SMOOTH_S``, off by default: see its comment) the delay stays
at 0.4 s through the circle at every phase (0.089-0.096 over the six; live, three demo runs at
load 17-18: 0.082-0.097).

What ships (latsm49, ``latency.TIMING_INFORMATION``): the data refute the current delay only
if the information the references carry could put the test between it and the best candidate;
the circle's ragged wheel profile carries none, so the right prior stays at every phase
(lead, pure Python, integ49: 0.090-0.101 deg over the four cases). The old refutation is kept as
the strict xfail beside it: the test fails on it.
"""
from __future__ import annotations

import numpy as np
import pytest

from ecu_daemon.estimator import latency
from ecu_daemon.io.logging_setup import setup_logging
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from tools_import import load_tool

LVR = load_tool("live_vs_replay")

pytestmark = pytest.mark.slow

#: (grid phase in ms after c0 = 1000 s, GNSS read lateness: uniform 0..this many ms, seeded)
CASES = [(0.0, 0.0), (3.0, 0.0), (5.0, 0.0), (0.0, 3.0)]
#: deg: the spread allowed over the cases (held latency: 0.007 over six phases, 0.014 with the
#: 0-3 ms lateness; the old refutation: 0.137 over six phases; what ships: 0.011 over the cases)
SPREAD_DEG = 0.03


@pytest.fixture(scope="module")
def demo_drive():
    setup_logging("error")
    sc = SCENARIOS["demo"]
    return sc, simulate(sc, vehicle_config(sc))


def _sideslip_rms(sc, sim, phase_ms: float, late_ms: float) -> float:
    """The drive on the daemon clock from ``c0``, fed item by item by the time rule (as a recording
    without tick record replays; ``tools/live_vs_replay.py``'s replay), GNSS receive times made
    late as a loaded loop reads them."""
    c0 = 1000.0 + phase_ms * 1e-3
    can, gnss = LVR.drive_items(sim, c0)
    late = np.random.default_rng(7).uniform(0.0, late_ms * 1e-3, len(gnss))
    gnss = [(float("%.6f" % (t + dl)), kind, fid, p) for (t, kind, fid, p), dl in zip(gnss, late)]
    ests = LVR.replay(vehicle_config(sc), sorted(can + gnss, key=lambda e: (e[0], e[1])))
    return LVR.score(sim, c0, ests)[0]


@pytest.mark.parametrize("timing_information", [
    True,
    pytest.param(False, marks=pytest.mark.xfail(strict=True, reason="live49: without the information test the"
                                                " refutation hangs on the step-grid phase (0.092-0.229 deg)"))])
def test_sideslip_does_not_depend_on_the_grid_phase_or_gnss_read_lateness(demo_drive, monkeypatch,
                                                                          timing_information):
    monkeypatch.setattr(latency, "TIMING_INFORMATION", timing_information)
    sc, sim = demo_drive
    got = [_sideslip_rms(sc, sim, ph, late) for ph, late in CASES]
    print(f"TIMING_INFORMATION {timing_information}: sideslip RMS {[round(g, 4) for g in got]} deg over {CASES}")
    assert max(got) < 0.3  # the product's bar, at every phase
    assert max(got) - min(got) <= SPREAD_DEG, got
