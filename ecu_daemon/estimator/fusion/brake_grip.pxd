# Cython declarations augmenting brake_grip.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step with the IMU (core.Estimator._step): ~11 attribute look-ups a step through Cython's generic getattr
cdef class BrakeGrip:
    cdef dict __dict__
    cdef public object lf, lr, L, h, a, drive_front, mu_shown, ax, u, ratio
