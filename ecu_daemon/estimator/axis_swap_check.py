"""Are the accelerometer's x and y inputs swapped? Each axis against its own witness.

Why: mapping ``accel_x`` to the lateral signal and ``accel_y`` to the longitudinal one (or an IMU
turned 90 deg with ``mounting_rpy_deg`` left at 0) is a one-line mistake that none of the other
checks sees: both signals are in m/s^2 with plausible ranges (unit_check.py), neither sign is
flipped (fault_detection.py), the longitudinal check (input_consistency.py) takes the steady
lateral acceleration of a circle in "ax" for ax's bias at a steady, GNSS-confirmed speed, and
the lateral one judges only 3-6 m/s. The filter then integrates the corner's ay into vx and
the acceleration's ax into vy, the bias states and the heading absorb what the wheels and GNSS
correct, and the heading was published 9.6 deg off while valid on a 15 m circle (2334 valid
rows beyond 3 sigma, lowspeed_r15), 4-7 deg in lane changes and slaloms, with no log line.

Physics gives each axis a witness that does not involve the accelerometer: at the CG
``ax = dvx/dt - r vy`` and ``ay = dvy/dt + r vx``. Over a window of ``SWAP_WINDOW_S`` the wheels'
speed change gives the mean dvx/dt, the gyro times the speed the mean r vx; r vy and dvy/dt
average to little (sideslip is small and changes little over a second). The two hypotheses,
"as mapped" (ax ~ dv/dt, ay ~ r vx) and "swapped" (ax ~ +-r vx, ay ~ +-dv/dt, either sign: a
swap or a 90 deg turn), predict mean accelerations that differ by ``sep``; only a window where
that difference is well beyond what the model leaves out (``SWAP_TOL_MPS2``: accelerometer bias,
grade and bank gravity, body roll, vy's rate, an unconfigured IMU lever arm; plus
``SWAP_TOL_REL`` of the excitation for wheel slip and scale) can tell them apart: a straight at
constant speed, or a corner taken while accelerating as hard as it turns (45 deg, where the two
agree), votes for neither. A window close to one hypothesis votes for it. A run of
``SWAP_VOTES`` swapped votes is the verdict (one log line naming both keys); a run of as many
as-mapped votes takes it back. A configuration does not change while the daemon runs: between
corners the verdict stands, so sideslip, heading and velocity (all of them integrate the two
axes) are not promised while it says swapped. Nothing is fused differently.

The witness leaves ``r vy`` out (within ``SWAP_TOL_MPS2``): a car sliding sideways breaks that, and
the slide itself then reads as a swap. Random drive 499 (j-turn on mu 0.35, the rear out from 22 s,
a 180 deg spin to a stop at 29-31 s): at 28.9-29.3 s, vx 1.3 -> -0.4 m/s, vy 3.4-4.3 m/s at a yaw
rate of -1 rad/s, ``r vy`` ~4 m/s^2 (the check's whole tolerance is 1): five windows voted
"swapped" (d 0.4-1.3 m/s^2 from it, 4-5 as mapped) after 26 as-mapped ones, and the verdict stood
to the end of the drive (the straight after it tells the mappings nothing): heading valid above 5 m/s
0.50 against 0.69 without it. The spin check knows nothing of that slide (r vx never beyond
1.2 g on that road; below 5 m/s it does not judge), but the filter does: its vy and vy's std are the
slide state it has, and ``|r| (|vy| + 3 std)`` bounds the term the witness leaves out (4.5-5.2
m/s^2 there). A step where that bound is beyond ``SWAP_RVY_MPS2`` restarts the window, as a missing
input does: a window over a slide votes for neither mapping. A swapped mapping is still convicted
where the witness holds (tests/test_accel_axes_swapped.py: the 15 m circle's turn-in, dlc_dry's
acceleration, where r is ~0). Its cost: a swap that made the filter's own vy large enough would go
unjudged while it does (the single-track model holds vy to a gripping car's).
"""
from __future__ import annotations

import math

SWAP_WINDOW_S = 0.6  # a turn-in: long enough to average noise and vy's own rate, short for a verdict
SWAP_EVERY = 10  # steps between ring samples (60 ms)
SWAP_TOL_MPS2 = 1.0  # bias 0.3, 6 % bank gravity 0.6, roll, r vy, dvy/dt, an unconfigured IMU lever arm
SWAP_TOL_REL = 0.1  # of the excitation |(dv/dt, r vx)|: wheel slip and scale, the speed's lag
SWAP_VOTES = 5  # consecutive windows (0.3 s of sliding windows) for a verdict either way
SWAP_RVY_MPS2 = SWAP_TOL_MPS2  # |r| (|vy| + 3 std) beyond which the window is no witness (a slide)


