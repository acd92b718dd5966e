# Cython declarations augmenting standstill.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
cdef class StandstillFusion:
    cdef dict __dict__
    cdef public object accel_R, count, gyro_R, gyro_floor_var, hold_steps, r_last, r_n, r_sq, r_t
