# Cython declarations augmenting axis_swap_check.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step (core.Estimator._step)
cdef class AxisSwapCheck:
    cdef dict __dict__
    cdef public object dt, _n, _win_s, _ring, _j, _cum, _ok, _votes, swapped, logged, d_mapped, d_swapped
    cdef public object windows
