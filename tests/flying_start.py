"""Flying starts for the estimator tests: simulate a drive, drop its first seconds, replay, score.

A log that begins with the car already at speed (a daemon restart, a CAN bus that comes up late)
is made from an ordinary simulated drive by cutting the candump and GNSS capture logs at
``t_cut``: everything the replay sees starts there, exactly as in a car. The scoring is what a
valid flag promises: how long after the first GNSS fix the flags come up, and whether the rows
flagged valid are right (worst error, fraction within 3 reported sigma).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from ecu_daemon import config as config_mod
from ecu_daemon.evaluate import ESTIMATE_REQUIRED, TRUTH_REQUIRED, read_csv
from ecu_daemon.replay import run_replay
from ecu_daemon.sim import Scenario, simulate, vehicle_config
from ecu_daemon.sim.manoeuvres import Circle, Manoeuvre, Phase, Wander
from ecu_daemon.sim.scenario import T0
from ecu_daemon.sim.writer import CAN_LOG, GNSS_LOG, write_all


@dataclasses.dataclass(frozen=True)
class CustomScenario(Scenario):
    """A scenario flying an explicit manoeuvre instead of a named builder."""

    custom: Manoeuvre | None = None

    def build_manoeuvre(self) -> Manoeuvre:
        return self.custom


def speed_profile(v: float, t_at_speed: float, duration: float) -> tuple:
    """Standstill, acceleration to ``v`` by ``t_at_speed``, then +-15 % speed changes (the
    latency identification needs them) every ~8 s."""
    knots = [(0.0, 0.0), (2.0, 0.0), (t_at_speed, v)]
    t, hi = t_at_speed, True
    while t < duration:
        knots.append((t + 3.0, v))
        knots.append((t + 8.0, v * (0.85 if hi else 1.0)))
        t += 8.0
        hi = not hi
    return tuple(knots)


def straight(v: float, heading_deg: float, t_at_speed: float = 25.0, duration: float = 70.0,
             speed_changes: bool = True, **kw) -> CustomScenario:
    knots = speed_profile(v, t_at_speed, duration) if speed_changes else ((0.0, 0.0), (2.0, 0.0), (t_at_speed, v))
    m = Manoeuvre(f"straight{v:g}", knots, (Phase(1e9, Wander()),), duration)
    return CustomScenario(f"flying_straight_{v:g}", "custom", custom=m, heading0_rad=math.radians(heading_deg),
                          **kw)


def corner(v: float, radius: float, heading_deg: float, t_at_speed: float = 25.0, left: bool = True,
           duration: float = 70.0, **kw) -> CustomScenario:
    """Accelerate to ``v`` on a straight, then circle at ``radius`` with the speed changes."""
    phases = (Phase(t_at_speed - 3.0, Wander()), Phase(1e9, Circle(radius, left)))
    m = Manoeuvre(f"corner{v:g}", speed_profile(v, t_at_speed, duration), phases, duration)
    return CustomScenario(f"flying_corner_{v:g}_{radius:g}", "custom", custom=m,
                          heading0_rad=math.radians(heading_deg), **kw)


def write_drive(sc: Scenario, out: Path) -> Path:
    cfg = vehicle_config(sc)
    write_all(out, simulate(sc, cfg), cfg)
    return out


WHEEL_FRAME = " 0B0#"  # WHEEL_SPEEDS in dbc/ecu_daemon_inputs.dbc


def cut_log(src: Path, dst: Path, t_from: float, late: str = "", late_until: float = 0.0) -> None:
    """Keep the lines of a ``(t) ...`` log stamped at or after ``t_from``; lines containing
    ``late`` only from ``late_until`` on (a sender that comes up later than the rest)."""
    with open(src, encoding="ascii") as f, open(dst, "w", encoding="ascii", newline="\n") as g:
        for line in f:
            t = float(line[1:line.index(")")])
            if t >= t_from and (not late or t >= late_until or late not in line):
                g.write(line)


def replay_from(d: Path, t_cut: float, tag: str = "", learned: dict | None = None,
                cfg: config_mod.Config | None = None, wheels_late_s: float = 0.0) -> tuple[Path, float]:
    """Replay drive ``d`` from ``t_cut`` s after its start (the wheel-speed frames from
    ``wheels_late_s`` later still). Returns (estimate CSV, first GNSS time)."""
    t_from = T0 + t_cut
    can, gnss = d / f"cut{t_cut:g}{tag}_{CAN_LOG}", d / f"cut{t_cut:g}{tag}_{GNSS_LOG}"
    cut_log(d / CAN_LOG, can, t_from, WHEEL_FRAME, t_from + wheels_late_s)
    cut_log(d / GNSS_LOG, gnss, t_from)
    with open(gnss, encoding="ascii") as f:
        first = f.readline()
    t_gnss = float(first[1:first.index(")")])
    out = d / f"cut{t_cut:g}{tag}_out.csv"
    cfg = cfg or config_mod.load(d / "config.toml")
    run_replay(cfg, str(can), str(gnss), str(out), learned=learned)
    return out, t_gnss


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def score(truth_csv: Path, est_csv: Path, t_gnss: float) -> dict:
    """Time to valid after ``t_gnss`` and the quality of the rows flagged valid, per quantity."""
    truth = read_csv(truth_csv, TRUTH_REQUIRED, "truth")
    est = read_csv(est_csv, ESTIMATE_REQUIRED + ("velocity_valid",), "estimate")
    t = est["t"]
    sel = t <= truth["t"][-1]
    t = t[sel]
    out = {}
    for name, unwrap in (("sideslip", False), ("heading", True)):
        ref_col = truth[f"{name}_rad"]
        ref = np.interp(t, truth["t"], np.unwrap(ref_col) if unwrap else ref_col)
        err = _wrap(est[f"{name}_rad"][sel] - ref)
        std = est[f"{name}_std_rad"][sel]
        valid = est[f"{name}_valid"][sel] > 0.5
        first = t[valid][0] - t_gnss if valid.any() else math.inf
        after = t >= t_gnss + 10.0
        out[name] = {
            "time_to_valid_s": float(first),
            "max_err_valid_deg": float(np.degrees(np.abs(err[valid]).max())) if valid.any() else 0.0,
            "within_3sigma_valid": float(np.mean(np.abs(err[valid]) <= 3 * std[valid])) if valid.any() else 1.0,
            "fraction_valid_after_10s": float(valid[after].mean()) if after.any() else 0.0,
            "rms_after_10s_deg": float(np.degrees(np.sqrt(np.mean(err[after] ** 2)))) if after.any() else 0.0,
        }
    vx_err = est["vx_mps"][sel] - np.interp(t, truth["t"], truth["vx_mps"])
    vvalid = est["velocity_valid"][sel] > 0.5
    out["vx_max_err_valid"] = float(np.abs(vx_err[vvalid]).max()) if vvalid.any() else 0.0
    dly = est["gnss_delay_s"][sel] - np.interp(t, truth["t"], truth["gnss_delay_s"])
    out["delay_err_after_30s"] = float(np.abs(dly[t >= t_gnss + 30.0]).max()) if (t >= t_gnss + 30).any() else 0.0
    out["delay_final"] = float(est["gnss_delay_s"][sel][-1])
    return out
