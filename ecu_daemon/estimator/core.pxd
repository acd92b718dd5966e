# Cython declarations augmenting core.py when setup.py compiles it (compiled_python.py); plain
# Python ignores this file. Estimator becomes an extension type whose instance attributes are
# struct slots, as FaultDetector's (fault_detection.pxd): ``self.fdi`` in the compiled step is a
# pointer load instead of a dict lookup (_step alone read ~60 attributes per 6 ms step, ~210
# instructions each through Cython's untyped getattr). Every slot is a Python ``object``: the
# values, their types and every operation on them stay those of the .py (the same bits).
# ``__dict__`` keeps instances open to any other attribute (a new one needs no edit here; list it
# when it is on the hot path). An extension type's methods cannot be replaced on the class: wrap
# them on the instance or in a subclass (tools/bench_replay.py does).
cimport cython


cdef class Estimator:
    cdef dict __dict__
    cdef public object learned_bounds, wheel_scale_seed  # the wheel-scale seed (input_consistency.WheelScaleSeed)
    cdef public object _learned0, _lp_r, _lp_rdot, _lp_turn, _reset_flag, _slip_decay
    cdef public object _velocity_latencies, _vy_density, align_lat_var, align_psi_var, aligned
    cdef public object augmented, cfg, considers, course_heading, delay_compensation, dt, fdi
    cdef public object fix_steps, gap_s, gaps, gnss, gnss_agrees, gnss_checked_t
    cdef public object gnss_conflict_last_t, gnss_conflict_t, gnss_run_t, heading, held, held_t
    cdef public object hist, imu_mount, initialized, k, last_gap, last_gnss_fused_t
    cdef public object last_gnss_rejected, last_gnss_speed, last_heading_fused_t, lat_drift_tol
    cdef public object lat_noise, lat_scale, lat_sens, late_inputs, latencies, latency, lon_scale
    cdef public object mag, mag_bridged, mag_new, model, model_ay, model_inputs, model_t
    cdef public object model_unsteady_t, queue, r_lp, rdot, realignments, receivers, resets, road
    cdef public object single_track, slip_hold, speed_integral, speed_latencies, standstill
    cdef public object steer_learner, steer_offset, steer_ratio, stiffness, timeouts, turn_lp
    cdef public object uses_velocity, wheel_new, wheel_reject_t, wheels, yaw_integral
    cdef public object yaw_scale_checks, yaw_scale_std, yaw_scale_applied, yaw_scale_ring, yaw_scale_changes
    cdef public object yaw_scale_heading, yaw_scale_realigned, scale_sens, wheel_scale_check
    cdef public object axis_swap, gyro_gate, spin, drive_slip, law_var_held, law_steady_t, law_var_min
    cdef public object brake_grip, speed_gap, gap_terms, slip_ratio_limit, rear_fy, spin_grip
    # read or written every step by _step / _estimate (perf46: each was a __dict__ look-up through
    # Cython's generic getattr)
    cdef public object return_level_sd, return_level_k  # WHEELS_RETURN_LEVEL (slide49)
    cdef public object ay_out, ay_out_new, awd_slip_hold, bank_lag_var, bank_walk, course_slide
    cdef public object course_slide_psi, course_slide_psi_t, friction, friction_var, input_age
    cdef public object law_bound, lever_flagged, mass_lf, readmit, sideslip_vouched, slide_rate
    cdef public object slip_witness, speed_run_grade, steer_vy_hold, velocity_vouched, wheelbase
    cdef public object yaw_inertia, model_fy_var, brake_slip_hold, fix_turn, wheel_bias_t

    # The published fields of every step: floating-point locals as C doubles (the same IEEE
    # operations as Python floats, -ffp-contract=off; an expression with an object operand is still
    # evaluated by Python in the same order; division keeps Python's ZeroDivisionError). The
    # validity flags stay Python objects (the Estimate carries bools exactly as before).
    @cython.locals(vx=double, vy=double, sp2=double, beta=double, var_b=double, beta_std=double,
                   vy_std=double, b=double, c=double, floor=double, turn=double, turn_var=double,
                   e=double, psi_std=double, vx_std=double)
    cpdef _estimate(self, t, x, pd, p_vxvy, r, status, imu_ok, wheels_ok, iso)

    # Methods the compiled step calls on itself every step: cpdef, so such a call is a C call
    # instead of a Python method call (a look-up plus an argument tuple, ~1 k instructions each).
    # Untyped: every operation in them stays the .py's (the same bits). Still callable (and
    # replaceable on an instance) from Python.
    cpdef _step(self, k, t)
    cpdef _road(self, imu_ok, iso)
    cpdef _published_delay(self)
    cpdef _gnss_conflict(self, t)
    cpdef _fresh_gnss_speed(self, t)
    cpdef _model_bound(self, t, vx, vy, r, iso)
    cpdef gnss_counts(self)
    cpdef _latency_std(self)
