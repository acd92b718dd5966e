"""The lateral force the rear tyres carry, from the accelerometer: the specific force, bank in (issue 7,
"the estimate is right, or it says it is not"; core.DRIVE_SLIP_TYRE_FORCE).

Why: drive_slip.py turns a driven rear axle's slip ratio at its friction limit into a slip angle,
``tan(alpha) = kappa F_yr / F_xr`` (the force along the slip vector), with F_yr the rear axle's
lateral force per mass. It took F_yr from the model's lateral acceleration, the specific force less
the filter's b_ay, and b_ay holds the road's bank as well as the sensor's offset (road.py splits the
two afterwards). That is the car's acceleration along its y, not the force its tyres carry: on a
road banked by phi the tyres hold the car against g sin(phi) with the car going straight, at a
kinematic ay of 0. Inside its grip that share is small to the law (a linear tyre, C_r 124 kN/rad,
takes 0.1 deg for 0.3 m/s^2), but at the limit the angle is kappa / kappa_lin times the linear
one, and a kinematic ay of ~0 made the rule's angle ~0 however hard the wheels spun.

Random drive 1714 (tools/random_drives.py, generator v1: rear drive, mu 0.36 -> 0.16 at 14.2 s,
+3.9 % grade, bank -1.9 deg): after a slide in the circle the car accelerates uphill at 0.2 m/s^2
(specific force ~0.7 m/s^2 with the grade, the rear axle's whole mu F_z: 0.16 x 9.81 x 0.46 = 0.72),
the rear wheels 5-9 % ahead of the free front (a linear tyre: 1 %), and a rear slip angle of -1 deg
at ay ~0. The drive-slip rule saw the slip (kappa 0.05-0.06, drive force 0.7-0.8 m/s^2) but took
F_yr from ay ~ -0.03 m/s^2: an angle of 0.05-0.3 deg, no widening, the law's 0 held at a 0.29-0.38
deg std; 117 of 1779 valid sideslip rows beyond 3 sigma, worst 4.63 deg. With the bank's share
(the specific force less the sensor's offset, road.py's split: ~0.32 m/s^2, the rear's lf / L of
it) the rule's angle is kappa F_yr / F_xr = 0.055 x 0.15 / 0.7 = 0.7 deg, the slip the car had.

So the rear axle's lateral force per mass here is the single-track regressor's (lf ay - I_z/m
rdot) / L with ay the accelerometer's specific force less the road's sensor offset (the slip
witness's ``fy``, wheel_slip.py), low-passed over SMOOTH_S like the rule's slip ratio and drive
force (a raw sample's noise, ~0.1 m/s^2, would bias |F_yr| upwards).

But that offset is known only as well as road.py's split of b_ay into offset and bank: a constant
bank and a constant offset read alike, and the bank's std never drops below its prior (1714: the
road's bank 0.0 +- 0.9 deg for a true -1.9 deg, so the force less the offset read ~0 again, -0.05
to +0.07 m/s^2 at the rear). The force is therefore a value with a std: the offset's std
(sqrt of road.bank.P[1, 1], ~0.15 m/s^2 there), times the rear's share lf / L. Its part of the
rule's angle is linear in the force (d(vx tan alpha) / dF_yr = vx kappa / F_xr), so it adds
(vx kappa sigma_Fyr / F_xr)^2 to the rule's variance (``angle_var``): 1714, vx 5.2 m/s, kappa
0.055, F_xr 0.7: 0.028 m/s, 0.3 deg of sideslip, at 1 sigma of the force. Only while the
drive-slip rule has found the rear on its limit (the wheels' slip beyond a linear tyre's); inside
the grip the force's doubt is the law's own (0.1 deg, above). Used only for the drive-slip rule;
the law itself and the rule's gates are unchanged.
"""
from __future__ import annotations

#: s: the force is low-passed over the drive-slip rule's own smoothing time (drive_slip.SMOOTH_S)
SMOOTH_S = 0.1
#: m/s^2: the drive force per mass the angle is divided by at least (drive_slip.MIN_FX_MPS2)
MIN_FX_MPS2 = 0.3


class RearLateralForce:
    """The rear axle's lateral tyre force per mass (m/s^2, the single-track regressor's sign) from
    the specific force less the sensor's offset, low-passed."""

    def __init__(self, dt: float, lf: float, lr: float, iz_m: float) -> None:
        self.a = min(dt / SMOOTH_S, 1.0)
        self.lf = lf
        self.L = lf + lr
        self.iz_m = iz_m  # the yaw inertia per mass (m^2)
        self.reset()

    def reset(self) -> None:
        self.fy = 0.0  # the tyres' lateral force per mass, low-passed
        self.std = 0.0  # the rear axle's share of its std (m/s^2): the sensor offset's
        self.started = False

    def step(self, fy: float, rdot: float, offset_std: float = 0.0) -> float:
        """``fy``: the specific lateral force less the sensor's offset (m/s^2; NaN: not heard, the
        last value held), ``rdot`` the yaw acceleration, ``offset_std`` that offset's std (road.py's
        split); returns the rear axle's share, as ``SingleTrackFusion.regressor_rear(1.0, fy, rdot)``."""
        self.std = self.lf * offset_std / self.L
        if fy == fy:
            if self.started:
                self.fy += self.a * (fy - self.fy)
            else:
                self.fy = fy
                self.started = True
        return -(self.lf * self.fy - self.iz_m * rdot) / self.L

    def angle_var(self, vx: float, kappa: float, fx: float) -> float:
        """Variance (m/s)^2 of the drive-slip rule's vy (vx tan(alpha), tan(alpha) = kappa F_yr /
        F_xr) from the rear force's std: ``kappa`` the rear's slip ratio and ``fx`` its force per
        mass (drive_slip.DriveSlip's, low-passed), at the rule's speed ``vx``."""
        e = vx * kappa * self.std / max(fx, MIN_FX_MPS2)
        return e * e
