"""PNG plots of one drive: the estimates with their +-2 sigma bands, validity, and what went in.

Shared by ``evaluate --plots`` (with the simulator's truth drawn over the estimates) and
``replay --plots`` (a real drive without truth: estimates, validity bits, GNSS use, and the
decoded CAN inputs and GNSS speed). matplotlib is imported here only (the ``plot`` extra).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .samples import INPUT_NAMES

_DEG = 180 / math.pi
#: bias-like panels: (title, estimate column, std column, unit, factor)
_BIAS_PANELS = (
    ("yaw_rate_bias", "yaw_rate_bias_radps", "yaw_rate_bias_std_radps", "deg/s", _DEG),
    ("accel_x_bias", "accel_x_bias_mps2", "accel_x_bias_std_mps2", "m/s^2", 1.0),
    ("accel_y_bias", "accel_y_bias_mps2", "accel_y_bias_std_mps2", "m/s^2", 1.0),
    ("gnss_delay", "gnss_delay_s", None, "s", 1.0),
)
_VALID = ("sideslip_valid", "heading_valid", "velocity_valid", "biases_valid")


def thin(cols: dict, max_points: int = 4000) -> dict:
    """Every n-th row so a plot has at most ~max_points (drawing time; statistics use all rows)."""
    step = max(1, math.ceil(len(cols["t"]) / max_points))
    return {k: v[::step] for k, v in cols.items()}


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles to [-pi, pi)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def write_plots(est: dict, out_dir: str | Path, truth: dict | None = None,
                inputs: dict | None = None) -> list[Path]:
    """Write the PNGs into ``out_dir``; returns the files written.

    ``est``/``truth``: columns as numpy arrays (the replay CSV / ``truth.csv`` layout).
    ``inputs``: optional ``{input name or "gnss_speed": (t array, value array)}`` in SI units.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    est = thin(est)
    truth = thin(truth) if truth is not None else None
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    te = est["t"]
    t0 = truth["t"][0] if truth is not None else te[0]
    tt = truth["t"] if truth is not None else None
    files: list[Path] = []

    def save(fig, axes, name):
        axes[-1].set_xlabel(f"t - {t0:.1f} s")
        fig.tight_layout()
        p = out / name
        fig.savefig(p, dpi=110)
        plt.close(fig)
        files.append(p)

    def band(a, col, std_col, k, label, valid_col):
        """The estimate, and its +-2 sigma band where the estimate says it is valid (the start-up
        sigma of pi would otherwise flatten every plot)."""
        v = est[col] * k
        if std_col is not None and std_col in est:
            s = np.where(est.get(valid_col, 1.0) > 0, est[std_col] * k, np.nan)
            a.fill_between(te - t0, v - 2 * s, v + 2 * s, color="tab:blue", alpha=0.2, label="+-2 sigma (valid)")
        a.plot(te - t0, v, color="tab:blue", lw=1, label=label)

    def truth_line(a, col, k=1.0):
        if truth is not None and col in truth:
            a.plot(tt - t0, truth[col] * k, color="k", lw=1, label="truth")

    fig, ax = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    band(ax[0], "sideslip_rad", "sideslip_std_rad", _DEG, "estimate", "sideslip_valid")
    truth_line(ax[0], "sideslip_rad", _DEG)
    ax[0].set_ylabel("sideslip (deg)")
    ax[0].legend(loc="upper right")
    ax[1].plot(te - t0, est["sideslip_valid"], drawstyle="steps-post", label="sideslip_valid")
    ax[1].plot(te - t0, est["heading_valid"] * 0.9, drawstyle="steps-post", label="heading_valid (x0.9)")
    ax[1].set_ylabel("valid")
    ax[1].legend(loc="lower right")
    save(fig, ax, "sideslip.png")

    fig, ax = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    truth_line(ax[0], "heading_rad", _DEG)
    ax[0].plot(te - t0, est["heading_rad"] * _DEG, "tab:blue", lw=1, label="estimate")
    ax[0].set_ylabel("heading (deg, cw from north)")
    ax[0].legend(loc="upper right")
    hs = np.where(est["heading_valid"] > 0, est["heading_std_rad"] * _DEG, np.nan)
    ax[1].fill_between(te - t0, -2 * hs, 2 * hs, color="tab:blue", alpha=0.2, label="+-2 sigma (valid)")
    if truth is not None:
        err = wrap(est["heading_rad"] - np.interp(te, tt, np.unwrap(truth["heading_rad"]))) * _DEG
        ax[1].plot(te - t0, err, "tab:red", lw=1, label="error")
        ax[1].set_ylabel("heading error (deg)")
    else:
        ax[1].set_ylabel("heading uncertainty (deg)")
    ax[1].legend(loc="upper right")
    save(fig, ax, "heading.png")

    fig, ax = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    for a, col, lab in ((ax[0], "vx_mps", "vx (m/s)"), (ax[1], "vy_mps", "vy (m/s)")):
        truth_line(a, col)
        band(a, col, col.replace("_mps", "_std_mps"), 1.0, "estimate", "velocity_valid")
        a.set_ylabel(lab)
        a.legend(loc="upper right")
    save(fig, ax, "velocities.png")

    fig, ax = plt.subplots(4, 1, figsize=(11, 10), sharex=True)
    for a, (name, col, std_col, unit, k) in zip(ax, _BIAS_PANELS):
        truth_col = next((c for c in (f"{col[:-5]}_eff{col[-5:]}", col) if truth is not None and c in truth), None)
        if truth_col:
            truth_line(a, truth_col, k)
        band(a, col, std_col, k, "estimate", "biases_valid")
        a.set_ylabel(f"{name} ({unit})")
        a.legend(loc="upper right")
    save(fig, ax, "biases.png")

    if truth is None:  # a real drive: what the flags said, and how GNSS was used
        fig, ax = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
        for i, col in enumerate(_VALID):
            if col in est:
                ax[0].plot(te - t0, est[col] * (1 - 0.05 * i), drawstyle="steps-post", label=col)
        ax[0].set_ylabel("valid")
        ax[0].legend(loc="lower right")
        for col in ("gnss_fused", "gnss_rejected", "gnss_late"):
            if col in est:
                ax[1].plot(te - t0, est[col], drawstyle="steps-post", label=col)
        ax[1].set_ylabel("GNSS samples (cumulative)")
        ax[1].legend(loc="upper left")
        save(fig, ax, "validity.png")

    if inputs:
        groups = (("wheel speeds (m/s)", [n for n in INPUT_NAMES if n.startswith("wheel_speed")] + ["gnss_speed"]),
                  ("steering wheel (deg)", ["steering_wheel_angle"]), ("yaw rate (deg/s)", ["yaw_rate"]),
                  ("acceleration (m/s^2)", ["accel_x", "accel_y"]))
        fig, ax = plt.subplots(len(groups), 1, figsize=(11, 10), sharex=True)
        for a, (label, names) in zip(ax, groups):
            k = _DEG if "deg" in label else 1.0
            for n in names:
                if n in inputs:
                    t, v = thin({"t": np.asarray(inputs[n][0]), "v": np.asarray(inputs[n][1])}).values()
                    a.plot(t - t0, v * k, lw=1, marker="." if n == "gnss_speed" else None, ms=3, label=n)
            a.set_ylabel(label)
            a.legend(loc="upper right", fontsize="small")
        save(fig, ax, "inputs.png")
    return files
