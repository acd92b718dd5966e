"""Issue 10 (perf41): the estimator's every-step state stays Python floats, never numpy scalars.

Why: a numpy float64 read out of an array (``x[VX]``, ``P[i, j]``, ``Xr[k][BR]``) and kept in a
low-pass (the yaw rate's ``r_lp``, its derivative ``rdot``)
makes every value later computed from it a numpy scalar, for the rest of the drive: on main the
fault detector's yaw checks, the tyre laws and the model's inputs all ran numpy scalar arithmetic
(``double_multiply``, ``gentype_alloc``, the FP-status checks: ~1 k instructions an operation
against ~50 for a float's). The doubles are the same either way (the same IEEE operations in the
same order), so no output bit depends on the type; the per-step instruction count does
(callgrind, bench_estimator's dlc_dry drive, plain Python: see DEVELOPERS.md's performance
paragraph). This test keeps a numpy scalar from leaking back into that state unseen.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ecu_daemon.estimator import Estimator
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config

sys.path.insert(0, str(Path(__file__).resolve().parent))
from drive_samples import decoded_events  # noqa: E402


def _sampled_through_dlc_dry(types_of) -> tuple:
    """The dlc_dry drive through a real Estimator, ``types_of(est)`` every 250th step once
    initialised: the estimator at the end and those samples."""
    sc = SCENARIOS["dlc_dry"]
    cfg = vehicle_config(sc)
    est = Estimator(cfg)
    seen = []
    n = 0
    for t, kind, s in decoded_events(cfg, simulate(sc, cfg)):
        (est.push_gnss if kind else est.push_input)(s)
        for _ in est.advance_to(t - 1e-6):
            n += 1
            if est.initialized and n % 250 == 0:
                seen.append(types_of(est))
    return est, seen


def _state_types(est: Estimator) -> dict:
    st = est.single_track
    phi = st.regressor_rear(20.0, 3.0, est.rdot)
    # (its variance is left out: the law's learned error, rel_var, is a numpy scalar once the
    # per-drive regression has been adopted, take_drive_estimate; set at a fix, not every step)
    y, _ = st.rear.predict(phi, 0.1, True)
    return {"r_lp": type(est.r_lp), "rdot": type(est.rdot), "model_inputs.ay": type(est.model_inputs.ay),
            "rear.predict y": type(y)}


def test_the_every_step_low_passes_are_python_floats_through_a_drive():
    est, seen = _sampled_through_dlc_dry(_state_types)
    assert len(seen) > 10
    bad = {k: v for types in seen for k, v in types.items() if v is not float}
    assert not bad, f"numpy scalars in the every-step state: {bad}"
    assert not any(v is np.float64 for types in seen for v in types.values())


def _road_and_gnss_types(est: Estimator) -> dict:
    road = est.road
    out = {"bank_walk.kappa": type(est.bank_walk.kappa), "bank_walk.total": type(est.bank_walk.total),
           "road.roll_doubt": type(road.roll_doubt), "road.var_gay_seen": type(road.var_gay_seen),
           "road.fy_lp": type(road.fy_lp), "road.roll": type(road.roll), "turn_lp": type(est.turn_lp),
           "align_lat_var": type(est.align_lat_var)}
    if est.course_heading is not None:
        out["course_heading var"] = type(est.course_heading[2])
    return out


def test_the_bank_walk_road_filters_and_gnss_alignment_state_are_python_floats():
    """perf42 (issue 10): the bank walk's curvature low-pass and its total, the road filters'
    roll doubt, force low-pass and roll (read every step), and what a GNSS alignment leaves in the
    every-step heading terms (the |yaw rate| low-pass, the alignment's latency term, the course
    heading's variance) stay Python floats through a drive with GNSS: each was a numpy scalar on
    main b26daff (a vx, a variance or a yaw rate read out of an array), so every later step's
    arithmetic on it was numpy scalar arithmetic. The same doubles either way (no output bit moves);
    only the instruction count does (DEVELOPERS.md's performance paragraph)."""
    est, seen = _sampled_through_dlc_dry(_road_and_gnss_types)
    assert est.aligned and est.course_heading is not None  # the GNSS terms were set, not only initialised
    assert len(seen) > 10
    bad = {k: v.__name__ for types in seen for k, v in types.items() if v is not float}
    assert not bad, f"numpy scalars in the every-step state: {bad}"
