# Cython declarations augmenting latency.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
cimport cython


cdef class SpeedIntegral:
    cdef dict __dict__
    cdef public object anchor, dt, first, last, n, total, v, vel
    # every step (~11 k instructions as Python objects, most of them numpy scalar arithmetic and
    # two numpy stores): the integrand as C doubles (the same IEEE operations as the .py's floats
    # and numpy float64 scalars, -ffp-contract=off; an expression with an object operand, self.dt,
    # is still Python's) and the two rings written through typed views of the same arrays
    cdef double[::1] _vm
    cdef double[:, ::1] _velm
    @cython.locals(vx=double, vy=double, r=double, ax=double, ay=double, vy_std=double, v=double,
                   total=double, i=Py_ssize_t, velm=double[:, ::1])
    cpdef step(self, k, vx, vy, r, ax, ay, vy_std=*, usable=*)
