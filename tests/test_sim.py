"""The simulator: physics sanity, sensor conventions, GNSS timing and the files replay reads."""
from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import can
import numpy as np
import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.cli import main as cli_main
from ecu_daemon.gnss.logfile import samples_from_log
from ecu_daemon.samples import INPUT_NAMES
from ecu_daemon.signals import SignalDecoder
from ecu_daemon.sim import SCENARIOS, simulate, tyre, vehicle_config
from ecu_daemon.sim import manoeuvres as mn
from ecu_daemon.sim import sensors as sens
from ecu_daemon.sim.sensors import UTC_OFFSET_S
from ecu_daemon.sim.vehicle import G, Road, VehicleParams, integrate
from ecu_daemon.sim.writer import write_all

TOYOTA_EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "toyota_rav4.toml"
CANDUMP_LINE = re.compile(r"^\(\d+\.\d{6}\) can0 [0-9A-F]{3}#([0-9A-F]{2})*$")
QUIET = dict(sensor_yaw_rate_noise_radps=0.0, sensor_accel_noise_mps2=0.0, sensor_wheel_speed_noise_mps=0.0,
             sensor_steering_noise_rad=0.0, sensor_jitter_s=0.0)


def _drive(manoeuvre: mn.Manoeuvre, mu: float = 1.0, bank: float = 0.0, v0: float = 0.0,
           params: VehicleParams | None = None):
    p = params or VehicleParams()
    return integrate(p, Road(mu, bank), mn.Driver(manoeuvre, p, mu, 0.0), 0.0, manoeuvre.duration_s, v0=v0)


def _constant(v: float, steer_sw_deg: float, duration: float = 12.0) -> mn.Manoeuvre:
    steer = mn.OpenLoop("jturn", math.radians(steer_sw_deg), hold_s=1e3)
    return mn.Manoeuvre("const", ((0.0, v),), (mn.Phase(1e9, steer),), duration)


# ----------------------------------------------------------------------------------- physics

def test_reported_cornering_stiffness_is_the_slope_of_the_tyre_model():
    p = VehicleParams()
    cf, cr = p.axle_cornering_stiffness()
    ff, fr = p.static_axle_loads()
    a = 1e-5
    slope_f = 2 * tyre.forces(p.tyre_front, ff / 2, 1.0, 0.0, math.tan(a))[1] / a
    slope_r = 2 * tyre.forces(p.tyre_rear, fr / 2, 0.3, 0.0, math.tan(a))[1] / a  # mu-independent
    assert slope_f == pytest.approx(cf, rel=1e-3)
    assert slope_r == pytest.approx(cr, rel=1e-3)
    assert 80e3 < cf < cr < 150e3  # a mid-size car that understeers
    assert p.understeer_gradient() > 0


def test_tyre_force_never_exceeds_the_friction_circle():
    p = tyre.TyreParams()
    for kappa in np.linspace(-1, 1, 21):
        for ta in np.linspace(-1, 1, 21):
            fx, fy = tyre.forces(p, 4000.0, 0.3, kappa, ta)
            assert math.hypot(fx, fy) <= 0.3 * 4000.0 * (1 + 1e-9)


def test_steady_circle_lateral_acceleration_is_v_squared_over_r():
    man = mn.Manoeuvre("circle", ((0.0, 14.0),), (mn.Phase(1e9, mn.Circle(40.0, left=True)),), 20.0)
    tr = _drive(man, v0=14.0)
    sel = tr.t > 12.0
    n, e = tr.col("north")[sel], tr.col("east")[sel]
    # least-squares circle through the integrated path: geometry independent of the force model
    a = np.c_[2 * n, 2 * e, np.ones_like(n)]
    cn, ce, c = np.linalg.lstsq(a, n ** 2 + e ** 2, rcond=None)[0]
    radius = math.sqrt(c + cn ** 2 + ce ** 2)
    speed = np.hypot(tr.col("vx"), tr.col("vy"))[sel]
    ay = tr.col("ay")[sel]  # from the tyre forces
    assert radius == pytest.approx(40.0, rel=0.03)  # the driver follows the circle
    assert np.mean(ay) == pytest.approx(np.mean(speed ** 2) / radius, rel=0.01)
    assert np.mean(tr.col("r")[sel]) > 0  # a left turn is positive yaw rate (ISO)
    heading_rate = np.gradient(np.unwrap(tr.col("psi")[sel]), tr.t[sel])
    assert np.mean(heading_rate) == pytest.approx(-np.mean(tr.col("r")[sel]), rel=1e-3)  # clockwise heading


