# Cython declarations augmenting fault_detection.py when setup.py compiles it (compiled_python.py);
# plain Python ignores this file. FaultDetector becomes an extension type whose instance attributes
# are struct slots: ``self.e_w`` in the compiled step is a pointer load instead of a dict lookup
# (the per-step checks read and write ~80 of them, ~40 % of the step's cost was these look-ups).
# Every slot is a Python ``object``: the values, their types and every operation on them stay
# exactly those of the .py (the same bits). ``__dict__`` keeps instances open to any other attribute.
cdef class FaultDetector:
    cdef dict __dict__
    cdef public object _a_lr, _a_slow, _a_yaw, _ax_jump_k, _ax_prev, _cum_a, _gnss_wheel_verdict
    cdef public object _gyro_suspect, _k, _lat_abs, _lat_cum, _lat_filled, _lat_k, _lat_n, _lat_ring
    cdef public object _measured, _model_vy, _n, _other_wheels, _r_prev, _relearn, _repair_lag
    cdef public object _ring_a, _ring_v, _rw_lp, _rw_prev, _scale, _stuck_ref, _stuck_steps
    cdef public object _suspect_k, _v_prev, _w_fail_since, _wheel_jump_k, _wheel_r2, _yaw_cum
    cdef public object _yaw_ring, ax_wheels, ay, ay_stuck, bias_relearn, dt, e_a, e_as, e_w, e_ws
    cdef public object events, frozen, fused_wheels, gnss, gyro, gyro_stuck, heading_repair, isolated
    cdef public object lat_excess, lat_residual, lat_unexplained, lf, lon, lon_culprit, lon_onset
    cdef public object lr, lr_m, new_isolation, r_wheels, rdot_abs, stuck_wheels, track
    cdef public object wheel_latches, wheel_mask, wheel_z, wheel_z_excess_var, wheels_back
    cdef public object wheels_isolated, wheels_stuck, wheels_vouch_gyro, witnesses_agree
    cdef public object yaw_catch_up, yaw_disagreement, yaw_suspect
