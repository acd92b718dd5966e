# Cython declarations augmenting spin_check.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step (core.Estimator._step): ~10 attribute look-ups a step through Cython's generic getattr
cdef class SpinCheck:
    cdef dict __dict__
    cdef public object dt, track, _decay, _a, excess, dbeta, release_excess, active, released, events
    cdef public object peak, fired_t, _grip_steps, _grip_need, wheelbase, steer_misfit, front_misfit
