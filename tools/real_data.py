"""Real-data evaluation through the real replay contract (CAN log + GNSS capture log -> replay).

Two subcommands:

``revs``  The Stanford Revs race car (550 s, 100 Hz, real INS sideslip truth) turned into exactly
          what a held-out scoring harness would feed the daemon: a candump log encoded with the
          real opendbc Toyota DBC through the ``[inputs]`` mapping of ``examples/toyota_rav4.toml``
          (KINEMATICS/STEER_ANGLE_SENSOR/WHEEL_SPEEDS at ~83.3 Hz, receive jitter, sensor biases,
          DBC quantisation), a delayed 5 Hz GNSS capture (UBX NAV-PVT or NMEA RMC+VTG+GGA), a
          ``truth.csv`` for ``ecu_daemon.evaluate`` and a ``config.toml``; then replay + evaluate.
``rav4``  The real comma2k19 Toyota RAV4 drive: the recorded candump log as is, a GNSS capture
          made from the u-blox fixes (stamped with their arrival time on the CAN clock), a
          RAV4-like config with a deliberately wrong delay prior; replay, then compare with the
          truths the data has (yaw-rate bias, wheel-speed scale, GNSS latency, course, beta ~ 0).

Why: the estimator must be judged on real vehicle motion through the same byte-level path a
car gives it (DBC decode, protocol parse, receive timestamps), not on samples fed directly.

    python3 tools/real_data.py revs --out /tmp/revs [--protocol ubx|nmea] [--wrong-params] [--seed N]
        [--gnss-outage START_S LENGTH_S]
    python3 tools/real_data.py rav4 --out /tmp/rav4 [--protocol ubx|nmea]
"""
from __future__ import annotations

import argparse
import copy
import gzip
import math
import shutil
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from ecu_daemon import config as config_mod  # noqa: E402
from ecu_daemon.canlog import CandumpWriter  # noqa: E402
from ecu_daemon.evaluate import evaluate, format_table, plot, read_csv  # noqa: E402
from ecu_daemon.gnss import encode  # noqa: E402
from ecu_daemon.gnss.logfile import GnssLogWriter  # noqa: E402
from ecu_daemon.replay import run_replay  # noqa: E402
from ecu_daemon.sim.can_encoder import FrameEncoder  # noqa: E402

SHARED = REPO.parent / "shared" / "data"
REVS_CSV = SHARED / "revs-250lm" / "revs_20140222_01_01_03_250lm.csv.gz"
RAV4_DIR = SHARED / "comma2k19-rav4"
EXAMPLE_TOML = REPO / "examples" / "toyota_rav4.toml"
DBC_NAME = "_toyota_2017.dbc"
EARTH_RADIUS_M = 6_378_137.0

T0 = 1000.0  # start of the Revs logs on the replay clock
UTC_OFFSET_S = 1393084800 - T0 + 18 * 3600  # t = 1000 s is 2014-02-22 18:00:00 UTC
TOYOTA_PERIOD_S = 0.012  # 83.3 Hz, as the RAV4's 0x24/0x25/0xAA
GNSS_PORT = "ttyACM0"

#: the sensor errors added to the Revs signals (also the truth of the bias states)
YAW_RATE_BIAS = math.radians(0.3)
ACCEL_X_BIAS = 0.1
ACCEL_Y_BIAS = -0.15
WHEEL_SCALE = 1.015  # true wheel speed / reported
STEERING_RATIO = 13.3
STEERING_OFFSET = math.radians(2.0)  # reading - true, at the steering wheel
GNSS_DELAY = 0.4
GNSS_RATE_HZ = 5.0

# README section 2: what the RAV4 segment's truth is
RAV4_YAW_BIAS_DEG_S = -0.41
RAV4_CAN_GNSS_SPEED_RATIO = 0.991
RAV4_DELAY_S = 0.202


# ------------------------------------------------------------------------------------ configs

def _base_config() -> config_mod.Config:
    return config_mod.load(EXAMPLE_TOML)


