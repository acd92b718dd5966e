# Cython declarations augmenting gnss_speed_gap.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots (same objects, same bits).


# GnssSpeedGap.step: every step (core.Estimator._step, GNSS_SPEED_GAP); .fix: every usable fix
cdef class GnssSpeedGap:
    cdef dict __dict__
    cdef public object tol_mps, tol_rel, speed, spread, gap, events
