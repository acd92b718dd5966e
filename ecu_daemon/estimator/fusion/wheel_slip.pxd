# Cython declarations augmenting wheel_slip.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. SlipWitness.step runs every step and steps or re-anchors its four
# comparisons (~36 k instructions a step compiled as plain Python objects, perf49's callgrind; ~50
# attribute look-ups and as many boxed floats). Its state is floats only: the attributes and the
# arithmetic on them as C doubles, a Python float being an IEEE double and each of + - * / the same
# C operation (-ffp-contract=off: no fused multiply-add); an expression with a module constant in it
# (SLIP_SIGMAS, WINDOW_S: Python objects, monkeypatched by tests) is still Python's, in the same
# order; division keeps Python's ZeroDivisionError, abs() is fabs(), max() of doubles keeps the
# first on ties and NaN as Python's. The comparisons' methods are C calls from the witness (typed).
cimport cython


cdef class SlipWitness


cdef class _Comparison:
    cdef dict __dict__
    cdef public bint hold, anchored
    cdef public double v_ref, bax, bax_var, t, ratio, excess, v0, diff

    cpdef anchor(self, SlipWitness w, double v_wheels, double ax_m, double bax, double bax_var, double r_vy)
    cpdef rewindow(self, double bax, double bax_var)
    cpdef _restart(self, double bax, double bax_var)
    @cython.locals(lost=double, braking=bint, sigma2=double, margin=double, speed=double)
    cpdef step(self, SlipWitness w, double v_wheels, double ax_m, double r_vy, double fx)


cdef class SlipWitness:
    cdef dict __dict__
    cdef public double dt, wheel_noise2, pull, ratio, excess
    cdef public bint driven_fused
    cdef public _Comparison free, straight
    cdef public tuple windows

    @cython.locals(known=bint, free=bint, slip_free=bint, c=_Comparison, w0=_Comparison, w1=_Comparison)
    cpdef step(self, double v_wheels, double ax_m, double bax, double bax_var, double r_vy, double fx=*,
               double fy=*, bint at_limit=*)