def test_sideslip_sign_left_turn_negative_at_high_speed_positive_at_low_speed():
    fast = _drive(_constant(25.0, 30.0), v0=25.0)
    slow = _drive(_constant(3.0, 90.0), v0=3.0)
    for tr in (fast, slow):
        assert tr.col("r")[-1] > 0.05  # turning left
    beta_fast = math.atan2(fast.col("vy")[-1], fast.col("vx")[-1])
    beta_slow = math.atan2(slow.col("vy")[-1], slow.col("vx")[-1])
    assert beta_fast < -math.radians(0.3)
    assert beta_slow > math.radians(1.0)
    # kinematic limit at low speed: beta ~ atan(lr / L * tan(delta))
    p = VehicleParams()
    delta = slow.col("delta")[-1]
    assert beta_slow == pytest.approx(math.atan(p.lr_m / p.wheelbase_m * math.tan(delta)), rel=0.15)


def test_low_friction_caps_lateral_acceleration_near_03_g_without_spinning():
    tr = _drive(_constant(16.0, 120.0, duration=8.0), mu=0.3, v0=16.0)
    ay = np.abs(tr.col("ay"))
    assert ay.max() <= 0.3 * G * 1.01
    assert ay.max() >= 0.25 * G
    assert tr.spin_time is None


def test_friction_falling_mid_drive_caps_the_lateral_force_from_then_on():
    """Rain on a dry road (``Road.mu_change``): the same steady steer holds ~0.6 g on the dry
    road and falls to the wet road's cap from the change on; the tyres' stiffness is the same, so
    the first seconds are identical to the dry drive (the trap for an outage: the stiffness learned
    on dry still looks right at small slip)."""
    p = VehicleParams()
    man = _constant(16.0, 120.0, duration=8.0)
    dry = integrate(p, Road(1.0, 0.0), mn.Driver(man, p, 1.0, 0.0), 0.0, man.duration_s, v0=16.0)
    wet = integrate(p, Road(1.0, 0.0, mu_change=(4.0, 0.4)), mn.Driver(man, p, 1.0, 0.0), 0.0,
                    man.duration_s, v0=16.0)
    t = wet.col("t")
    before, after = t < 4.0, t >= 5.0
    np.testing.assert_array_equal(wet.col("ay")[before], dry.col("ay")[before])
    assert np.abs(dry.col("ay")[after]).min() >= 0.5 * G
    assert np.abs(wet.col("ay")[after]).max() <= 0.4 * G * 1.01


def test_scenario_friction_change_is_in_the_truth():
    """``Scenario.mu_change`` (seconds from the drive's start) reaches the simulator and the truth's
    ``mu`` column, so a scored drive says which road each row was on."""
    sc = SCENARIOS["straight_dry"].with_(name="rain", mu_change=(5.0, 0.6), duration_s=8.0)
    truth = simulate(sc).truth_table()
    t = truth["t"] - truth["t"][0]
    assert set(truth["mu"][t < 4.99]) == {1.0}
    assert set(truth["mu"][t > 5.01]) == {0.6}


@pytest.mark.parametrize("name", ["sine_mu03", "dlc_mu03"])
def test_low_friction_scenarios_stay_controllable(name):
    sc = SCENARIOS[name]
    man = sc.build_manoeuvre()
    tr = integrate(sc.vehicle, Road(sc.mu, sc.bank_rad), mn.Driver(man, sc.vehicle, sc.mu, 0.0), 0.0,
                   man.duration_s)
    assert tr.spin_time is None
    assert np.abs(tr.col("ay")).max() > 0.2 * G  # and they are not trivially gentle


def test_spin_out_is_detected():
    # a rear-light car (rear cornering stiffness cut to a third) is unstable above ~15 m/s
    p = VehicleParams().scaled(cr=0.3)
    tr = _drive(_constant(25.0, 20.0, duration=6.0), mu=1.0, v0=25.0, params=p)
    assert tr.spin_time is not None
    assert tr.max_abs_sideslip > math.radians(25.0)


