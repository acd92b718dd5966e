# Cython declarations augmenting law_excess_bound.py when setup.py compiles it (see ../fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step (core.Estimator._step)
cdef class LawExcessBound:
    cdef dict __dict__
    cdef public object q
