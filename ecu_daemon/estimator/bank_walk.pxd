# Cython declarations augmenting bank_walk.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots (same objects, same bits); the
# step's float locals as C doubles (each an IEEE double and the same C operation as Python's float,
# -ffp-contract=off; an expression with an object operand is still evaluated by Python).
cimport cython


# every step (core.Estimator._step)
cdef class BankWalk:
    cdef dict __dict__
    cdef public object dt, k, distance_m, kappa, total

    @cython.locals(v=double, a=double, dk=double, q=double)
    cpdef step(self, P, j, vx, r)
