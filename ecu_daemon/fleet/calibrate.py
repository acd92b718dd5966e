"""A vehicle's parameters from all its drives: inverse-variance combination, outliers, TOML override.

Each drive's learned value comes with the estimator's own 1-sigma (:meth:`Estimator.learned_std`);
a drive that taught the estimator little (no cornering, no turns for the latency) has a wide one
and hardly counts. Drives far from the vehicle's median (robust z, and beyond their own 3 sigma)
are flagged as outliers and left out of the combination. How far the combined std averages down
with the number of drives depends on the drives' scatter (:func:`with_scatter`): a filter's
end-of-drive covariance carries its process noise, so drives may agree better (or worse) than their
own stds say, and the scatter is what they really agree to; an error all of a car's drives share,
which no scatter shows, is added once (:data:`SHARED`). ``spread`` is the drives' standard deviation.
"""
from __future__ import annotations

import hashlib
import math

import numpy as np
import tomli_w

from .job import NO_STD, PARAMS

OUTLIER_Z = 4.0  # robust z (MAD-based) beyond which a drive's value is an outlier
MIN_DRIVES_FOR_OUTLIERS = 4
#: relative error of a drive's stiffness slope per second of latency (replays 0.02 s apart moved
#: the estimate 0.4-1.4x the slope; tests/test_stiffness_regression.py)
SLOPE_REL_ERR = 0.5
#: a vehicle's latency error its drives share: the 20 x 20 simulated fleet's combined latencies
#: were -0.015..+0.020 s off (stiffer or softer tyres than the config, long latencies), at z up
#: to 4.5 with the spread-based std alone
LATENCY_SYSTEMATIC_S = 0.01


def outliers(values: np.ndarray, stds: np.ndarray) -> np.ndarray:
    """True where a value is far from the others: beyond OUTLIER_Z robust sigmas of the median and
    beyond 3 of its own sigmas (NaN values are never outliers; too few drives: none)."""
    ok = np.isfinite(values)
    flag = np.zeros(len(values), dtype=bool)
    if ok.sum() < MIN_DRIVES_FOR_OUTLIERS:
        return flag
    med = float(np.median(values[ok]))
    mad = 1.4826 * float(np.median(np.abs(values[ok] - med)))
    dev = np.abs(values - med)
    own = np.where(np.isfinite(stds), 3.0 * stds, 0.0)
    flag[ok] = (dev[ok] > OUTLIER_Z * mad) & (dev[ok] > own[ok])
    return flag


def combine(values: np.ndarray, stds: np.ndarray | None) -> dict:
    """Inverse-variance mean of the values with a finite, positive std (NaN when none has one);
    ``stds`` None (a parameter learned without uncertainty): the plain mean and its standard error."""
    if stds is None:
        v = values[np.isfinite(values)]
        n = len(v)
        return {"value": float(np.mean(v)) if n else math.nan,
                "std": float(np.std(v, ddof=1) / math.sqrt(n)) if n > 1 else math.nan,
                "drives": n, "spread": float(np.std(v)) if n > 1 else math.nan}
    ok = np.isfinite(values) & np.isfinite(stds) & (stds > 0)
    if not ok.any():
        return {"value": math.nan, "std": math.nan, "drives": 0, "spread": math.nan}
    w = 1.0 / stds[ok] ** 2
    return {"value": float(np.sum(w * values[ok]) / np.sum(w)), "std": float(1.0 / math.sqrt(np.sum(w))),
            "drives": int(ok.sum()), "spread": float(np.std(values[ok])) if ok.sum() > 1 else math.nan}


