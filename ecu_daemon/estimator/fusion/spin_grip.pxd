# Cython declarations augmenting spin_grip.py when setup.py compiles it (see ../fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step (core.Estimator._step, SPIN_GRIP)
cdef class SpinGrip:
    cdef dict __dict__
    cdef public object a, f, grip, at_limit