def _write_config(cfg: config_mod.Config, out: Path) -> Path:
    """config.toml in ``out`` with the Toyota DBC copied next to it (relative path resolves)."""
    src_dbc = cfg.dbc_path()
    shutil.copyfile(src_dbc, out / DBC_NAME)
    lic = src_dbc.parent / "LICENSE-opendbc"
    if lic.is_file():
        shutil.copyfile(lic, out / "LICENSE-opendbc")
    cfg = copy.deepcopy(cfg)
    cfg.can.output_dbc = str(cfg.output_dbc_path().resolve())
    cfg.can.dbc = DBC_NAME
    cfg.base_dir = None
    path = out / "config.toml"
    path.write_text(config_mod.to_toml(cfg), encoding="utf-8")
    config_mod.load(path)  # fail here, not in the replay, if it does not round-trip
    return path


def revs_config(wrong: bool = False, lever_x: float = 0.0) -> config_mod.Config:
    """Toyota [can]/[inputs] + the Revs car as the authors modelled it (``wrong``: detuned)."""
    cfg = _base_config()
    v = cfg.vehicle
    f = 0.3 if wrong else 0.0
    v.mass_kg = 982.0 * (1 + f)
    v.yaw_inertia_kgm2 = 1605.0 * (1 - f)
    v.cg_to_front_axle_m = 1.33
    v.cg_to_rear_axle_m = 1.07
    v.track_m = 1.35
    v.cornering_stiffness_front_n_per_rad = 7e4 * (1 - f)
    v.cornering_stiffness_rear_n_per_rad = 1.2e5 * (1 - f)
    v.steering_ratio = STEERING_RATIO
    v.driven_axle = "rear"
    v.wheel_radius_m = 0.3
    cfg.gnss.delay_s = 0.2 if wrong else GNSS_DELAY
    cfg.gnss.lever_arm_m = [float(lever_x), 0.0]
    return cfg


def rav4_config(protocol: str = "auto") -> config_mod.Config:
    cfg = _base_config()
    v = cfg.vehicle
    v.mass_kg = 1700.0
    v.yaw_inertia_kgm2 = 2900.0
    v.cg_to_front_axle_m = 1.1
    v.cg_to_rear_axle_m = 1.6
    v.track_m = 1.6
    v.wheel_radius_m = 0.34
    v.steering_ratio = 15.0
    v.cornering_stiffness_front_n_per_rad = 1.2e5
    v.cornering_stiffness_rear_n_per_rad = 1.4e5
    v.driven_axle = "front"
    cfg.gnss.delay_s = 0.1  # deliberately wrong prior (measured 0.20 s)
    cfg.gnss.protocol = protocol
    return cfg


# ------------------------------------------------------------------------------------ Revs

def load_revs(duration_s: float | None = None) -> dict[str, np.ndarray]:
    """Revs columns (SI, ISO 8855), time shifted to start at T0; optionally the first ``duration_s``."""
    with gzip.open(REVS_CSV, "rt") as f:
        header = f.readline().strip().split(",")
        data = np.loadtxt(f, delimiter=",")
    d = {name: data[:, i] for i, name in enumerate(header)}
    d["t"] = np.round(d["t_s"] - d["t_s"][0], 6) + T0
    if duration_s is not None:
        keep = d["t"] <= T0 + duration_s + 1e-9
        d = {k: v[keep] for k, v in d.items()}
    return d


def _heading(t: np.ndarray, r: np.ndarray, psi0: float) -> np.ndarray:
    """Heading clockwise from north integrated from the (CCW-positive) yaw rate, trapezoidal."""
    return psi0 - np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(t))])


def revs_truth(d: dict, lever_x: float) -> dict[str, np.ndarray]:
    t, vx, vy, r = d["t"], d["vx_mps"], d["vy_mps"], d["yaw_rate_radps"]
    psi = _heading(t, r, math.radians(30.0))
    cps, sps = np.cos(psi), np.sin(psi)
    vn, ve = vx * cps + vy * sps, vx * sps - vy * cps
    north = np.concatenate([[0.0], np.cumsum(0.5 * (vn[1:] + vn[:-1]) * np.diff(t))])
    east = np.concatenate([[0.0], np.cumsum(0.5 * (ve[1:] + ve[:-1]) * np.diff(t))])
    n = len(t)
    const = lambda v: np.full(n, float(v))  # noqa: E731
    return {
        "t": t,
        "sideslip_rad": d["beta_true_rad"],
        "heading_rad": np.mod(psi, 2 * math.pi),
        "vx_mps": vx,
        "vy_mps": vy,
        "yaw_rate_radps": r,
        "ax_mps2": d["ax_mps2"],
        "ay_mps2": d["ay_mps2"],
        "yaw_rate_bias_radps": const(YAW_RATE_BIAS),
        "accel_x_bias_mps2": const(ACCEL_X_BIAS),
        "accel_y_bias_mps2": const(ACCEL_Y_BIAS),
        "wheel_scale": const(WHEEL_SCALE),
        "steering_offset_rad": const(STEERING_OFFSET),
        "gnss_delay_s": const(GNSS_DELAY),
        "speed_mps": np.hypot(vx, vy),
        "vel_n_mps": vn,
        "vel_e_mps": ve,
        "north_m": north,
        "east_m": east,
        "road_wheel_angle_rad": d["delta_rad"],
        "antenna_lever_x_m": const(lever_x),
    }


