"""``ecu-daemon simulate``: write a simulated drive (CAN log, GNSS capture, truth, config) to a folder."""
from __future__ import annotations

import argparse
import logging
import math
import time
from pathlib import Path

from .. import config as config_mod
from .scenario import GNSS_SETUPS, SCENARIOS, get

log = logging.getLogger("ecu_daemon.simulate")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", "-s", help="scenario name (see --list)")
    parser.add_argument("--list", action="store_true", help="list the scenarios and exit")
    parser.add_argument("--out", "-o", help="output folder (default: out/<scenario>)")
    parser.add_argument("--duration", type=float, help="seconds to simulate (default: the manoeuvre's length)")
    parser.add_argument("--seed", type=int, help="random seed of the sensor errors and timing (default 1)")
    parser.add_argument("--gnss-rate", type=float, help="GNSS solutions per second (default 5)")
    parser.add_argument("--gnss-delay", type=float,
                        help="GNSS latency: receive time - time of validity, s (default 0.4)")
    parser.add_argument("--gnss-protocol", choices=("ubx", "nmea"), help="receiver output (default ubx)")
    parser.add_argument("--gnss", choices=tuple(GNSS_SETUPS), default="velocity",
                        help="receivers: one for velocity (default); a dual-antenna moving-base pair (heading,"
                             " 1.2 m baseline across the car); two velocity receivers front and rear, 2.5 m apart"
                             " (a second capture drive_gnss2.log; replay it with a second --gnss)")
    parser.add_argument("--config", "-C", help="encode CAN with this config's DBC and [inputs.*] mapping")
    parser.add_argument("--can-dbc", help="use this DBC instead of the config's (same mapping)")
    parser.add_argument("--can-rate", type=float,
                        help="CAN message rate in Hz (default: the DBC's GenMsgCycleTime, else 100)")
    parser.add_argument("--usb-batch-ms", type=float, default=0.0,
                        help="stamp CAN frames in batches of this period, like a USB adapter (default off)")
    parser.add_argument("--wrong-params", action="store_true",
                        help="write a config with mass +30 %%, inertia -30 %%, Cf -30 %%, Cr +30 %%"
                             " and a GNSS delay prior 0.2 s off")


def _fail(text: str):
    from ..errors import UserError

    raise UserError(text)


def _list() -> int:
    width = max(len(n) for n in SCENARIOS)
    for name in sorted(SCENARIOS):
        sc = SCENARIOS[name]
        print(f"{name:<{width}}  {sc.duration():5.0f} s  {sc.description}")
    return 0


def _check_positive(name: str, value, upper: float | None = None) -> None:
    if value is None:
        return
    if not (value > 0 and math.isfinite(value)) or (upper is not None and value > upper):
        _fail(f"{name} must be a positive number{'' if upper is None else f' up to {upper:g}'}, got {value}")


def main(args: argparse.Namespace) -> int:
    from .can_encoder import UnencodableValue
    from .run import simulate, vehicle_config
    from .writer import write_all

    if args.list:
        return _list()
    if not args.scenario:
        _fail("give --scenario NAME (or --list)")
    try:
        sc = get(args.scenario)
    except KeyError as e:
        _fail(e.args[0])
    _check_positive("--duration", args.duration, 3600.0)
    _check_positive("--gnss-rate", args.gnss_rate, 50.0)
    _check_positive("--can-rate", args.can_rate, 2000.0)
    if args.gnss_delay is not None and not (0.0 <= args.gnss_delay <= 2.0):
        _fail(f"--gnss-delay must be between 0 and 2 s, got {args.gnss_delay}")
    if args.usb_batch_ms < 0 or not math.isfinite(args.usb_batch_ms):
        _fail(f"--usb-batch-ms must be >= 0, got {args.usb_batch_ms}")
    changes = dict(GNSS_SETUPS[args.gnss])
    if args.duration is not None:
        changes["duration_s"] = args.duration
    if args.seed is not None:
        changes["seed"] = args.seed
    if args.gnss_rate is not None:
        changes["gnss_rate_hz"] = args.gnss_rate
    if args.gnss_delay is not None:
        changes["gnss_latency_s"] = args.gnss_delay
    if args.gnss_protocol is not None:
        changes["gnss_protocol"] = args.gnss_protocol
    if args.can_rate is not None:
        changes["sensor_can_rate_hz"] = args.can_rate
    if args.usb_batch_ms:
        changes["sensor_usb_batch_s"] = args.usb_batch_ms / 1000.0
    sc = sc.with_(**changes)
    base = config_mod.load(args.config)
    if args.can_dbc:
        base.can.dbc = str(config_mod.find_data_file(args.can_dbc))
        if not Path(base.can.dbc).exists():
            _fail(f"--can-dbc: no such file {args.can_dbc}")
    cfg = vehicle_config(sc, base)
    started = time.perf_counter()
    try:
        result = simulate(sc, cfg)
    except UnencodableValue as e:
        _fail(str(e))
    out_cfg = vehicle_config(sc, base, wrong=args.wrong_params)
    out = args.out or f"out/{sc.name}"
    try:
        paths = write_all(out, result, out_cfg)
    except OSError as e:
        _fail(f"cannot write to {out}: {e.strerror or e}")
    elapsed = time.perf_counter() - started
    tr = result.truth
    cf, cr = sc.vehicle.axle_cornering_stiffness()
    print(f"scenario {sc.name}: {result.t_end - result.t0:.1f} s simulated in {elapsed:.1f} s;"
          f" mu {sc.mu:g}, bank {math.degrees(sc.bank_rad):+.2f} deg, seed {sc.seed}")
    print(f"  {len(result.can_frames)} CAN frames ({result.config.dbc_path().name}),"
          f" {len(result.gnss_messages)} GNSS messages ({sc.gnss.protocol}, {sc.gnss.rate_hz:g} Hz,"
          f" latency {sc.gnss.latency_s:g} s)"
          + (f" + {len(result.gnss2_messages)} from the second receiver (latency {sc.gnss2.latency_s:g} s)"
             if sc.gnss2 is not None else ""))
    print(f"  max |sideslip| {math.degrees(tr.max_abs_sideslip):.2f} deg, max |ay|"
          f" {abs(tr.col('ay')).max():.2f} m/s^2; true Cf {cf:.0f} N/rad, Cr {cr:.0f} N/rad"
          + ("; config has WRONG vehicle parameters" if args.wrong_params else ""))
    for p in paths.values():
        print(f"  wrote {p}")
    if result.spun_out:
        log.warning("the car spun out at t = %.2f s (|sideslip| > 25 deg); the manoeuvre is too hard"
                    " for this road", tr.spin_time)
    return 0
