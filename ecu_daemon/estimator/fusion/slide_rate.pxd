# Cython declarations augmenting slide_rate.py when setup.py compiles it (see ../fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step (core.Estimator._step, SLIDE_RATE)
cdef class SlideRate:
    cdef dict __dict__
    cdef public object dt, tau, e, vy_model, _keep, _lim_acc
