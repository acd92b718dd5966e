# Cython declarations augmenting input_consistency.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step (core.Estimator._step)
cdef class LongitudinalScaleCheck:
    cdef dict __dict__
    cdef public object _a_ok, _cum_a, _hold, _j, _last_fail_k, _n, _ring_a, _ring_v, dt, failing
    cdef public object failures, offsets, residual

# every step (core.Estimator._step)
cdef class LateralScaleCheck:
    cdef dict __dict__
    cdef public object _a, _ay, _hold, _last_fail_k, _rdot, _rdot_decay, _rv, dt, failing, failures
    cdef public object residual
