# Cython declarations augmenting wheel_speed.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
cdef class WheelSpeedFusion:
    cdef dict __dict__
    cdef public object consecutive_rejects, frac, h, lf, noise2, rejected, use_all, use_front
