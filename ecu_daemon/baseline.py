"""A plain single-track (bicycle) observer: the yardstick the estimator must beat.

Linear bicycle model with the configured mass, yaw inertia, axle distances and cornering
stiffnesses, driven by the road-wheel angle (steering-wheel angle / ratio) and the wheel-speed
vx, with the measured yaw rate fed back (Luenberger observer, gain on the yaw-rate error), no
GNSS, no adaptation, no bias estimation. It reads a CAN log through the same signal mapping as
``ecu-daemon replay`` (``tools/baseline_single_track.py`` writes its output as a CSV that
``ecu-daemon evaluate`` scores; ``ecu-daemon evaluate --suite`` calls it directly).
"""
from __future__ import annotations

import math
from collections.abc import Iterator

from .canlog import read_can_log
from .config import Config
from .samples import INPUT_INDEX
from .signals import SignalDecoder

DT = 0.006
L_R = 8.0  # 1/s: yaw-rate error feedback into r
L_V = 2.0  # m/s per rad/s: yaw-rate error feedback into vy


def single_track_sideslip(cfg: Config, can_path: str) -> Iterator[tuple[float, float]]:
    """``(t, sideslip_rad)`` every 6 ms on the absolute grid; NaN below 1 m/s or without inputs."""
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
            yield k * DT, beta
            k += 1
        for s in dec.decode(t, fid, data, ext):
            held[s.index] = s.value
