"""Real data through the real replay contract (tools/real_data.py): Revs race car and RAV4 drive.

Revs: a 200 s slice (the CLI runs all 550 s) encoded as Toyota CAN + delayed UBX NAV-PVT, replayed
and scored against the INS sideslip truth. RAV4: the recorded candump + u-blox fixes, checked
against the truths the README measured. Bounds are ~25 % above the measured values (see the
comments) so that a regression shows; skipped when ../shared/data is absent.
"""
from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import pytest

from tools_import import load_tool

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
if not SHARED.is_dir():  # a clone without ../shared beside it; with it, a missing data set fails
    pytest.skip(f"shared data not found at {SHARED}", allow_module_level=True)


rd = load_tool("real_data")


@pytest.fixture(scope="module")
def revs(tmp_path_factory):
    out = tmp_path_factory.mktemp("revs")
    result, summary = rd.run_revs(out, protocol="ubx", seed=1, duration_s=200.0)
    return out, result, summary


@pytest.fixture(scope="module")
def rav4(tmp_path_factory):
    out = tmp_path_factory.mktemp("rav4")
    metrics, summary = rd.run_rav4(out, protocol="ubx")
    return out, metrics, summary


def test_revs_logs_look_like_the_car(revs):
    out, _, summary = revs
    ids = Counter(line.split()[2].split("#")[0] for line in (out / "drive.log").open())
    assert set(ids) == {"024", "025", "0AA"}
    for n in ids.values():  # ~83.3 Hz over 200 s
        assert abs(n / 200.0 - 1 / 0.012) < 0.5
    assert summary["error_frames"] == 0
    assert 990 <= summary["gnss_samples"] <= 1000  # 5 Hz; the last 0.4 s arrive after the end
    cfg = rd.config_mod.load(out / "config.toml")
    assert cfg.dbc_path().resolve() == (out / rd.DBC_NAME).resolve()  # the copied DBC, not the repo's


def test_revs_sideslip_and_heading(revs):
    _, r, _ = revs
    # measured (seed 1, 200 s, settle 20 s): sideslip RMS 0.353 deg, heading RMS@valid 0.163 deg
    assert math.degrees(r["sideslip"]["rms"]) < 0.45
    assert r["heading"]["fraction_valid"] > 0.95
    assert math.degrees(r["heading"]["rms_valid"]) < 0.21


def test_revs_sideslip_valid_where_right(revs):
    _, r, _ = revs
    b, h = r["sideslip"]["validity"], r["heading"]["validity"]
    # measured (seed 1, 200 s): sideslip valid on 83.5 % of the rows above 5 m/s (70.6 % with the
    # receiver's sAcc of 0.3 m/s for 0.05 m/s of scatter, see estimator/gnss_noise.py), and the
    # flags still keep their promise: 100 % of valid sideslip and heading rows within 3 sigma
    # (heading 98.6 % without the course floor under its std, core.COURSE_FLOOR_RAD)
    assert b["valid_fraction_above_5mps"] > 0.80
    assert b["coverage_3sigma"] >= 0.99 and h["coverage_3sigma"] >= 0.99


def test_revs_biases(revs):
    _, r, _ = revs
    # measured: yaw-rate bias 0.306 deg/s (true 0.3), wheel scale 1.0151 (1.015), delay 0.401 s (0.4)
    assert abs(math.degrees(r["yaw_rate_bias"]["final_error"])) < 0.03
    assert abs(r["wheel_scale"]["final_error"]) < 0.002
    assert abs(r["gnss_delay"]["final_error"]) < 0.04



@pytest.fixture(scope="module")
def revs_outage(tmp_path_factory):
    out = tmp_path_factory.mktemp("revs_outage")
    result, summary = rd.run_revs(out, protocol="ubx", seed=1, duration_s=100.0, outage=(60.0, 30.0))
    return out, result, summary


def test_revs_gnss_outage_keeps_the_sideslip_promise(revs_outage):
    """30 s without GNSS in the race car's corners (up to 1.2 g): only the single-track model holds
    the sideslip. Its error there is real (measured, seed 1: rms 0.87 deg, 95 % within 2.0 deg,
    max 2.4 deg; the whole 550 s drive with the outage at 300 s: max 2.3 deg, valid rows up to
    1.6 deg off), so the flag must follow the std: measured 79 % valid, 100 % of them within
    3 sigma, the worst 1.37 deg. A rule that narrowed the model's std in outages (a correlated-
    error treatment trusting a learned law) breaks this first."""
    _, r, summary = revs_outage
    assert 340 <= summary["gnss_samples"] <= 350  # 100 s at 5 Hz, less the 150 fixes of the outage
    m = r["outage"]
    assert m["rows"] > 5000
    assert m["err_max_deg"] > 1.0  # the model alone is wrong by this much somewhere: a real test
    assert m["coverage_3sigma"] >= 0.99
    assert m["worst_valid_deg"] < 2.0

def test_rav4_yaw_rate_bias_and_wheel_scale(rav4):
    _, m, _ = rav4
    # measured: -0.413 deg/s final, wheel scale 1.0094 (README: 1/0.991 = 1.0091)
    assert abs(m["yaw_rate_bias_deg_s"] - rd.RAV4_YAW_BIAS_DEG_S) < 0.1
    assert abs(m["wheel_scale"] - 1 / 0.991) < 0.004


def test_rav4_sideslip_near_zero_and_heading_follows_course(rav4):
    _, m, _ = rav4
    # measured: mean |beta| 0.010 deg; heading - u-blox course RMS 0.36 deg
    assert m["sideslip_mean_abs_deg"] < 0.5
    assert m["heading_minus_course_rms_deg"] < 0.5


def test_rav4_gnss_delay(rav4):
    """Real receiver latency (README: 0.20 s mean arrival - fix epoch), found from a 0.1 s prior."""
    _, m, _ = rav4
    assert abs(m["gnss_delay_s"] - 0.20) < 0.06
