"""Dual-antenna heading: NAV-RELPOSNED / HDT / THS through the stream parser and capture log, the
fusion module on its own, and the estimator at standstill on a simulated moving-base pair."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator import Estimator
from ecu_daemon.estimator.fusion.gnss_heading import GnssHeadingFusion
from ecu_daemon.estimator.history import StepHistory
from ecu_daemon.estimator.kinematic import NX, PSI
from ecu_daemon.gnss import GnssLogWriter, GnssStreamParser, encode, samples_from_log
from ecu_daemon.gnss.ubx import ubx_checksum
from ecu_daemon.samples import GnssHeadingSample, GnssSample


def _feed(parser, *chunks):
    out = []
    for t, data in chunks:
        out += parser.feed(t, data)
    return out + parser.finish()


def _line(s: str) -> bytes:
    return (s + "\r\n").encode("ascii")


# ----------------------------------------------------------------------------- parsing
def test_relposned_gives_heading_accuracy_baseline_and_carrier_solution():
    frame = encode.nav_relposned(itow_ms=5000, heading_deg=271.23456, baseline_m=1.2345, head_acc_deg=0.25,
                                 carr_soln=1)
    # split anywhere: the frame is stamped with its last byte's time
    (s,) = _feed(GnssStreamParser(), (1.0, frame[:20]), (1.01, frame[20:]))
    assert isinstance(s, GnssHeadingSample) and s.protocol == "ubx" and s.t == 1.01
    assert math.degrees(s.heading_rad) == pytest.approx(271.23456, abs=2e-5)
    assert math.degrees(s.heading_acc_rad) == pytest.approx(0.25, abs=2e-5)
    assert s.baseline_m == pytest.approx(1.2345, abs=1e-4)  # cm + the 0.1 mm high-precision part
    assert s.valid and s.carr_soln == 1


def test_relposned_is_dated_by_the_nav_pvt_of_its_epoch():
    """A NAV-RELPOSNED shares its epoch's iTOW with the NAV-PVT before it: that NAV-PVT's UTC is
    its time of validity, so the estimator fuses both at one step (not 4 ms apart by receive time)."""
    utc = 1717228800.2
    f = encode.utc_fields(utc)
    pvt = encode.nav_pvt(**f, lat_deg=48.1, lon_deg=11.5, vel_n_mps=10.0, vel_e_mps=0.0)
    same = encode.nav_relposned(itow_ms=f["itow_ms"], heading_deg=90.0, baseline_m=1.2)
    other = encode.nav_relposned(itow_ms=f["itow_ms"] + 200, heading_deg=90.0, baseline_m=1.2)
    v, h1, h2 = _feed(GnssStreamParser(), (1.0, pvt), (1.004, same), (1.2, other))
    assert h1.fix_time_utc_s == v.fix_time_utc_s == pytest.approx(utc, abs=1e-6)
    assert math.isnan(h2.fix_time_utc_s)  # its own epoch's NAV-PVT was not seen: undated
    (alone,) = _feed(GnssStreamParser(), (1.0, same))
    assert math.isnan(alone.fix_time_utc_s)


@pytest.mark.parametrize("flag", ["fix_ok", "rel_pos_valid", "heading_valid"])
def test_relposned_is_invalid_when_any_receiver_flag_says_so(flag):
    frame = encode.nav_relposned(itow_ms=0, heading_deg=10.0, baseline_m=1.0, **{flag: False})
    (s,) = _feed(GnssStreamParser(), (0.0, frame))
    assert not s.valid


def test_relposned_version_0_has_no_heading_and_is_no_error():
    frame = encode.nav_relposned(itow_ms=0, heading_deg=10.0, baseline_m=1.0)
    body = frame[2:4] + (40).to_bytes(2, "little") + frame[6:46]  # the M8P's 40-byte layout
    v0 = b"\xb5\x62" + body + ubx_checksum(body)
    p = GnssStreamParser()
    assert _feed(p, (0.0, v0)) == []
    assert p.stats["malformed"] == 0 and p.stats["ubx_frames"] == 1


def test_hdt_and_ths_give_heading_samples_with_their_validity():
    p = GnssStreamParser("nmea")
    out = _feed(p, (1.0, _line(encode.nmea_hdt(heading_deg=359.99))), (2.0, _line(encode.nmea_ths(heading_deg=12.5))),
                (3.0, _line(encode.nmea_ths(heading_deg=12.5, mode="E"))),  # dead reckoning: not measured
                (4.0, _line(encode.nmea_ths(heading_deg=None, mode="V"))),
                (5.0, _line(encode.nmea_hdt(heading_deg=None))))
    assert [s.valid for s in out] == [True, True, False, False, False]
    assert math.degrees(out[0].heading_rad) == pytest.approx(359.99)
    assert math.degrees(out[1].heading_rad) == pytest.approx(12.5)
    assert all(s.protocol == "nmea" and math.isnan(s.heading_acc_rad) for s in out)
    assert p.stats["samples"] == 5 and p.stats["unsupported"] == 0


def test_auto_prefers_the_ubx_heading_but_a_ubx_velocity_does_not_hide_an_nmea_heading():
    pvt = encode.nav_pvt(**encode.utc_fields(1.7e9), lat_deg=48.0, lon_deg=11.0, vel_n_mps=1.0, vel_e_mps=0.0)
    hdt = _line(encode.nmea_hdt(heading_deg=45.0))
    out = _feed(GnssStreamParser(), (0.0, pvt), (0.1, hdt))
    assert [type(s) for s in out] == [GnssSample, GnssHeadingSample]
    rel = encode.nav_relposned(itow_ms=0, heading_deg=45.0, baseline_m=1.0)
    p = GnssStreamParser()
    out = _feed(p, (0.0, rel), (0.1, hdt))
    assert [s.protocol for s in out] == ["ubx"] and p.stats["suppressed"] == 1


def test_capture_log_round_trip_keeps_relposned(tmp_path):
    path = tmp_path / "gnss.log"
    frames = [encode.nav_relposned(itow_ms=200 * i, heading_deg=30.0 + i, baseline_m=1.2) for i in range(3)]
    with GnssLogWriter(path) as w:
        for i, f in enumerate(frames):
            w.write(100.0 + 0.2 * i, f)
    out = list(samples_from_log(path))
    assert [round(math.degrees(s.heading_rad), 3) for s in out] == [30.0, 31.0, 32.0]
    assert [s.t for s in out] == [100.0, 100.2, 100.4]


# ----------------------------------------------------------------------------- fusion module
def _hist(psi_deg: float = 10.0, psi_std_deg: float = 5.0, steps: int = 20) -> StepHistory:
    h = StepHistory(64)
    h.reset(0)
    for k in range(steps):
        i = h.slot(k)
        h.X[i] = 0.0
        h.X[i, PSI] = math.radians(psi_deg)
        h.P[i] = np.eye(NX) * 0.01
        h.P[i, PSI, PSI] = math.radians(psi_std_deg) ** 2
        h.A[i] = np.eye(NX)
        h.last = k
    return h


def _heading(deg: float, acc: float = 0.3, baseline: float = 1.2, valid: bool = True) -> GnssHeadingSample:
    return GnssHeadingSample(t=0.0, heading_rad=math.radians(deg) % (2 * math.pi), heading_acc_rad=math.radians(acc),
                             baseline_m=baseline, valid=valid, carr_soln=2, protocol="ubx")


def test_fusion_applies_the_mounting_offset_and_carries_the_update_to_the_present():
    fus = GnssHeadingFusion([(90.0, 1.2)], 0.05, 2.0, 0.3, 5.0)  # antennas across the car, left to right
    h = _hist(psi_deg=10.0)
    assert fus.fuse(h, 5, _heading(101.0), 0.0)  # vehicle heading 11 deg, the filter says 10
    last = h.slot(h.last)
    assert math.degrees(h.X[last, PSI]) == pytest.approx(11.0, abs=0.01)
    assert math.degrees(math.sqrt(h.P[last, PSI, PSI])) < 0.31


def test_fusion_wraps_through_north_and_gates_a_wrong_heading():
    fus = GnssHeadingFusion([(0.0, 0.0)], 0.05, 2.0, 0.3, 5.0)
    h = _hist(psi_deg=359.5, psi_std_deg=0.5)
    assert fus.fuse(h, 3, _heading(0.3), 0.0)  # +0.8 deg across north, not -359.2
    assert math.degrees(h.X[h.slot(h.last), PSI]) % 360 == pytest.approx(0.2, abs=0.15)
    x_before = h.X.copy()
    assert not fus.fuse(h, 3, _heading(20.0), 0.0)
    assert fus.consecutive_rejects == 1 and "gate" in fus.last_reason
    assert np.array_equal(h.X, x_before)


def test_a_correction_the_history_refuses_is_a_rejection_and_changes_nothing():
    """StepHistory.correct refuses a correction that leaves a stored covariance not positive
    definite (here a later step's, already broken): the heading is then not fused."""
    fus = GnssHeadingFusion([(0.0, 0.0)], 0.05, 2.0, 0.3, 5.0)
    h = _hist(psi_deg=10.0)
    h.P[h.slot(15), 0, 0] = -1.0
    x_before, p_before = h.X.copy(), h.P.copy()
    assert not fus.fuse(h, 5, _heading(11.0), 0.0)
    assert (fus.fused, fus.rejected) == (0, 1) and "positive definite" in fus.last_reason
    assert np.array_equal(h.X, x_before) and np.array_equal(h.P, p_before)


@pytest.mark.parametrize("sample, reason", [
    (_heading(10.0, baseline=1.31), "baseline"),  # a wrong carrier fix shows in the length
    (_heading(10.0, acc=2.5), "accuracy"),
    (_heading(10.0, valid=False), "no valid heading"),
])
def test_unusable_headings_say_why(sample, reason):
    fus = GnssHeadingFusion([(0.0, 1.2)], 0.05, 2.0, 0.3, 5.0)
    assert not fus.usable(sample) and reason in fus.last_reason


def test_align_sets_every_stored_step_keeping_what_was_integrated_since():
    fus = GnssHeadingFusion([(0.0, 0.0)], 0.05, 2.0, 0.3, 5.0)
    h = _hist(psi_deg=0.0, psi_std_deg=180.0)
    for k in range(20):
        h.X[h.slot(k), PSI] = math.radians(0.1 * k)  # the car turned 0.1 deg per step
    fus.align(h, 10, _heading(200.0), 0.0, q_step=1e-8)
    psi = np.degrees([h.X[h.slot(k), PSI] for k in range(20)])
    assert psi[10] == pytest.approx(200.0) and np.allclose(np.diff(psi), 0.1)
    var = np.array([h.P[h.slot(k), PSI, PSI] for k in range(20)])
    assert var[10] == pytest.approx(math.radians(0.3) ** 2) and np.all(np.diff(var[10:]) > 0)
    assert h.P[h.slot(19), PSI, 0] == 0.0  # uncorrelated with the other states


# ----------------------------------------------------------------------------- estimator
def _standstill_run(dual: bool, baseline_cfg: float = 1.2):
    from ecu_daemon.sim.run import simulate, vehicle_config
    from ecu_daemon.sim.scenario import SCENARIOS

    sc = SCENARIOS["straight"].with_(name="s", duration_s=6.0, gnss_dual_antenna=dual, gnss_baseline_offset_deg=90.0)
    cfg = vehicle_config(sc)
    cfg.gnss.baseline_m = baseline_cfg if dual else 0.0
    res = simulate(sc, cfg)
    est = Estimator(cfg)
    from ecu_daemon.signals import SignalDecoder
    dec = SignalDecoder(cfg)
    parser = GnssStreamParser()
    items = [(t, 0, s) for t, fid, data in res.can_frames for s in dec.decode(t, fid, data, fid in res.extended_ids)]
    items += [(t, 1, s) for t, payload in res.gnss_messages for s in parser.feed(t, payload)]
    items.sort(key=lambda e: (e[0], e[1]))
    rows = []
    for t, kind, s in items:
        (est.push_gnss if kind else est.push_input)(s)
        rows += est.advance_to(t - 2e-9)
    truth = res.truth
    psi = np.interp([e.t for e in rows], truth.t, np.unwrap(truth.col("psi")))
    speed = np.interp([e.t for e in rows], truth.t, np.hypot(truth.col("vx"), truth.col("vy")))
    return rows, psi, speed, est


def test_heading_is_valid_and_right_at_standstill_with_a_dual_antenna():
    rows, psi, speed, est = _standstill_run(dual=True)
    still = speed < 0.01
    assert still.sum() > 300  # the drive starts standing
    late = np.array([e.t - rows[0].t > 1.5 for e in rows]) & still
    valid = np.array([e.heading_valid for e in rows])
    assert valid[late].all()
    err = np.degrees(np.abs((np.array([e.heading_rad for e in rows]) - psi + np.pi) % (2 * np.pi) - np.pi))
    assert err[late].max() < 0.3
    assert est.heading.fused > 10


def test_without_a_dual_antenna_standstill_has_no_heading():
    rows, _, speed, _ = _standstill_run(dual=False)
    assert not any(e.heading_valid for e, v in zip(rows, speed) if v < 0.01)


def test_a_baseline_that_does_not_match_the_mounted_one_is_never_used():
    rows, _, speed, est = _standstill_run(dual=True, baseline_cfg=1.5)
    assert est.heading.fused == 0 and est.heading.rejected > 10
    assert not any(e.heading_valid for e, v in zip(rows, speed) if v < 0.01)


def test_replay_reads_the_heading_from_the_capture_and_reports_it_on_can(tmp_path):
    """The whole offline path: simulate -> capture files -> replay -> EST_DIAG heading page on CAN."""
    import cantools

    from ecu_daemon import config as config_mod
    from ecu_daemon.canlog import read_can_log
    from ecu_daemon.replay import run_replay
    from ecu_daemon.sim import writer
    from ecu_daemon.sim.run import simulate, vehicle_config
    from ecu_daemon.sim.scenario import SCENARIOS

    sc = SCENARIOS["straight"].with_(name="s", duration_s=4.0, gnss_dual_antenna=True, gnss_baseline_m=1.2,
                                     gnss_baseline_offset_deg=-90.0)
    cfg = vehicle_config(sc)
    paths = writer.write_all(tmp_path, simulate(sc, cfg), cfg)
    rcfg = config_mod.load(paths["config"])  # the written config carries the mounting and the baseline
    assert (rcfg.gnss.heading_offset_deg, rcfg.gnss.baseline_m) == (-90.0, 1.2)
    out = tmp_path / "out.log"
    run_replay(rcfg, str(paths["can"]), str(paths["gnss"]), out_can=str(out))
    db = cantools.database.load_file(rcfg.output_dbc_path())
    pages = {}
    for t, fid, ext, err, data in read_can_log(out):
        if fid == 0x320:
            d = db.decode_message(fid, data, decode_choices=False)
            pages[d["DIAG_PAGE"]] = d
        elif fid == 0x302:
            heading_frame = db.decode_message(fid, data, decode_choices=False)
    assert pages[36]["GNSS_HEADING_STATE"] == 1 and pages[36]["GNSS_HEADING_CARR_SOLN"] == 2
    assert pages[36]["GNSS_HEADING_BASELINE"] == pytest.approx(1.2, abs=2e-3)
    assert pages[37]["GNSS_HEADING_FUSED"] > 10 and pages[37]["GNSS_HEADING_REJECTED"] == 0
    assert heading_frame["STATUS_GNSS_HEADING"] == 1 and heading_frame["HEADING_VALID"] == 1


def test_a_wrong_carrier_fix_never_takes_the_heading_while_moving(tmp_path):
    """8 deg off for 5 s with a plausible baseline: gated, and the run of rejections does not re-set
    the heading because the GNSS course disagrees with the baseline; heading_valid drops meanwhile."""
    from ecu_daemon import config as config_mod
    from ecu_daemon.evaluate import ESTIMATE_REQUIRED, TRUTH_REQUIRED, read_csv
    from ecu_daemon.replay import run_replay
    from ecu_daemon.sim import writer
    from ecu_daemon.sim.run import simulate, vehicle_config
    from ecu_daemon.sim.suite import SUITE

    sc = next(c.scenario for c in SUITE if c.name == "dual_heading_fault").with_(duration_s=32.0)
    cfg = vehicle_config(sc)
    paths = writer.write_all(tmp_path, simulate(sc, cfg), cfg)
    run_replay(config_mod.load(paths["config"]), str(paths["can"]), str(paths["gnss"]), str(tmp_path / "out.csv"))
    est = read_csv(tmp_path / "out.csv", ESTIMATE_REQUIRED, "estimate")
    truth = read_csv(paths["truth"], TRUTH_REQUIRED, "truth")
    psi = np.interp(est["t"], truth["t"], np.unwrap(truth["heading_rad"]))
    err = np.degrees(np.abs((est["heading_rad"] - psi + np.pi) % (2 * np.pi) - np.pi))
    valid = est["heading_valid"] > 0.5
    fault = (est["t"] >= est["t"][0] + 24.5) & (est["t"] < est["t"][0] + 29.0)
    assert err[fault].max() < 0.5 and err[valid].max() < 0.5  # never followed the wrong baseline
    assert not valid[fault].all()  # said so: the two GNSS sources disagree


def test_a_fresh_dual_antenna_heading_is_published_without_the_course_floor():
    """The 0.3 deg floor is the error of a heading taken from the GNSS course; a heading measured by
    the antenna pair is better, and its std says so while it stays honest (3 sigma)."""
    from ecu_daemon.estimator.core import COURSE_FLOOR_RAD

    rows, psi, _, _ = _standstill_run(dual=True)
    late = np.array([e.t - rows[0].t > 1.5 and e.heading_valid for e in rows])
    std = np.array([e.heading_std_rad for e in rows])
    err = np.abs((np.array([e.heading_rad for e in rows]) - psi + np.pi) % (2 * np.pi) - np.pi)
    assert late.sum() > 300
    assert np.median(std[late]) < 0.5 * COURSE_FLOOR_RAD
    assert (err[late] <= 3 * std[late]).mean() >= 0.99
    rows, _, _, _ = _standstill_run(dual=False)
    assert all(e.heading_std_rad >= COURSE_FLOOR_RAD for e in rows if e.heading_valid)