def test_bank_shows_in_the_accelerometer_with_the_documented_sign():
    bank = math.atan(0.05)  # positive: left side up, the road falls to the right
    sc = SCENARIOS["straight_dry_bank"].with_(duration_s=4.0, **QUIET)
    assert sc.bank_rad == pytest.approx(bank)
    res = simulate(sc)
    tr = res.truth
    assert np.all(tr.col("vx") == 0.0) and np.all(tr.col("vy") == 0.0)  # brake hold, no creep
    assert np.allclose(tr.col("acc_y"), G * math.sin(bank), rtol=0.1)  # + body roll towards the low side
    assert np.allclose(tr.col("fy"), G * math.sin(bank))
    dec = SignalDecoder(res.config)
    ay = [s.value for f in res.can_frames for s in dec.decode(f[0], f[1], f[2])
          if s.index == INPUT_NAMES.index("accel_y")]
    # the truth's effective bias is what the sensor reads at rest: bias + gravity via bank and roll
    eff = res.truth_table()["accel_y_bias_eff_mps2"][0]
    assert np.mean(ay) == pytest.approx(eff, abs=0.001)
    roll = VehicleParams().roll_gradient_rad_per_g * math.sin(bank)
    assert eff == pytest.approx(sc.sensors.accel_y_bias_mps2 + G * math.sin(bank + roll), abs=1e-3)


# ----------------------------------------------------------------------------------- files


@pytest.fixture(scope="module")
def dlc(tmp_path_factory):
    """A short, noise-free lane change written to disk (shared by several tests)."""
    sc = SCENARIOS["dlc_dry"].with_(duration_s=26.0, **QUIET)
    res = simulate(sc)
    out = tmp_path_factory.mktemp("dlc")
    write_all(out, res, vehicle_config(sc))
    return sc, res, out


def _expected_inputs(res, t: np.ndarray) -> dict[str, np.ndarray]:
    """Error-free sensor model for a noise-free scenario: truth + the documented biases."""
    tr, sp = res.truth, res.scenario.sensors
    col = lambda c: np.interp(t, tr.t, tr.col(c))  # noqa: E731
    out = {}
    for w in ("fl", "fr", "rl", "rr"):
        v = col(f"omega_{w}") * tr.params.wheel_radius_m / sp.wheel_scale
        out[f"wheel_speed_{w}"] = np.where(np.abs(v) < sp.wheel_speed_min_mps, 0.0, v)
    out["steering_wheel_angle"] = col("steer_sw") + sp.steering_offset_rad
    out["yaw_rate"] = col("r") + sp.yaw_rate_bias_radps
    out["accel_x"] = col("acc_x") + sp.accel_x_bias_mps2
    out["accel_y"] = col("acc_y") + sp.accel_y_bias_mps2
    return out


def _round_trip_errors(log: Path, cfg) -> tuple[dict, dict, SignalDecoder]:
    dec = SignalDecoder(cfg)
    got = {n: ([], []) for n in INPUT_NAMES if n in cfg.inputs}
    for msg in can.LogReader(str(log)):
        for s in dec.decode(msg.timestamp, msg.arbitration_id, bytes(msg.data)):
            got[INPUT_NAMES[s.index]][0].append(s.t)
            got[INPUT_NAMES[s.index]][1].append(s.value)
    return got, {k: {e: v for e, v in h.errors.items() if v} for k, h in dec.health.items()}, dec


def test_drive_log_is_candump_and_round_trips_to_the_sensor_values_within_one_lsb(dlc):
    sc, res, out = dlc
    lines = (out / "drive.log").read_text().splitlines()
    assert len(lines) == len(res.can_frames) > 0
    assert all(CANDUMP_LINE.match(line) for line in lines)
    ts = [float(line[1:line.index(")")]) for line in lines]
    assert ts == sorted(ts) and ts[0] >= 1200.0
    cfg = config_mod.load(out / "config.toml")  # the written config decodes the written log
    got, errors, dec = _round_trip_errors(out / "drive.log", cfg)
    assert not any(errors.values())  # counters and E2E CRCs all good
    lsb = {"wheel_speed": 0.032, "steering_wheel_angle": 0.0005, "yaw_rate": 0.0001, "accel": 0.001}
    for name, (t, v) in got.items():
        assert len(t) > 0.9 * 100 * 26  # 100 Hz
        exp = _expected_inputs(res, np.array(t))[name]
        tol = next(q for k, q in lsb.items() if name.startswith(k)) / 2 + 1e-6
        assert np.max(np.abs(np.array(v) - exp)) <= tol, name


