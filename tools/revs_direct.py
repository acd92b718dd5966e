"""Dev harness: Revs race car (real INS sideslip truth) -> synthetic sensors -> estimator core.

Feeds InputSample/GnssSample directly (no CAN/GNSS encoding), so the estimator can be tuned
before the I/O exists. Sensor biases, quantisation and a low-cost GNSS (5 Hz, 0.4 s latency)
are added here. Prints RMS errors.
"""
from __future__ import annotations

import argparse
import gzip
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from ecu_daemon import config as config_mod  # noqa: E402
from ecu_daemon.estimator import Estimator  # noqa: E402
from ecu_daemon.samples import INPUT_INDEX, GnssSample, InputSample  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared/data/revs-250lm/revs_20140222_01_01_03_250lm.csv.gz"


def load():
    return np.genfromtxt(gzip.open(DATA), delimiter=",", names=True)


def make_cfg(args):
    cfg = config_mod.load(None)
    v = cfg.vehicle
    f = args.wrong
    v.mass_kg = 982 * (1 + f)
    v.yaw_inertia_kgm2 = 1605 * (1 - f)
    v.cg_to_front_axle_m = 1.33
    v.cg_to_rear_axle_m = 1.07
    v.cornering_stiffness_front_n_per_rad = 7e4 * (1 - f)
    v.cornering_stiffness_rear_n_per_rad = 1.2e5 * (1 - f)
    v.steering_ratio = 13.3
    v.driven_axle = "rear"
    cfg.gnss.delay_s = args.prior
    cfg.gnss.lever_arm_m = [args.lever, 0.0]
    cfg.estimator.delay_compensation = not args.no_delay_comp
    cfg.gnss.estimate_delay = not getattr(args, "fixed_delay", False)
    return cfg


def synth(d, args, rng):
    t = d["t_s"]
    dt = 0.01
    vx, vy, r = d["vx_mps"], d["vy_mps"], d["yaw_rate_radps"]
    psi = np.radians(30.0) - np.concatenate([[0], np.cumsum(0.5 * (r[1:] + r[:-1]) * dt)])
    b_r, b_ax, b_ay = 0.006, 0.12, -0.15
    q_r, q_a = math.radians(0.244), 0.03589
    if getattr(args, "consistent", False):
        d = d.copy()
        d["ay_mps2"] = np.gradient(vy, dt) + r * vx
        d["ax_mps2"] = np.gradient(vx, dt) - r * vy
    rm = np.round((r + b_r + rng.normal(0, 0.002, len(t))) / q_r) * q_r
    axm = np.round((d["ax_mps2"] + b_ax + rng.normal(0, 0.05, len(t))) / q_a) * q_a
    aym = np.round((d["ay_mps2"] + b_ay + rng.normal(0, 0.05, len(t))) / q_a) * q_a
    kw = 1.015
    ws = np.round(vx / kw / 0.00278) * 0.00278
    steer = d["delta_rad"] * 13.3 + math.radians(2.0)
    samples = []
    I = INPUT_INDEX
    for j in range(len(t)):
        tj = t[j] + 1000.0
        samples.append(InputSample(tj, I["yaw_rate"], rm[j]))
        samples.append(InputSample(tj, I["accel_x"], axm[j]))
        samples.append(InputSample(tj, I["accel_y"], aym[j]))
        samples.append(InputSample(tj, I["steering_wheel_angle"], steer[j]))
        for n in ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr"):
            samples.append(InputSample(tj, I[n], ws[j]))
    lx = args.lever
    vax = vx
    vay = vy + r * lx
    vn = vax * np.cos(psi) + vay * np.sin(psi)
    ve = vax * np.sin(psi) - vay * np.cos(psi)
    step = int(round(1.0 / args.rate / dt))
    for j in range(0, len(t), step):
        tv = t[j] + 1000.0
        samples.append(GnssSample(tv + args.delay, vn[j] + rng.normal(0, args.noise),
                                  ve[j] + rng.normal(0, args.noise), args.sacc, 3, True, 12, "ubx"))
    samples.sort(key=lambda s: s.t)
    truth = dict(t=t + 1000.0, beta=d["beta_true_rad"], psi=psi % (2 * math.pi), vx=vx, vy=vy,
                 b_r=b_r, b_ax=b_ax, b_ay=b_ay, kw=kw)
    return samples, truth


def run(args):
    d = load()
    rng = np.random.default_rng(args.seed)
    samples, truth = synth(d, args, rng)
    est = Estimator(make_cfg(args))
    outs = []
    t0 = time.perf_counter()
    for s in samples:
        outs.extend(est.advance_to(s.t))
        if isinstance(s, GnssSample):
            est.push_gnss(s)
        else:
            est.push_input(s)
    el = time.perf_counter() - t0
    T = np.array([o.t for o in outs])
    B = np.array([o.sideslip_rad for o in outs])
    H = np.array([o.heading_rad for o in outs])
    m = T > truth["t"][0] + args.settle
    bt = np.interp(T, truth["t"], truth["beta"])
    pt = np.interp(T, truth["t"], np.unwrap(truth["psi"]))
    eb = np.degrees(B - bt)[m]
    eh = np.degrees((H - pt + np.pi) % (2 * np.pi) - np.pi)[m]
    last = outs[-1]
    print(f"steps {len(outs)}  {el/len(outs)*1e6:.1f} us/step (incl. sample push)  realtime x{(T[-1]-T[0])/el:.0f}")
    print(f"sideslip RMS {np.sqrt(np.nanmean(eb**2)):.3f} deg  max {np.nanmax(np.abs(eb)):.2f}  "
          f"(beta=0 baseline {np.degrees(np.sqrt(np.mean(bt[m]**2))):.3f})")
    print(f"heading  RMS {np.sqrt(np.nanmean(eh**2)):.3f} deg  max {np.nanmax(np.abs(eh)):.2f}")
    print(f"biases: r {last.yaw_rate_bias_radps:.5f} (true {truth['b_r']})  ax {last.accel_x_bias_mps2:.3f} "
          f"({truth['b_ax']})  ay {last.accel_y_bias_mps2:.3f} ({truth['b_ay']})  kw {last.wheel_scale:.4f} "
          f"({truth['kw']})  delay {last.gnss_delay_s:.3f}  Cr {last.cornering_stiffness_rear_n_per_rad:.0f} "
          f"Cf {last.cornering_stiffness_front_n_per_rad:.0f}  fused {last.gnss_fused} rej {last.gnss_rejected} late {last.gnss_late}")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(3, 1, figsize=(14, 9), sharex=True)
        ax[0].plot(T, np.degrees(bt), label="truth"); ax[0].plot(T, np.degrees(B), label="est"); ax[0].legend()
        ax[1].plot(T[m], eb); ax[1].set_ylabel("beta err deg")
        ax[2].plot(T[m], eh); ax[2].set_ylabel("heading err deg")
        fig.savefig(args.plot, dpi=80)


if __name__ == "__main__":
    p = argparse.ArgumentParser()
    p.add_argument("--rate", type=float, default=5.0)
    p.add_argument("--delay", type=float, default=0.4)
    p.add_argument("--prior", type=float, default=0.4)
    p.add_argument("--noise", type=float, default=0.05)
    p.add_argument("--sacc", type=float, default=0.1)
    p.add_argument("--lever", type=float, default=0.0)
    p.add_argument("--wrong", type=float, default=0.0)
    p.add_argument("--settle", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--no-delay-comp", action="store_true")
    p.add_argument("--plot")
    run(p.parse_args())
