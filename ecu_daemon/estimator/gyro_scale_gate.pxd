# Cython declarations augmenting gyro_scale_gate.py when setup.py compiles it (see fault_detection.pxd: why);
# plain Python ignores this file. Instance attributes as object slots: same objects, same bits.
# every step until the gyro is confirmed (motion_ok, heading_scale_sd*, sideslip_ok_forgetting
# from core.Estimator._step / _estimate; step every GSC_EVERY steps)
cdef class GyroScaleGate:
    cdef dict __dict__
    cdef public object track, sample_dt, slow_turn, wheels, lateral, confirmed, contradicted, exercised
    cdef public object by_speed, implausible, logged
