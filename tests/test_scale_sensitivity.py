"""The heading std's gyro-scale term after a corner (estimator/scale_sensitivity.py), end to end.

A flying start mid-corner (the suite's flying_10: 10 m/s on a 14 m circle, 40 deg/s, for ~12 s,
then straight) with the yaw rate read x0.97 and x1.03. The heading is aligned at the first fix and
the corner's rotation (~6 rad) turns it by s x that rotation as far as the courses do not take it
back; on the straight the sideslip is model-anchored near zero and the courses take the heading
back within seconds. What the heading carries of the scale error is S_psi x s, S_psi tracked
through the filter's own gains: it must not forget faster than the error (the std stays honest),
nor hold on for the 20 s memory of the rotation gyro17 used (flying_10's heading was valid 24 s
after the fix instead of 13 s: invalid while right).
"""
import math

import numpy as np
import pytest


def _record_published(monkeypatch, what):
    """(t, *what(estimator)) at every published step once the estimator is initialised."""
    from ecu_daemon.pipeline import Pipeline

    rec = []
    publish = Pipeline._publish

    def _publish(self, e, send):
        est = self.estimator
        if est.initialized and est.hist.last >= 0:
            rec.append((e.t, *what(est)))
        return publish(self, e, send)

    monkeypatch.setattr(Pipeline, "_publish", _publish)
    return rec


def _run(tmp_path, factor, monkeypatch):
    from ecu_daemon.sim.sensors import Fault
    from ecu_daemon.sim.suite import SUITE, SuiteCase
    from ecu_daemon.suite import run_case

    rec = _record_published(monkeypatch, lambda est: (est.scale_sens.heading(est.hist.last),
                                                      bool(est.yaw_scale_realigned)))
    base = {c.name: c for c in SUITE}["flying_10_r14l_h45"]
    name = f"flying_10_scale_{factor}"
    case = SuiteCase(name, base.family, base.scenario.with_(
        sensor_faults=(Fault("yaw_rate", "scaled", 0.0, 1.0e4, factor),)))
    row = run_case(case, tmp_path)

    def read(p):
        return np.genfromtxt(p, delimiter=",", names=True)

    est, tru = read(tmp_path / name / "estimate.csv"), read(tmp_path / name / "truth.csv")
    th = np.interp(est["t"], tru["t"], np.unwrap(tru["heading_rad"]))
    err = np.remainder(est["heading_rad"] - th + math.pi, 2.0 * math.pi) - math.pi
    r_true = np.interp(est["t"], tru["t"], tru["yaw_rate_radps"])
    return row, est["t"], err, r_true, np.array(rec)


