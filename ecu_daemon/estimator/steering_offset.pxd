# Cython declarations augmenting steering_offset.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every gentle-path step (core.Estimator._step)
cdef class SteeringOffset:
    cdef dict __dict__
    cdef public object dt, n, offset, ratio, var, wheelbase
