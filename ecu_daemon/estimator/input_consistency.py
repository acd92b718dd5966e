"""Slow longitudinal consistency: do the wheels' speed changes have the accelerometer's scale and sign?

Why a second, slow check beside the fault detector's 0.15 s longitudinal test: that test must
tolerate wheel slip transients, so its tolerance (1 m/s + 3 % of speed per window) hides any
error that is *proportional* to the speed change. Two configuration errors a user makes on day
one are exactly that: wheel speeds in km/h mapped as m/s (every speed change 3.6x what ax
integrates to) and an accelerometer whose x axis points backwards (every change of the opposite
sign). Four agreeing wheels then outvote the one GNSS receiver, and vx was published valid
tens of m/s off. Over a 2 s window the integral of ax and the change of the wheel speed must
agree within what physics allows:

* the accelerometer's bias error and a grade change: ``LON2_TOL_MPS`` over the window;
* wheel slip (driving and ABS braking, up to ~15 % on ice) and a wrong wheel radius:
  ``LON2_TOL_SPEED`` of the speed, and ``LON2_TOL_SCALE`` of the speed change itself.

A window beyond that cannot be a tyre or a sensor's noise: one of the two is mis-scaled or
mis-signed, and nothing in the window says which (GNSS may be the arbiter, but the wheels have
already outvoted it), so velocity is not promised while windows fail and ``LON2_HOLD_S`` after
the last. Nothing is fused differently: this check only withholds the promise. While the fault
detector has isolated the wheels or ax it has found the culprit (a sensor fault, not a mapping
error) and the filter no longer fuses it: the check stands aside and starts afresh after.
"""
from __future__ import annotations

import math

LON2_WINDOW_S = 2.0  # long enough for a gentle acceleration to show a 3.6x scale (1 m/s^2: 7 m/s vs 2)
LON2_EVERY = 10  # steps between samples of the window's ring (60 ms): the check is slow by design
LON2_TOL_MPS = 1.0  # accelerometer bias error (0.2 m/s^2) and grade change over the window
LON2_TOL_SPEED = 0.05  # wheel slip change over the window, as a share of the speed
LON2_TOL_SCALE = 0.35  # ... and of the speed change: wheel radius error, slip growing with deceleration
LON2_HOLD_S = 5.0  # the promise stays withheld this long after the last failing window


class LongitudinalScaleCheck:
    """Wheel speed change against integrated ax over ``LON2_WINDOW_S``; :attr:`failing` while they
    disagree in scale or sign beyond physics (module docstring)."""

    def __init__(self, dt: float):
        self.dt = dt
        self._n = max(2, int(round(LON2_WINDOW_S / (LON2_EVERY * dt))))
        self._ring_v = [math.nan] * self._n
        self._ring_a = [math.nan] * self._n
        self._j = 0
        self._cum_a = 0.0
        self._a_ok = True  # every ax sample since the ring's oldest entry was finite
        self._hold = int(round(LON2_HOLD_S / dt))
        self._last_fail_k = -(1 << 62)
        self.failing = False
        self.residual = 0.0  # m/s, the last window's wheel change minus ax's integral
        self.failures = 0  # windows that failed, over the drive

    def reset(self) -> None:
        """The fault detector has isolated the wheels or ax (it knows which is wrong and the filter
        no longer fuses it): its verdict stands, and this check starts afresh when both return."""
        self._ring_v = [math.nan] * self._n
        self._ring_a = [math.nan] * self._n
        self._cum_a = 0.0
        self._last_fail_k = -(1 << 62)
        self.failing = False

    def step(self, k: int, v_wheels: float, ax: float) -> bool:
        """One estimator step: ``v_wheels`` the fused wheel speed (scaled; NaN: none), ``ax`` the
        bias-corrected longitudinal acceleration (NaN: none). Returns :attr:`failing`."""
        if ax == ax:
            self._cum_a += ax * self.dt
        else:
            self._cum_a = math.nan  # a gap: the integral restarts with the ring below
        if k % LON2_EVERY == 0:
            n = self._n
            j = self._j
            v_old = self._ring_v[j]
            a_old = self._ring_a[j]
            cum = self._cum_a
            if cum != cum:
                cum = self._cum_a = 0.0
                self._ring_a = [math.nan] * n  # older integrals are of another run
                a_old = math.nan
            self._ring_v[j] = v_wheels
            self._ring_a[j] = cum
            self._j = (j + 1) % n
            if v_wheels == v_wheels and v_old == v_old and a_old == a_old:
                dv_a = cum - a_old
                res = (v_wheels - v_old) - dv_a
                self.residual = res
                tol = (LON2_TOL_MPS + LON2_TOL_SPEED * max(abs(v_wheels), abs(v_old))
                       + LON2_TOL_SCALE * abs(dv_a))
                if abs(res) > tol:
                    self._last_fail_k = k
                    self.failures += 1
        self.failing = k - self._last_fail_k <= self._hold
        return self.failing
