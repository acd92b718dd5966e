# Cython declarations augmenting slip_ratio_limit.py when setup.py compiles it (see ../fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step (core.Estimator._step, SLIP_RATIO_LIMIT)
cdef class SlipRatioLimit:
    cdef dict __dict__
    cdef public object a, fx, kappa, ratio, f_seen, fx_seen
