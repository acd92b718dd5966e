"""``ecu-daemon fleet``: a small simulated fleet through the real replay, on every backend.

The fleet is 3 vehicles x 3 short drives written by ``fleet simulate`` (the real simulator). The
Dask test starts a real ``LocalCluster`` with two worker processes and requires the same table
bytes as the run in this process.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.cli import main as cli_main
from ecu_daemon.fleet import job as job_mod
from ecu_daemon.evaluate import EvaluationError
from ecu_daemon.fleet.calibrate import LATENCY_SYSTEMATIC_S, SLOPE_REL_ERR, combine, outliers, override_toml, vehicle_parameters
from ecu_daemon.fleet.cli import run_fleet
from ecu_daemon.fleet.manifest import discover, load_drives
from ecu_daemon.fleet.simfleet import write_fleet
from ecu_daemon.fleet.tables import read_drives

TABLES = ("drives.parquet", "drives.csv", "vehicles.parquet", "vehicles.csv")


@pytest.fixture(scope="module")
def fleet(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("fleet") / "fleet"
    write_fleet(root, vehicles=3, drives=3, seed=5, duration_s=14.0, jobs=1)
    return root


@pytest.fixture(scope="module")
def serial(fleet, tmp_path_factory) -> tuple[Path, list[dict]]:
    out = tmp_path_factory.mktemp("serial")
    return out, run_fleet(str(fleet), out, jobs=1, report=True)


@pytest.fixture(scope="module")
def timed_fleet(tmp_path_factory) -> Path:
    """Drives long enough to time the GNSS (the second pass needs a vehicle with a learned latency).
    The 14 s drives of ``fleet`` carry too little timing information: with latency.TIMING_INFORMATION
    none of them leaves its 0.3 s prior; before it, one did (car02 drive002: 0.284 s for a true 0.410,
    moved the wrong way by the wheels' sample noise), and that spurious latency was the second pass's
    only start. At 30 s every drive learns its latency (within 0.035 s of the truth, std 0.012-0.042 s)."""
    root = tmp_path_factory.mktemp("timed") / "fleet"
    write_fleet(root, vehicles=2, drives=2, seed=5, duration_s=30.0, jobs=1)
    return root


@pytest.fixture(scope="module")
def timed_serial(timed_fleet, tmp_path_factory) -> tuple[Path, list[dict]]:
    out = tmp_path_factory.mktemp("timed_serial")
    return out, run_fleet(str(timed_fleet), out, jobs=1, report=False)


def _bytes(out: Path) -> dict[str, bytes]:
    return {n: (out / n).read_bytes() for n in TABLES}


def test_simulated_fleet_has_known_different_vehicles(fleet):
    drives = discover(fleet)
    assert [(d.vehicle, d.drive) for d in drives][:2] == [("car01", "drive001"), ("car01", "drive002")]
    assert len(drives) == 9 and all(d.truth and len(d.gnss) == 1 for d in drives)
    assert all(d.config == str(fleet / d.vehicle / "config.toml") for d in drives)
    latencies = {config_mod.load(d.config).gnss.delay_s for d in drives}
    assert latencies == {0.3}  # the nominal prior; the truth differs per vehicle
    truth = [job_mod.read_csv(d.truth, ("t", "gnss_delay_s", "wheel_scale"), "truth") for d in drives[::3]]
    assert len({round(float(t["gnss_delay_s"][0]), 3) for t in truth}) == 3
    assert len({round(float(t["wheel_scale"][0]), 4) for t in truth}) == 3


def test_serial_run_scores_and_learns_every_drive(fleet, serial):
    out, records = serial
    assert [r["status"] for r in records] == ["ok"] * 9
    rows = read_drives(out)
    assert len(rows) == 9
    for r in rows:
        assert r["duration_s"] == pytest.approx(14.0, abs=0.1)
        assert 0.0 <= r["sideslip_valid_fraction"] <= 1.0
        assert math.isfinite(r["wheel_scale"]) and 0 < r["wheel_scale_std"] < 0.05
        truth = json.loads((fleet / r["vehicle"] / "vehicle.json").read_text())
        assert r["true_wheel_scale"] == truth["wheel_scale"]
        assert r["true_gnss_delay_s"] == pytest.approx(truth["gnss_latency_s"])
        assert math.isfinite(r["sideslip_rms"])
    report = (out / "report.md").read_text()
    pngs = [line.split("(")[1].rstrip(")") for line in report.splitlines() if line.startswith("![")]
    assert set(pngs) == {"validity.png", "latency.png", "params_car01.png", "params_car02.png", "params_car03.png"}
    assert all((out / p).stat().st_size > 1000 for p in pngs)


def test_dask_local_cluster_gives_the_same_bytes(fleet, serial, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:
        recs = run_fleet(str(fleet), tmp_path, scheduler=cluster.scheduler_address, report=False)
    assert not any(r["cached"] for r in recs)  # really replayed on the workers
    assert _bytes(tmp_path) == _bytes(serial[0])


def test_local_process_pool_gives_the_same_bytes(fleet, serial, tmp_path):
    recs = run_fleet(str(fleet), tmp_path, jobs=2, report=False)
    assert not any(r["cached"] for r in recs)
    assert _bytes(tmp_path) == _bytes(serial[0])


def test_rerun_skips_stored_drives_and_redoes_a_missing_one(fleet, serial, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(serial[0], out)
    stored = sorted((out / "results").rglob("*.json"))
    assert len(stored) == 9
    mtimes = [p.stat().st_mtime_ns for p in stored]
    stored[4].unlink()  # as if the run had been killed before this drive finished
    recs = run_fleet(str(fleet), out, jobs=1, report=False)
    assert sum(not r["cached"] for r in recs) == 1
    assert [p.stat().st_mtime_ns for i, p in enumerate(stored) if i != 4] == mtimes[:4] + mtimes[5:]
    assert _bytes(out) == _bytes(serial[0])
    assert all(r["cached"] for r in run_fleet(str(fleet), out, jobs=1, report=False))


def test_content_key_follows_inputs_config_and_version(fleet, tmp_path, monkeypatch):
    d = discover(fleet)[0]
    key = job_mod.content_key(d)
    cfg = tmp_path / "config.toml"
    cfg.write_text(Path(d.config).read_text().replace("delay_s = 0.3", "delay_s = 0.31"))
    assert job_mod.content_key(type(d)(**{**d.__dict__, "config": str(cfg)})) != key
    monkeypatch.setattr(job_mod, "__version__", "9.9.9")
    assert job_mod.content_key(d) != key


def test_bad_drives_are_rows_with_their_error_and_the_rest_finish(fleet, tmp_path, capsys):
    root = tmp_path / "fleet"
    shutil.copytree(fleet, root)
    bad = root / "car02" / "drive004"
    bad.mkdir()
    (bad / "drive.log").write_bytes(b"\x00\xffnot a candump log\n" * 50)
    gone = root / "car03" / "drive002" / "drive_gnss.log"
    gone.chmod(0)
    unreadable = not os.access(gone, os.R_OK)  # root reads anything: then the drive is just fine
    out = tmp_path / "out"
    rc = cli_main(["fleet", "run", str(root), "--out", str(out), "--jobs", "2", "--no-progress"])
    rows = {(r["vehicle"], r["drive"]): r for r in read_drives(out)}
    assert rc == 1
    assert rows[("car02", "drive004")]["status"] == "error"
    assert "drive004" in capsys.readouterr().err
    err = rows[("car02", "drive004")]["error"]
    assert "expected '(timestamp) interface ID#DATA'" in err and "Traceback" not in err
    assert "kept in" not in err  # the job's temporary estimate is gone: no path that differs per run
    if unreadable:
        assert rows[("car03", "drive002")]["status"] == "error"
        assert "ermission" in rows[("car03", "drive002")]["error"]
    ok = [r for r in rows.values() if r["status"] == "ok"]

    assert len(ok) == 9 - unreadable
    assert "car02/drive004" in (out / "report.md").read_text()


def test_manifest_and_record_layout(fleet, tmp_path):
    """A manifest names the files; a ``--record`` folder (can.log + gnss.log) is found as it is."""
    from ecu_daemon.canlog import read_can_log
    from ecu_daemon.gnss.logfile import read_gnss_log
    from ecu_daemon.io.recorder import Recorder

    import can

    src = discover(fleet)[0]
    rec_dir = tmp_path / "tree" / "car01" / "2026-12-01"
    rec = Recorder(rec_dir)
    for t, fid, ext, err, data in read_can_log(src.can):
        rec.on_can(t, can.Message(arbitration_id=fid, data=data, is_extended_id=ext, is_error_frame=err))
    for t, _, payload in read_gnss_log(src.gnss[0]):
        rec.on_gnss(t, payload)
    rec.close()
    shutil.copy(src.config, tmp_path / "tree" / "car01" / "config.toml")
    (d,) = load_drives(tmp_path / "tree")
    assert (d.vehicle, d.drive, Path(d.can).name, [Path(g).name for g in d.gnss]) == \
        ("car01", "2026-12-01", "can.log", ["gnss.log"])
    manifest = tmp_path / "fleet.toml"
    manifest.write_text(f'[[drive]]\nvehicle = "car01"\ndrive = "m1"\nconfig = "{src.config}"\ncan = "{src.can}"\n'
                        f'gnss = "{src.gnss[0]}"\n')
    (m,) = load_drives(manifest)
    recorded = job_mod.run_drive(d, str(tmp_path / "r1"))
    listed = job_mod.run_drive(m, str(tmp_path / "r2"))
    assert recorded["status"] == listed["status"] == "ok"
    for k in ("wheel_scale", "gnss_delay_s", "yaw_rate_bias_radps", "sideslip_valid_fraction"):
        assert recorded[k] == listed[k]


def test_calibrate_prints_an_override_the_config_loader_reads(serial, tmp_path, capsys):
    out, _ = serial
    assert cli_main(["fleet", "calibrate", "--out", str(out), "--vehicle", "car02"]) == 0
    text = capsys.readouterr().out
    path = tmp_path / "override.toml"
    path.write_text(text)
    cfg = config_mod.load(path)
    doc = tomllib.loads(text)
    rows = [r for r in read_drives(out) if r["vehicle"] == "car02"]
    learned = [r["gnss_delay_s"] for r in rows if math.isfinite(r["gnss_delay_s_std"])]
    if "gnss" in doc:  # set only when the drives know it to 0.02 s
        assert cfg.gnss.delay_s == doc["gnss"]["delay_s"]
        assert min(learned) - 1e-4 <= cfg.gnss.delay_s <= max(learned) + 1e-4
    assert "wheel_scale" in text and "learned state, no config key" in text
    assert override_toml("car02", rows) == text
    assert cli_main(["fleet", "calibrate", "--out", str(out), "--vehicle", "nope"]) == 2


def test_combine_weights_by_information_and_skips_the_uninformed():
    r = combine(np.array([1.0, 2.0, 50.0]), np.array([0.1, 0.2, math.nan]))
    w = np.array([100.0, 25.0])
    assert r["value"] == pytest.approx((w @ [1.0, 2.0]) / w.sum())
    assert r["std"] == pytest.approx(1 / math.sqrt(w.sum()))
    assert r["drives"] == 2
    plain = combine(np.array([1.0, 3.0]), None)  # no uncertainty model: mean and its standard error
    assert plain["value"] == 2.0 and plain["std"] == pytest.approx(math.sqrt(2) / math.sqrt(2))
    assert math.isnan(combine(np.array([1.0]), np.array([math.nan]))["value"])


def test_outliers_need_a_robust_and_an_own_sigma_excess():
    v = np.array([1.00, 1.01, 0.99, 1.02, 0.98, 1.5])
    assert outliers(v, np.full(6, 0.01)).tolist() == [False] * 5 + [True]
    assert not outliers(v, np.full(6, 0.3)).any()  # within its own 3 sigma: not flagged
    assert not outliers(v[:3], np.full(3, 0.01)).any()  # too few drives to say


def test_progress_counts_failures_and_only_the_drives_replayed_now():
    from ecu_daemon.fleet.progress import FleetProgress

    with FleetProgress(3, enabled=False) as bar:
        bar.done({"status": "ok", "duration_s": 3600.0, "cached": False})
        bar.done({"status": "ok", "duration_s": 7200.0, "cached": True})  # stored earlier: no work now
        bar.done({"status": "error", "cached": False})
    assert (bar.drive_s, bar.failed) == (3600.0, 1)
    assert bar.progress.tasks[0].completed == 3


def _row(i: int, **values) -> dict:
    row = {"vehicle": "v", "drive": f"d{i}", "status": "ok"}
    for name in job_mod.PARAMS:
        row[name], row[f"{name}_std"] = values.get(name, (math.nan, math.nan))
    return row


def test_override_sets_only_well_known_config_parameters_and_loads(tmp_path):
    rows = [_row(i, gnss_delay_s=(0.41 + 0.01 * (i % 2), 0.02), wheel_scale=(1.01, 1e-4),
                 cornering_stiffness_front_n_per_rad=(90e3 + 1e3 * i, 5e3),
                 cornering_stiffness_rear_n_per_rad=(140e3, 60e3)) for i in range(4)]
    rows.append({"vehicle": "v", "drive": "broken", "status": "error", "error": "x"})
    text = override_toml("v", rows)
    path = tmp_path / "o.toml"
    path.write_text(text)
    cfg = config_mod.load(path)
    assert cfg.gnss.delay_s == 0.415  # 4 drives of 0.02 s each: 0.01 s combined
    assert cfg.vehicle.cornering_stiffness_front_n_per_rad == 91500.0  # 2.5 kN/rad: 2.7 % of the value
    rear_default = config_mod.Config().vehicle.cornering_stiffness_rear_n_per_rad
    assert cfg.vehicle.cornering_stiffness_rear_n_per_rad == rear_default  # 30 kN/rad: not set
    # identical drives: their scatter (none) beside their stds' own degree of freedom, and the shared part
    from ecu_daemon.fleet.calibrate import OWN_STD_DOF, SHARED

    ws_std = math.hypot(1e-4 / 2 * math.sqrt(OWN_STD_DOF / (3 + OWN_STD_DOF)), SHARED["wheel_scale"])
    assert "4 of 5 drive(s) usable" in text and f"# wheel_scale: 1.01 +- {ws_std:.3g}" in text


def test_an_unreachable_scheduler_is_one_line(fleet, tmp_path, capsys):
    pytest.importorskip("distributed")
    import dask

    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        rc = cli_main(["fleet", "run", str(fleet), "--out", str(tmp_path), "--scheduler", "tcp://127.0.0.1:9",
                       "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in err and "Traceback" not in err


def test_calibrate_state_file_is_what_the_estimator_restores(serial, tmp_path, capsys):
    from ecu_daemon.estimator import Estimator
    from ecu_daemon.fleet.calibrate import vehicle_parameters
    from ecu_daemon.io.state_store import load_state

    out, _ = serial
    state = tmp_path / "state.json"
    assert cli_main(["fleet", "calibrate", "--out", str(out), "--vehicle", "car03", "--state", str(state)]) == 0
    capsys.readouterr()
    rows = [r for r in read_drives(out) if r["vehicle"] == "car03"]
    params, _ = vehicle_parameters(rows)
    cfg = config_mod.load(None)
    restored = Estimator(cfg, load_state(state)).learned_state()  # before the first sample: what it starts from
    assert restored["wheel_scale"] == params["wheel_scale"]["value"]
    assert restored["yaw_rate_bias_radps"] == params["yaw_rate_bias_radps"]["value"]


def test_a_drive_with_two_receivers_replays_both_captures(tmp_path):
    """A front-rear drive's two captures are both found, in receiver order, and both fused."""
    from ecu_daemon.sim import writer
    from ecu_daemon.sim.run import simulate, vehicle_config
    from ecu_daemon.sim.scenario import SCENARIOS

    sc = SCENARIOS["dlc_dry"].with_(name="two", gnss_lever_arm_m=(1.5, 0.0), gnss_latency_s=0.4,
                                    gnss2_lever_arm_m=(-1.0, 0.0), gnss2_latency_s=0.33, latency_prior_s=0.3)
    cfg = vehicle_config(sc)
    d = tmp_path / "fleet" / "car09" / "d1"
    d.mkdir(parents=True)
    writer.write_all(d, simulate(sc, cfg), cfg)
    (drive,) = discover(tmp_path / "fleet")
    assert [Path(g).name for g in drive.gnss] == ["drive_gnss.log", "drive_gnss2.log"]
    (rec,) = run_fleet(str(tmp_path / "fleet"), tmp_path / "out", jobs=1, report=False)
    assert rec["status"] == "ok", rec["error"]
    assert rec["gnss_delay_s"] == pytest.approx(0.4, abs=0.03)


def test_stiffness_is_combined_at_the_vehicles_latency_with_the_latency_error_added_once():
    # each drive's stiffness was learned at its own latency estimate (0.30 +- 0.02 s around the
    # truth 0.30) and moves with it by its slope (the regression's d C / d tau); the drives
    # least sensitive to the latency (so the most weighted) have it short: the plain average is biased
    true_c, tau = 100e3, 0.30
    offsets = [0.02, 0.02, -0.02, -0.02, 0.01, -0.01]
    slopes = [-3e6, -3e6, -1e6, -1e6, -2e6, -2e6]  # N/rad per s: -60 %/0.2 s .. -20 %/0.2 s
    rows = []
    for i, (off, k) in enumerate(zip(offsets, slopes)):
        row = _row(i, gnss_delay_s=(tau + off, 0.02),
                   cornering_stiffness_front_n_per_rad=(true_c + k * off, math.hypot(2e3, k * 0.02)))
        row.update({"stiffness_latency_s": tau + off,
                    "cornering_stiffness_front_n_per_rad_std_given_latency": 2e3,
                    "cornering_stiffness_front_n_per_rad_per_latency_s": k})
        rows.append(row)
    plain = combine(np.array([r["cornering_stiffness_front_n_per_rad"] for r in rows]),
                    np.array([r["cornering_stiffness_front_n_per_rad_std"] for r in rows]))
    assert plain["value"] > 1.08 * true_c  # what the combination gave before
    params, flagged = vehicle_parameters(rows)
    lat, front = params["gnss_delay_s"], params["cornering_stiffness_front_n_per_rad"]
    assert lat["value"] == pytest.approx(tau) and not flagged
    assert front["value"] == pytest.approx(true_c, rel=1e-9)
    # per drive: the noise and the move's own uncertainty (the slope is first order); the noise
    # averages down over the 6 drives, the latency's error (common to all) does not
    w = 1.0 / (2e3 ** 2 + (SLOPE_REL_ERR * np.array(slopes) * np.array(offsets)) ** 2)
    mean_slope = float(w @ slopes / w.sum())
    assert front["std"] == pytest.approx(math.hypot(1.0 / math.sqrt(w.sum()), mean_slope * lat["std"]))
    assert front["std"] > 1.0 / math.sqrt(w.sum()) * 1.5
    # without the slopes (records of an older version): the drives' own values and stds
    old = [{k: v for k, v in r.items() if "latency" not in k} for r in rows]
    assert vehicle_parameters(old)[0]["cornering_stiffness_front_n_per_rad"]["value"] == pytest.approx(plain["value"])


def test_latency_std_of_a_vehicle_is_at_least_what_its_drives_spread_shows():
    rows = [_row(i, gnss_delay_s=(0.30 + (0.03 if i % 2 else -0.03), 0.005)) for i in range(8)]
    lat = vehicle_parameters(rows)[0]["gnss_delay_s"]
    # not 0.005 / sqrt(8); and the error all of one car's drives share on top
    assert lat["std"] == pytest.approx(math.hypot(0.03 / math.sqrt(7), LATENCY_SYSTEMATIC_S))


def test_numeric_csv_reader_gives_read_csvs_columns_and_errors(tmp_path):
    good = tmp_path / "good.csv"
    good.write_text("t,a,b\n0.0,1.5,nan\n0.1,2.25e-3,-7\n0.2,0.1,1\n")
    fast, ref = job_mod.read_numeric_csv(str(good), ("t", "a"), "x"), job_mod.read_csv(good, ("t", "a"), "x")
    assert fast.keys() == ref.keys()
    assert all(np.array_equal(fast[k], ref[k], equal_nan=True) for k in ref)
    words = tmp_path / "words.csv"  # booleans as words: read_csv's own conversion
    words.write_text("t,a,ok\n0.0,1,true\n0.1,2,false\n")
    assert job_mod.read_numeric_csv(str(words), ("t",), "x")["ok"].tolist() == [1.0, 0.0]
    bad = tmp_path / "bad.csv"
    bad.write_text("t,a\n0.0,1\n0.1,x\n")
    with pytest.raises(EvaluationError, match=r"bad.csv:3: column a: 'x' is not a number"):
        job_mod.read_numeric_csv(str(bad), ("t", "a"), "truth CSV")
    backwards = tmp_path / "backwards.csv"
    backwards.write_text("t,a\n0.2,1\n0.1,2\n")
    with pytest.raises(EvaluationError, match="not in time order"):
        job_mod.read_numeric_csv(str(backwards), ("t", "a"), "truth CSV")


def _wheel_scale_z(drives: int, own: float, said: float, cars: int = 400, seed: int = 3) -> np.ndarray:
    """z-scores of ``cars`` vehicles' combined wheel scale: each drive off by N(0, own) and saying
    ``said``, the car's truth at SHARED's common error (the braking slip every drive leaves in)."""
    from ecu_daemon.fleet.calibrate import SHARED

    rng = np.random.default_rng(seed)
    z = []
    for _ in range(cars):
        truth, common = 1.0 + 0.02 * rng.random(), SHARED["wheel_scale"] * rng.standard_normal()
        values = truth + common + own * rng.standard_normal(drives)
        p = vehicle_parameters([_row(i, wheel_scale=(x, said)) for i, x in enumerate(values)])[0]["wheel_scale"]
        z.append((p["value"] - truth) / p["std"])
    return np.array(z)


def test_wheel_scale_std_follows_the_drives_scatter_when_their_stds_are_cautious():
    # a filter's end-of-drive std carries its process noise: 20 x 20 simulated fleet, the drives
    # scatter ~0.4x their stds; the combined std must follow the scatter (z of unit variance),
    # not the stds (|z| <= 0.3 with them) nor read the deficit as a shared error (|z| <= 0.2)
    z = _wheel_scale_z(drives=20, own=0.0002, said=0.0005)
    assert 0.75 < float(np.mean(z ** 2)) < 1.3
    assert float(np.mean(np.abs(z) > 3)) < 0.02
    honest = _wheel_scale_z(drives=20, own=0.0005, said=0.0005)  # stds right: unchanged meaning
    assert 0.75 < float(np.mean(honest ** 2)) < 1.3


def test_wheel_scale_std_of_few_drives_does_not_collapse_when_they_agree_by_chance():
    from ecu_daemon.fleet.calibrate import OWN_STD_DOF, SHARED

    rows = [_row(i, wheel_scale=(1.02, 0.0005)) for i in range(2)]  # identical: scatter 0
    p = vehicle_parameters(rows)[0]["wheel_scale"]
    independent = 0.0005 / math.sqrt(2)
    assert p["std"] == pytest.approx(math.hypot(independent * math.sqrt(OWN_STD_DOF / (1 + OWN_STD_DOF)),
                                                SHARED["wheel_scale"]))
    assert p["std"] > 0.5 * independent
    # honest stds, 3 drives: a scatter of 2 degrees of freedom is itself uncertain (Student's t:
    # heavier tails than a Gaussian), the std's own degree of freedom keeps them near
    few = _wheel_scale_z(drives=3, own=0.0005, said=0.0005)
    assert float(np.mean(few ** 2)) < 1.4 and float(np.mean(np.abs(few) > 3)) < 0.03  # t, 3 dof: 5.8 %


def test_wheel_scale_std_of_independent_drives_averages_down():
    from ecu_daemon.fleet.calibrate import OWN_STD_DOF, SHARED

    rng = np.random.default_rng(4)
    s = np.full(20, 0.0005)
    values = 1.02 + s * rng.standard_normal(20)
    p = vehicle_parameters([_row(i, wheel_scale=(x, 0.0005)) for i, x in enumerate(values)])[0]["wheel_scale"]
    assert p["std"] < 2.0 * 0.0005 / math.sqrt(20)
    wide = 1.02 + 3 * s * rng.standard_normal(20)  # scattered 3x their stds: the std follows the scatter
    q = vehicle_parameters([_row(i, wheel_scale=(x, 0.0005)) for i, x in enumerate(wide)])[0]["wheel_scale"]
    r = (np.sum((wide - wide.mean()) ** 2) / 0.0005 ** 2 + OWN_STD_DOF) / (19 + OWN_STD_DOF)
    assert q["std"] == pytest.approx(math.hypot(0.0005 * math.sqrt(r / 20), SHARED["wheel_scale"]), rel=1e-9)
    assert q["std"] > 2.5 * 0.0005 / math.sqrt(20)


def test_yaw_rate_bias_std_follows_the_drives_scatter_too():
    rng = np.random.default_rng(6)
    values = 0.01 + 2e-5 * rng.standard_normal(20)  # drives agree to 2e-5, each says 5e-5
    p = vehicle_parameters([_row(i, yaw_rate_bias_radps=(x, 5e-5)) for i, x in enumerate(values)])[0]
    assert p["yaw_rate_bias_radps"]["std"] < 0.6 * 5e-5 / math.sqrt(20)


def test_drives_are_handed_out_longest_first(tmp_path):
    from ecu_daemon.fleet.backends import longest_first
    from ecu_daemon.fleet.manifest import Drive

    def drive(name: str, can_bytes: int, gnss_bytes: int) -> Drive:
        (tmp_path / f"{name}.log").write_bytes(b"x" * can_bytes)
        (tmp_path / f"{name}_gnss.log").write_bytes(b"x" * gnss_bytes)
        return Drive("v", name, str(tmp_path / f"{name}.log"), (str(tmp_path / f"{name}_gnss.log"),))

    drives = [drive("short", 100, 10), drive("long", 300, 10), drive("mid", 100, 150), drive("same", 100, 10),
              Drive("v", "missing", str(tmp_path / "nope.log"))]
    # the last to start are the short ones, so no worker is left with a long drive at the end
    assert longest_first(drives) == [1, 2, 0, 3, 4]


def test_second_pass_starts_half_the_drives_above_and_half_below_the_vehicles_latency():
    from ecu_daemon.fleet.calibrate import STRADDLE_S, second_pass_starts
    from ecu_daemon.fleet.manifest import Drive

    drives = [Drive("a", f"d{i}", "x.log") for i in range(6)] + [Drive("b", "d0", "x.log")]
    records = [_row(i, gnss_delay_s=(0.25 + 0.01 * (i % 2), 0.01)) for i in range(6)]
    records.append(_row(9))  # vehicle b learned no latency: its drive is left as it was
    starts = second_pass_starts(drives, records)
    tau = vehicle_parameters(records[:6])[0]["gnss_delay_s"]["value"]
    assert sorted(starts[:6]) == [round(tau - STRADDLE_S, 4)] * 3 + [round(tau + STRADDLE_S, 4)] * 3
    assert starts[6] is None
    assert second_pass_starts(drives, records) == starts  # by the drives' names, not by chance


def test_a_second_pass_replays_each_drive_from_its_vehicles_latency(timed_fleet, timed_serial, tmp_path):
    from ecu_daemon.fleet.calibrate import second_pass_starts

    fleet, serial = timed_fleet, timed_serial

    out = tmp_path / "two"
    shutil.copytree(serial[0] / "results", out / "results")  # the first pass is stored already
    recs = run_fleet(str(fleet), out, jobs=1, report=False, passes=2)
    first = {(r["vehicle"], r["drive"]): r for r in serial[1]}
    starts = second_pass_starts(load_drives(str(fleet)), serial[1])
    assert sum(s is not None for s in starts) >= 3  # (a vehicle whose drives learned no latency would keep pass 1)
    moved = []
    for r, s in zip(recs, starts):
        f = first[(r["vehicle"], r["drive"])]
        if s is None:
            assert r["cached"] and r["key"] == f["key"] and math.isnan(r["start_latency_s"])
            continue
        assert r["status"] == "ok" and not r["cached"] and r["key"] != f["key"] and r["start_latency_s"] == s
        moved.append(r["gnss_delay_s"] - f["gnss_delay_s"])
    assert any(abs(m) > 0.005 for m in moved)  # the estimator started where it was told
    assert math.isnan(read_drives(serial[0])[0]["start_latency_s"])  # the first pass: the config's
    tables = _bytes(out)
    again = run_fleet(str(fleet), out, jobs=1, report=False, passes=2)
    assert all(r["cached"] for r in again) and _bytes(out) == tables


def test_pool_workers_start_with_the_replay_imported():
    """A fresh interpreter (nothing of the replay imported) hands its pool workers a warm start."""
    import subprocess
    import sys

    code = ("from ecu_daemon.fleet.backends import pool_executor\n"
            "with pool_executor(1) as pool:\n"
            "    print(pool.submit(eval, \"'ecu_daemon.replay' in __import__('sys').modules\").result())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"


def test_a_drive_record_says_how_long_the_replay_itself_took(serial):
    _, recs = serial
    assert all(0.0 < r["replay_s"] <= r["wall_s"] for r in recs if r["status"] == "ok")


def test_free_rolling_wheels_read_the_scale_the_fleet_truth_names(tmp_path):
    """The non-driven (rear) wheels roll against their rolling resistance with a braking slip of
    -f_rr / kx1: at steady speed they read ground speed / wheel_scale_free_rolling, not / wheel_scale
    (the learned scale's +0.07 % over vehicle.json's wheel_scale on every simulated car)."""
    write_fleet(tmp_path, vehicles=1, drives=1, seed=5, duration_s=25.0, jobs=1)  # demo: speeds up, then holds 16 m/s
    truth = json.loads((tmp_path / "car01" / "vehicle.json").read_text())
    ws, free = truth["wheel_scale"], truth["wheel_scale_free_rolling"]
    assert free / ws - 1.0 == pytest.approx(0.012 / 18.0, rel=0.01)  # sim defaults: f_rr 0.012, kx1 18
    t = job_mod.read_numeric_csv(str(tmp_path / "car01" / "drive001" / "truth.csv"), ("t",), "truth")
    reported = 0.5 * (t["wheel_speed_rl_mps"] + t["wheel_speed_rr_mps"]) / ws  # what the ABS sensor sends
    steady = (t["vx_mps"] > 3.0) & (np.abs(t["ax_mps2"]) < 0.05)
    assert steady.sum() > 500
    shown = float(np.median(t["vx_mps"][steady] / reported[steady]))
    assert abs(shown / free - 1.0) < 5e-5 < 5e-4 < abs(shown / ws - 1.0)


def test_a_partial_second_pass_takes_the_most_informative_drives_straddled():
    from ecu_daemon.fleet.calibrate import STRADDLE_S, second_pass_starts
    from ecu_daemon.fleet.manifest import Drive

    drives = [Drive("a", f"d{i}", "x.log") for i in range(8)]
    # drives 5 and 6 know the latency best, 2 and 7 the front stiffness: a scale-free ranking
    lat_std = [0.04, 0.04, 0.04, 0.04, 0.04, 0.005, 0.006, 0.04]
    cf_std = [30e3, 30e3, 2e3, 30e3, 30e3, 30e3, 30e3, 2.5e3]
    records = [_row(i, gnss_delay_s=(0.25, lat_std[i]), cornering_stiffness_front_n_per_rad=(9e4, cf_std[i]))
               for i in range(8)]
    starts = second_pass_starts(drives, records, share=0.5)
    chosen = [i for i, s in enumerate(starts) if s is not None]
    assert chosen == [2, 5, 6, 7]
    tau = vehicle_parameters(records)[0]["gnss_delay_s"]["value"]
    assert sorted(starts[i] for i in chosen) == [round(tau - STRADDLE_S, 4)] * 2 + [round(tau + STRADDLE_S, 4)] * 2
    assert second_pass_starts(drives, records, share=0.01).count(None) == 6  # at least two drives
    assert second_pass_starts(drives, records) == second_pass_starts(drives, records, share=1.0)


def test_after_a_partial_second_pass_latency_and_stiffness_come_from_its_drives_alone():
    rows = [_row(i, gnss_delay_s=(0.30, 0.01), wheel_scale=(1.010, 1e-3),
                 cornering_stiffness_front_n_per_rad=(120e3, 5e3)) for i in range(4)]  # first pass
    for i in (0, 1):
        rows[i] = {**_row(i, gnss_delay_s=(0.20 + 0.02 * i, 0.01), wheel_scale=(1.012, 1e-3),
                          cornering_stiffness_front_n_per_rad=(90e3, 5e3)), "start_latency_s": 0.2 + 0.06 * i}
    p, _ = vehicle_parameters(rows)
    assert p["gnss_delay_s"]["value"] == pytest.approx(0.21) and p["gnss_delay_s"]["drives"] == 2
    assert p["cornering_stiffness_front_n_per_rad"]["drives"] == 2
    assert p["wheel_scale"]["drives"] == 4 and p["wheel_scale"]["value"] == pytest.approx(1.011)
    first_only = [{**r, "start_latency_s": math.nan} for r in rows]
    assert vehicle_parameters(first_only)[0]["gnss_delay_s"]["drives"] == 4


def test_a_partial_second_pass_replays_only_its_drives(timed_fleet, timed_serial, tmp_path):
    from ecu_daemon.fleet.calibrate import second_pass_starts

    fleet, serial = timed_fleet, timed_serial

    out = tmp_path / "part"
    shutil.copytree(serial[0] / "results", out / "results")  # the first pass is stored already
    assert cli_main(["fleet", "run", str(fleet), "--out", str(out), "--jobs", "1", "--no-report", "--no-progress",
                     "--passes", "2", "--second-pass-share", "0.5"]) == 0
    starts = second_pass_starts(load_drives(str(fleet)), serial[1], share=0.5)
    rows = read_drives(out)
    assert sum(s is not None for s in starts) >= 2
    for r, s in zip(rows, starts):
        assert (r["start_latency_s"] == s) if s is not None else math.isnan(r["start_latency_s"])
    assert cli_main(["fleet", "run", str(fleet), "--out", str(out), "--second-pass-share", "0"]) == 2