def write_truth(path: Path, table: dict[str, np.ndarray]) -> None:
    names = list(table)
    cols = np.column_stack([table[n] for n in names])
    fmt = ["%.6f"] + ["%.9g"] * (len(names) - 1)
    np.savetxt(path, cols, fmt=fmt, delimiter=",", header=",".join(names), comments="")


def revs_sensor_values(d: dict, track: float, lf: float) -> dict[str, np.ndarray]:
    """What the Toyota sensors would measure, at the 100 Hz data rate (SI, before quantisation).

    No wheel speeds exist in the data: each is the ground speed of that wheel's contact point
    (CG velocity + yaw rate x position) projected on the wheel's heading (front wheels along
    their own road-wheel angle), divided by the wheel scale (ABS radius 1.5 % too small).
    """
    vx, vy, r = d["vx_mps"], d["vy_mps"], d["yaw_rate_radps"]
    half = 0.5 * track
    vxl, vxr = vx - r * half, vx + r * half
    vyf = vy + r * lf
    dfl, dfr = d["delta_fl_rad"], d["delta_fr_rad"]
    return {
        "wheel_speed_fl": (vxl * np.cos(dfl) + vyf * np.sin(dfl)) / WHEEL_SCALE,
        "wheel_speed_fr": (vxr * np.cos(dfr) + vyf * np.sin(dfr)) / WHEEL_SCALE,
        "wheel_speed_rl": vxl / WHEEL_SCALE,
        "wheel_speed_rr": vxr / WHEEL_SCALE,
        "steering_wheel_angle": d["delta_rad"] * STEERING_RATIO + STEERING_OFFSET,
        "yaw_rate": r + YAW_RATE_BIAS,
        "accel_x": d["ax_mps2"] + ACCEL_X_BIAS,
        "accel_y": d["ay_mps2"] + ACCEL_Y_BIAS,
    }


def write_revs_can(path: Path, cfg: config_mod.Config, d: dict, rng: np.random.Generator) -> int:
    """Candump log of the three Toyota messages at 83.3 Hz, sampled (interpolated) from 100 Hz.

    Each message has its own phase; a frame's value is the signal at its send time, and its
    receive stamp is the send time plus 0.1..0.9 ms of bus/driver latency (never reordered).
    """
    enc = FrameEncoder(cfg)
    values = revs_sensor_values(d, cfg.vehicle.track_m, cfg.vehicle.cg_to_front_axle_m)
    t = d["t"]
    frames = []
    for k, plan in enumerate(enc.plans):
        ts = np.arange(t[0] + 0.001 + 0.004 * k, t[-1], TOYOTA_PERIOD_S)
        rx = ts + rng.uniform(0.0001, 0.0009, len(ts))
        names = [name for name, *_ in plan.inputs]
        cols = {n: np.interp(ts, t, values[n]) for n in names}
        for i in range(len(ts)):
            data = enc.encode(plan, {n: cols[n][i] for n in names})
            frames.append((rx[i], plan.frame_id, data, plan.is_extended))
    frames.sort(key=lambda f: f[0])
    with CandumpWriter(path) as w:
        for tr, fid, data, ext in frames:
            w.write_frame(tr, fid, data, ext)
    return len(frames)


