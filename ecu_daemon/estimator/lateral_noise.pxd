# Cython declarations augmenting lateral_noise.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every lateral-accelerometer sample (core.Estimator.advance_to)
cdef class LateralNoise:
    cdef dict __dict__
    cdef public object _m0, _m1, _ms, _n, _span, _sum, _t0, _t1, _w, density, floor
