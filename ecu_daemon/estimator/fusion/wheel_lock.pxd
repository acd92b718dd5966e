# Cython declarations augmenting wheel_lock.py when setup.py compiles it (see ../fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step (core.Estimator._step, WHEEL_LOCK_SKIP)
cdef class WheelLock:
    cdef dict __dict__
    cdef public object dt, wheel_noise2, pull, v_ref, bax, bax_var, t, locked