def write_revs_gnss(path: Path, d: dict, truth: dict, protocol: str, lever_x: float,
                    rng: np.random.Generator, noise_mps: float = 0.05,
                    outage: tuple[float, float] | None = None) -> int:
    """5 Hz fixes on the UTC grid, antenna velocity + white noise, received 0.4 s (+-4 ms) later.
    ``outage``: (start, end) on the replay clock: fixes valid in it are not written (a tunnel);
    the noise drawn is the same as without it, so the rest of the capture is byte-identical."""
    t = d["t"]
    period = 1.0 / GNSS_RATE_HZ
    tv = np.arange(math.ceil(round(t[0] / period, 9)), math.floor(round(t[-1] / period, 9)) + 1) * period
    vx, vy, r = (np.interp(tv, t, d[c]) for c in ("vx_mps", "vy_mps", "yaw_rate_radps"))
    psi = np.interp(tv, t, np.unwrap(truth["heading_rad"]))
    cps, sps = np.cos(psi), np.sin(psi)
    ux, uy = vx, vy + r * lever_x
    vn = ux * cps + uy * sps + rng.normal(0.0, noise_mps, len(tv))
    ve = ux * sps - uy * cps + rng.normal(0.0, noise_mps, len(tv))
    north = np.interp(tv, t, truth["north_m"]) + lever_x * cps
    east = np.interp(tv, t, truth["east_m"]) + lever_x * sps
    lat0, lon0 = 39.5387, -122.3316  # any start point (Thunderhill Raceway)
    lat = lat0 + np.degrees(north / EARTH_RADIUS_M)
    lon = lon0 + np.degrees(east / (EARTH_RADIUS_M * math.cos(math.radians(lat0))))
    t_rx = tv + GNSS_DELAY + rng.uniform(-0.004, 0.004, len(tv))
    n = 0
    with GnssLogWriter(path, GNSS_PORT) as w:
        for i in range(len(tv)):
            if t_rx[i] > t[-1]:
                break
            if outage is not None and outage[0] <= tv[i] < outage[1]:
                continue
            utc = round((tv[i] + UTC_OFFSET_S) * 1000.0) / 1000.0
            # the Revs data has no altitude: NMEA sends none (a made-up constant would say "flat")
            n += _write_fix(w, protocol, t_rx[i], utc, lat[i], lon[i], 50.0 if protocol == "ubx" else None,
                            vn[i], ve[i])
    return n


def _write_fix(w: GnssLogWriter, protocol: str, t_rx: float, utc: float, lat: float, lon: float,
               alt: float | None, vn: float, ve: float) -> int:
    """One receiver epoch into the capture log; returns the number of messages written."""
    if protocol == "ubx":
        frame = encode.nav_pvt(**encode.utc_fields(utc), fix_type=3, fix_ok=True, num_sv=14,
                               lat_deg=lat, lon_deg=lon, height_m=alt, vel_n_mps=vn, vel_e_mps=ve,
                               speed_acc_mps=0.3)
        w.write(t_rx, frame)
        return 1
    speed = math.hypot(vn, ve)
    course = math.degrees(math.atan2(ve, vn)) % 360.0
    lines = [encode.nmea_rmc(utc=utc, lat_deg=lat, lon_deg=lon, speed_mps=speed, course_deg=course),
             encode.nmea_vtg(speed_mps=speed, course_deg=course),
             encode.nmea_gga(utc=utc, lat_deg=lat, lon_deg=lon, num_sv=14, alt_m=alt)]
    for i, s in enumerate(lines):
        w.write(t_rx + 0.004 * i, (s + "\r\n").encode("ascii"))
    return len(lines)


def build_revs(out: Path, protocol: str = "ubx", wrong: bool = False, seed: int = 1,
               duration_s: float | None = None, lever_x: float = 0.0,
               outage: tuple[float, float] | None = None) -> dict[str, Path]:
    """Write drive.log, drive_gnss.log, truth.csv, config.toml (+ the DBC) into ``out``;
    ``outage``: a GNSS outage (start, end) on the replay clock (:func:`write_revs_gnss`)."""
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    d = load_revs(duration_s)
    truth = revs_truth(d, lever_x)
    enc_cfg = revs_config(False, lever_x)  # the sensors are the same whatever the config believes
    paths = {"can": out / "drive.log", "gnss": out / "drive_gnss.log", "truth": out / "truth.csv"}
    write_revs_can(paths["can"], enc_cfg, d, rng)
    write_revs_gnss(paths["gnss"], d, truth, protocol, lever_x, rng, outage=outage)
    write_truth(paths["truth"], truth)
    paths["config"] = _write_config(revs_config(wrong, lever_x), out)
    return paths


