"""``ecu-daemon evaluate``: error statistics that are right, including the awkward cases."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from ecu_daemon.cli import main as cli_main
from ecu_daemon.evaluate import ESTIMATE_REQUIRED, EvaluationError, evaluate

T0 = 1200.0


def _write(path: Path, cols: dict) -> Path:
    names = list(cols)
    n = len(cols["t"])
    with open(path, "w") as f:
        f.write(",".join(names) + "\n")
        for i in range(n):
            f.write(",".join(str(cols[k][i]) for k in names) + "\n")
    return path


def _truth(tmp_path: Path) -> tuple[Path, dict]:
    t = T0 + 0.006 * np.arange(5001)  # 30 s
    tau = t - T0
    cols = {
        "t": t,
        "sideslip_rad": 0.02 * np.sin(tau),
        "heading_rad": np.mod(6.0 + 0.05 * tau, 2 * math.pi),  # crosses north (2 pi -> 0) at ~5.7 s
        "vx_mps": 10.0 + 0.1 * tau,
        "vy_mps": 0.2 * np.sin(tau),
        "yaw_rate_bias_radps": np.full_like(t, 0.01),
        "accel_x_bias_mps2": np.full_like(t, 0.1),
        "accel_y_bias_mps2": np.full_like(t, 0.15),
        "accel_y_bias_eff_mps2": np.full_like(t, 0.15 + 0.49),  # + g sin(bank)
        "gnss_delay_s": np.full_like(t, 0.4),
        "wheel_scale": np.full_like(t, 1.015),
    }
    return _write(tmp_path / "truth.csv", cols), cols


def _estimate(truth: dict, **errors) -> dict:
    """An estimate 3 ms off the truth grid, with the given error arrays/constants added."""
    t = truth["t"][:-1] + 0.003
    est = {"t": t}
    for k in ("sideslip_rad", "vx_mps", "vy_mps"):
        est[k] = np.interp(t, truth["t"], truth[k])
    est["heading_rad"] = np.mod(np.interp(t, truth["t"], np.unwrap(truth["heading_rad"])), 2 * math.pi)
    est["sideslip_std_rad"] = np.full_like(t, 0.006)
    est["heading_std_rad"] = np.full_like(t, 0.01)
    est["yaw_rate_bias_radps"] = np.full_like(t, 0.01)
    est["accel_x_bias_mps2"] = np.full_like(t, 0.1)
    est["accel_y_bias_mps2"] = np.full_like(t, 0.64)
    est["gnss_delay_s"] = np.full_like(t, 0.4)
    est["sideslip_valid"] = np.array(["True"] * len(t), dtype=object)
    est["heading_valid"] = np.ones(len(t), dtype=int)
    for k, e in errors.items():
        est[k] = est[k] + e
    if "heading_rad" in errors:
        est["heading_rad"] = np.mod(est["heading_rad"], 2 * math.pi)
    return est


def test_known_errors_give_exact_statistics_and_heading_wraps(tmp_path):
    tpath, truth = _truth(tmp_path)
    est = _estimate(truth, sideslip_rad=0.01, heading_rad=-0.02, vx_mps=0.3,
                    yaw_rate_bias_radps=0.002, gnss_delay_s=-0.1)
    r = evaluate(tpath, _write(tmp_path / "est.csv", est), settle_s=2.0)
    assert r["sideslip"]["rms"] == pytest.approx(0.01, rel=1e-6)
    assert r["sideslip"]["mean"] == pytest.approx(0.01, rel=1e-6)
    # heading crosses north: errors must be -0.02, not ~2 pi
    assert r["heading"]["max_abs"] == pytest.approx(0.02, rel=1e-4)
    assert r["vx"]["rms"] == pytest.approx(0.3, rel=1e-6)
    assert r["vy"]["rms"] < 1e-4  # interpolated truth of a smooth signal: nothing else
    b = r["yaw_rate_bias"]
    assert b["final_error"] == pytest.approx(0.002) and b["relative_error"] == pytest.approx(0.2)
    # accel_y_bias is compared with the effective bias (incl. the bank's gravity component)
    assert r["accel_y_bias"]["final_error"] == pytest.approx(0.0, abs=1e-9)
    assert r["gnss_delay"]["final"] == pytest.approx(0.3)
    assert r["t_start"] >= T0 + 2.0
    # the sideslip error (0.01) is inside 2 std (0.012)
    assert r["sideslip"]["within_2sigma"] == pytest.approx(1.0)


def test_validity_flags_select_rows_and_settling_skips_the_start(tmp_path):
    tpath, truth = _truth(tmp_path)
    n = len(truth["t"]) - 1
    err = np.zeros(n)
    err[:1000] = 0.5  # a big error during the first 6 s ...
    err[2000:2500] = 0.1  # ... and later, while flagged invalid
    est = _estimate(truth, sideslip_rad=err)
    valid = np.array(["True"] * n, dtype=object)
    valid[2000:2500] = "False"
    est["sideslip_valid"] = valid
    path = _write(tmp_path / "est.csv", est)
    r = evaluate(tpath, path, settle_s=7.0)
    rows = n - int(np.ceil((7.0 - 0.003) / 0.006))
    assert r["rows"] == pytest.approx(rows, abs=1)
    assert r["sideslip"]["max_abs"] == pytest.approx(0.1)  # the start is excluded
    assert r["sideslip"]["rms_valid"] < 1e-9
    assert r["sideslip"]["fraction_valid"] == pytest.approx(1 - 500 / r["rows"], abs=1e-3)
    assert evaluate(tpath, path, settle_s=0.0)["sideslip"]["max_abs"] == pytest.approx(0.5)


def test_missing_and_malformed_files_are_one_clear_line(tmp_path, capsys):
    tpath, truth = _truth(tmp_path)
    est = _estimate(truth)
    with pytest.raises(EvaluationError, match="cannot read estimate CSV"):
        evaluate(tpath, tmp_path / "nope.csv")
    del est["heading_std_rad"], est["gnss_delay_s"]
    with pytest.raises(EvaluationError, match="missing column.*heading_std_rad, gnss_delay_s"):
        evaluate(tpath, _write(tmp_path / "cols.csv", est))
    est = _estimate(truth)
    est["vx_mps"] = est["vx_mps"].astype(object)
    est["vx_mps"][7] = "fast"
    with pytest.raises(EvaluationError, match=r"est.csv:9: column vx_mps: 'fast' is not a number"):
        evaluate(tpath, _write(tmp_path / "est.csv", est))
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(EvaluationError, match="is empty"):
        evaluate(tmp_path / "empty.csv", tpath)
    (tmp_path / "header.csv").write_text(",".join(ESTIMATE_REQUIRED) + "\n")
    with pytest.raises(EvaluationError, match="no data rows"):
        evaluate(tpath, tmp_path / "header.csv")
    late = _estimate(truth)
    late["t"] = late["t"] + 100.0
    with pytest.raises(EvaluationError, match="no estimate rows inside the truth time span"):
        evaluate(tpath, _write(tmp_path / "late.csv", late))
    capsys.readouterr()
    rc = cli_main(["evaluate", "--truth", str(tpath), "--estimate", str(tmp_path / "cols.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "heading_std_rad" in err


def test_cli_table_json_and_plots(tmp_path, capsys):
    tpath, truth = _truth(tmp_path)
    epath = _write(tmp_path / "est.csv", _estimate(truth, sideslip_rad=0.01))
    assert cli_main(["evaluate", "--truth", str(tpath), "--estimate", str(epath), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sideslip"]["rms"] == pytest.approx(0.01, rel=1e-6)
    plots = tmp_path / "plots"
    assert cli_main(["evaluate", "--truth", str(tpath), "--estimate", str(epath), "--plots", str(plots)]) == 0
    out = capsys.readouterr().out
    assert "sideslip" in out and "gnss_delay" in out
    pngs = sorted(plots.glob("*.png"))
    assert [p.name for p in pngs] == ["biases.png", "heading.png", "sideslip.png", "velocities.png"]
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


# ------------------------------------------------------------------------------ honest validity
from ecu_daemon.evaluate import first_good_fix, validity_metrics  # noqa: E402


def test_validity_metrics_on_a_table_with_known_answers():
    t = np.arange(10.0)
    err = np.array([0, 0, 0, 0.5, 1, 2, 3, 4, 0, 0])
    std = np.ones(10)
    valid = np.array([0, 0, 1, 1, 1, 1, 1, 1, 1, 0], dtype=bool)
    speed = np.array([0, 2, 4, 6, 8, 10, 10, 10, 10, 10.0])
    v = validity_metrics(t, -err, std, valid, speed, t_start=0.0, t_fix=4.5)  # sign must not matter
    assert v["valid_rows"] == 7
    assert v["coverage_1sigma"] == pytest.approx(4 / 7)
    assert v["coverage_2sigma"] == pytest.approx(5 / 7)
    assert v["coverage_3sigma"] == pytest.approx(6 / 7)
    assert v["valid_beyond_3sigma"] == 1
    assert v["worst_error_valid"] == 4.0
    assert v["time_to_valid_s"] == 2.0
    assert v["time_to_valid_after_fix_s"] == 0.0  # already valid when the fix came
    assert v["valid_fraction"] == pytest.approx(0.7)
    # above 5 m/s and from 3 s after the fix (t >= 7.5): rows 8 (valid) and 9 (not)
    assert v["valid_fraction_above_5mps"] == pytest.approx(0.5)


def test_validity_metrics_never_valid_and_missing_std():
    t = np.arange(5.0)
    v = validity_metrics(t, np.zeros(5), np.ones(5), np.zeros(5, bool), np.full(5, 10.0), 0.0, math.nan)
    assert v["valid_rows"] == 0 and v["valid_beyond_3sigma"] == 0
    assert all(math.isnan(v[k]) for k in ("coverage_3sigma", "worst_error_valid", "time_to_valid_s",
                                          "time_to_valid_after_fix_s"))
    assert v["valid_fraction"] == 0.0 and v["valid_fraction_above_5mps"] == 0.0  # no fix: all fast rows
    # a valid row whose std is not a number is not covered (a promise without a bound)
    w = validity_metrics(t, np.zeros(5), np.full(5, np.nan), np.ones(5, bool), np.full(5, 10.0), 0.0, math.nan)
    assert w["coverage_3sigma"] == 0.0 and w["valid_beyond_3sigma"] == 5


def test_first_good_fix_uses_the_gnss_good_column_or_speed_plus_delay():
    t = 100.0 + np.arange(10.0)
    vx = np.array([0, 2, 4, 6, 8, 10, 10, 10, 10, 10.0])
    truth = {"t": t, "vx_mps": vx, "vy_mps": np.zeros(10), "gnss_delay_s": np.full(10, 0.4)}
    assert first_good_fix(truth) == pytest.approx(103.4)
    truth["gnss_good"] = np.array([1, 1, 1, 0, 0, 0, 1, 1, 1, 1.0])  # an outage from 103 to 105
    assert first_good_fix(truth) == 106.0
    truth["gnss_good"][:] = 0
    assert math.isnan(first_good_fix(truth))


def test_validity_covers_the_settling_time_and_json_is_strict(tmp_path, capsys):
    """A valid flag is a promise from the first row: a big error while valid in the first seconds
    shows in worst_error_valid even though the RMS figures leave those seconds out."""
    tpath, truth = _truth(tmp_path)
    n = len(truth["t"]) - 1
    err = np.zeros(n)
    err[100:200] = math.radians(5.0)  # 0.6-1.2 s: 5 deg off, flagged valid, std 0.34 deg
    est = _estimate(truth, sideslip_rad=err)
    est["vx_std_mps"] = np.full(n, 0.1)
    est["velocity_valid"] = np.ones(n, dtype=int)
    path = _write(tmp_path / "est.csv", est)
    r = evaluate(tpath, path, settle_s=5.0)
    v = r["sideslip"]["validity"]
    assert r["sideslip"]["max_abs"] < 1e-9  # settled statistics do not see it ...
    assert v["worst_error_valid"] == pytest.approx(math.radians(5.0))  # ... the validity metrics do
    assert v["valid_beyond_3sigma"] == 100
    assert v["coverage_3sigma"] == pytest.approx(1 - 100 / n)
    assert v["time_to_valid_s"] == 0.0
    assert "validity" not in r["vy"] and r["vx"]["validity"]["valid_rows"] == n  # no vy_std_mps column here
    assert cli_main(["evaluate", "--truth", str(tpath), "--estimate", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(f"non-JSON {c}"))
    assert doc["sideslip"]["validity"]["valid_beyond_3sigma"] == 100
    assert doc["heading"]["validity"]["time_to_valid_after_fix_s"] is not None
    assert cli_main(["evaluate", "--truth", str(tpath), "--estimate", str(path)]) == 0
    assert "in 3sig" in capsys.readouterr().out


def test_time_to_valid_after_fix_is_zero_when_already_valid():
    t = np.arange(6.0)
    v = validity_metrics(t, np.zeros(6), np.ones(6), np.array([0, 1, 1, 1, 0, 1], bool), np.full(6, 9.0),
                         0.0, 2.5)
    assert v["time_to_valid_after_fix_s"] == 0.0 and v["time_to_valid_s"] == 1.0
    v = validity_metrics(t, np.zeros(6), np.ones(6), np.array([0, 1, 1, 1, 0, 1], bool), np.full(6, 9.0),
                         0.0, 4.5)
    assert v["time_to_valid_after_fix_s"] == 0.5  # invalid when the fix came, valid at t = 5
