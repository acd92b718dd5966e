# Cython declarations augmenting single_track.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
cdef class SingleTrackFusion:
    cdef dict __dict__
    cdef public object L, adapt, base_sigma_beta, front, iz_m, lf, lr, mass, rear