def run_revs(out: Path, protocol: str = "ubx", wrong: bool = False, seed: int = 1,
             duration_s: float | None = None, lever_x: float = 0.0, settle_s: float = 20.0,
             plots: Path | None = None, outage: tuple[float, float] | None = None) -> tuple[dict, dict]:
    """Build the Revs drive, replay it, evaluate; returns (evaluate result, replay summary).
    ``outage``: (start, length) in s from the start of the drive: no GNSS fix valid in it, and
    ``result["outage"]`` is :func:`outage_metrics` over it."""
    window = None if outage is None else (T0 + outage[0], T0 + outage[0] + outage[1])
    paths = build_revs(out, protocol, wrong, seed, duration_s, lever_x, window)
    cfg = config_mod.load(paths["config"])
    est = out / "estimate.csv"
    summary = run_replay(cfg, str(paths["can"]), str(paths["gnss"]), str(est))
    result = evaluate(paths["truth"], est, settle_s=settle_s)
    if window is not None:
        result["outage"] = outage_metrics(paths["truth"], est, *window)
    if plots is not None:
        plot(paths["truth"], est, plots)
    return result, summary


#: an outage is scored until this long after its end (the fixes' latency, then the re-convergence)
OUTAGE_AFTER_S = 5.0


def outage_metrics(truth_csv: Path, est_csv: Path, start: float, end: float) -> dict:
    """Sideslip in a GNSS outage (start..end, replay clock) and the OUTAGE_AFTER_S after it, on the
    rows above 5 m/s: where the single-track model alone holds it, how wrong it is against the std
    it publishes (error percentiles, std percentiles) and what its valid flag promised (valid
    share, valid rows within 3 sigma, worst error while valid). Angles in degrees."""
    truth = read_csv(truth_csv, ("t", "sideslip_rad", "vx_mps"), "truth CSV")
    est = read_csv(est_csv, ("t", "sideslip_rad", "sideslip_std_rad", "sideslip_valid"), "estimate CSV")
    te = est["t"]
    keep = (te >= start) & (te < end + OUTAGE_AFTER_S)
    te = te[keep]
    err = np.degrees(est["sideslip_rad"][keep] - np.interp(te, truth["t"], truth["sideslip_rad"]))
    std = np.degrees(est["sideslip_std_rad"][keep])
    fast = np.interp(te, truth["t"], truth["vx_mps"]) > 5.0
    err, std, valid = np.abs(err[fast]), std[fast], est["sideslip_valid"][keep][fast] > 0.5
    if len(err) == 0:
        return {"rows": 0}
    out = {"rows": int(len(err)), "rms_deg": float(np.sqrt(np.mean(err ** 2))),
           "err_p50_deg": float(np.percentile(err, 50)), "err_p95_deg": float(np.percentile(err, 95)),
           "err_max_deg": float(err.max()), "std_p50_deg": float(np.percentile(std, 50)),
           "std_p95_deg": float(np.percentile(std, 95)), "valid_fraction": float(valid.mean()),
           "coverage_3sigma": math.nan, "worst_valid_deg": math.nan}
    if valid.any():
        out["coverage_3sigma"] = float(np.mean(err[valid] <= 3.0 * std[valid]))
        out["worst_valid_deg"] = float(err[valid].max())
    return out


def format_outage(m: dict, start: float, length: float) -> str:
    if not m.get("rows"):
        return f"GNSS outage {start:g}+{length:g} s: no rows above 5 m/s"
    return (f"GNSS outage {start:g}+{length:g} s (and {OUTAGE_AFTER_S:g} s after), sideslip on {m['rows']} rows"
            f" above 5 m/s: rms {m['rms_deg']:.3f} deg, |error| p50 {m['err_p50_deg']:.2f} p95"
            f" {m['err_p95_deg']:.2f} max {m['err_max_deg']:.2f}; std p50 {m['std_p50_deg']:.2f} p95"
            f" {m['std_p95_deg']:.2f}; valid {m['valid_fraction']:.1%}, valid within 3 sigma"
            f" {m['coverage_3sigma']:.1%}, worst valid {m['worst_valid_deg']:.2f} deg")