def test_toyota_dbc_with_split_steering_and_flipped_accelerations_round_trips(tmp_path):
    cfg = config_mod.load(TOYOTA_EXAMPLE)  # the shipped example: opendbc's DBC + our RAV4 mapping
    sc = SCENARIOS["slalom_dry"].with_(duration_s=24.0, sensor_can_rate_hz=83.3, **QUIET)
    res = simulate(sc, cfg)
    write_all(tmp_path, res, vehicle_config(sc, cfg))
    got, errors, _ = _round_trip_errors(tmp_path / "drive.log", config_mod.load(tmp_path / "config.toml"))
    assert not any(errors.values())
    lsb = {"wheel_speed": 0.01 / 3.6, "steering_wheel_angle": math.radians(0.1), "yaw_rate": math.radians(0.244),
           "accel": 0.03589}
    for name, (t, v) in got.items():
        assert 0.9 * 83.3 * 24 < len(t) < 1.1 * 83.3 * 24
        exp = _expected_inputs(res, np.array(t))[name]
        tol = next(q for k, q in lsb.items() if name.startswith(k)) / 2 + 1e-6
        assert np.max(np.abs(np.array(v) - exp)) <= tol, name
    # the slalom really used negative accelerations and both signs of steering
    steer = np.array(got["steering_wheel_angle"][1])
    assert steer.min() < -0.5 and steer.max() > 0.5
    assert min(got["accel_y"][1]) < -2.0


def test_toyota_checksum_is_set_where_the_mapping_asks_for_it():
    cfg = config_mod.load(TOYOTA_EXAMPLE)
    for c in ("fl", "fr", "rl", "rr"):  # the display speed frame carries Toyota's checksum
        cfg.inputs[f"wheel_speed_{c}"] = config_mod.InputMapping(message="SPEED", signal="SPEED", scale=1 / 3.6,
                                                                 checksum="toyota")
    res = simulate(SCENARIOS["straight"].with_(duration_s=8.0), cfg)
    dec = SignalDecoder(cfg)
    speeds = [s.value for f in res.can_frames for s in dec.decode(*f) if s.index == 0]
    assert len(speeds) > 500 and max(speeds) > 1.0
    assert not any(v for h in dec.health.values() for v in h.errors.values())
    data = next(f[2] for f in res.can_frames if f[1] == 0xB4)
    assert data[-1] == (len(data) + 0x00 + 0xB4 + sum(data[:-1])) & 0xFF


def test_gnss_receive_time_is_validity_plus_latency_and_velocity_is_the_antennas(dlc):
    sc, res, out = dlc
    samples = list(samples_from_log(out / "drive_gnss.log", {"protocol": "ubx"}))
    assert len(samples) == pytest.approx(sc.gnss.rate_hz * (26.0 - sc.gnss.latency_s), abs=2)
    tr = res.truth
    lx, ly = sc.gnss.lever_arm_m
    bound = 3 * sc.gnss.latency_jitter_s + 1e-6
    for s in samples:
        t_valid = s.fix_time_utc_s - UTC_OFFSET_S
        assert s.t - t_valid == pytest.approx(sc.gnss.latency_s, abs=bound)
        vx, vy, r, psi = (np.interp(t_valid, tr.t, tr.col(c)) for c in ("vx", "vy", "r", "psi"))
        ux, uy = vx - r * ly, vy + r * lx
        vn, ve = ux * math.cos(psi) + uy * math.sin(psi), ux * math.sin(psi) - uy * math.cos(psi)
        assert s.vel_n_mps == pytest.approx(vn, abs=6 * sc.gnss.vel_noise_mps)
        assert s.vel_e_mps == pytest.approx(ve, abs=6 * sc.gnss.vel_noise_mps)
        assert s.speed_acc_mps == pytest.approx(sc.gnss.speed_acc_mps, abs=1e-3)
    # the lever arm matters: in the lane change the antenna moves sideways faster than the CG
    assert np.abs(tr.col("r")).max() * lx > 0.1