@pytest.fixture(scope="module")
def exact_gyro(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    try:
        return _run(tmp_path_factory.mktemp("exact"), 1.0, mp)
    finally:
        mp.undo()


@pytest.mark.parametrize("factor", [0.97, 1.03])
def test_a_scale_error_after_a_corner_is_covered_and_the_heading_valid_soon_on_the_straight(
        tmp_path, monkeypatch, exact_gyro, factor):
    row, t, err, r_true, rec = _run(tmp_path, factor, monkeypatch)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    # never wrong while valid
    assert row["heading_coverage_3sigma"] >= 0.99 and row["heading_worst_valid_deg"] < 2.0
    # the corner ends ~12.3 s after the first fix; valid within 2.5 s of it (gyro17: 24 s exact gyro)
    assert row["heading_time_to_valid_after_fix_s"] <= 15.0
    assert row["heading_valid_above_5mps"] > 0.7  # gyro17: 49 % for the exact gyro

    # the term itself: what the scale left in the heading is this run's error less the same drive's
    # with an exact gyro (the same noise); S_psi x s must cover it from the corner's last seconds
    # through the straight, before a realignment to the fit changes what S refers to. Measured
    # (x0.97): 0.95 / 1.15 deg (actual / S s) in the corner, 1.12 / 1.17 deg at the straight's peak
    # 5.5 s after the corner, 0.31 / 0.35 deg 12 s after it; the 20 s memory of the rotation said
    # 3.4 deg there. 1.25 x and 0.15 deg for the corner exit, where S_psi changes sign.
    _, t0, err0, _, _ = exact_gyro
    n = min(len(t), len(t0))
    assert np.allclose(t[:n], t0[:n])
    d = np.abs(err[:n] - err0[:n])
    t, r_true = t[:n], r_true[:n]
    s = factor - 1.0
    t_s, S, realigned = rec[:, 0], rec[:, 1], rec[:, 2] > 0.5
    S_at = np.interp(t, t_s, S)
    re_at = np.interp(t, t_s, realigned.astype(float)) > 0.5
    corner_end = t[np.argmax((t > t[0] + 5.0) & (np.abs(r_true) < 0.1))]
    window = (t > corner_end - 3.0) & (t < corner_end + 15.0) & ~re_at
    assert window.sum() > 300
    assert np.all(d[window] <= 1.25 * S_at[window] * abs(s) + math.radians(0.15))
    assert d[window].max() > math.radians(0.6)  # the scale did turn the heading
    # and it forgets once the straight's courses have taken the error back: S_psi (rad of heading
    # per unit scale) below 0.2 within 15 s of the corner's end (the 20 s memory held 2.6 there)
    late = (t_s > corner_end + 12.0) & (t_s < corner_end + 15.0)
    assert S[late].min() < 0.2


def _run_suite_row(tmp_path, name, monkeypatch):
    """One suite row, with the scale applied to the gyro at every published step."""
    from ecu_daemon.sim.suite import SUITE
    from ecu_daemon.suite import run_case

    rec = _record_published(monkeypatch, lambda est: (float(est.yaw_scale_applied),))
    row = run_case({c.name: c for c in SUITE}[name], tmp_path)

    def read(p):
        return np.genfromtxt(p, delimiter=",", names=True)

    est, tru = read(tmp_path / name / "estimate.csv"), read(tmp_path / name / "truth.csv")
    th = np.interp(est["t"], tru["t"], np.unwrap(tru["heading_rad"]))
    err = np.remainder(est["heading_rad"] - th + math.pi, 2.0 * math.pi) - math.pi
    return row, est["t"], err, np.array(rec)


@pytest.mark.parametrize("name", ["flying_6_gyro_+3pct", "flying_10_gyro_-5pct"])
def test_applying_the_scale_moves_the_heading_by_what_it_carries_not_to_the_fits_heading(tmp_path, monkeypatch, name):
    """A flying start's corner with the gyro 3-5 % off: the fit applies its scale ~5 s into the
    straight, while the calibrated prior still shrinks it (0.76 % of a 2.9 % scale) and the fit's
    heading, drawn with that scale, is 1.8-3 deg off with a std of 0.44 deg. integ18 realigned the
    state to that heading: flying_6 +3 % went from 0.84 to 1.56 deg off publishing 0.44-0.6 deg,
    flying_10 -5 % from 0.44 to 3.0 deg off (and its heading was never valid). Moved by S x applied
    (what the state carries of the scale, scale_sensitivity.py), the heading gets closer to the
    truth, and the residual S_psi x (scale - applied) stays on its std."""
    row, t, err, rec = _run_suite_row(tmp_path, name, monkeypatch)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["heading_coverage_3sigma"] >= 0.99 and row["sideslip_coverage_3sigma"] >= 0.99
    assert row["heading_worst_valid_deg"] < 1.6
    assert row["heading_valid_above_5mps"] > 0.5  # integ18: 0 % on flying_10 -5 %
    # the heading error just before and just after the scale is first applied (one publish apart)
    first = int(np.argmax(rec[:, 1] != 0.0))
    assert rec[first, 1] != 0.0
    t_before, t_after = rec[first - 1, 0], rec[first, 0] + 0.05
    e_before = abs(float(np.interp(t_before, t, err)))
    e_after = abs(float(np.interp(t_after, t, err)))
    assert e_after <= e_before + math.radians(0.1), (math.degrees(e_before), math.degrees(e_after))
