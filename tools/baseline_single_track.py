"""A plain single-track (bicycle) observer, the yardstick the estimator must beat.

Linear bicycle model with the configured mass, yaw inertia, axle distances and cornering
stiffnesses, driven by the road-wheel angle (steering-wheel angle / ratio) and the wheel-speed
vx, with the measured yaw rate fed back (Luenberger observer, gain on the yaw-rate error), no
GNSS, no adaptation, no bias estimation. It reads the same CAN log through the same signal
mapping as ``ecu-daemon replay`` and writes a CSV with ``t, sideslip_rad`` (plus the columns
``evaluate`` requires, as NaN), so both can be scored against the same truth::

    python3 tools/baseline_single_track.py --config CFG --can drive.log --out-csv base.csv
    ecu-daemon evaluate --truth truth.csv --estimate base.csv
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from ecu_daemon import config as config_mod  # noqa: E402
from ecu_daemon.canlog import read_can_log  # noqa: E402
from ecu_daemon.estimator.estimate import ESTIMATE_FIELDS  # noqa: E402
from ecu_daemon.samples import INPUT_INDEX  # noqa: E402
from ecu_daemon.signals import SignalDecoder  # noqa: E402

DT = 0.006
L_R = 8.0  # 1/s: yaw-rate error feedback into r
L_V = 2.0  # m/s per rad/s: yaw-rate error feedback into vy


def run(cfg, can_path: str, out_csv: str) -> int:
    v = cfg.vehicle
    m, iz, lf, lr = v.mass_kg, v.yaw_inertia_kgm2, v.cg_to_front_axle_m, v.cg_to_rear_axle_m
    cf, cr = v.cornering_stiffness_front_n_per_rad, v.cornering_stiffness_rear_n_per_rad
    dec = SignalDecoder(cfg)
    held = [math.nan] * len(INPUT_INDEX)
    wheels = [INPUT_INDEX[n] for n in ("wheel_speed_rl", "wheel_speed_rr")] if v.driven_axle == "front" \
        else [INPUT_INDEX[n] for n in ("wheel_speed_fl", "wheel_speed_fr")]
    i_sw, i_r = INPUT_INDEX["steering_wheel_angle"], INPUT_INDEX["yaw_rate"]
    vy = r = 0.0
    k = None
    rows = 0
    cols = ["t", "sideslip_rad"] + [c for c in ESTIMATE_FIELDS if c not in ("t", "sideslip_rad")]
    with open(out_csv, "w") as f:
        f.write(",".join(cols) + "\n")
        for t, fid, ext, err, data in read_can_log(can_path):
            if err:
                continue
            if k is None:
                k = math.ceil(t / DT)
            while k * DT < t:
                vx = 0.5 * (held[wheels[0]] + held[wheels[1]])
                delta = held[i_sw] / v.steering_ratio
                rm = held[i_r]
                beta = math.nan
                if math.isfinite(vx) and math.isfinite(delta) and math.isfinite(rm) and vx > 1.0:
                    af = delta - (vy + lf * r) / vx
                    ar = -(vy - lr * r) / vx
                    fyf, fyr = cf * af, cr * ar
                    e = rm - r
                    dvy = (fyf + fyr) / m - r * vx + L_V * e
                    dr = (lf * fyf - lr * fyr) / iz + L_R * e
                    vy += DT * dvy
                    r += DT * dr
                    beta = math.atan2(vy, vx)
                else:
                    vy, r = 0.0, rm if math.isfinite(rm) else 0.0
                f.write(f"{k * DT:.6f},{beta:.9g}" + ",nan" * (len(cols) - 2) + "\n")
                rows += 1
                k += 1
            for s in dec.decode(t, fid, data, ext):
                held[s.index] = s.value
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", required=True)
    p.add_argument("--can", required=True)
    p.add_argument("--out-csv", required=True)
    a = p.parse_args()
    n = run(config_mod.load(a.config), a.can, a.out_csv)
    print(f"{n} rows -> {a.out_csv}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
