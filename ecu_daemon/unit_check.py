"""An input's mapping ``scale`` checked against the unit its DBC signal declares.

Why: the mapping's ``scale`` turns the DBC's physical value into SI, and the commonest mistake is
to leave it at 1 for a signal in km/h, deg, deg/s or g. Wheel speeds 3.6x too fast are the worst of
them: four agreeing wheels outvote the one receiver and the velocity stays *valid* at 3.6x the
truth (field9's report). The DBC says the unit; when the scale is far from what that unit converts
by, one line says so at start-up, naming the signal.

Only a factor far off is reported: the tolerance (``TOLERANCE``) leaves room for a deliberate
correction (a tyre size, a sensor gain) and catches every unit confusion (km/h 3.6, deg 57, g 9.8,
mph 2.2; the smallest, km/h vs mph, is 1.6). Units are matched case-insensitively over the
spellings the opendbc DBCs use (``km/h``, ``kph``, ``Unit_KiloMeterPerHour``, ``Grad/sec``, ...); a
unit not listed (none, ``""``, a typo) is not judged. A DBC's unit can be wrong too, which is why
this warns and does not refuse.
"""
from __future__ import annotations

import math

#: accepted ratio of |scale| to the unit's SI factor: within 1/1.25 .. 1.25
TOLERANCE = 1.25

_DEG = math.pi / 180.0
_RPM = 2.0 * math.pi / 60.0  # rev/min -> rad/s
_UNITS = {
    "speed": {"m/s": 1.0, "meters/sec": 1.0, "unit_meterpersecon": 1.0, "km/h": 1 / 3.6, "kph": 1 / 3.6,
              "kmh": 1 / 3.6, "unit_kilometerperhour": 1 / 3.6, "mph": 0.44704},
    "angle": {"rad": 1.0, "radians": 1.0, "deg": _DEG, "degree": _DEG, "degrees": _DEG, "grad": _DEG,
              "°": _DEG, "°grad": _DEG, "unit_degreofarc": _DEG, "unit_degreeofarc": _DEG},
    "rate": {"rad/s": 1.0, "radians/second": 1.0, "radians/sec": 1.0, "deg/s": _DEG, "deg/sec": _DEG,
             "deg/sek": _DEG, "degrees/second": _DEG, "degrees/sec": _DEG, "grad/sec": _DEG, "°/s": _DEG,
             "°grad/s": _DEG, "unit_degreofarcpersecon": _DEG},
    "accel": {"m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0, "m/sec^2": 1.0, "unit_meterpersecon squar": 1.0,
              "unit_meterpersecsquar": 1.0, "unit_meterperseconsquar": 1.0, "g": 9.80665,
              "unit_forceofgravi": 9.80665},
    # a wheel's own angular speed: the scale to m/s is the rolling radius
    "wheel": {"rad/s": 1.0, "rpm": _RPM, "u/min": _RPM, "1/min": _RPM, "upm": _RPM, "unit_minutinver": _RPM},
}
_KIND = {"wheel_speed_fl": "speed", "wheel_speed_fr": "speed", "wheel_speed_rl": "speed",
         "wheel_speed_rr": "speed", "steering_wheel_angle": "angle", "yaw_rate": "rate", "roll_rate": "rate",
         "accel_x": "accel", "accel_y": "accel"}
_SI = {"speed": "m/s", "angle": "rad", "rate": "rad/s", "accel": "m/s^2"}


def _unit_key(unit: str) -> str:
    # a DBC written in cp1252 and read as UTF-8 (or the reverse) turns the degree sign into "Â°"
    return unit.strip().lower().replace("â°", "°")


def scale_warning(input_name: str, signal_name: str, unit: str | None, scale: float,
                  wheel_radius_m: float) -> str | None:
    """One line when ``scale`` cannot be the conversion of ``unit`` to the input's SI unit; else None."""
    kind = _KIND.get(input_name)
    if kind is None or not unit or not scale:
        return None
    key = _unit_key(unit)
    if kind == "speed" and key in _UNITS["wheel"]:  # wheel angular speed: scale = factor x radius
        expected = _UNITS["wheel"][key] * wheel_radius_m
        what = (f"{unit} of a wheel -> m/s is its rolling radius"
                + (" x 2 pi / 60" if _UNITS["wheel"][key] != 1.0 else "")
                + f": scale = {expected:.6g} for [vehicle] wheel_radius_m = {wheel_radius_m:g}")
    elif key in _UNITS[kind]:
        expected = _UNITS[kind][key]
        what = f"{unit} -> {_SI[kind]} is scale = {expected:.6g} (negative to flip the axis)"
    else:
        return None
    ratio = abs(scale) / expected
    if 1 / TOLERANCE <= ratio <= TOLERANCE:
        return None
    how = f"{ratio:.3g}x too large" if ratio > 1 else f"{1 / ratio:.3g}x too small"
    return (f"[inputs.{input_name}] signal '{signal_name}' is in {unit} (its DBC unit), but scale = {scale:g}"
            f" reads it {how} in {_SI[kind]}: {what}")