class AxisSwapCheck:
    """Windowed means of ax, ay against the wheels' dv/dt and the gyro's r vx; :attr:`swapped`
    while the evidence says the two accelerometer inputs are exchanged (module docstring)."""

    def __init__(self, dt: float):
        self.dt = dt
        self._n = max(2, int(round(SWAP_WINDOW_S / (SWAP_EVERY * dt))))
        self._win_s = self._n * SWAP_EVERY * dt
        self._ring = [None] * self._n  # (v, cum ax, cum ay, cum r v) at each ring sample
        self._j = 0
        self._cum = [0.0, 0.0, 0.0]
        self._ok = True  # every sample since the last restart was finite
        self._votes = 0  # > 0: consecutive swapped votes, < 0: consecutive as-mapped votes
        self.swapped = False
        self.logged = False
        self.d_mapped = math.nan  # the last judged window's distance to each hypothesis, m/s^2
        self.d_swapped = math.nan
        self.windows = [0, 0]  # judged windows over the drive: (as mapped, swapped)

    def _restart(self) -> None:
        self._ring = [None] * self._n
        self._cum = [0.0, 0.0, 0.0]

    def step(self, k: int, v: float, ax: float, ay: float, r: float, vx: float, rvy: float = 0.0) -> bool:
        """One estimator step: ``v`` the fused wheel speed (scaled), ``ax``, ``ay`` the accelerometer
        as mapped (at the CG, body axes), ``r`` the bias-corrected yaw rate, ``vx`` the filter's;
        any NaN (a stale or isolated input): the window restarts. ``rvy``: a bound of ``|r vy|``
        (the filter's ``|r| (|vy| + 3 std)``); beyond ``SWAP_RVY_MPS2`` (a slide) the window restarts
        too. True the first time the verdict says swapped (the caller logs :meth:`message`)."""
        rv = r * vx
        if not (ax == ax and ay == ay and rv == rv and v == v) or rvy > SWAP_RVY_MPS2:
            self._restart()
            return False
        c = self._cum
        dt = self.dt
        c[0] += ax * dt
        c[1] += ay * dt
        c[2] += rv * dt
        if k % SWAP_EVERY:
            return False
        j = self._j
        old = self._ring[j]
        self._ring[j] = (v, c[0], c[1], c[2])
        self._j = (j + 1) % self._n
        if old is None:
            return False
        T = self._win_s
        wx = (v - old[0]) / T  # mean dvx/dt, the wheels'
        wy = (c[2] - old[3]) / T  # mean r vx
        mx = (c[0] - old[1]) / T
        my = (c[1] - old[2]) / T
        # the swapped hypothesis with the signs that fit best: a swap or a 90 deg turn either way
        sx = 1.0 if mx * wy >= 0.0 else -1.0
        sy = 1.0 if my * wx >= 0.0 else -1.0
        sep = math.hypot(wx - sx * wy, wy - sy * wx)  # what tells the two predictions apart
        tol = SWAP_TOL_MPS2 + SWAP_TOL_REL * math.hypot(wx, wy)
        if sep < 2.0 * tol:
            return False  # the two hypotheses predict the same within what the model leaves out
        d_m = math.hypot(mx - wx, my - wy)
        d_s = math.hypot(mx - sx * wy, my - sy * wx)
        self.d_mapped, self.d_swapped = d_m, d_s
        if d_s <= tol < d_m:
            self.windows[1] += 1
            self._votes = self._votes + 1 if self._votes > 0 else 1
        elif d_m <= tol < d_s:
            self.windows[0] += 1
            self._votes = self._votes - 1 if self._votes < 0 else -1
        else:
            return False
        if self._votes >= SWAP_VOTES and not self.swapped:
            self.swapped = True
            if not self.logged:
                self.logged = True
                return True
        elif self._votes <= -SWAP_VOTES:
            self.swapped = False
        return False

    def message(self) -> str:
        """The log line: both keys, what each reads."""
        return ("[inputs.accel_x] / [inputs.accel_y]: accel_x reads the yaw rate times the speed "
                "and accel_y the wheels' speed change (mean over %.1f s: %.1f m/s^2 from the swapped "
                "mapping, %.1f as mapped): the two signals look swapped (or the IMU is turned 90 deg: "
                "[imu] mounting_rpy_deg); sideslip, heading and velocity are not promised while they do"
                % (self._win_s, self.d_swapped, self.d_mapped))
