# Cython declarations augmenting single_track.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
cdef class SingleTrackFusion:
    cdef dict __dict__
    cdef public object L, adapt, base_sigma_beta, front, iz_f, iz_m, iz_r, lf, lr, mass, rear

# every step (core.Estimator._step)
cdef class LaggedModelInputs:
    cdef dict __dict__
    cdef public object a1, a2, ay, ay1, dt, r, vy1, vy2

# one per axle: predict three times a step (the law's bound, its misfit, the pseudo-measurement)
cdef class AxleRls:
    cdef dict __dict__
    cdef public object k10, k, P0, P, p00_prior, updates, from_drive, rel_var, rel_var0, n2_shown