def test_nmea_epochs_are_staggered_and_parse(tmp_path):
    sc = SCENARIOS["straight"].with_(duration_s=12.0, gnss_protocol="nmea", gnss_rate_hz=10.0, gnss_latency_s=0.25)
    res = simulate(sc)
    kinds = [p[3:6] for _, p in res.gnss_messages]
    assert kinds[:3] == [b"RMC", b"VTG", b"GGA"]
    t = [m[0] for m in res.gnss_messages]
    assert t[1] - t[0] == pytest.approx(sc.gnss.nmea_stagger_s)
    write_all(tmp_path, res)
    samples = list(samples_from_log(tmp_path / "drive_gnss.log", {"protocol": "nmea"}))
    assert len(samples) == pytest.approx(10 * (12.0 - 0.25), abs=2)
    late = [s.t - (s.fix_time_utc_s - UTC_OFFSET_S) for s in samples]
    assert 0.24 < min(late) and max(late) < 0.25 + 2 * sc.gnss.nmea_stagger_s + 3 * sc.gnss.latency_jitter_s


def test_truth_csv_shares_the_log_clock_and_has_the_contract_columns(dlc):
    sc, res, out = dlc
    header = (out / "truth.csv").read_text().splitlines()[0].split(",")
    for col in ("t", "sideslip_rad", "heading_rad", "vx_mps", "vy_mps", "yaw_rate_radps", "ax_mps2", "ay_mps2",
                "yaw_rate_bias_radps", "accel_x_bias_mps2", "accel_y_bias_mps2", "wheel_scale",
                "steering_offset_rad", "gnss_delay_s", "bank_rad", "mu"):
        assert col in header
    data = np.loadtxt(out / "truth.csv", delimiter=",", skiprows=1)
    t = data[:, 0]
    assert t[0] == 1200.0 and np.allclose(np.diff(t), 0.006)
    assert np.allclose(t / 0.006, np.round(t / 0.006))  # on the estimator's absolute 6 ms grid
    heading = data[:, header.index("heading_rad")]
    assert heading.min() >= 0 and heading.max() < 2 * math.pi
    beta = data[:, header.index("sideslip_rad")]
    assert np.allclose(beta, np.arctan2(data[:, header.index("vy_mps")], data[:, header.index("vx_mps")]))
    # standstill at the start (5 s) then moving
    vx = data[:, header.index("vx_mps")]
    assert np.all(vx[t < 1204.9] == 0.0) and vx[-1] > 20.0


