# Cython declarations augmenting fault_detection.py when setup.py compiles it (compiled_python.py);
# plain Python ignores this file. FaultDetector becomes an extension type whose instance attributes
# are struct slots: ``self.e_w`` in the compiled step is a pointer load instead of a dict lookup
# (the per-step checks read and write ~80 of them, ~40 % of the step's cost was these look-ups).
# Every slot is a Python ``object``: the values, their types and every operation on them stay
# exactly those of the .py (the same bits). ``__dict__`` keeps instances open to any other attribute.
cimport cython


# one watched reading of _unchanged, updated in place (ten a step): the value, witness and step
# as the objects the .py keeps (same bits), the verdict a C flag
cdef class _StuckRef:
    cdef public object value, witness, k
    cdef public bint stuck


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
    cdef public object yaw_catch_up, yaw_disagreement, yaw_suspect, substitute_yaw_error, e_sub
    cdef public object yaw_pair, yaw_pair_mask, witnesses_must_agree, _scale_ay
    cdef public object _rg_lp, _rdot_g  # the yaw vote's gyro low-pass, every step (perf46)
    cdef public object _fused_mask  # the fused wheels' bits (SLIDE_WHEEL_HOLD, slide49)
    # The yaw vote (~half of the detector's per-step cost): its floating-point locals are C doubles
    # and its verdicts C flags. A Python float is an IEEE double and each of its operators is the
    # same C operation (+ - * / on two doubles, compiled with -ffp-contract=off: no fused
    # multiply-add), so the values are bit for bit those of the .py; only boxing is skipped. An
    # expression that mixes in an attribute, argument or module constant (all objects) is still
    # evaluated as Python, in the same order. Division keeps Python's ZeroDivisionError (no
    # cdivision), abs() is fabs(), max() of doubles compares as Python's (the first on ties and NaN).
    @cython.locals(a_slow=double, a_yaw=double, rdot_abs=double, wide=double, vx=double, kw=double,
                   r_g=double, v_axle=double, e_w=double, e_ws=double, r_wheels=double, rw_lp=double,
                   d=double, ay=double, e_a=double, e_as=double, ref=double, tol_w=double, slow=double,
                   catch_up=double, e_sub=double, wheels_yaw=bint, have_w=bint, have_a=bint, w_fail=bint, a_fail=bint,
                   scale_fail=bint, jump=bint, gyro_suspect=bint)
    cpdef _yaw(self, k, left, right, wheels_ok, r_m, ay_m, imu_ok, x, rdot, braking=*)
    # the same for the wheel vote, the longitudinal window and the lateral window
    @cython.locals(h=double, c=double, s=double, lat=double, med=double, tol=double, others=double,
                   should=double, dev=double, d=double)
    cpdef _each_wheel(self, w, r, delta, vy)
    @cython.locals(cum_a=double, v_old=double, a_old=double, dv=double, res=double)
    cpdef _longitudinal(self, k, v, ax, ax_raw)
    @cython.locals(dt=double, lat_cum=double, lat_abs=double, vy_m=double, w=double, res=double,
                   unexplained=double)
    cpdef _lateral(self, vx, r, ay, rdot)
    # the stuck-value test, ten calls a step (from _each_wheel, _yaw, _all_wheels_stuck): as cpdef
    # those are C calls instead of Python method calls with their argument tuples (~1.3 k
    # instructions each). Untyped: every operation on the values stays the .py's.
    @cython.locals(ref=_StuckRef)
    cpdef _unchanged(self, key, k, value, witness, tol)
    cpdef _all_wheels_stuck(self, k, wheels, wheels_ok, r)
    # likewise, untyped: called by step / _yaw / _longitudinal every step (C calls, the .py's operations)
    cpdef _wheels_return(self, v, vx, p_vx, wheel_r2)
    cpdef _scale_test(self, r_w, d_w, d_a, rdot=*, e_w=*)
    cpdef _attribute(self, k)
    cpdef _yaw_wheels(self, fl, fr, rl, rr, delta)


# the hysteresis counters (a dozen latches updated every step): C ints and a C flag, so a latch's
# update is integer arithmetic on its struct, not ~10 generic attribute look-ups through __slots__.
# Python sees the same values (ints, a bool); counts of 6 ms steps stay far inside a C long.
cdef class _Latch:
    cdef public long on, off, bad, good, events
    cdef public bint active
