"""Standard gravity, written once.

Why a module of one line: the estimator's road, bank, spin and roll checks, the magnetometer's tilt and the
IMU-mounting calibration each convert specific force to angles with g; a value written in each of them can
drift apart without a test noticing. (The tyre modules' friction arithmetic still uses its own 9.81: moving it
here would change their bits, and is a change of its own, not a tidy.)
"""

#: standard gravity (CGPM 1901), m/s^2
G = 9.80665
