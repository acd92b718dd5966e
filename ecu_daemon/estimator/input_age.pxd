# Cython declarations augmenting input_age.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every input sample (observe, ~2 a step) and three times a step (at_mid; core.Estimator)
cdef class InputAge:
    cdef dict __dict__
    cdef public object half_dt, slope, v, t
