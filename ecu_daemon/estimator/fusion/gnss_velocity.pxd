# Cython declarations augmenting gnss_velocity.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
cdef class GnssVelocityFusion:
    cdef dict __dict__
    cdef public object _H1, _H2, _M, _R1, _R2, _dx, _y1, _y2, consecutive_rejects, fused, gate, last_reason
    cdef public object late, lever_x, lever_y, max_speed_acc, min_fix_type, nmea_speed_acc, noise, rejected