# ------------------------------------------------------------------------------------ RAV4

def load_rav4_gnss() -> dict[str, np.ndarray]:
    """Columns of comma's u-blox fixes (README section 2), float64 (utc_ms is exact in float64)."""
    path = RAV4_DIR / "ublox_live_gnss.csv"
    with open(path, encoding="ascii") as f:
        header = f.readline().strip().split(",")
        data = np.loadtxt(f, delimiter=",", ndmin=2)
    return {name: data[:, i] for i, name in enumerate(header)}


def write_rav4_gnss(path: Path, protocol: str) -> int:
    """The u-blox fixes as a capture log, each stamped with its arrival time (CAN clock)."""
    g = load_rav4_gnss()
    n = 0
    with GnssLogWriter(path, GNSS_PORT) as w:
        for i in range(len(g["t_boot_s"])):
            n += _write_fix(w, protocol, float(g["t_boot_s"][i]), float(g["utc_ms"][i]) / 1000.0,
                            float(g["lat_deg"][i]), float(g["lon_deg"][i]), float(g["alt_m"][i]),
                            float(g["vn_mps"][i]), float(g["ve_mps"][i]))
    return n


def rav4_metrics(est_csv: Path, settle_s: float = 20.0) -> dict:
    """Estimates vs the truths the RAV4 segment has (README section 2), after ``settle_s``."""
    e = read_csv(est_csv, ("t", "sideslip_rad", "heading_rad", "yaw_rate_bias_radps", "wheel_scale",
                           "gnss_delay_s"), "estimate CSV")
    g = load_rav4_gnss()
    t = e["t"]
    sel = t >= t[0] + settle_s
    # course vs heading at the fix's own epoch; on a straight highway beta ~ 0 so they agree
    gs = (g["fix_time_boot_s"] >= t[sel][0]) & (g["fix_time_boot_s"] <= t[-1])
    hd = np.interp(g["fix_time_boot_s"][gs], t, np.unwrap(e["heading_rad"]))
    dh = np.degrees((hd - np.radians(g["bearing_deg"][gs]) + math.pi) % (2 * math.pi) - math.pi)
    beta = np.degrees(e["sideslip_rad"][sel])
    hv = e["heading_valid"][sel] > 0.5 if "heading_valid" in e else np.ones(sel.sum(), bool)
    return {
        "settle_s": settle_s,
        "t_span_s": float(t[-1] - t[0]),
        "yaw_rate_bias_deg_s": float(np.degrees(e["yaw_rate_bias_radps"][-1])),
        "yaw_rate_bias_mean_deg_s": float(np.degrees(np.mean(e["yaw_rate_bias_radps"][sel]))),
        "yaw_rate_bias_ref_deg_s": RAV4_YAW_BIAS_DEG_S,
        "wheel_scale": float(e["wheel_scale"][-1]),
        "wheel_scale_ref": 1.0 / RAV4_CAN_GNSS_SPEED_RATIO,
        "gnss_delay_s": float(e["gnss_delay_s"][-1]),
        "gnss_delay_ref_s": RAV4_DELAY_S,
        "heading_minus_course_mean_deg": float(np.mean(dh)),
        "heading_minus_course_rms_deg": float(np.sqrt(np.mean(dh ** 2))),
        "heading_minus_course_max_deg": float(np.max(np.abs(dh))),
        "heading_valid_fraction": float(np.mean(hv)),
        "sideslip_mean_abs_deg": float(np.mean(np.abs(beta))),
        "sideslip_max_abs_deg": float(np.max(np.abs(beta))),
        "sideslip_mean_deg": float(np.mean(beta)),
    }


def run_rav4(out: Path, protocol: str = "ubx", settle_s: float = 20.0) -> tuple[dict, dict]:
    out.mkdir(parents=True, exist_ok=True)
    gnss = out / "drive_gnss.log"
    write_rav4_gnss(gnss, protocol)
    cfg_path = _write_config(rav4_config(), out)
    cfg = config_mod.load(cfg_path)
    est = out / "estimate.csv"
    summary = run_replay(cfg, str(RAV4_DIR / "rav4_bus0_candump.log"), str(gnss), str(est))
    return rav4_metrics(est, settle_s), summary