def test_same_seed_gives_identical_files_and_another_seed_does_not(tmp_path):
    sc = SCENARIOS["sine_dry"].with_(duration_s=6.0)
    for d, seed in (("a", 7), ("b", 7), ("c", 8)):
        write_all(tmp_path / d, simulate(sc.with_(seed=seed)))
    for f in ("drive.log", "drive_gnss.log", "truth.csv", "config.toml", "scenario.json"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes(), f
    assert (tmp_path / "a" / "drive.log").read_bytes() != (tmp_path / "c" / "drive.log").read_bytes()


def test_usb_batching_gives_shared_timestamps_and_keeps_order():
    sc = SCENARIOS["straight"].with_(duration_s=3.0, sensor_usb_batch_s=0.01)
    t = np.array([f[0] for f in simulate(sc).can_frames])
    assert np.all(np.diff(t) >= 0)
    assert np.allclose(np.round(t / 0.01) * 0.01, t)
    assert len(np.unique(t)) < len(t) / 2


def test_wrong_params_config_is_off_by_the_documented_factors():
    sc = SCENARIOS["dlc_dry"]
    good, bad = vehicle_config(sc), vehicle_config(sc, wrong=True)
    assert bad.vehicle.mass_kg == pytest.approx(1.3 * good.vehicle.mass_kg)
    assert bad.vehicle.yaw_inertia_kgm2 == pytest.approx(0.7 * good.vehicle.yaw_inertia_kgm2)
    assert bad.vehicle.cornering_stiffness_front_n_per_rad == pytest.approx(
        0.7 * good.vehicle.cornering_stiffness_front_n_per_rad, rel=1e-5)
    assert abs(bad.gnss.delay_s - sc.gnss.latency_s) == pytest.approx(0.2)
    assert good.gnss.delay_s == sc.gnss.latency_s
    config_mod.from_dict(config_mod.to_dict(bad))  # valid


def test_cli_writes_the_files_and_reports_bad_input_in_one_line(tmp_path, capsys):
    out = tmp_path / "o"
    rc = cli_main(["simulate", "--scenario", "jturn_mu03", "--duration", "4", "--out", str(out),
                   "--gnss-protocol", "nmea", "--gnss-delay", "0.3", "--wrong-params", "--seed", "3"])
    assert rc == 0
    assert {p.name for p in out.iterdir()} >= {"drive.log", "drive_gnss.log", "truth.csv", "config.toml"}
    cfg = config_mod.load(out / "config.toml")
    assert cfg.gnss.protocol == "nmea" and abs(cfg.gnss.delay_s - 0.3) == pytest.approx(0.2)
    capsys.readouterr()
    assert cli_main(["simulate", "--scenario", "no_such"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unknown scenario 'no_such'" in err and "dlc_dry" in err
    assert cli_main(["simulate", "--scenario", "dlc_dry", "--duration", "-1"]) == 2
    assert cli_main(["simulate", "--list"]) == 0
    assert "slalom_mu03" in capsys.readouterr().out


def test_registry_has_the_named_scenarios():
    for name in ("dlc_dry", "slalom_mu03", "circle_bank", "jturn_dry", "straight", "demo"):
        assert name in SCENARIOS
    assert SCENARIOS["circle_bank"].bank_rad < 0 < SCENARIOS["dlc_dry_bank"].bank_rad
    assert SCENARIOS["slalom_mu03"].mu == 0.3
    # the road courses (sim/road.py) run several curves of a real road's length: up to 150 s
    assert all(30 <= sc.duration() <= (150 if sc.manoeuvre == "road_course" else 90) for sc in SCENARIOS.values())
    assert replace(SCENARIOS["dlc_dry"], duration_s=5.0).duration() == 5.0


def test_wheel_lag_is_a_first_order_lag_of_the_wheel_speeds_and_zero_leaves_them_untouched():
    """``SensorParams.wheel_lag_s``: the ABS ECU's filter. Accelerating at a constant rate, a
    first-order lag tau reads the speed of tau ago (tau * ax low) once settled; the IMU is not
    delayed; 0 (the default) is the truth column itself, so every existing scenario is unchanged."""
    sc = SCENARIOS["dlc_dry"].with_(duration_s=14.0, **QUIET)
    res = simulate(sc)
    tr = res.truth
    t = np.arange(tr.t[0] + 7.0, tr.t[0] + 12.0, 0.01)  # the launch at ~2.2 m/s^2
    ax = np.interp(t, tr.t, tr.col("acc_x"))
    assert ax.min() > 1.5
    rng = np.random.default_rng(0)
    plain = sens.CanSensors(tr, sc.sensors, rng)
    exact = np.interp(t, tr.t, tr.col("omega_rl")) * (tr.params.wheel_radius_m / sc.sensors.wheel_scale)
    assert np.array_equal(plain.measure("wheel_speed_rl", t), exact)
    for tau in (0.02, 0.06):
        lagged = sens.CanSensors(tr, replace(sc.sensors, wheel_lag_s=tau), rng)
        late = lagged.measure("wheel_speed_rl", t)
        assert np.allclose(exact - late, tau * ax / sc.sensors.wheel_scale, atol=0.1 * tau * ax.max())
        assert np.array_equal(lagged.measure("accel_x", t), plain.measure("accel_x", t))


# ----------------------------------------------------------------------------------- tyre relaxation

def test_relaxed_slip_is_a_first_order_lag_with_time_constant_sigma_over_v():
    """A step in slip: after sigma / v the relaxed slip has covered 1 - 1/e of the step, at 5 and
    at 30 m/s; the exact exponential stays stable where Euler would not (sigma / v << dt)."""
    dt = 1e-3
    for v, sigma in ((5.0, 0.5), (30.0, 0.5), (2.0, 0.3)):
        tau = sigma / v
        lagged, t = 0.0, 0.0
        while t < tau - 1e-12:
            lagged = tyre.relax_step(lagged, 0.1, v, sigma, dt)
            t += dt
        assert lagged == pytest.approx(0.1 * (1 - math.exp(-t / tau)), rel=1e-9)
        assert lagged == pytest.approx(0.1 * (1 - math.exp(-1.0)), rel=0.02)
    assert tyre.relax_step(-0.2, 0.1, 30.0, 1e-4, dt) == pytest.approx(0.1)  # no overshoot
    assert tyre.relax_step(-0.2, 0.1, 5.0, 0.0, dt) == 0.1  # sigma 0: the instant tyre


def _step_steer_yaw_rise_s(params: VehicleParams, v: float) -> float:
    """Time from the steering step to 63 % of the steady yaw rate (small steer: linear range)."""
    man = mn.Manoeuvre("step", ((0.0, v),), (mn.Phase(1.0, mn.Line()),
                                            mn.Phase(1e9, mn.OpenLoop("jturn", math.radians(10.0),
                                                                      rate_radps=math.radians(1000.0),
                                                                      hold_s=1e3))), 6.0)
    tr = _drive(man, v0=v, params=params)
    t, r = tr.t, tr.col("r")
    steady = np.mean(r[t > 5.0])
    return float(t[np.argmax(r > 0.63 * steady)] - 1.0)


def test_relaxation_delays_the_vehicle_response_by_about_sigma_over_v():
    """In the vehicle, the force lag sigma / v shows as a later yaw response, by a part of sigma / v
    (measured 0.49, 0.58, 0.6 of it at 5, 10, 25 m/s: the rear axle's lag, which lets the car yaw
    before the rear force resists, takes some of the front's back): 0.05 s at 5 m/s, 0.01 s at
    25 m/s. The steady state is the same (relaxation changes no stiffness)."""
    from ecu_daemon.sim.suite import relaxed_vehicle
    p0, p1 = VehicleParams(), relaxed_vehicle(0.5)
    delays = {}
    for v in (5.0, 25.0):
        delays[v] = _step_steer_yaw_rise_s(p1, v) - _step_steer_yaw_rise_s(p0, v)
        assert 0.3 * 0.5 / v < delays[v] < 1.2 * 0.5 / v
    assert delays[5.0] > 3.0 * delays[25.0]
    man = _constant(10.0, 30.0)
    r0, r1 = _drive(man, v0=10.0).col("r")[-1], _drive(man, v0=10.0, params=p1).col("r")[-1]
    assert r1 == pytest.approx(r0, rel=1e-3)


def test_relaxation_is_stable_from_and_to_standstill():
    """Start, a tight turn at walking pace, stop and hold: nothing blows up as v -> 0 (the lag is
    capped by the slip's 1 m/s regularisation) and the held car stands still."""
    from ecu_daemon.sim.suite import relaxed_vehicle
    p = relaxed_vehicle(0.8)
    steer = mn.OpenLoop("jturn", math.radians(300.0), hold_s=1e3)
    man = mn.Manoeuvre("creep", ((0.0, 0.0), (2.0, 0.0), (5.0, 2.0), (12.0, 2.0), (15.0, 0.0), (20.0, 0.0)),
                       (mn.Phase(3.0, mn.Line()), mn.Phase(1e9, steer)), 20.0)
    tr = _drive(man, params=p)
    assert np.all(np.isfinite(tr.data))
    assert np.max(np.abs(tr.col("vy"))) < 0.5 and np.max(np.abs(tr.col("r"))) < 1.0
    assert np.all(tr.col("vx")[tr.t > 17.0] == 0.0)


def test_zero_relaxation_length_is_the_instant_tyre_bit_for_bit():
    """relaxation_length_m = 0 (the default) must leave every existing drive's truth unchanged."""
    man = mn.slalom(1.0)
    base = _drive(man)
    explicit = _drive(man, params=replace(VehicleParams(), tyre_front=replace(VehicleParams().tyre_front,
                                                                              relaxation_length_m=0.0)))
    assert np.array_equal(base.data, explicit.data)


def test_a_spin_through_low_vx_is_detected():
    """A car sliding sideways at speed (vx 2 m/s, vy 8 m/s: 76 deg of sideslip, a spin passing
    vx ~ 0 on its way to rolling on tail first, random drive 3170) is spun out although vx stays
    below 3 m/s: the sideslip is judged at speed hypot(vx, vy), not at vx."""
    p = VehicleParams()
    man = _constant(2.0, 0.0, duration=1.0)
    tr = integrate(p, Road(0.1, 0.0), mn.Driver(man, p, 0.1, 0.0), 0.0, man.duration_s, v0=2.0, vy0=8.0)
    assert tr.col("vx").max() < 3.0 and math.hypot(2.0, 8.0) > 3.0
    assert tr.spin_time == 0.0
    assert tr.max_abs_sideslip == pytest.approx(math.atan2(8.0, 2.0), abs=0.05)