#: parameters whose combined std is judged by the drives' scatter (:func:`with_scatter`); the
#: latency has its own rule (:func:`_with_spread`), the stiffnesses the latency's (:func:`at_latency`).
#: Both are states of the filter, whose end-of-drive std carries the random walk it allows them
#: (process noise for a tyre's wear, a gyro's drift) on top of what the drive taught it: on the
#: simulated fleet their drives scatter 0.3-0.65x their stds (chi-square per degree of freedom
#: 0.08-0.43 on 10 cars x 20 drives), and 1 / sqrt(W) gave the yaw-rate bias a z mean square of 0.26.
SCATTER_RULED = ("wheel_scale", "yaw_rate_bias_radps", "steering_offset_rad")
#: per parameter of :data:`SCATTER_RULED`, the 1-sigma error all drives of one car share (added once,
#: no averaging removes it, no scatter shows it). Wheel scale: the learned scale is what the
#: non-driven wheels show, rolling-resistance slip (-f_rr / kx1 = -0.067 %, the same on every drive)
#: included, which is the factor the wheel fusion needs, so that slip is no error; what stays is the
#: braking slip the fusion's |ax| de-weighting leaves in (every drive brakes alike, ~0.2 % at
#: 0.5 m/s^2 on a non-driven axle before de-weighting): on the simulated fleet 13 of 14 cars' combined
#: scale came out above its free-rolling truth, +0.0031 % on average (-0.008..+0.009 %).
#: Yaw-rate bias: none shared (a gyro's bias is observed directly at every standstill and straight
#: run; its drift shows in the scatter; fleet: mean square z 1.1 without). Steering offset: none
#: shared (what the wheel reads when the car drives straight is the offset, by definition).
SHARED = {"wheel_scale": 3e-5, "yaw_rate_bias_radps": 0.0, "steering_offset_rad": 0.0}
#: how many degrees of freedom the drives' own stds count for beside their scatter's n - 1
#: (:func:`with_scatter`): with 20 drives the scatter rules, with 2-3 it cannot pull the std
#: below ~0.6 of what the drives' stds give, however closely two drives agree by chance
OWN_STD_DOF = 1.0


def with_scatter(p: dict, values: np.ndarray, stds: np.ndarray, shared: float = 0.0) -> dict:
    """The combined std as the drives' scatter says, with ``shared`` (an error common to all of
    a car's drives) added once.

    The scatter's chi-square per degree of freedom, r = Q / (n - 1) with Q = sum w_i (x_i - mean)^2
    and w_i = 1 / s_i^2, is 1 when each drive's std s_i is its true error; the drives' stds scaled
    by sqrt(r) are (Birge ratio), so the mean's variance is r / W (W = sum w_i), whether r is above
    1 (drives scattered more than they say) or below (cautious stds: a filter's covariance with its
    process noise). r is itself uncertain with few drives (2 drives agreeing by chance give r ~ 0),
    so the stds' own r = 1 counts as :data:`OWN_STD_DOF` more degrees of freedom:
    r = (Q + OWN_STD_DOF) / (n - 1 + OWN_STD_DOF).
    An earlier rule read r < 1 as a share of the error common to the drives and kept it whole; on
    the simulated fleet (14 cars x 20 drives) that gave the wheel scale |z| <= 0.19 against the truth, once the
    truth was the scale the rolling wheels show (the common +0.067 % it was for is physics, not
    error)."""
    ok = np.isfinite(values) & np.isfinite(stds) & (stds > 0)
    n = int(ok.sum())
    if n < 2 or not math.isfinite(p["value"]):
        return {**p, "std": math.hypot(p["std"], shared)} if math.isfinite(p["std"]) else p
    w = 1.0 / stds[ok] ** 2
    big_w = float(np.sum(w))
    q = float(np.sum(w * (values[ok] - p["value"]) ** 2))
    r = (q + OWN_STD_DOF) / (n - 1 + OWN_STD_DOF)
    return {**p, "std": math.sqrt(r / big_w + shared ** 2)}


def vehicle_parameters(rows: list[dict]) -> tuple[dict[str, dict], dict[int, list[str]]]:
    """Per parameter the combination over the vehicle's good drives; and per row index the names of
    the parameters in which that drive is an outlier. The cornering stiffnesses are combined at
    the vehicle's latency (:func:`at_latency`)."""
    good = [i for i, r in enumerate(rows) if r.get("status") == "ok"]
    # after a second pass on some of the drives (second_pass_starts' share), the latency and the
    # stiffness come from those drives alone: the others still carry the first pass's pull
    second = [i for i in good if math.isfinite(_num(rows[i].get("start_latency_s")))]
    all_good = good
    params: dict[str, dict] = {}
    flagged: dict[int, list[str]] = {}
    for name in PARAMS:
        good = second if second and name in LATENCY_BOUND else all_good
        v = np.array([_num(rows[i].get(name)) for i in good])
        s = np.array([_num(rows[i].get(f"{name}_std")) for i in good])
        slopes = None
        if name.startswith("cornering_stiffness") and "gnss_delay_s" in params:
            v, s, slopes = at_latency(name, [rows[i] for i in good], params["gnss_delay_s"])
        out = outliers(v, s)
        for j in np.flatnonzero(out):
            flagged.setdefault(good[j], []).append(name)
        params[name] = combine(v[~out], None if name in NO_STD else s[~out])
        if name == "gnss_delay_s":
            params[name] = _with_spread(params[name])
        elif name in SCATTER_RULED:
            params[name] = with_scatter(params[name], v[~out], s[~out], SHARED[name])
        elif slopes is not None:
            p = params[name]
            w = _weights(s[~out])
            if w is not None:  # the latency's error moves every drive the same way: added once
                slope = float(np.sum(w * slopes[~out]) / np.sum(w))
                p["std"] = math.hypot(p["std"], slope * params["gnss_delay_s"]["std"])
        params[name]["outliers"] = int(out.sum())
    return params, flagged


