# Cython declarations augmenting road.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
cimport cython


cdef class _Channel


cdef class RoadAttitude:
    cdef dict __dict__
    cdef public object _k, _lp, _ring, altitude, altitude_fused, altitude_rejected, baselines, dt
    cdef public object elevation_fused, elevation_rejected, fy_lp, gyro, roll, roll_bias0
    # typed: set_roll reads the bank channel's typed views directly (a C load, not an attribute
    # look-up and a numpy scalar); they are only ever these two _Channel objects
    cdef public _Channel grade, bank
    cdef public object roll_gyro_params, roll_std, vertical_fused, vertical_zero
    cdef public object dist, bank_walk_seen, var_gay_seen, roll_doubt  # step's, every step (perf46)
    # every step: the lateral force and its low-pass as C doubles (the same IEEE operations as the
    # .py's floats and numpy float64 scalars; fabs as Python's; see fault_detection.pxd). Never
    # x ** 2 of a C double: gcc makes pow(x, 2.0) x * x, Python's libm pow differs in the last bit
    # for ~0.1 % of x (dlc_dry once: roll_std 1 ulp off at one step); write x * x in the .py
    @cython.locals(fy=double, lp=double, k2=double, d=double, ay_m=double, g_ay=double,
                   var_gay=double, ay_doubt=double)
    cpdef set_roll(self, ay_m, g_ay, var_gay, ay_doubt=*)


# one [angle, offset] filter (grade, bank): read for the published fields and validity every step
cdef class _Channel:
    cdef dict __dict__
    cdef public object P, floor2, updates, x
    # x and P as typed views (the same memory): std and set_roll read them every step
    cdef double[::1] _xm
    cdef double[:, ::1] _Pm
