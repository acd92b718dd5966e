"""GNSS let back in while nothing vouched for the velocity is not yet a check of the state
(``core.GNSS_READMIT_CHECK``; issue 7, readmit45, random drive 2446).

Why: a GNSS receiver returns from isolation after its fixes agree with a witness for a while; with
the wheels isolated the witness is the filter's own vx, within 5 of its sigma. After a spin (2446:
mu 0.37, the car slid backwards at 7.7 m/s, wheels and GNSS isolated, vx std 3-6 m/s) that window
is 15-30 m/s wide: any fix "agrees", so the re-admission checked nothing (a speed-only test also
cannot see a car going backwards). The fixes then pull vx in and the wheels come back, and the
covariance collapses in a few steps (vy std 2.1 -> 0.04 m/s) around biases and a vy that no
residual has tested yet: the sideslip was promised 0.3 s later, 2.7 deg off at 0.64 deg.

So after a re-admission made while the velocity was not vouched for (``vel_valid`` false), the
sideslip waits for the next fix fused while it is: a fix checked against trusted wheels (or a
converged filter) and passed through the filter's innovation gate at its collapsed covariance. A
re-admission while the velocity is vouched for (the usual case: wheels trusted throughout) costs
nothing. One flag, one state; no time constant."""
from __future__ import annotations


class GnssReadmitCheck:
    """``pending`` from a GNSS return from isolation made without a vouched velocity until a fix is
    fused while the velocity is vouched for."""

    __slots__ = ("pending",)

    def __init__(self) -> None:
        self.pending = False

    def released(self, vel_vouched: bool) -> None:
        """GNSS has just come back from isolation; ``vel_vouched``: the last estimate's velocity was
        valid (then the fixes were checked against a witness that knew the speed)."""
        if not vel_vouched:
            self.pending = True

    def fused(self, vel_vouched: bool) -> None:
        """A fix was fused; while the velocity is vouched for it has passed a real check."""
        if vel_vouched:
            self.pending = False
