# Cython declarations augmenting latency.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
cdef class SpeedIntegral:
    cdef dict __dict__
    cdef public object anchor, dt, first, last, n, total, v, vel