def format_rav4(m: dict) -> str:
    return "\n".join([
        f"RAV4 comma2k19, {m['t_span_s']:.1f} s, statistics after the first {m['settle_s']:g} s",
        f"{'quantity':<28}{'estimate':>12}{'reference':>12}",
        f"{'yaw-rate bias (final)':<28}{m['yaw_rate_bias_deg_s']:>12.3f}{m['yaw_rate_bias_ref_deg_s']:>12.3f}  deg/s",
        f"{'yaw-rate bias (mean)':<28}{m['yaw_rate_bias_mean_deg_s']:>12.3f}{m['yaw_rate_bias_ref_deg_s']:>12.3f}  deg/s",
        f"{'wheel scale (final)':<28}{m['wheel_scale']:>12.4f}{m['wheel_scale_ref']:>12.4f}  true/wheel",
        f"{'GNSS delay (final)':<28}{m['gnss_delay_s']:>12.3f}{m['gnss_delay_ref_s']:>12.3f}  s (prior 0.1)",
        f"{'heading - GNSS course':<28}{'mean':>12}{'rms':>12}{'max':>8}",
        f"{'':<28}{m['heading_minus_course_mean_deg']:>12.2f}{m['heading_minus_course_rms_deg']:>12.2f}"
        f"{m['heading_minus_course_max_deg']:>8.2f}  deg ({m['heading_valid_fraction'] * 100:.0f}% heading valid)",
        f"{'sideslip':<28}{'mean':>12}{'mean |.|':>12}{'max |.|':>8}",
        f"{'':<28}{m['sideslip_mean_deg']:>12.3f}{m['sideslip_mean_abs_deg']:>12.3f}"
        f"{m['sideslip_max_abs_deg']:>8.3f}  deg (truth ~0, highway)",
    ])


# ------------------------------------------------------------------------------------ CLI

def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    pr = sub.add_parser("revs", help="Revs race car -> Toyota CAN + GNSS logs -> replay -> evaluate")
    pr.add_argument("--out", required=True, type=Path)
    pr.add_argument("--protocol", choices=("ubx", "nmea"), default="ubx")
    pr.add_argument("--wrong-params", action="store_true",
                    help="mass +30 %%, inertia -30 %%, Cf/Cr -30 %%, GNSS delay prior 0.2 s")
    pr.add_argument("--seed", type=int, default=1)
    pr.add_argument("--duration-s", type=float, help="only the first N seconds of the 550 s")
    pr.add_argument("--lever-arm-x", type=float, default=0.0, help="GNSS antenna x from the CG (m)")
    pr.add_argument("--settle-s", type=float, default=20.0)
    pr.add_argument("--plots", type=Path, metavar="DIR")
    pr.add_argument("--gnss-outage", type=float, nargs=2, metavar=("START_S", "LENGTH_S"),
                    help="no GNSS fix from START_S for LENGTH_S (s from the start of the drive): the"
                         " sideslip the model alone holds, scored over the outage and 5 s after")
    pa = sub.add_parser("rav4", help="real RAV4 candump + u-blox fixes -> replay -> checks")
    pa.add_argument("--out", required=True, type=Path)
    pa.add_argument("--protocol", choices=("ubx", "nmea"), default="ubx")
    pa.add_argument("--settle-s", type=float, default=20.0)
    args = p.parse_args(argv)
    if not SHARED.is_dir():
        print(f"real data not found at {SHARED}", file=sys.stderr)
        return 2
    if args.cmd == "revs":
        outage = tuple(args.gnss_outage) if args.gnss_outage else None
        result, summary = run_revs(args.out, args.protocol, args.wrong_params, args.seed, args.duration_s,
                                   args.lever_arm_x, args.settle_s, args.plots, outage)
        print(f"replayed {summary['duration_s']:.1f} s ({summary['frames']} frames, {summary['gnss_samples']}"
              f" GNSS samples) in {summary['wall_s']:.1f} s")
        print(format_table(result))
        if outage is not None:
            print(format_outage(result["outage"], *outage))
    else:
        m, summary = run_rav4(args.out, args.protocol, args.settle_s)
        print(f"replayed {summary['duration_s']:.1f} s ({summary['frames']} frames, {summary['gnss_samples']}"
              f" GNSS samples) in {summary['wall_s']:.1f} s")
        print(format_rav4(m))
    return 0


if __name__ == "__main__":
    sys.exit(main())