def at_latency(name: str, rows: list[dict], latency: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The drives' stiffness moved from the latency each drive estimated to the vehicle's combined
    one (its slope per second of latency, ``*_per_latency_s``: first order, the regression's own),
    with the std it would have at an exact latency; and the slopes (None: left as they are).

    Why: the regression reads the slip from GNSS lateral velocity, and a sample placed d_tau off
    reads ay d_tau more or less, as large as the slip itself at ~0.15 s; one drive knows its
    latency to ~0.01-0.03 s, a vehicle's drives together several times better, and the latency's
    error is then one bias common to all of them (added back once by the caller)."""
    v = np.array([_num(r.get(name)) for r in rows])
    s_all = np.array([_num(r.get(f"{name}_std")) for r in rows])
    tau = latency["value"]
    if not (math.isfinite(tau) and math.isfinite(latency["std"])):
        return v, s_all, None
    slope = np.array([_num(r.get(f"{name}_per_latency_s")) for r in rows])
    at = np.array([_num(r.get("stiffness_latency_s")) for r in rows])
    s = np.array([_num(r.get(f"{name}_std_given_latency")) for r in rows])
    ok = np.isfinite(slope) & np.isfinite(at) & np.isfinite(s)
    if not ok.any():
        return v, s_all, None
    shift = slope * (tau - at)
    moved = np.where(ok, v + shift, v)
    s = np.hypot(s, SLOPE_REL_ERR * shift)  # the first-order slope is itself this uncertain
    return moved, np.where(ok, s, s_all), np.where(ok, slope, 0.0)


def _weights(stds: np.ndarray) -> np.ndarray | None:
    ok = np.isfinite(stds) & (stds > 0)
    if not ok.any():
        return None
    return np.where(ok, 1.0 / np.where(ok, stds, 1.0) ** 2, 0.0)


def _with_spread(p: dict) -> dict:
    """The latency's combined std: at least the standard error the drives' spread shows, and
    with :data:`LATENCY_SYSTEMATIC_S` added: the per-drive estimates share the errors of one car
    (the estimator's model of it, e.g. its cornering stiffness, biases them alike), which no
    averaging removes. The stiffness leans on this std."""
    n = p["drives"]
    if n > 1 and math.isfinite(p["spread"]) and math.isfinite(p["std"]):
        p["std"] = max(p["std"], p["spread"] / math.sqrt(n - 1))
    if math.isfinite(p["std"]):
        p["std"] = math.hypot(p["std"], LATENCY_SYSTEMATIC_S)
    return p


#: how far above or below the vehicle's first-pass latency the second pass starts its drives: wider
#: than the 0.01-0.02 s a drive's data leave open (see :func:`second_pass_starts`)
STRADDLE_S = 0.03


#: the parameters a second pass is for: they lean on the latency a drive started from
LATENCY_BOUND = ("gnss_delay_s", "cornering_stiffness_front_n_per_rad", "cornering_stiffness_rear_n_per_rad")


def information_shares(rows: list[dict]) -> np.ndarray:
    """Per drive, its share of its vehicle's information (1 / std^2) summed over
    :data:`LATENCY_BOUND`: scale-free, so a parameter with large numbers does not rank alone."""
    score = np.zeros(len(rows))
    for name in LATENCY_BOUND:
        s = np.array([_num(r.get(f"{name}_std")) if r.get("status") == "ok" else math.nan for r in rows])
        ok = np.isfinite(s) & (s > 0)
        w = np.zeros(len(rows))
        w[ok] = 1.0 / s[ok] ** 2
        if w.sum() > 0:
            score += w / w.sum()
    return score


def second_pass_starts(drives: list, records: list[dict], share: float = 1.0) -> list[float | None]:
    """Per drive (``records[i]`` is ``drives[i]``'s first-pass record) the latency its second pass
    starts from: its vehicle's combined latency STRADDLE_S above for half of its drives and below
    for the other half (by a hash of the drive's name: balanced, and not tied to their order);
    None where the vehicle has no latency. ``share`` < 1: only that share of each vehicle's drives
    (at least 2), those that told the first pass most about the latency and the stiffness
    (:func:`information_shares`), straddled the same way; None for the rest, whose stored
    first-pass record stands and whose latency and stiffness the vehicle then leaves out
    (:func:`vehicle_parameters`).

    Why: the latency estimator leaves its start only when the data reject it (a likelihood-ratio
    test), so a drive's estimate stops at the edge of the latencies its data still accept, on the
    side it started from. Every drive of the first pass starts at the config's prior, so the
    vehicle's combination is pulled towards it (20 x 20 simulated fleet, prior 0.3 s: true
    latencies of 0.11-0.17 s came out +0.010..+0.015 s, 0.42-0.48 s -0.012..-0.016 s; four drives
    of a car of 0.254 s started at 0.200 / 0.254 / 0.300 s ended -0.007 / +0.004 / +0.011 s off on
    average), and the cornering stiffness, read from GNSS samples placed by that latency, follows
    (+4 % per 0.01 s on the front: the front misses). Started from both sides, the drives'
    stopping errors cancel in the combination."""
    from collections import defaultdict

    by_vehicle: dict[str, list[int]] = defaultdict(list)
    for i, d in enumerate(drives):
        by_vehicle[d.vehicle].append(i)
    starts: list[float | None] = [None] * len(drives)
    for idx in by_vehicle.values():
        tau = vehicle_parameters([records[i] for i in idx])[0]["gnss_delay_s"]["value"]
        if not math.isfinite(tau):
            continue
        if share < 1.0:
            keep = min(len(idx), max(2, math.ceil(share * len(idx))))
            score = information_shares([records[i] for i in idx])
            idx = [idx[j] for j in np.argsort(-score, kind="stable")[:keep]]
        order = sorted(idx, key=lambda i: (hashlib.sha256(drives[i].drive.encode()).hexdigest(), i))
        for j, i in enumerate(order):
            starts[i] = round(max(tau + (STRADDLE_S if j % 2 == 0 else -STRADDLE_S), 0.0), 4)
    return starts


def _num(v) -> float:
    return math.nan if v is None else float(v)


#: config parameters go into the override only when the combination knows them this well (issue
#: 12's fleet targets): (absolute or relative, 1-sigma limit, decimals kept)
RECOMMEND = {"gnss_delay_s": ("abs", 0.02, 4), "cornering_stiffness_front_n_per_rad": ("rel", 0.10, 0),
             "cornering_stiffness_rear_n_per_rad": ("rel", 0.10, 0)}


def _known(name: str, p: dict) -> bool:
    kind, limit, _ = RECOMMEND[name]
    if not (math.isfinite(p["value"]) and math.isfinite(p["std"])):
        return False
    return p["std"] <= (limit if kind == "abs" else limit * abs(p["value"]))


def override_toml(vehicle: str, rows: list[dict]) -> str:
    """The config override (the keys :data:`PARAMS` maps to the config, those known well enough),
    commented with every parameter's combination, including the learned-state-only ones."""
    params, flagged = vehicle_parameters(rows)
    ok = sum(r.get("status") == "ok" for r in rows)
    lines = [f"# ecu-daemon fleet calibrate --vehicle {vehicle}: {ok} of {len(rows)} drive(s) usable,"
             f" {len(flagged)} with outliers; value +- 1 sigma (combined), spread over drives"]
    doc: dict = {}
    for name, (unit, key) in PARAMS.items():
        p = params[name]
        note = " (learned state, no config key)" if not key else "" if _known(name, p) else " (not set: too uncertain)"
        lines.append(f"# {name}: {p['value']:.6g} +- {p['std']:.3g} {unit} from {p['drives']} drive(s),"
                     f" spread {p['spread']:.3g}, {p['outliers']} outlier(s){note}")
        if key and _known(name, p):
            doc.setdefault(key[0], {})[key[1]] = float(round(p["value"], RECOMMEND[name][2]))
    return "\n".join(lines) + "\n" + tomli_w.dumps(doc)


#: the learned-state keys a vehicle's drives agree on (the rest the estimator relearns each start)
STATE_KEYS = ("wheel_scale", "steering_offset_rad", "yaw_rate_bias_radps", "gnss_delay_s")


def learned_state(rows: list[dict]) -> dict:
    """The combined values as the estimator's learned state (``[daemon] state_file``,
    ``replay --state``): where the parameters without a config key can go."""
    from ..estimator.core import LEARNED_VERSION

    params, _ = vehicle_parameters(rows)
    out: dict = {"version": LEARNED_VERSION}
    for name in STATE_KEYS:
        if math.isfinite(params[name]["value"]):
            out[name] = params[name]["value"]
    if "gnss_delay_s" in out and math.isfinite(params["gnss_delay_s"]["std"]):
        out["gnss_delay_std_s"] = params["gnss_delay_s"]["std"]
    return out
