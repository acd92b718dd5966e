"""A vehicle's parameters from all its drives: inverse-variance combination, outliers, TOML override.

Each drive's learned value comes with the estimator's own 1-sigma (:meth:`Estimator.learned_std`);
a drive that taught the estimator little (no cornering, no turns for the latency) has a wide one
and hardly counts. Drives far from the vehicle's median (robust z, and beyond their own 3 sigma)
are flagged as outliers and left out of the combination. The combined std assumes independent
drives; ``spread`` (the drives' standard deviation) shows what the drives really agree to.
"""
from __future__ import annotations

import math

import numpy as np
import tomli_w

from .job import NO_STD, PARAMS

OUTLIER_Z = 4.0  # robust z (MAD-based) beyond which a drive's value is an outlier
MIN_DRIVES_FOR_OUTLIERS = 4


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


def vehicle_parameters(rows: list[dict]) -> tuple[dict[str, dict], dict[int, list[str]]]:
    """Per parameter the combination over the vehicle's good drives; and per row index the names of
    the parameters in which that drive is an outlier."""
    good = [i for i, r in enumerate(rows) if r.get("status") == "ok"]
    params: dict[str, dict] = {}
    flagged: dict[int, list[str]] = {}
    for name in PARAMS:
        v = np.array([_num(rows[i].get(name)) for i in good])
        s = np.array([_num(rows[i].get(f"{name}_std")) for i in good])
        out = outliers(v, s)
        for j in np.flatnonzero(out):
            flagged.setdefault(good[j], []).append(name)
        params[name] = combine(v[~out], None if name in NO_STD else s[~out])
        params[name]["outliers"] = int(out.sum())
    return params, flagged


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
