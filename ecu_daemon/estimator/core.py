"""The fixed-step estimator: samples in, one Estimate per 6 ms step out.

Design (one filter, several aiding sources, see the package docstring for the contract):

* ``kinematic.py`` predicts [vx, vy, heading, b_r, b_ax, b_ay, k_w] from the IMU every step;
* ``fusion/wheel_speed.py`` corrects vx (and the wheel scale) from the undriven wheels;
* ``fusion/single_track.py`` adds the single-track model's lateral velocity as a pseudo-measurement
  whose weight follows its conditioning, and adapts the cornering stiffness;
* ``fusion/standstill.py`` zero-velocity and gyro-bias-at-rest updates;
* ``fusion/gnss_velocity.py`` fuses late GNSS velocity at its time of validity, through the step
  history (``history.py``), and ``latency.py`` identifies the latency online;
* ``fusion/gnss_heading.py`` fuses a dual-antenna heading the same way (and sets the heading
  directly when the filter has none, at standstill too);
* ``road.py`` splits the accelerometer-bias states into road grade / bank and sensor offset (with
  GNSS vertical velocity) beside the filter, and gives the body roll.

Start-up and recovery (``_initialize``, ``_align``, ``_wheels_diverged``): the filter starts from
the wheels in whatever state the car is in, takes its heading from a GNSS course that the wheels
confirm, and re-initialises when the wheels and GNSS together say it has diverged; the validity
bits follow the published stds (which include what the filter cannot average away: the heading
error a latency error causes while turning).

Steps sit on the absolute grid t_k = k * dt, so live and replay runs of the same samples produce
the same steps. Everything here is deterministic floating-point arithmetic on the inputs.
"""
from __future__ import annotations

import logging
import math
import zlib
from collections import deque

import numpy as np

from ..config import Config
from ..imu_mounting import ImuMount
from ..samples import INPUT_INDEX, GnssHeadingSample, GnssSample, InputSample
from ..step_grid import last_step_at, step_of
from . import backend, kalman
from .axis_swap_check import AxisSwapCheck
from .spin_check import SpinCheck
from . import slip_heading
from . import steered_wheel_vx
from . import gnss_speed_gap
from .gnss_speed_gap import GnssSpeedGap
from .gnss_readmit import GnssReadmitCheck
from . import awd_limit_slip
from .gyro_scale_gate import GSC_EVERY, GyroScaleGate
from .estimate import (STATUS_GNSS_FRESH, STATUS_GNSS_HEADING, STATUS_GNSS_REJECTED, STATUS_HEADING_ALIGNED,
                       STATUS_INPUT_STALE, STATUS_KINEMATIC_OBSERVABLE, STATUS_MAGNETOMETER, STATUS_MODEL_FALLBACK,
                       STATUS_RESET, STATUS_STANDSTILL, Estimate)
from .fault_detection import ACCEL_X, ACCEL_Y, LAT_WINDOW_S, LEARNED_BOUNDS, WHEELS, YAW_RATE, FaultDetector
from .fusion.gnss_heading import REALIGN_REJECTS, STAGGER_S, GnssHeadingFusion
from .fusion.magnetometer import STATE_LEARNING as MAG_LEARNING, MagnetometerFusion
from .fusion.gnss_velocity import ALIGN_SPEED, IMPLAUSIBLE, align_speed_ok, MAX_CONSECUTIVE_REJECTS, GnssVelocityFusion
from .fusion.single_track import G as MODEL_G, LEARNED_MAX_N, LaggedModelInputs, SingleTrackFusion, std_keys as stiffness_std_keys
from .fusion.stiffness_regression import StiffnessRegression
from .fusion.standstill import WHEEL_PULSE_FLOOR_MPS, StandstillFusion
from .fusion.wheel_lock import WheelLock
from .fusion.wheel_slip import SlipWitness
from .fusion.brake_grip import BrakeGrip
from .fusion.drive_slip import DriveSlip, resistance
from .fusion.slip_ratio_limit import SlipRatioLimit
from .fusion.spin_grip import SpinGrip
from .fusion.law_excess_bound import LawExcessBound
from .fusion.tyre_lateral_force import RearLateralForce
from .fusion.friction_limit import FrictionLimit
from .fusion.slide_rate import SlideRate
from .fusion.course_slide import CourseSlide
from .fusion.wheel_speed import WheelSpeedFusion
from .history import AUX_AX, AUX_AY, AUX_DELTA, AUX_R, AUX_RDOT, AUX_WHEEL, StepHistory
from .input_age import InputAge
from .input_consistency import (KWS_TOTAL, WSC_UNCHECKED_REL, LateralScaleCheck, LongitudinalScaleCheck,
                                WheelScaleCheck, WheelScaleSeed, recentred_bounds)
from .kinematic import BAX, BAY, BR, GAY, KW, NX, PSI, VX, VY, KinematicModel, wrap_pi
from .latency import HEADING_SPREAD_RAD, MIN_SPEED_SPREAD, LatencyEstimator, SpeedIntegral, YawIntegral
from .latency_consider import LatencyConsider, antenna_acceleration_ned
from . import latency_sensitivity
from .latency_sensitivity import LatencySensitivity
from .scale_sensitivity import ScaleSensitivity
from . import timing_window
from .timing_trust import along_track_std, at_prior, timing_std
from .lateral_noise import LateralNoise
from . import lever_arm_check
from .lever_arm_check import LeverArmCheck, LeverArmYCheck
from .wheel_launch_check import WLC_PRECISION, WheelLaunchCheck
from .wheel_yaw_check import WYC_EVERY, WheelYawCheck
from .yaw_scale_check import YawScaleCheck
from .bank_walk import BankWalk
from . import bank_lag
from .road import ANGLE_STD_VALID
from ..gravity import G
from .road import BaselineMount, RoadAttitude
from .steering_offset import MAX_YAW_RATE_RADPS as STEER_LEARN_MAX_R, SteeringOffset

I_FL, I_FR, I_RL, I_RR = (INPUT_INDEX[n] for n in ("wheel_speed_fl", "wheel_speed_fr",
                                                   "wheel_speed_rl", "wheel_speed_rr"))
I_STEER = INPUT_INDEX["steering_wheel_angle"]
I_YAW = INPUT_INDEX["yaw_rate"]
I_AX = INPUT_INDEX["accel_x"]
I_AY = INPUT_INDEX["accel_y"]
I_MX, I_MY, I_MZ = (INPUT_INDEX[n] for n in ("mag_x", "mag_y", "mag_z"))
I_ROLL = INPUT_INDEX["roll_rate"]
assert I_ROLL > I_MZ  # the magnetometer's axes: I_MX <= j < I_ROLL
WHEEL_INPUTS = (I_FL, I_FR, I_RL, I_RR)
assert sorted(WHEEL_INPUTS) == [0, 1, 2, 3]  # wheels first in INPUT_NAMES: one comparison in the hot path
I_RR_MAX = 3
# the held gyro / accelerometer samples carried to the middle of the step that integrates them
# by their own slope (input_age.py): a sample is on average half a CAN period old
GYRO_AGE_COMPENSATION = True
ACCEL_AGE_COMPENSATION = True

MIN_SPEED_SIDESLIP = 3.0  # m/s: below this sideslip is not meaningful (flagged invalid)
SIDESLIP_STD_VALID = math.radians(2.0) / 3.0  # 3 sigma inside the 2 deg a valid sideslip promises
# m/s: the largest vx std the CAN frame carries (EST_VELOCITY.VX_STD, 0-1.275 m/s in the output DBC;
# tests/test_wheel_yaw_check.py holds them equal). A velocity is promised only with a std the bus
# can say: beyond it the encoder would clear VELOCITY_VALID (and log a saturation), and the
# estimate, its recording and the frame must agree on what was promised (unchecked wheels at
# speed, WSC_UNCHECKED_REL, are the usual case; a long slip hold the rare one).
VX_STD_VALID = 1.275
HEADING_STD_VALID = math.radians(1.5)  # 3 sigma inside the 5 deg a valid heading promises
BIAS_STD_VALID = math.radians(0.2)  # yaw-rate bias std below which the biases are published valid
GNSS_FRESH_S = 1.0
SAME_EPOCH_S = 5e-4  # a heading and a velocity fix dated within this are of the same receiver epoch
# while an IMU signal is isolated its substitute is coarse: process noise for what it drives
ISO_ACCEL_NOISE = 2.0  # m/s^2/sqrt(Hz)
ISO_YAW_RATE_NOISE = 0.02  # rad/s/sqrt(Hz)
ISO_HEADING_STEP = math.radians(3.0)
# ay substituted by r vx while the gyro is trusted: vy's rate the model expects (single_track.py
# substitute_vy_rate) plus this floor (road, wind, relaxation the model does not have)
ISO_LATERAL_FLOOR = 0.5  # m/s^2/sqrt(Hz)
SUBSTITUTE_MODEL_VAR_SCALE = 4.0  # the single-track model's vy from the wheels' yaw rate: 2x its std
MODEL_EVERY = 3  # steps between single-track pseudo-measurements (18 ms; noise scaled to match)
LEARNED_VERSION = 1
# divergence: the wheels and GNSS speed cross-check each other before either re-initialises
GNSS_WHEEL_TOL_MPS = 1.0  # speed agreement: lever arm, sideslip and wheel slip stay inside this
GNSS_WHEEL_TOL_REL = 0.05  # ... plus a wheel-scale error this large
WHEEL_DIVERGED_S = 0.5  # wheel innovations rejected this long: the filter or the wheels are wrong
GNSS_CHECK_FRESH_S = 2.0
# A GNSS velocity glitch (multipath, a cycle slip, a receiver fault) lasts seconds; a receiver that
# keeps reporting usable fixes the wheels (or the filter) contradict for longer than this is no
# glitch: one of the two is wrong (wheel speeds in km/h mapped as m/s, a wrong wheel radius or
# gear ratio, a wrong lever arm...) and nothing here can tell which, so velocity is not promised
# while the conflict lasts (STATUS_GNSS_ISOLATED says GNSS is the one out, VELOCITY_VALID 0 that
# the wheels are not vouched for either). Twice the longest glitch the suite's faults inject (5 s)
# and below the 10 s in which a wrong speed would spoil a minute's heading.
GNSS_CONFLICT_S = 8.0
TURN_MEMORY_S = 5.0  # how long a heading error from a latency error outlives the turn (GNSS corrects it)
SLIP_MEMORY_S = 1.0  # how long a slip bias outlives the braking (the wheels pull vx back)
COURSE_FLOOR_RAD = math.radians(0.3)  # course errors the speed accuracy does not cover (multipath)
# The live stiffness RLS learns from the filter's vy only where the data, not the single-track
# model, told vy (issue 7, learn14). With one antenna in a steady corner GNSS does not see vy: a
# heading error d_psi, vy off by vx d_psi and a body-fixed accelerometer bias explain the same fixes,
# and only the model's pseudo-measurement holds vy there, so the RLS fitted the model to itself
# (mu03_circle with an honest 0.013 s latency std: 121 correlated updates counted as independent,
# C_r +22 %). That mode breaks when the body-frame acceleration turns (a heading error then rotates a
# different vector than the bias is): learn only if the rear regressor (~ the lateral load, ay and
# vx) changed by half its size over the last LEARN_EXCITE_FIXES fused fixes (2 s at 5 Hz, the
# length of a transient), or a dual-antenna heading (which measures d_psi) was fused within
# GNSS_FRESH_S.
LEARN_EXCITE_FIXES = 10
LEARN_EXCITE_REL = 0.5
HEADING_FRESH_S = 2.0  # a dual-antenna heading this recent, not the course, sets the heading std
MAG_LEARN_SPEED = 5.0  # m/s: the GNSS course (so the filter's heading) is good enough to learn the offset from
MAG_LEARN_STD = math.radians(1.0)  # ... and the filter's heading std is below this
COURSE_CONFIRM_RAD = math.radians(1.0)  # margin of a course confirming a baseline heading
# Lateral-acceleration errors that are neither white (lateral_noise.py) nor a state (b_ay, g_ay):
# each is a bias while it lasts, so vy's std grows linearly by it (not as a random walk).
# The IMU is not at the CG: it reads x_imu * dr/dt more (and the CG moves with the load); where
# it sits is known to about this (m). Zero in a steady corner, large in a lane change.
IMU_LEVER_STD_M = 0.3
# An IMU hold (its samples stopped: a CAN gap, a logger hiccup, a sensor reset) predicts no
# rotation, so the heading misses the car's turn for as long as it lasts: a bias, grown linearly.
# The turn is bounded by the yaw rate at the last sample plus a yaw acceleration (a lane change
# reaches ~1-2 rad/s^2), by the tightest circle at the speed (radius HOLD_MIN_RADIUS_M: no yaw
# without motion) and by an absolute yaw rate no road car exceeds in normal driving.
HOLD_RDOT_MAX = 2.0  # rad/s^2
HOLD_MIN_RADIUS_M = 4.0
HOLD_R_MAX = 1.0  # rad/s
HOLD_ACCEL_MAX = 10.0  # m/s^2: how fast the speed (so the circle bound) can grow during the hold
# A yaw-rate scale error (sensor sensitivity, and the tilt of a banked road: the heading turns at
# r / cos(bank)) turns the heading by scale x r. In a steady corner GNSS course cannot tell that
# from sideslip, and the filter takes it into vy through the accelerometer states (a 6 % banked
# circle: heading and sideslip 1.4 deg off together with a white vy noise of 0.05): vy may drift
# by this fraction of r vx. This is the prior: the courses against the integrated gyro learn the
# scale over the turns (yaw_scale_check.py) and the term follows what they allow.
YAW_SCALE_STD = 0.005
# ... of which the road's bank is known where road.py knows the bank: the gyro (fixed to the body)
# turns about the road plane's normal, so the heading turns at r / cos(bank). On the suite's 5 %
# banked circle ramped to 0.65 g that is 0.125 % of r, ~0.9 deg of heading over the ramp, which
# course cannot tell from sideslip: sideslip RMS 0.31 deg against the single-track observer's 0.12.
# Taken off where the bank estimate says (road.py; with one antenna it holds part of the sensor's
# offset and lags the body roll the gain takes); the rest stays in YAW_SCALE_STD. Capped at this sin.
MAX_TILT_SIN = 0.3
# The scale fit reads low: it integrates the gyro corrected by the filter's yaw-bias state, which
# takes a part of s r on a steady circle (suite circle: 0.78 % of 0.99 %, 2.72 % of 3.09 %); once
# the applied scale is the fit's, the residual published is at least this share of it
YAW_SCALE_FIT_LOW = 0.25
# The single-track model anchors vy wherever GNSS course cannot (a steady corner: course is
# heading + sideslip, and the yaw rate x latency std turns it by degrees on a tight circle). Its
# error is a bias over the corner, which the filter fuses as a pseudo-measurement inflated to a
# ~2 s correlation while vy random-walks at the lateral noise floor in between: the filter's vy
# std then settles near sqrt(q x model variance x 2 s), above the model's own error whenever that
# error is small (lowspeed circles at 5 m/s: 0.085 m/s against the model's 0.037). The filter's vy
# is never further from the truth than from the model plus the model's own error, both known at
# each step: |vy - vy_true| <= |vy - vy_model| + |model error|. So the published vy std is at most
# model std + |vy - vy_model| / 3 (3 sigma of it covers the known offset plus 3 model sigmas),
# The argument holds in a *steady* corner only, where the model's error is the constant bias its
# std describes: not in transients (tyre relaxation lags the model's instantaneous vy; on mu 0.3 a
# car sliding through a yaw-rate reversal had model and filter 2 m/s off together while ay was
# crossing zero and the model's std with it), nor while the lateral cross-check or the gyro's
# witnesses disagree (the model is one of the voters), nor with an IMU signal substituted, nor
# without fresh GNSS unless the steering confirms the tyre law (below). The bound applies once none
# of these has happened for MODEL_STEADY_S, the correlation time of the model's errors
# (single_track.CORNER_STEPS x 6 ms).
# Without GNSS the filter's vy level is the model's own (the IMU integrates only its changes), so
# |vy - vy_model| is ~0 and the bound is the model's word for itself: honest while its tyre law
# holds, not at the friction limit, which a lateral force normalised by g cannot see (mu 0.5,
# 0.48 g: rear slip 60 % above the linear law, the model 1.2 deg off against its 0.6 deg). The
# steering sees it: L r - vx delta = front slip - rear slip needs no vy and no GNSS
# (SingleTrackFusion.law_holds); an axle at its limit puts degrees into it (mu 0.5: 22 deg of
# front slip beyond the law). So in an outage the bound applies only while the steering agrees
# with the law; before, a steady circle lost the bound with the GNSS (mag_circle_outage: std
# 0.67-0.92 deg against an error of 0.03-0.08, invalid for the outage's 20 s).
MODEL_BOUND = True
# The single-track model's bias is counted once (issue 7, floor46; random drive 2684: a steady 115 m
# circle at 26.7 m/s, mu 0.71, 0.89 of the grip, m / C_r configured 76 % / 82 % of the car's, GNSS
# 1 Hz). The pseudo-measurement is inflated by CORNER_STEPS (2 s) and so counts again every 2 s, but
# its parameter and tyre-law error is a bias for as long as the corner lasts (20 s there): the
# filter's sideslip std fell to 0.66-0.70 deg where the model's own error std was 0.92 deg
# (model_error: the rear at 0.89 of its grip, the n^2 law learned below 0.6 g and extrapolated) and
# the heading, the one other witness of vy through course = heading + sideslip, was unknown to
# 2.4-3.1 deg. Sideslip was published valid 2.05 deg off (56 rows, the validity flickering at the
# threshold with every fix). With one antenna and no fresh dual-antenna heading, while GNSS is fresh
# and the model fused, sideslip is known no better than the model's bias (the part CORNER_STEPS
# inflates; the unmodelled dynamics' 0.1 s floor does average out) combined with the published
# heading's std: beta_std >= 1 / sqrt(1 / s_bias^2 + 1 / psi_std^2). It raises only the published
# std (the filter's state and gains are main's); see _model_bias_floor.
MODEL_BIAS_FLOOR = True
# The model's bound holds only up to the grip the drive has shown its law at (issue 7, mstd47; random
# drive 3332: a J-turn on mu 0.255, the car's first corner, both axles at the limit alike: front 4.8 deg
# and rear 3.3 deg of slip, each ~3x its linear law's, as a brush tyre at full utilisation has). The
# law's lateral force is normalised by g, not by the road's friction, so at 0.25 g it called the tyres
# linear: its vy 2.1 deg of sideslip off at its own (counted-once) 0.5 deg; the steering's misfit, the
# one vy-free witness, sees only the *difference* of the axles' excess (1.4 of its sigmas there). The
# bound (published std <= model std + |vy - vy_model| / 3) then published 0.55 deg where the filter's
# own std was 0.76: 112 valid rows beyond 3 sigma, worst 2.03 deg. Nothing the filter has tells mu
# there, but a vy the data told (a GNSS-fused fix, SingleTrackFusion.adapt_from's gate) that found the
# law within LAW_HOLDS_SIGMA of its uncertainty at |ay| says the road grips at least that well with
# the tyres still in their law (AxleRls.n2_shown): up to that |ay| the bound stands, beyond it the
# published std is the filter's own. False: the bound at any |ay| (main's).
# Off (mstd47): the price is every corner no data-told vy has checked, and a steady circle never is
# (adapt_from's excitation gate: heading and rotated biases trade off there): the exact-configuration
# dry circle of tests/test_law_excess_bound.py (1708, mu 1.03, 0.57 g) fell from 0.79 to 0.13 of its
# rows valid above 5 m/s, all right; confirming without that gate (the filter's vy variance alone)
# confirmed nothing there either. The filter cannot tell 1708's 0.57 g on mu 1.03 from 3332's 0.25 g
# on mu 0.255 before a fix has checked the law at that |ay|: the trade is the lead's to make
# (tests/test_grip_shown.py runs it on).
MODEL_BOUND_GRIP_SHOWN = False
# ... only while the heading is not valid (psi_std >= HEADING_STD_VALID): where, as in 2684, nothing
# the system vouches for besides the model tells vy. The physics says the floor holds with a valid
# heading too, but there the model's own std is what it gets wrong: beyond the learned range (n > 0.6)
# it is the prior's 40 % stacked on the law's 30 % (AxleRls.predict), and on 2641-2760 the floor
# withdrew ~5,000 rows under a valid heading that were all right (error p50 <= 0.4, max 0.54 deg;
# 2691: a 123 m circle, valid above 5 m/s 0.86 -> 0.59 at 0.05 deg p50). True: also there.
MODEL_BIAS_FLOOR_VALID_HEADING = False
# ... and only beyond the lateral force the tyre law's error is learned up to (single_track.
# LEARNED_MAX_N, 0.6 g): below it the per-drive regression learns the law through GNSS and the gyro's
# heading, which the model does not pull; beyond, the law is an extrapolation nothing has checked
# (2684: 0.63 g, the rear at 0.89 of its grip), its error a bias only the model's std describes.
# Measured (floor46, pure Python, flag off / on): 2684 56 -> 0 rows beyond 3 sigma, worst 2.05 -> 1.44
# deg, valid above 5 m/s 0.780 -> 0.748; no other drive of 2641-2760 moved (with either gate off, 7
# resp. 14 did, on right rows). The cost is the suite's circles above 0.6 g with the heading unknown
# after an outage, right because their configuration is exact: outage_circle_bank 0.786 -> 0.605,
# mag_circle_outage 0.818 -> 0.646, bank_circle 0.962 -> 0.925 (targets unchanged; coverage 1.0).
MODEL_BIAS_FLOOR_BEYOND_LEARNED = True
# The single-track pseudo-measurement asserts the rear tyre law, whose lateral force is normalised by
# g, not by the road's friction: an axle at its combined-slip limit on a low-friction road (braking
# or power in a corner) slips degrees beyond it at a force the law calls linear (tools/random_drives.py
# seed 40: mu 0.21, 0.17 g, rear slip 5.8 deg against ~1). With fresh GNSS that is a lie: one antenna
# in a steady corner measures course = heading + sideslip, the model holds vy, the heading takes up
# the rest, and the filter's vy std stays the model's (~0.5 deg of sideslip at 4-5 deg off; all 1378
# such rows of seeds 12 and 159 had GNSS fresh). The steering sees it without vy or GNSS: the misfit
# of the understeer relation beyond the laws' and the steering's 3 sigma (SingleTrackFusion.
# law_excess_var) widens the pseudo-measurement (a bias for the corner, like the law's other errors)
# and keeps the model's bound off, so the published std is the filter's own, grown for it.
# In an outage the same misfit already turns the bound off (law_holds, above) and nothing pairs the
# model with a heading; widening there only traded availability (mu03_outage_30s: sideslip valid
# above 5 m/s 92 -> 67 %) for rows that were within 3 sigma already. LAW_EXCESS_IN_OUTAGE keeps it
# for comparison (False: the outage is left to law_holds). Nor in a transient (|rdot| beyond
# MODEL_STEADY_RDOT, where the model is unsteady anyway): the understeer relation leaves out the
# tyres' relaxation lag behind the steering, which a step steer puts into the misfit at a force far
# from any limit (relax_jturn_12: 75 deg at 400 deg/s, sideslip within 0.35 deg made invalid).
LAW_EXCESS = True
LAW_EXCESS_IN_OUTAGE = False
# GNSS isolated is no outage (issue 7, reinit44; random drive 2360: braking in a 93 m turn on mu 0.31,
# AWD, rear slip 4 deg). The fault detector isolates a receiver whose speed disagrees with the wheels
# (or the filter); on a braked low-friction road that is the slipping wheels' doing, and exactly then
# the tyres are beyond their law. With the check above keyed on "a fix fused within GNSS_FRESH_S", the
# isolation read as an outage 1 s after the last fused fix: every excess rule (steering misfit, brake
# grip, slip ratio; the held excess too) dropped to 0 at once and the model's pseudo-measurement came
# back at full weight: vy moved 0.8 m/s in 0.1 s, its std 0.62 -> 0.11 m/s, sideslip valid 4.2 deg off
# at 0.65 deg (1247.1-1249.5 s). While GNSS is isolated the rules keep running (fixes arrive; it is
# the filter / wheels they contradict); a true outage (no fixes) stays as LAW_EXCESS_IN_OUTAGE says.
# Off (stop 44): on the never-seen drives 2401-2640 it broke 2446 (an AWD steady circle, mu 0.88 -> 0.37,
# that spins and drives off again): the excess kept running through the spin with GNSS isolated, the
# sideslip's std grew to 11-14 deg, GNSS was re-admitted at 1258.3 s and the wheels at 1259.3 s as the car
# rolled forwards, and the sideslip was published valid at 1259.6 s 2.7 deg off at a 0.64 deg std (main:
# GNSS still isolated there, the sideslip invalid, 0 rows beyond 3 sigma). A sideslip promised 0.3 s
# after the wheels' return, from a state just pulled in from a 14 deg std, is the defect it exposes;
# on again since readmit45, with GNSS_READMIT_CHECK below (2446: 0 rows beyond 3 sigma, worst 0.24 deg;
# tests/test_gnss_isolated_law_excess.py checks both drives with the defaults).
LAW_EXCESS_GNSS_ISOLATED = True
# GNSS let back in without a witness is no check of the state (issue 7, readmit45; random drive 2446:
# an AWD spin on mu 0.37, the car sliding backwards, wheels and GNSS isolated): the fixes re-admit
# GNSS through the filter's vx within 5 of its sigma, which after a spin is 15-30 m/s wide, then
# pull vx in; the wheels return and vy's std collapses 2.1 -> 0.04 m/s around a state no residual has
# tested: sideslip valid 2.7 deg off at 0.64 deg (1259.6 s). After a re-admission made while the
# velocity was not vouched for, the sideslip waits for a fix fused while it is (gnss_readmit.py).
GNSS_READMIT_CHECK = True
# A transient is no sign that a tyre has come back inside its law: a car sliding (random drive 279:
# a rear-driven car spun out on ice, rear slip 60 deg at 1.3 m/s, the steering's misfit ~1.5 m/s)
# swings its yaw rate as it slides, and with the excess dropped at |rdot| > MODEL_STEADY_RDOT the
# pseudo-measurement came back at its full weight (at low speed the law is vy = lr r, its std
# ~0.02 m/s): one update moved vy by 2.3 m/s (9 sigma of the filter's own), vx with it through the
# front wheels' (vy + lf r) sin(delta) at 42 deg of steering, and the GNSS fixes after it were
# rejected as outliers: vx valid 1.9 m/s off. So in a transient the excess of the last steady step
# is held (the misfit itself is not taken there: relaxation lag, above); it is 0 on a straight
# before a step steer, so a transient entered inside the law (relax_jturn_12) stays unwidened.
# What is held is the least excess over a whole steady stretch of LAW_HOLD_STEADY_S, not the last
# step's: a step steer's first steps come before the (low-passed) yaw rate moves, so the steering
# alone puts a misfit into them (relax_jturn_12: 0.24 m/s; held through the turn-in that cost 3
# points of sideslip validity at 0.34 deg error). A slide's misfit lasts seconds; a turn-in's
# lasts a few steps, and the relaxation lag decays with l / vx (0.5 m at 5 m/s: 0.1 s).
LAW_EXCESS_HOLD = True
LAW_HOLD_STEADY_S = 0.5
# The law excess (steering misfit, drive slip, braking, slip ratio) widens the model's vy bound by
# its std instead of switching the bound off (fusion/law_excess_bound.py): a small excess is the
# law's scatter a little wider (random drives 1708, 2008: the brake rule at 0.03-0.11 m/s withheld
# ~9,400 right rows of dry circles); a large one (seeds 12, 159) makes the bound wider than the
# filter's own std, as off did. False: law_var > 0 switches the bound off (main's).
LAW_EXCESS_BOUND = True
# The steering's misfit misses a rear-driven car with the power on at its limit on ice (both axles
# leave their law alike: random drive 40, mu 0.21, 0.16 g, rear slip 2.7 deg against the law's 0.6).
# The driven rear wheels' slip against the free front does (fusion/drive_slip.py): beyond a linear
# tyre's slip for its drive force the rear is on its limit, and its slip angle follows from the
# friction ellipse; the difference to the law's joins the law excess (same gates).
DRIVE_SLIP = True
# The drive-slip rule's "while driving" is the drive force, not the net force: at a steady speed on
# a circle the rear tyres push against rolling resistance and the front's lateral force tilted by the
# steering while the accelerometer's net force reads ~0 (random drive 279: a rear-driven car on a
# 44 m circle, the friction halving to 0.105; the rear wheels 1.3-2.9 % ahead of the free front at a
# net force of -0.03 to -0.11 m/s^2, the rule silent, sideslip valid 3.46 deg off). True: the gate
# and the linear tyre's slip take net force + drive_slip.resistance(); False: main's rule bit for bit.
DRIVE_RESISTANCE = True
# Braking in a corner takes load off the rear and the rear brakes take their share of what is left of
# its friction ellipse: the rear nears its limit while the front, which drives the steering's misfit,
# stays inside its grip (random drives 507, 504, 637: ax -4.6 at ay 3.8 m/s^2, rear slip 3.4 deg, the
# law ~1; 301 on snow). fusion/brake_grip.py bounds the rear's lateral utilisation by the grip the
# road has shown and a brush tyre's slip at it; what that exceeds the law by joins the law excess
# (same gates). False: main's behaviour bit for bit.
BRAKE_GRIP = True
# Braking (or driving) on ice the tyres spend their grip longitudinally and a small lateral force takes
# a slip angle several times the law's, with no corner and no misfit of the steering (random drive
# 1481: all-wheel drive braking on a downhill at mu 0.10, friction use 1.0, wheels 3 % slow where a
# linear tyre slips 0.6 %, ay 0.3-0.4 m/s^2: rear slip 1.6 deg against the law's 0.24; the sideslip
# published valid 1.3 deg off at 0.2 deg, 1479 rows beyond 3 sigma; brake_grip.py's grip shown is
# floored at 0.15, above the road's). A tyre's force follows its stiffness-weighted slip vector, so
# tan(alpha) / tan(alpha_law) = kappa / kappa_lin: the wheels' slip ratio (wheel_slip.py's witness)
# over a linear tyre's for the force is the factor the rear's angle exceeds the law by
# (fusion/slip_ratio_limit.py); what that exceeds the law by joins the law excess (same gates).
# False: main's behaviour, bit for bit.
SLIP_RATIO_LIMIT = True
# A spin has shown the road's grip: while the car slides its tyres carry the friction ellipse's radius,
# and after it tyres carrying HOLD_SHARE of that again are at their limit, where the tyre law bounds
# no slip angle: the single-track pseudo-measurement is then left out (and its bound off), vy rests on
# the kinematics and GNSS (fusion/spin_grip.py). Random drive 3169 (AWD, mu 0.19, GNSS 1 Hz at 0.72 s):
# after its spin the car drove off at 0.93-0.96 of mu g, both axles slid to -12..-14 deg and the
# sideslip was published valid at -2.2 +- 0.4-0.65 deg for a true 0..+11 (735 rows beyond 3 sigma).
# False: main's behaviour, bit for bit.
SPIN_GRIP = True
# The drive-slip rule's angle, kappa F_yr / F_xr, takes the rear tyres' lateral force from the specific
# force less the sensor's offset (the bank's g sin(phi) in), not from the model's ay (b_ay holds the
# bank): on a banked road the tyres hold the car against gravity at a kinematic ay of 0, and at the
# friction limit that force takes kappa / kappa_lin times the law's angle (random drive 1714: rear
# drive up a +3.9 % grade on mu 0.16, bank -1.9 deg, the rear wheels 5-9 % ahead of the front, rear
# slip -1 deg at ay ~0; the rule's angle from ay ~0 was ~0.1 deg, the sideslip valid 4.6 deg off,
# 117 rows beyond 3 sigma). That offset is road.py's split of b_ay, which cannot tell a constant bank
# from a constant offset (1714: bank 0.0 +- 0.9 deg for -1.9), so the force's std (the offset's) adds
# its share of the rule's angle to the rule's variance. fusion/tyre_lateral_force.py. False: main's
# rule bit for bit.
DRIVE_SLIP_TYRE_FORCE = True
# A spin's re-initialisation keeps the gyro's bias as the filter knew it when the slide began
# (its std grown by the bias walk over the slide), not the warm-restart prior (0.3 deg/s): a slide
# changes the car's motion, not the sensor's offset, and with the prior the heading after it rests
# on a bias the sliding car then teaches wrong (random drives 424 and 297: a rear-driven car spins
# on a friction drop, then circles with its rear on its limit; the bias learned 0.3-0.5 deg/s off,
# the heading 6 deg off at a 1.4 deg std, valid). ``Estimator._after_spin``.
SPIN_KEEPS_GYRO_BIAS = True
# The axis-swap check's witness (ax = dv/dt, ay = r vx) leaves r vy out; a car sliding sideways puts
# metres per second into vy and the slide reads as a swap (random drive 499: a 180 deg spin at a
# stop, |r vy| ~4 m/s^2, a "swapped" verdict that stood to the end, heading valid 0.50 against 0.69).
# The filter's own |vy| + 3 std, times |r|, bounds that term: beyond the check's tolerance the window
# judges nothing (axis_swap_check.SWAP_RVY_MPS2).
AXIS_SWAP_SLIDE = True
# An axle seen beyond its law (the steering's misfit) says the road's friction is near |ay| / g, and
# in a corner both axles use the same share of their load: while |ay| stays at that limit the rear
# may be as far beyond its law as the steering has shown, even where the misfit shrinks because both
# axles let go alike (random drive 683: rear slip 0.6 -> 22 deg at |ay| 1.1 m/s^2 while the misfit
# fell from 29 to 3.6 deg; the gyro's scale fit took the sideslip's growth for a 3.8 % scale and the
# heading was published valid 14.5 deg off). So the gyro's scale fit, which integrates courses read
# against the model over a whole corner and applies what it finds to the state, counts the model's
# vy as off by the largest excess the steering has shown while |ay| stays at that limit
# (fusion/friction_limit.py). The pseudo-measurement keeps the present misfit: held there too, it
# cost slaloms and lane changes on snow up to 60 points of sideslip validity at errors within 0.5
# deg (random drives 636, 563, 505, 515). False: main's behaviour, bit for bit.
FRICTION_MEMORY = True
# ... and on the pseudo-measurement too, narrowly: once the front has ploughed in a corner and the
# steering's misfit swings to the oversteer side while |ay| stays at that limit, the rear has let go
# as well (fusion/friction_limit.py, FrictionLimit.rear_var): the misfit shrinks while both axles are
# off their law, and the law held vy near a gripping car's (random drive 3791: front slip -6 deg at
# |ay| 2.8 m/s^2, then the rear -3 -> -4 deg at the same |ay|; sideslip published valid 0.8 +- 0.65
# deg against 3.1). Ends when |ay| falls below the hold or ay changes side. On (stop 49): 3791 37 -> 0
# valid rows beyond 3 sigma; on 278 dev drives it fired in 17, changed no verdict, cost 0-1.9 points of
# sideslip validity above 5 m/s (it fires 0.1-0.3 s as a driver unwinds at the end of a plough).
# False: stop 48's bits.
FRICTION_REAR = True
# The steered front pair measures vx only through vy (vx cos delta + (vy + lf r) sin delta): in a slide
# the filter's vy stays near a gripping car's at a gripping std while the driver counter-steers, and vx
# was published valid 4.65 m/s (random drive 760) and 2.34 m/s (297) off at 0.2-0.34 m/s. The published
# vx std carries the vx error the steering's misfit (vx delta - L r, the axles' slip difference) puts
# through the fused wheels, held with the wheel-slip memory (steered_wheel_vx.py), while the sideslip
# is not valid (a valid one vouches for vy, and vx's std already carries its share). False: main's
# behaviour, bit for bit.
STEERED_WHEEL_VY = True
# The plough's exemption above (the rear grips, its kinematics hold vy) needs the gyro: with it isolated
# the filter's vy integrates a substitute yaw rate (the wheels', 0 with them out) and nothing holds it.
# Random drive 1761 (rear-driven, 222 kW, mu 1.04): a spin isolated a right gyro, and in the plough after
# it the filter's vy went 8 m/s off at 0.6 m/s; the front pair put that into vx, published valid
# 0.79-0.92 m/s off at 0.19 m/s. With the gyro isolated every misfit counts (steered_wheel_vx.py,
# ``vy_tied``). False: main's behaviour, bit for bit.
ISOLATED_GYRO_PLOUGH = True
# An all-wheel drive has no free-rolling axle: every fused wheel is vx plus its own drive slip, which
# the linear law for the kinematic ax (~0 on a circle at a steady speed) leaves out and the slip
# witness misses when it builds slowly. Random drive 1936 (AWD, 240 kW, a 66 m circle on mu 0.63 up a
# 7.9 % grade, ploughing, then spinning out): the wheels ran 0.05 -> 1.0 m/s ahead of vx over 13 s and vx
# was published valid 0.92-1.02 m/s off at 0.30 m/s before the spin check fired. While the steering says
# a tyre has left its law, the published vx std carries a brush tyre's slip at its limit for the drive
# force (3x the linear law's; awd_limit_slip.py), held with the wheel-slip memory. False: main's
# behaviour, bit for bit.
AWD_LIMIT_SLIP = True
# An all-wheel drive's wheels back from an isolation (stop 49, issue 7: random drive 3169, AWD on mu 0.19,
# the wheels held out after a spin by fault_detection.SLIDE_WHEEL_HOLD): their common drive slip is a
# level no vote sees (every fused wheel is driven) and no change-based witness sees either (the slip
# witness and the longitudinal check compare speed changes with ax; this slip built while the wheels were
# out). The one comparison of that level was the return test's, against a vx whose std the isolation had
# grown (3169: 1.34 m/s); the first update then takes vx to the wheels at the wheels' noise (std 1.34 ->
# 0.24), and 1.2 s later vx was published 0.25 m/s off at 0.08 (the four wheels 0.2 m/s ahead, spinning
# at 65 % of the road's grip). So until a GNSS fix taken after the return has compared the wheels' level
# (WheelScaleSeed.gap then publishes what it saw), the published vx std carries vx's std at the return.
# Only with a receiver configured (no other level witness exists). False: main's behaviour, bit for bit.
WHEELS_RETURN_LEVEL = True
# While the road's bank ramps, b_ay (which holds g sin(bank)) lags it by seconds and the filter
# integrates the lag into vy, which its P[b_ay] (grown by the bank walk, which a ramp outruns) does
# not carry (random drive 1796, t+118 s: b_ay 0.65 m/s^2 behind, sideslip valid 0.9 deg off at a 0.29
# deg std, 31 rows beyond 3 sigma). The lag the ay-vs-gyro test's slow residual shows beyond P[b_ay],
# carried into vy by the filter's own P[vy, b_ay] / P[b_ay], is added to the published vy and
# sideslip variance (bank_lag.py). False: main's behaviour, bit for bit.
BANK_LAG_STD = True
# The single-track pseudo-measurement's lateral force is the tyres' (the specific force less the sensor's
# offset, road.py's split: the bank's g sin(phi) in), not the kinematic ay (b_ay holds the bank): on a
# banked road the tyres hold the car against gravity on a straight at a kinematic ay of 0, and the rear
# slips for it (random drives 3319, 3172: the car crabs 0.2-0.75 deg at r ~ 0 on a 2-4 deg bank, the
# model said ~0, valid at a 0.11-0.24 deg std). The bank's share, b_ay less the offset, is known only as
# well as that split (it cannot tell a constant bank from a constant offset): the offset's std, through
# the rear law's d vy / d fy = vx kappa_r lf / L, joins the model's bias terms (the law excess's slot,
# inflated alike) and its bound. False: main's behaviour, bit for bit.
# The law's learners (SingleTrackFusion.adapt_from, StiffnessRegression.observe) regress vy on the same
# force: learned on the kinematic ay, a law fitted to the other force missed by the share (the suite's
# dual_circle, rms above 5 m/s 0.100 -> 0.096 deg; the same circle on a 0.88 deg bank 0.107 -> 0.101).
# b_ay's own doubt does not enter the force: ay_c + b_ay cancels it; what does is the offset's, and the
# offset is what keeps it off: no sensor tells a standing offset from a bank (road.py), and on a flat road
# with the suite's 0.15 m/s^2 offset (1.5 sigma of its 0.1 prior) the model's force is 0.15 off
# (dual_circle 0.096 vs 0.091 off; tests/test_fault_detection.py yaw_rate_stuck: b_ay 0.0315 off after
# the gyro's isolation (0.0253 off), 0.0278 with the offset set to its true value) (tyre48 report).
# Its cost on random drive 3655 (flying, 3.8 deg bank, 8 m circle at 5.3 m/s; valid above 5 m/s 0.984 -> 0.585,
# crab50) is the law's own doubt at the force the tyres carry: on the circle P's sideslip std is 1.3-1.5 deg
# (heading unaligned, 8 deg) and the published one is the model's bound (MODEL_BOUND), whose parameter term
# (the configured law's prior: below 8 m/s the law never learns) grows with the force, 3.9 -> 4.6 m/s^2 with the
# bank's 0.73 in: bias std 0.043 -> 0.055 m/s, the bound 0.55-0.57 -> 0.65-0.69 deg, past the 0.667 limit. The
# error in the withheld 1203.6-1213 s was 0.0-0.1 deg (main 0.2-0.35, valid at 0.59-0.62): right by the law's
# stated doubt at the right force (main stated it at the wrong one), not a defect of the force.
# ON since stop 51 (chosen at stop 50): dev 3841-3931 (crab50) sideslip rows beyond 3 sigma 619 -> 0 and
# heading 930 -> 0 for
# -1.7 % valid sideslip rows; the never-seen 4081-4320 drives 4085 (a plough on ice: heading 13.1 deg off,
# valid), 4147 and 4309 clear with it.
MODEL_TYRE_FORCE = True
# The slip-ratio rule (SLIP_RATIO_LIMIT) scales the rear law's linear angle by the wheels' slip ratio over a
# linear tyre's, and took that angle for the kinematic ay (b_ay holds the bank's g sin(phi)): on a banked
# straight the kinematic ay is ~0, so a tyre at its limit longitudinally widened nothing, however far it
# slipped. The tyres carry the bank's force: random drive 3876 (AWD, straight, 2.2 deg bank, +6 % grade,
# mu 0.41 -> 0.187, accelerating 15 -> 25 m/s): the slip witness read 3.2-4.5 % against a linear tyre's
# 1.0 % (ratio 2.8-4.5) while the kinematic ay was -0.25..+0.24 m/s^2 and the tyres' force 0.3-0.5; the
# rule's excess std was 0.002-0.12 m/s, the true rear slip 0.5-0.9 deg (the law's 0.1), the sideslip
# published valid 0.85 deg off at 0.16-0.28 deg (439 rows beyond 3 sigma). With the tyres' force (the
# specific force less road.py's offset, as MODEL_TYRE_FORCE and DRIVE_SLIP_TYRE_FORCE take it) the
# rule's angle is the bank's, against the law as it is fused, and the split's doubt (the offset's std)
# joins it, times the ratio. Off: 3876 439 -> 0 and 85 low-friction dev drives 52 -> 52 rows beyond 3
# sigma at -0.07 % valid rows (crab49), but tests/test_slip_ratio_limit.py's drive 1481 (AWD braking on
# ice downhill, no bank) loses sideslip validity above 5 m/s 1.000 -> 0.917: the offset's doubt times the
# ratio squared (4.5^2) widens where no bank is (stop 49 CI). That doubt is right, flat road or not (crab50):
# 1481's -0.29 m/s^2 offset sits in road.py's split as a 1.6 deg bank (the bank's prior is the wider), so the
# tyres' force was taken 0.28 m/s^2 off while the rear slid 1.0-1.6 deg at ratio 4.4 (the excess 0.03 m/s at
# 1246.7 s against a true 0.41); without the doubt 494 valid rows beyond 3 sigma, worst 1.27 deg (breaks);
# with it 0, worst 0.86, at 0.92 valid. Its share when MODEL_TYRE_FORCE's law carries 1x of it already:
# SingleTrackFusion.split_var. False: stop 48's bits.
SLIP_RATIO_TYRE_FORCE = False
# A standstill is declared from the wheels reading ~0, and a wheel sensor sees no pulses below its floor
# (~0.15 m/s, fusion/standstill.WHEEL_PULSE_FLOOR_MPS): "every wheel 0" says |v| below that floor, not v = 0,
# and the accelerometer cannot tell a steady creep from rest (ax ~0 both). The zero-velocity update pins vx
# at 0 to 0.01 m/s, right at rest, but a car sliding back down a grade on ice creeps unseen (random drive
# 3219: 4.4 deg up a grade on mu 0.15, the driven front spinning, the car sliding back at 0.03-0.10 m/s with
# every wheel below the floor: vx published valid 0.00 at 0.01 m/s, 197 rows beyond 3 sigma). While the
# standstill holds, the published vx std is at least a third of that floor (3 sigma covers it); the state
# and its update are unchanged. False: main's behaviour, bit for bit.
STANDSTILL_CREEP_STD = True
# Braked to a stop on low friction the wheels lock below walking pace (no ABS acts there) while the car
# still slides: they fell 0.55 -> 0 m/s in 50 ms at ax -2.2 m/s^2 and each wheel update, inside its gate,
# pulled vx after them (random drives 3319, 3422, 3475, mu 0.14-0.26: vx valid 0 +- 0.06 while the car
# slid at 0.3-0.4 m/s). The wheels losing speed faster than the accelerometer says the car does, beyond
# the comparison's own error, below 2 m/s, is a lock: their update is skipped until they are back with the
# car (fusion/wheel_lock.py). False: main's behaviour, bit for bit.
WHEEL_LOCK_SKIP = True
# After a spin the filter re-initialises from the wheels with a gripping car's vy while the car may
# still slide sideways (random drive 879: 13 m/s at -80 deg sideslip, vx published valid 2.6 m/s off;
# 760 after its spin); the fault detector isolates GNSS, the one source that sees it. A fix's speed
# against the filter's antenna speed, beyond the GNSS/wheel tolerance while the sideslip is not
# valid, floors vx's published std by the gap to the last fix's speed widened by the acceleration
# measured since (gnss_speed_gap.py: no timer). False: main's behaviour, bit for bit.
GNSS_SPEED_GAP = True
# GNSS measures the speed and the course; vx is speed x cos(sideslip), so with the wheels out (not
# trusted) vx rests on the sideslip. A car sliding on ice (random drive 770: mu 0.21, r vx never
# beyond the spin check's 1.2 g, the fault detector isolating the wheels, the gyro and ay in turn)
# kept the model's vy ~0 at 0.5-0.8 m/s while the sideslip reached -47 to -110 deg: the filter
# read the GNSS velocity as vx (heading off by the sideslip) and published it valid 7.6 m/s off.
# So vx from GNSS alone is promised only where the sideslip's own conditions hold (the IMU trusted,
# its std below the valid bound), or where the speed itself is within the frame's vx std.
# False: main's behaviour, bit for bit.
GNSS_VX_NEEDS_SIDESLIP = True
# One antenna's heading is its course less the sideslip. Wheel slip under braking or traction makes
# the wheels' vx wrong by a bias (slip_hold) that P does not carry; each GNSS fix then splits its
# speed with that vx, the rest going into vy, and turns the heading the other way by the sideslip's
# error to keep the course (random drive 1006: braking at -3 m/s^2 at the limit of a 0.55 road, the
# wheels 1.8 m/s slow, sideslip 3.4 deg off at its 2.1 deg std, invalid; heading 5.0 deg off at
# 1.45 deg, valid). While that bias is the larger part of vx's error, the heading rests on
# courses and the fixes hold it (P's heading std not far below the sideslip's: not one the gyro
# carries from before, random drive 499), the published heading std is at least the sideslip's
# (slip_heading.py).
# False: main's behaviour, bit for bit.
SLIP_HEADING = True
# The same split seen from the sideslip: braking wheels slow by up to b leave a GNSS speed that only vy
# can reach, so the fixes (where the single-track law no longer holds vy) grow |vy| to
# sqrt(S^2 - vx^2): random drive 4085 (a FWD ploughing on a 0.187 circle, braking at -0.6 m/s^2, the
# wheels 0.65 m/s slow) reached 15-17 deg of sideslip against the true 3-5 at a 0.9 deg std, and the
# heading turned by the same 12 deg, valid (964 rows beyond 3 sigma). The geometric bound of that
# split (slip_heading.split_sideslip_error: the true vy^2 is at least vy^2 - 2 |vx| b - b^2), as a
# uniform bias on the sideslip's std while the braking slip bound exceeds P's vx std and the
# heading rests on courses; the heading floor of SLIP_HEADING then carries it to the heading.
# False: main's behaviour, bit for bit.
SLIP_SPLIT = False
# Every vx error the wheel updates pass into vx that P does not carry (the slip bound, the steered
# pair's missed vy STEERED_WHEEL_VY, an AWD's drive slip AWD_LIMIT_SLIP) is split by each fix into the
# sideslip and the heading; a persistent one turns the heading fix after fix, whatever one fix's share
# (SLIP_HEADING's HELD_SHARE). Random drive 4217 (a RWD spun out on a 0.237 circle, sliding on at -64
# deg of sideslip on power, rear wheels 0.7 m/s fast, slip bound 0, steered-wheel bound 2.0 m/s): the
# fixes after the spin's rejected ones turned the heading +1.85, +0.49, +0.42 ... deg, 4.1 deg off at
# a 1.0-1.3 deg std, valid (634 rows beyond 3 sigma). While such a bias exceeds P's vx std, the heading
# std is at least the smaller of the sideslip's std and the net turn the fused fixes gave the heading
# since the bias began (the split's part of the heading error is at most what the fixes moved it).
# ON since stop 50 (no metric moved on 18 dev drives where such a bias arose, plough50). False: the
# behaviour before, bit for bit.
WHEEL_BIAS_HEADING = True
# The fault detector isolated a right gyro in 21 of 240 random drives without a fault (1201-1440,
# 16 of them all-wheel drive): its two witnesses, the slipping wheels and ay / vx off by the
# sideslip's rate, each disagreed with it by its own error, and far from each other (scale slopes
# 0.44 against 1.07, residuals of opposite sign). The gyro is now isolated only when the two agree
# with each other and not with it (gyro_vote.py; the onset of an isolation only). False: main's
# vote bit for bit.
GYRO_WITNESSES_AGREE = True
# An unconfirmed gyro that read a slow turn (below the gyro-scale gate's witnesses' 3 m/s, where no
# sideslip is promised) withheld the sideslip for the rest of the drive when no turn at speed came
# to confirm it (random drives 1203, 1209, 1301, 1362, 1386, 1414, 1423: reversing through a curve,
# then straight; sideslip valid on 0.50 of the rows above 5 m/s, 0.1-0.16 deg off at 0.21 deg std).
# Such a turn is forgotten for the sideslip once the rear wheels, summed over the slow turns, counted
# the rotation the gyro read (a flip reads it the other way, a 1/57 gyro not at all) and the gyro has
# read what the witnesses read at speed for a while (vy's memory) (slow_exercise.py); exercise at
# speed still withholds until confirmed, the heading keeps the gate's rule. False: main's
# behaviour, bit for bit.
SLOW_TURN_FORGOTTEN = True
# The same slow reversing turn kept the heading withheld while right (random drives 1487, 1532, 1547,
# 1584, 1653, 1667 on main 81ac01f: heading valid on 0.50 of the rows above 5 m/s, 0.0-0.5 deg off):
# its std carried a flipped gyro's scale error times the slow rotation (24 deg on 1487) and the gate
# required "never exercised". Once slow_exercise.py forgave the turn (the rear wheels counted the
# rotation the gyro read), the std carries the scale error the wheels measured instead and the heading
# takes the gate's forgetting rule (slow_turn_heading.py). False: main's behaviour, bit for bit.
HEADING_SLOW_TURN_FORGOTTEN = True
# The steering's misfit is blind to a car sliding with both axles at their limit alike: never-seen
# random drive 2254 (all-wheel drive, double lane change on mu 0.099, front and rear slip ~15 deg) had
# the misfit pass through 0 as the steering crossed L r / vx, the pseudo-measurement back at full
# weight moved vy from -2.1 to -0.6 m/s in 36 ms (true -2.9), and the sideslip was published valid
# 17.5 deg off at 0.6 deg. The kinematics see the slide: vy changes at ay - r vx (0.87 - 1.68 m/s^2
# there) while the model's vy, from a steady r and ay, stays put; the mismatch integrated over the
# model's correlation time, beyond the residual offsets' share, is what the model's vy is off by and
# joins the law excess (fusion/slide_rate.py; with fresh GNSS, the law excess's gate), while the car is
# at the friction the steering has shown (FRICTION_MEMORY's hold): a bank stepping faster than b_ay
# follows puts the same mismatch into ay - r vx on a gripping car (suite road_handling: -0.6 m/s^2 for
# 4 s at a bank step of 2.9 deg; ungated, sideslip RMS 0.40 -> 0.67 deg). False: main's behaviour, bit
# for bit.
SLIDE_RATE = True
# A slow slide on ice that neither the steering's misfit nor SLIDE_RATE sees (never-seen random drives
# 2271, a steady circle on mu 0.22 with a 2.9 deg bank, and 2318, a j-turn on mu 0.22: the sideslip grew
# at ~1 deg/s, 0.25 m/s^2 in ay - r vx, inside the accelerometer offset's 3 sigma, with no friction limit
# shown first; sideslip published valid up to 5.9 deg off, 2271's heading 3.7 deg). The GNSS course
# changes by the heading's change plus the sideslip's, and the gyro measures the first: over 4 s the
# course less the gyro's turn less the model's sideslip change, beyond 3 sigma of the courses' noise and
# the gyro's bias and scale errors, is the model's error; it joins the law excess (fusion/course_slide.py).
# A bank enters ay, not the gyro or the course: it cannot open this rule. False: main's behaviour, bit
# for bit.
# Was off at stop 44: with the GNSS latency configured fixed and far off (tests/test_latency_prior_wrong.py:
# dlc_lat08 replayed with delay_s = 0.1 for a true 0.8, estimate_delay false) the sideslip was published
# valid beyond 3 sigma on 86 rows with it on, 0 with it off. Traced at stop 45: the rule's timing term
# (COURSE_SLIDE_TIMING below). Off again at stop 45: a gyro scale error the filter has not found yet
# opens it as a slide does (tests/test_scale_sensitivity.py, a corner with the gyro 3-5 % off: the
# courses turn 3-5 % less or more than the gyro; its 3 sigma counts the scale as yaw_scale_std x the
# turn, the scale check's std, not traced whether that covered the error before the check found it;
# failing with it on, passing with it off): the heading floor then made a right heading invalid (flying_10_gyro_-5pct: valid
# above 5 m/s 0.40) and left a valid one 2.7 deg off within its 3 sigma (x0.97). With it on, on the
# never-seen drives 2641-2880, the heading rows valid beyond 3 sigma went 280 -> 0 (2827) for 87.1 ->
# 86.7 % heading availability; it waits for a scale term that counts the scale as far as the gyro's
# scale check has confirmed it (as COURSE_SLIDE_TIMING does the latency). Its tests run it on.
# Still off at stop 46: traced (COURSE_SLIDE_SCALE_SENS below), the scale term is now the residual's own
# sensitivity to the scale, but what it multiplies, the scale check's std, does not bound the share the
# bias state took (course_slide.BIAS_SHARE_SCALE_SD: no bound tried both passes the -5 % flying start and
# keeps 2271 / 2404 / 2827).
COURSE_SLIDE = False
# ... and while they do, a single antenna's heading (course + sideslip) took the sideslip's error: the
# courses moved it by what the model withheld from vy (2271: heading 2-2.8 deg off at a 0.6 deg std,
# 709 rows beyond 3 sigma, the sideslip's own std 0.7-2.6 deg). The published heading std is at least
# the largest sideslip std seen while the rule is open, held TURN_MEMORY_S after it closes (the courses
# take the heading back). False: COURSE_SLIDE alone.
COURSE_SLIDE_HEADING = True
# The rule's timing term with the latency as far as it is known (issue 7, stop 45: test_latency_prior_wrong
# [fixed], dlc_dry with a 0.8 s receiver configured fixed at 0.1 s: 86 sideslip rows valid beyond 3 sigma
# with COURSE_SLIDE on). Each course is from its true instant, the latency error d earlier, so it carries
# the heading turned over d: the term was the latency's std times the change of r *at the two fixes*, a
# linearisation that fails for a d of 0.7 s (a lane change's r is 0 at both fixes 4 s apart while it was
# 0.3 rad/s 0.7 s before each) and used a fixed delay's 0.01-0.15 s std although the data never vouch for
# a fixed delay (timing_trust). The rule measured 7-10 deg on straights at a 3 sigma of 1.7-2 deg, opened,
# and the widened model let the mistimed courses move vy (published 5-7 deg off at 0.3-0.65 deg). Now:
# the std is timing_trust.along_track_std (the receiver's range until identified) and r's change is the
# largest the yaw rate shows between any two instants the courses may be from (its min / max over +- 3
# std around each fix, within the receiver's range). A steady circle (2271) keeps a constant r: unchanged.
# False: the stop-44 term.
COURSE_SLIDE_TIMING = True
# The rule's scale term (stop 46): COURSE_SLIDE was off at stop 45 because a gyro scale error the scale
# check had not applied opened it (tests/test_scale_sensitivity.py: flying_10 with the gyro x0.97 heading
# valid 2.7 deg off, -5 % heading valid 0.40 above 5 m/s). Traced: it opened on the straight after the
# corner, not in it: in the corner the bias state b_r took part of the scale (b_r -1.4 deg/s on the -5 %
# gyro) and the rule subtracts the bias as known at the older fix, so on the straight it measured 7-9 deg
# against a 3 sigma of ~3 deg: its term was yaw_scale_std (0.8-1.3 % for a true 5 %: the fit of the
# bias-corrected gyro) x the turn, 0 on the straight. The residual's sensitivity to the scale is
# turn + S_br(t0) x W, signed (S_br: b_r's share of the scale, scale_sensitivity.py; in a steady corner
# they cancel as far as b_r took it), times the scale not applied yet over both priors
# (YawScaleCheck.heading_scale, the heading std's term). Measured with COURSE_SLIDE on: the -5 % flying
# start is still opened (heading valid above 5 m/s 0.41): the fit's std is 0.45-1.3 % for the true 5 %
# (b_r held -S_br s = -1.4 deg/s; the fit reads the bias-corrected gyro and cannot see that share), see
# course_slide.BIAS_SHARE_SCALE_SD. False: the stop-45 term, yaw_scale_std x turn.
COURSE_SLIDE_SCALE_SENS = True
# The gyro scale error the heading's std carries (S_psi x the scale not applied yet: _estimate) is, in a
# corner, the sideslip's error too: the courses read heading - sideslip, so the filter keeps that
# difference right and whatever of s r dt the heading owes, vy owes at vx times it (the consider
# analysis itself shows it: scale_sensitivity.py's S_vy / vx follows S_psi, 0.54 against 0.70 at 12 s
# into a steady circle, 3.43 against 3.45 at 40 s). The tilt of a banked road is such a scale on the heading only (r / cos(bank), the bank
# taken off where road.py knows it, which with one antenna holds part of the ay offset): random drive
# 2946, a 140 m circle at bank -3.3 deg estimated -1.3..-1.5, heading 0.9 deg off at a published
# 0.68 with this term 0.49 deg, sideslip 1.0 deg off at 0.33 without it (534 valid rows beyond 3
# sigma). The sideslip publishes the same term: |d beta / d s| x the fit's scale std, in quadrature
# (scale_sensitivity.ScaleSensitivity.sideslip): 2946 then 0 rows beyond 3 sigma, sideslip valid above
# 5 m/s 98.1 -> 93.1 %. OFF: it also withholds right sideslips, the suite's mu03_outage_30s (after a
# 30 s outage the courses put the rotation's scale share into vy) valid above 5 m/s 91.9 -> 87.7 %
# (target 90 %, worst 0.85 deg, all within 3 sigma either way). False: main's behaviour, bit for bit.
SIDESLIP_SCALE_SENS = False
# The latency error the heading's std carries (|S_psi| x latency std, latency_sensitivity.py) reaches vy
# too, and vy is where a single antenna's velocity fixes put most of it (issue 7, stop 48): a fix fused at
# t_rx - delay with the delay off by d reads v(t_s - d) = v - a d, a the antenna's acceleration across
# the track, the same sign on every fix of a turn: a bias the filter averages into vy (and b_ay) however
# many fixes it fuses, and the consider analysis tracks it exactly (x_err = S d). Random drive 3358
# (demo, mu 0.32, 10 Hz UBX): the latency identification walked from its right prior 0.066 s to 0.32 s
# (std 0.133) before the corner; in the corner S_vy rose to 2.2 m/s per s, S_psi stayed 0.005: vy
# -0.54 m/s for a true +0.15 (S_vy d = -0.57), published at 0.20 m/s, sideslip 2.3 deg off as valid (74
# rows beyond 3 sigma). The sideslip publishes that term too: |d beta / d d| x the latency std (the
# heading's, _latency_std), in quadrature, vy |S_vy| x it. Only with one velocity receiver whose latency
# error is not a state (with a fresh dual-antenna heading P carries it: latency_consider.py).
# With it, 3358: 0 rows beyond 3 sigma, worst valid 1.07 deg, valid above 5 m/s 0.988 -> 0.946. OFF: it
# also withholds right sideslips wherever the latency is not identified yet (its std the prior's
# 0.10-0.15 s) and a transient makes S_vy large: on the 60 low-friction drives of 3121-3360 sideslip
# valid rows -0.6 %, 3124 (double lane change, latency 0.057 s off at a std of 0.106, worst 0.57 deg)
# valid above 5 m/s 0.937 -> 0.732 (tests/test_sideslip_latency_sens.py runs it on). ON since stop 51,
# with latency.INFORMATION_STD (the delay's std no narrower than the data's timing information): a
# wrong configured latency is a wrong configuration users make, and it was the mechanism of 4 of the
# last 13 never-seen breaks (3991, 4147, 4199, 3846: sideslip valid 1.1-2.8 deg off at a 0.3-0.66 std);
# the cost is right sideslips withheld while a right prior is unconfirmed (dev 3841-3953: valid above
# 5 m/s 0.843 -> 0.828, latstd50). False: the behaviour before, bit for bit.
SIDESLIP_LATENCY_SENS = True
MODEL_STEADY_S = 2.0
# yaw acceleration above which the corner is a transient: a 0.5 m tyre relaxation length lags the
# model's vy by (0.5 m / vx) x lr x r_dot, 0.03 m/s (0.3 deg) at 5 m/s and this rate
MODEL_STEADY_RDOT = 0.2  # rad/s^2


# A receiver's latency error is a filter state (latency_consider.py) while its dual-antenna heading
# is fresh (the heading measures r d against the course's r d: course - heading is the sideslip at
# any latency) and latency.py has the latency within this (s). Without a baseline only the lateral
# dynamics' model would tell a latency error from a sideslip error, and it passed its own errors
# for one (0.02 s at the 10-15 m circles' entry, sideslip RMS x2; Revs sideslip RMS +3 %, +10 %
# with the wrong parameters; a warm restart mid-corner 0.7 deg off in heading): the timing stays
# white noise there, as its std says.
AUGMENT_MAX_STD_S = 0.05
LAT_BIAS_STEPS = 1.0  # the ay bias's variance grows by (excess * dt)^2 per step over this

# BEFORE_START: a GNSS sample whose time of validity (receive time - latency) precedes the
# filter's first step (a flying start, a daemon restart while driving, a re-initialisation) is
# left out. The history holds no state of that time; clamped to the first step, its course was
# the heading of up to one latency earlier: r x 0.4 s = 5-7 deg at 13-19 deg/s. On Revs cut
# mid-corner and restarted with a learned (tight) latency std, that heading was valid 5.2 deg off
# (tools/cut_starts.py revs, cut 420 s). It costs at most one latency before the first fix is used.
MAX_RECEIVERS = 8  # learned latencies kept per receiver index
GRADE_RUN_CHANGE = 0.3  # m/s^2: g x the grade change (3 %) a speed-integral run may span (its ramp holds one grade)
LEARNED_BOUNDS_LIST = tuple((j, lo, hi) for j, (lo, hi) in LEARNED_BOUNDS.items())

log = logging.getLogger(__name__)
# Estimate(...) is a NamedTuple: its generated __new__ takes 38 keyword-capable arguments and
# builds the same tuple; every step has all of them in order, so the tuple is built directly
# (perf11: ~7 k instructions per step less). Only for a complete field list (no defaults).
_new_estimate = tuple.__new__
assert len(Estimate._fields) == 38


def _learned_key(key: str, receiver: int) -> str:
    """Learned-state key of a receiver's value: the primary keeps the single-receiver name."""
    return key if receiver == 0 else f"{key}_{receiver}"



def _mapping_fingerprint(cfg: Config, names: tuple[str, ...]) -> float:
    """The named input mappings (message, signals, scale, offset, sign) as a CRC-32: what a
    restored "checked" must match (another mapping, another check). A float: the learned state's
    values are."""
    parts = []
    for n in names:
        m = cfg.inputs.get(n)
        parts.append("-" if m is None else repr((m.message, m.signal_names(), float(m.scale), float(m.offset),
                                                 m.sign_signal)))
    return float(zlib.crc32("|".join(parts).encode()))


def _wheel_mapping_fingerprint(cfg: Config) -> float:
    """The four wheel-speed mappings' fingerprint (``wheel_mapping_checked``)."""
    return _mapping_fingerprint(cfg, ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr"))


def _gyro_mapping_fingerprint(cfg: Config) -> float:
    """The yaw-rate mapping's fingerprint (``gyro_mapping_checked``)."""
    return _mapping_fingerprint(cfg, ("yaw_rate",))


def hold_heading_step(since_gyro: float, timeout: float, r_last: float, vx: float, dt: float) -> float:
    """The heading error one held step adds (rad): the rotation the hold leaves out.

    ``since_gyro`` is the time since the last gyro sample. While that sample is still within its
    timeout the gyro is known and only the other IMU inputs are missing: the step leaves out
    exactly ``r_last dt``. Past it the yaw rate is unknown; it can have moved from ``r_last`` by
    ``HOLD_RDOT_MAX`` per second, within the circle and absolute bounds at the speed the car may
    have reached. The bound itself, not a fraction: a gap ends in whatever turn the car is in
    (dlc_dry, CAN and GNSS gone for 2 s: 2.7 deg off at 0.34 deg std, valid again at once).
    """
    r0 = abs(r_last)
    if since_gyro <= timeout:
        return r0 * dt
    v_hi = abs(vx) + HOLD_ACCEL_MAX * since_gyro
    r_max = min(HOLD_R_MAX, v_hi / HOLD_MIN_RADIUS_M)
    return min(r_max, r0 + HOLD_RDOT_MAX * since_gyro) * dt

class Estimator:
    def __init__(self, cfg: Config, learned: dict | None = None):
        es = cfg.estimator
        veh = cfg.vehicle
        gn = cfg.gnss
        backend.announce()
        self.cfg = cfg
        self.dt = dt = es.dt_s
        self.model = KinematicModel(dt, es.accel_noise_mps2, es.yaw_rate_noise_radps,
                                    es.yaw_rate_bias_walk, es.accel_bias_walk, es.wheel_scale_walk,
                                    lateral_accel_noise=es.lateral_accel_noise_mps2)
        self.hist = StepHistory(int(math.ceil((gn.max_delay_s + 0.3) / dt)) + 2)
        self.delay_compensation = es.delay_compensation
        learned = self._check_learned(learned)
        # one velocity fusion and one latency per receiver (GnssSample.source), each at its own
        # time of validity through the same history; the first is the primary one (published latency)
        receivers = gn.receivers()
        self.uses_velocity = [rx.role == "velocity" for rx in receivers]
        # the receiver whose fixes teach the per-drive stiffness regression (one latency: see _on_gnss)
        self.stiffness_source = self.uses_velocity.index(True)
        self.latencies = [LatencyEstimator(dt, float(learned.get(_learned_key("gnss_delay_s", i), rx.delay_s)),
                                           gn.max_delay_s, gn.estimate_delay or gn.delay_monitor,
                                           fixed=not gn.estimate_delay,
                                           prior_std_s=learned.get(_learned_key("gnss_delay_std_s", i), math.inf),
                                           min_spread=MIN_SPEED_SPREAD if rx.role == "velocity" else HEADING_SPREAD_RAD)
                          for i, rx in enumerate(receivers)]
        # a heading-only receiver identifies its latency from its heading changes against the gyro
        self.yaw_integral = YawIntegral(dt, gn.max_delay_s) if not all(self.uses_velocity) else None
        self.speed_integral = SpeedIntegral(dt, gn.max_delay_s)
        self.speed_run_grade = 0.0  # the road grade its current run began on
        self.receivers = [GnssVelocityFusion(rx.lever_arm_m[0], rx.lever_arm_m[1], gn.min_fix_type,
                                             gn.max_speed_acc_mps, gn.nmea_speed_acc_mps, es.gnss_gate_sigma)
                          for rx in receivers]
        # each antenna's configured lever arm x checked against its courses and the gyro
        self.lever_checks = [LeverArmCheck(rx.lever_arm_m[0]) for rx in receivers]
        self.lever_y_checks = [LeverArmYCheck(*rx.lever_arm_m) for rx in receivers]
        # ... and the gyro's scale against each antenna's course changes: vy's std grows by the best
        # (the scale is a sensor constant: one learned before a restart is the fit's prior)
        scale_prior = ((learned["yaw_rate_scale"], learned.get("yaw_rate_scale_std", YAW_SCALE_STD))
                       if "yaw_rate_scale" in learned else None)
        self.yaw_scale_checks = [YawScaleCheck(rx.lever_arm_m[0], scale_prior) for rx in receivers]
        # the scale applied to the gyro (r = r_m (1 - applied)) and, per history slot, the one each
        # step ran with: the fit reads the raw gyro back from the stored corrected rates
        self.yaw_scale_ring = np.zeros(self.hist.n)
        self.yaw_scale_changes = 0
        # whether the state was realigned to the scale fit's heading since the scale was applied
        self.yaw_scale_realigned = False
        self._set_yaw_scale()
        self.lever_flagged = False  # a lever arm found wrong: its course error goes into the heading std
        self.latency = self.latencies[0]
        # each receiver's latency error as the one unknown its fixes share (latency_consider.py)
        self.considers = [LatencyConsider(self.hist.n) for _ in receivers]
        # what of that error the heading still carries while it is not a state (latency_sensitivity.py);
        # one receiver only (two have two latency errors: the low-pass of |r| below stays for them)
        self.lat_sens = LatencySensitivity(self.hist.n) if len(receivers) == 1 else None
        self.scale_sens = ScaleSensitivity(self.hist.n, dt)
        # per receiver: the UTC epoch of its last velocity fix and the step it was fused at; a
        # dual-antenna heading of the same epoch (UBX RELPOSNED: NAV-PVT's iTOW) takes that step
        self.fix_steps: dict[int, tuple[float, int]] = {}
        self.augmented = False  # the primary receiver's last velocity fix had its latency error as a state
        self._velocity_latencies = [lat for lat, v in zip(self.latencies, self.uses_velocity) if v]
        # each velocity receiver's latency also from its speed against the integrated accelerometer
        self.speed_latencies = [LatencyEstimator(dt, lat.delay_s, gn.max_delay_s, lat.enabled, extra=1)
                                for lat in self.latencies]
        for lat, ref, v in zip(self.latencies, self.speed_latencies, self.uses_velocity):
            if v:
                lat.attach(ref)
        self.gnss = self.receivers[0]
        self.heading = GnssHeadingFusion([(rx.heading_offset_deg, rx.baseline_m) for rx in receivers],
                                         gn.baseline_tol_m, gn.max_heading_acc_deg, gn.nmea_heading_acc_deg,
                                         es.gnss_gate_sigma)
        self.last_heading_fused_t = -math.inf
        self.learn_phi = deque(maxlen=LEARN_EXCITE_FIXES)  # the rear regressor at the last fused fixes
        # the optional magnetometer ([inputs.mag_x/y/z]): None when not mapped
        self.mag = None
        if all(n in cfg.inputs for n in ("mag_x", "mag_y", "mag_z")):
            self.mag = MagnetometerFusion(es.mag_tilt, es.mag_noise_deg, es.mag_bias_deg, es.mag_tilt_std_deg,
                                          es.mag_norm_tol, es.mag_dip_tol_deg, es.mag_gate_sigma)
        self.mag_new = False
        self.wheels = WheelSpeedFusion(veh.driven_axle, veh.cg_to_front_axle_m, es.wheel_speed_noise_mps)
        self.wheelbase = veh.cg_to_front_axle_m + veh.cg_to_rear_axle_m  # steered_wheel_vx.py
        self.mass_lf = veh.mass_kg * veh.cg_to_front_axle_m  # the rear's force: m ay lf - Iz rdot (steered_wheel_vx.py)
        self.yaw_inertia = veh.yaw_inertia_kgm2
        # slip measured against the accelerometer: the linear law's bound fails at the friction limit
        self.slip_witness = SlipWitness(dt, self.wheels.noise2, self.wheels.use_all)
        self.wheel_lock = WheelLock(dt, self.wheels.noise2)  # WHEEL_LOCK_SKIP
        # a driven rear axle on its limit, from its wheels against the free front (drive_slip.py)
        self.drive_slip = DriveSlip(dt, veh.driven_axle, veh.cg_to_front_axle_m, veh.cg_to_rear_axle_m)
        self.friction = FrictionLimit()  # FRICTION_MEMORY
        self.slide_rate = SlideRate(dt)  # SLIDE_RATE
        self.course_slide = CourseSlide()  # COURSE_SLIDE
        self.course_slide_k = -1  # the step of its last fix
        self.course_slide_psi = 0.0  # the heading's std floor while the courses show the model off
        self.course_slide_psi_t = -math.inf
        self.friction_var = 0.0  # its held law excess at the last step ((m/s)^2)
        # the rear axle's friction ellipse at its braking load against the road's grip shown (brake_grip.py)
        self.brake_grip = BrakeGrip(dt, veh.driven_axle, veh.cg_to_front_axle_m, veh.cg_to_rear_axle_m,
                                    veh.cg_height_m)
        # the wheels' slip ratio against a linear tyre's for its force (slip_ratio_limit.py)
        self.slip_ratio_limit = SlipRatioLimit(dt)
        self.standstill = StandstillFusion(dt, es.yaw_rate_noise_radps)
        self.single_track = SingleTrackFusion(
            veh.mass_kg, veh.yaw_inertia_kgm2, veh.cg_to_front_axle_m, veh.cg_to_rear_axle_m,
            veh.cornering_stiffness_front_n_per_rad, veh.cornering_stiffness_rear_n_per_rad,
            es.adapt_cornering_stiffness, learned, veh.tyre_relaxation_length_m)
        # the drive slip angle's lateral force: the tyres', bank in (DRIVE_SLIP_TYRE_FORCE, tyre_lateral_force.py)
        self.rear_fy = RearLateralForce(dt, veh.cg_to_front_axle_m, veh.cg_to_rear_axle_m,
                                        self.single_track.iz_r)
        self.stiffness = StiffnessRegression(
            veh.mass_kg, veh.yaw_inertia_kgm2, veh.cg_to_front_axle_m, veh.cg_to_rear_axle_m,
            veh.cornering_stiffness_front_n_per_rad, veh.cornering_stiffness_rear_n_per_rad,
            es.yaw_rate_noise_radps, es.yaw_rate_bias_walk, dt, veh.tyre_relaxation_length_m)
        self.fdi = self._new_fault_detector()
        # the optional baseline elevations (per receiver) and roll-rate gyro of road.py
        self.road = RoadAttitude(
            dt, es.accel_offset_std_mps2, learned,
            [BaselineMount(math.radians(rx.heading_offset_deg), math.radians(rx.baseline_elevation_deg),
                           math.radians(rx.baseline_elevation_std_deg)) if rx.fuse_baseline_elevation else None
             for rx in receivers], self.hist.n,
            (es.yaw_rate_noise_radps, es.yaw_rate_bias_walk) if "roll_rate" in cfg.inputs else None)
        self.steer_ratio = veh.steering_ratio
        self.steer_learner = SteeringOffset(dt, veh.steering_ratio,
                                            veh.cg_to_front_axle_m + veh.cg_to_rear_axle_m,
                                            learned.get("steering_offset_rad"))
        self.steer_offset = self.steer_learner.offset
        self._learned0 = learned
        # the learned states' bounds (fault_detection.LEARNED_BOUNDS); the wheel scale's re-centred
        # around a scale learned beyond them (WheelScaleSeed: a wrong tyre size in the config), here
        # when the learned state brings one, so that a restart keeps it
        self.learned_bounds = LEARNED_BOUNDS_LIST
        kw = learned.get("wheel_scale")
        if kw is not None and not LEARNED_BOUNDS[KW][0] <= kw <= LEARNED_BOUNDS[KW][1]:
            self._set_wheel_scale_bounds(recentred_bounds(kw))
        # input timeouts (s): configured, else generous defaults for 50-100 Hz CAN signals
        self.timeouts = [0.25] * len(INPUT_INDEX)
        for name, m in cfg.inputs.items():
            if m.timeout_s > 0:
                self.timeouts[INPUT_INDEX[name]] = m.timeout_s
        self.held = [math.nan] * len(INPUT_INDEX)
        self.held_t = [-math.inf] * len(INPUT_INDEX)
        # [imu] off the CG / off the body axes: its samples converted as they enter (None: at the CG)
        self.imu_mount = ImuMount.from_config(cfg.imu, I_YAW, I_AX, I_AY)
        # the gyro's and accelerometers' held samples taken to each step's middle (input_age.py)
        self.input_age = InputAge(I_AY - I_YAW + 1, dt)
        self.queue: deque = deque()
        self.k: int | None = None
        # no sample for longer than every timeout: a gap, skipped instead of stepped through
        self.gap_s = max(max(self.timeouts), gn.timeout_s)
        self.gaps = 0
        self.last_gap: tuple[float, float] | None = None  # (last step run, next sample or target)
        self.initialized = False
        self.aligned = False
        self.wheel_new = False
        self.r_lp = 0.0
        self.rdot = 0.0
        self.model_t = -math.inf  # last single-track fusion (MODEL_BOUND) and its lateral acceleration
        self.model_ay = 0.0
        self.model_fy_var = 0.0  # (m/s)^2: the model's vy doubt from the bank/offset split (MODEL_TYRE_FORCE)
        self.model_unsteady_t = math.inf  # last step the model's bound could not apply (MODEL_STEADY_S)
        self.law_bound = LawExcessBound()  # the law excess the model's bound is widened by (LAW_EXCESS_BOUND)
        self.law_var_held = 0.0  # the law excess of the last steady stretch, held through a transient
        self.law_steady_t = math.inf  # last step in a transient (or without the check): LAW_HOLD_STEADY_S
        self.law_var_min = math.inf
        self.last_gnss_fused_t = -math.inf
        self.gnss_run_t = -math.inf  # first fix of the current run of fused GNSS (no gap > HEADING_FRESH_S)
        self.mag_bridged = False  # the magnetometer held the heading in the gap before that run
        self.last_gnss_speed = math.nan
        self.course_heading: tuple[int, float, float] | None = None  # (step, heading, var) a GNSS course implies
        self.last_gnss_rejected = False
        self.late_inputs = 0
        self.resets = 0
        self.realignments = 0
        self.gnss_agrees = True
        self.gnss_checked_t = -math.inf
        self.wheel_reject_t = math.inf  # time of the first of the current run of wheel rejections
        # first and latest time of the current run of usable GNSS fixes rejected as inconsistent
        self.gnss_conflict_t = math.inf
        self.gnss_conflict_last_t = -math.inf
        self.lon_scale = LongitudinalScaleCheck(dt)  # wheels vs ax in scale and sign (mapping errors)
        self.lat_scale = LateralScaleCheck(dt)  # ay vs r vx at any speed (mapping errors)
        self.spin = SpinCheck(dt, veh.track_m, self.wheelbase)  # a spinning car: nothing promised (spin_check.py)
        self.spin_grip = SpinGrip(dt)  # the grip a spin showed (SPIN_GRIP, fusion/spin_grip.py)
        self.yaw_bias_walk = es.yaw_rate_bias_walk
        # (yaw-rate bias, its variance, t) when the last slide began; what _after_spin carries over
        self.spin_bias = None
        self.bias_carry = None  # (yaw-rate bias, variance) the next _initialize starts from
        self.axis_swap = AxisSwapCheck(dt)  # ax and ay each against its witness (a swapped mapping)
        self.gyro_gate = GyroScaleGate(veh.track_m, GSC_EVERY * dt)  # the gyro's scale against wheels and ay (a unit error)
        # ... a sensor's mapping, not a state: once confirmed, a restart with the same yaw-rate mapping
        # need not confirm it again (a restart mid-corner had its heading withheld 2.5 s while the
        # witnesses re-judged a gyro the learned state had already seen confirmed: test_cut_starts)
        self._gyro_mapping = _gyro_mapping_fingerprint(cfg)
        if learned.get("gyro_mapping_checked") == self._gyro_mapping:
            self.gyro_gate.confirmed = True
        self.ay_out = self.ay_out_new = False  # ay alone stale: substituted (_step)
        self.wheel_scale_check = WheelScaleCheck()  # the wheels' scale against GNSS speed (mapping errors)
        self.wheel_scale_seed = WheelScaleSeed()  # ... averaged over steady fixes (a wrong tyre size)
        if not any(rx.port for rx in gn.receivers() if rx.role == "velocity"):
            # GNSS off: nothing will ever check the wheels, and the user chose to run without a
            # witness; the unchecked std would withhold velocity for good (the CAN VX_STD range):
            # as before the check, the wheels are taken as mapped
            self.wheel_scale_check.confirmed = True
            self._wheels_assumed = True  # taken, not checked: not recorded as checked (learned_state)
        else:
            self._wheels_assumed = False
        # the wheels' scale also against the gyro, on the rear axle's speed difference in turns
        # (wheel_yaw_check.py): a right mapping is confirmed within the first turn, GNSS or not
        self.wheel_yaw = WheelYawCheck(veh.track_m)
        # ... and against the integrated ax on a launch from rest (wheel_launch_check.py), on the
        # wheels that do not drive (a driven axle spins): a drive from rest is confirmed at 4 m/s
        self.wheel_launch = WheelLaunchCheck()
        self._launch_axle = veh.driven_axle
        # ... and once checked, by whichever witness, a restart with the same wheel mapping need not
        # check again: the learned state keeps that mapping's fingerprint (learned_state)
        self._wheel_mapping = _wheel_mapping_fingerprint(cfg)
        if learned.get("wheel_mapping_checked") == self._wheel_mapping:
            self.wheel_scale_check.confirm()
        self._reset_flag = False
        self._lp_r = dt / (0.03 + dt)
        self.bank_walk = BankWalk(dt)
        self._lp_rdot = dt / (0.05 + dt)
        self.model_inputs = LaggedModelInputs(self._lp_r, self._lp_rdot, dt)  # r, ay at rdot's lag
        self.turn_lp = 0.0  # |yaw rate| over the last seconds (the latency-induced heading error)
        # the (yaw rate x latency std)^2 a course alignment put into P, and P's heading variance then
        # (``_estimate``: that part of P and the published latency term are one error, counted once)
        self.align_lat_var = 0.0
        self.align_psi_var = 0.0
        self._lp_turn = dt / (TURN_MEMORY_S + dt)
        self.slip_hold = 0.0  # peak-held wheel-slip bound (m/s), see ``_estimate``
        self.brake_slip_hold = 0.0  # the same, refreshed only while braking (SLIP_SPLIT)
        self.fix_turn = 0.0  # net heading turn of fused fixes while a wheel bias beyond P's vx std lasts (WHEEL_BIAS_HEADING)
        self.wheel_bias_t = -math.inf  # last step such a bias was published (WHEEL_BIAS_HEADING)
        self._slip_decay = math.exp(-dt / SLIP_MEMORY_S)
        self.speed_gap = GnssSpeedGap(GNSS_WHEEL_TOL_MPS, GNSS_WHEEL_TOL_REL)  # GNSS_SPEED_GAP
        # each history slot's widening of the speed bound, (|(ax, ay)| + ACCEL_ERR) dt from the aux row
        # written with it (the same floats, the same bits): a fix sums a Python list, not numpy rows
        self.gap_terms = [0.0] * self.hist.n
        self.sideslip_vouched = False  # the last estimate's sideslip valid (GNSS_SPEED_GAP)
        self.velocity_vouched = False  # the last estimate's velocity valid (GNSS_READMIT_CHECK)
        self.readmit = GnssReadmitCheck()  # GNSS back from isolation, not yet checked (GNSS_READMIT_CHECK)
        self.bank_lag_var = 0.0  # (m/s)^2: vy's variance of b_ay's lag behind a changing bank (BANK_LAG_STD)
        self.steer_vy_hold = 0.0  # held vx error a missed vy puts through steered wheels (STEERED_WHEEL_VY)
        self.awd_slip_hold = 0.0  # held drive slip an AWD's wheels may carry at the limit (AWD_LIMIT_SLIP)
        self.return_level_sd = 0.0  # vx's std when an AWD's wheels came back, until a fix checks them (WHEELS_RETURN_LEVEL)
        self.return_level_k = 0  # the step they came back at
        # The lateral cross-check's residual rate (fault_detection.py) that the filter's own
        # lateral-acceleration noise covers (1 sigma over the check's window). Beyond it vy may be
        # drifting faster than its std grows: an ay error below the fault tolerance (which real
        # bank and roll set wide) must still not pass as a valid sideslip. Its std then grows by
        # the rest (the ay bias stays: that is for the faults beyond the tolerance).
        self.lat_drift_tol = es.lateral_accel_noise_mps2 / math.sqrt(LAT_WINDOW_S)
        # vy's white noise: the accelerometer's own, measured, never below the configured one
        self.lat_noise = LateralNoise(es.lateral_accel_noise_mps2)
        self._vy_density = es.lateral_accel_noise_mps2

    # ----------------------------------------------------------------------------------------
    # public contract
    def push_input(self, s: InputSample) -> None:
        self.queue.append(s)

    def push_gnss(self, g: GnssSample) -> None:
        self.queue.append(g)

    def no_estimate(self, t: float) -> Estimate:
        """What a step before the first sample publishes: finite, every validity bit false."""
        return self._invalid(t)

    def advance_to(self, t: float) -> list[Estimate]:
        """Run every step up to time ``t``; step k applies the queued samples of ``step_of`` <= k."""
        out: list[Estimate] = []
        dt = self.dt
        q = self.queue
        if self.k is None:
            if not q:
                return out
            self.k = step_of(q[0].t, dt)
        k = self.k
        k_end = last_step_at(t, dt)
        gap = self.gap_s
        held = self.held
        held_t = self.held_t
        imu = self.imu_mount
        while k <= k_end:
            tk = k * dt
            if (q[0].t if q else t) - tk > gap:
                k = self.k = self._skip_gap(k, q[0].t if q else t, bool(q))
                held_t = self.held_t  # replaced by the gap
                continue
            while q and step_of(q[0].t, dt) <= k:
                s = q.popleft()
                if type(s) is InputSample:  # ~5 per step: inline, the only place inputs enter held
                    ts, j, v = s
                    if ts < (k - 1) * dt - 1e-9 and self.initialized:
                        self.late_inputs += 1
                    if imu is not None and I_YAW <= j <= I_AY:
                        v = imu.convert(j, ts, v)
                    held[j] = v
                    held_t[j] = ts
                    if I_YAW <= j <= I_AY:
                        self.input_age.observe(j - I_YAW, ts, v)
                    if j <= I_RR_MAX:
                        self.wheel_new = True
                    elif j == I_AY:
                        self.lat_noise.observe(ts, v)
                    elif I_MX <= j < I_ROLL:
                        self.mag_new = True
                else:
                    self._apply(s, k)
            out.append(self._step(k, tk))
            k += 1
            self.k = k
        return out

    def learned_state(self) -> dict:
        if not self.initialized:
            return dict(self._learned0)
        x = self.hist.X[self.hist.slot(self.hist.last)]
        return {
            "version": LEARNED_VERSION,
            "yaw_rate_bias_radps": float(x[BR]),
            "accel_x_bias_mps2": float(x[BAX]),
            "accel_y_bias_mps2": float(x[BAY]),
            "wheel_scale": float(x[KW]),
            "accel_y_gain": float(x[GAY]),
            **self.single_track.learned(),
            **self.stiffness.learned(),
            "steering_offset_rad": float(self.steer_offset),
            **self.road.learned(),
            **self._yaw_scale_learned(),
            **self._wheels_checked_learned(),
            **self._gyro_checked_learned(),
            **{_learned_key(k, i): float(getattr(lat, a)) for i, lat in enumerate(self.latencies)
               for k, a in (("gnss_delay_s", "delay_s"), ("gnss_delay_std_s", "std_s"))},
        }

    def _wheels_checked_learned(self) -> dict:
        """The wheel mapping's fingerprint once a witness (GNSS, the gyro, a restored state) has
        confirmed its scale; nothing when it was only taken as mapped (GNSS off)."""
        if self.wheel_scale_check.confirmed and not self._wheels_assumed:
            return {"wheel_mapping_checked": self._wheel_mapping}
        return {}

    def _gyro_checked_learned(self) -> dict:
        """The yaw-rate mapping's fingerprint once the gyro-scale gate (or a restored state) has
        confirmed it (gyro_scale_gate.py); nothing before."""
        if self.gyro_gate.confirmed:
            return {"gyro_mapping_checked": self._gyro_mapping}
        return {}

    def _yaw_scale_learned(self) -> dict:
        """The gyro's scale error and its std, once a fit has seen a fix or was restored (the bare
        prior is not learned: a drive without GNSS keeps what the file had)."""
        best = min(self.yaw_scale_checks, key=lambda c: c.scale_sd)
        if not (best.n or best.restored):
            return {}
        return {"yaw_rate_scale": float(best.scale), "yaw_rate_scale_std": float(best.scale_sd)}

    def learned_std(self) -> dict:
        """1-sigma of the learned values, from what already carries it: the filter covariance
        (biases, wheel scale), the RLS covariance (cornering compliances kappa = m / C) and the
        latency estimator and the steering offset's own (steering_offset.py: its scatter over the
        independent samples behind it); empty before initialisation."""
        if not self.initialized:
            return {}
        P = self.hist.P[self.hist.slot(self.hist.last)]
        sd = lambda i: float(math.sqrt(max(P[i, i], 0.0)))  # noqa: E731
        return {"yaw_rate_bias_radps": sd(BR), "accel_x_bias_mps2": sd(BAX), "accel_y_bias_mps2": sd(BAY),
                "wheel_scale": sd(KW), "accel_y_gain": sd(GAY),
                "kappa_r": float(math.sqrt(self.single_track.rear.P[0, 0])),
                "kappa_f": float(math.sqrt(self.single_track.front.P[0, 0])),
                **self.stiffness.learned_std(),
                "gnss_delay_s": float(self.latency.std_s),
                "steering_offset_rad": self.steer_learner.std()}

    # ----------------------------------------------------------------------------------------
    @staticmethod
    def _check_learned(learned: dict | None) -> dict:
        """Keep only finite, plausible learned values (a restored file must not poison the filter)."""
        if not learned or learned.get("version") != LEARNED_VERSION:
            return {}
        limits = {"yaw_rate_bias_radps": 0.1, "accel_x_bias_mps2": 2.0, "accel_y_bias_mps2": 2.0,
                  "wheel_scale": KWS_TOTAL, "accel_y_gain": 0.2, "kappa_r": (1e-4, 1.0), "kappa_f": (1e-4, 1.0),
                  "kappa_r3": (-1.0, 1.0), "kappa_f3": (-1.0, 1.0),
                  **{key: (-1.0, 1.0) if key.endswith("_corr") else (0.0, 1.0)
                     for axle in ("kappa_r", "kappa_f") for key in stiffness_std_keys(axle)},
                  "steering_offset_rad": 0.5, "gnss_delay_s": (0.0, 1.0),
                  "gnss_delay_std_s": (0.0, 1.0),
                  "accel_x_offset_mps2": 2.0, "accel_y_offset_mps2": 2.0,
                  "accel_x_offset_std_mps2": (0.0, 10.0), "accel_y_offset_std_mps2": (0.0, 10.0),
                  "roll_rate_bias_radps": 0.1, "roll_rate_bias_std_radps": (0.0, 1.0),
                  "yaw_rate_scale": 0.1, "yaw_rate_scale_std": (0.0, 0.1),
                  "wheel_mapping_checked": (0.0, float(0xFFFFFFFF)),
                  "gyro_mapping_checked": (0.0, float(0xFFFFFFFF))}
        for i in range(1, MAX_RECEIVERS):
            limits[_learned_key("gnss_delay_s", i)] = limits["gnss_delay_s"]
            limits[_learned_key("gnss_delay_std_s", i)] = limits["gnss_delay_std_s"]
        out = {"version": LEARNED_VERSION}
        for key, lim in limits.items():
            v = learned.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                continue
            lo, hi = lim if isinstance(lim, tuple) else (-lim, lim)
            if lo <= v <= hi:
                out[key] = float(v)
        return out

    def _apply(self, s, k: int) -> None:
        """A GNSS sample at step k. Input samples (~5 per step) are applied inline in
        ``advance_to``, the one place they enter ``held``."""
        if isinstance(s, GnssSample):
            if (WHEEL_BIAS_HEADING and self.initialized
                    and k * self.dt - self.wheel_bias_t <= TURN_MEMORY_S):  # the fix's turn of the present heading
                h = self.hist
                last0 = h.last
                psi0 = h.X.item(h.slot(last0), PSI)
                self._on_gnss(s, k)
                if self.initialized and h.last == last0:
                    d = (h.X.item(h.slot(last0), PSI) - psi0 + math.pi) % (2.0 * math.pi) - math.pi
                    self.fix_turn += d
                return
            self._on_gnss(s, k)
        elif type(s) is GnssHeadingSample:
            self._on_heading(s, k)

    def _check_wheels_without_gnss(self, k: int, fl: float, fr: float, rl: float, rr: float, ok: bool,
                                   r: float, ax: float, bax_var: float, vx: float) -> None:
        """Until a witness has confirmed the wheels' scale: the rear axle's speed difference against
        the gyro (wheel_yaw_check.py, every WYC_EVERY steps) and a launch's wheel speed change
        against the integrated ax (wheel_launch_check.py), each only on raw inputs that are not a
        known fault (``ok``); either confirms (WheelScaleCheck.confirm)."""
        wsc = self.wheel_scale_check
        nan = math.nan
        axle = self._launch_axle
        v = (0.5 * (rl + rr) if axle == "front" else 0.5 * (fl + fr) if axle == "rear"
             else min(fl, fr, rl, rr)) if ok else nan
        if self.wheel_launch.step(v, ax if ok else nan, math.sqrt(max(bax_var, 0.0)), self.dt):
            # the launch's measured scale error, and its precision as 3 sigma
            wsc.confirm(math.hypot(self.wheel_launch.scale - 1.0, WLC_PRECISION / 3.0))
            if wsc.confirmed:
                log.info("wheel speeds' scale confirmed by the accelerometer on a launch: the wheels "
                         "changed %.3fx what ax integrates to", self.wheel_launch.scale)
                return
        if k % WYC_EVERY == 0 and self.wheel_yaw.step(rl if ok else nan, rr, r, ax, WYC_EVERY * self.dt, vx):
            wy = self.wheel_yaw
            # its measured scale error (the configured track's error in it too) and the fit's std
            wsc.confirm(math.hypot(wy.scale - 1.0, wy.scale_std))
            if wsc.confirmed:
                wy = self.wheel_yaw
                log.info("wheel speeds' scale confirmed by the gyro: the rear axle's speed difference "
                         "is %.3f +- %.3f x yaw rate x track over %.0f deg of turns", wy.scale,
                         wy.scale_std, math.degrees(wy.turn))

    def _skip_gap(self, k: int, t_next: float, to_sample: bool) -> int:
        """Nothing arrives from step k until ``t_next``, longer than every input timeout (a logging
        gap, a timestamp typo, a clock jump): every input is stale, so instead of building each step
        of the gap, mark them stale, re-initialise (keeping what was learned) and return the step to
        resume at -- the next sample's, or the target's when nothing is queued (a live clock jump).
        """
        self.gaps += 1
        self.last_gap = ((k - 1) * self.dt, t_next)
        self.held_t = [-math.inf] * len(self.held_t)
        self.input_age.reset()
        if self.initialized:
            self._reset(k)
        return step_of(t_next, self.dt) if to_sample else last_step_at(t_next, self.dt)

    def _initialize(self, k: int, wheel_speed: float, r_m: float, ay_m: float) -> None:
        """Start the filter in whatever state the car is in (standstill or moving, straight or
        cornering): vx from the wheels, vy from the single-track model, heading unknown.

        The standard deviations are what these sources are worth on a flying start: the wheel
        scale's uncertainty times the speed, the model's sideslip error (~1.5 deg plus a bit),
        no heading at all until GNSS course gives one (``_align``).
        """
        L = self._learned0
        h = self.hist
        h.reset(k)
        i = h.slot(k)
        x = h.X[i]
        x[:] = 0.0
        kw = L.get("wheel_scale", 1.0)
        x[VX] = vx = wheel_speed * kw
        x[BR] = L.get("yaw_rate_bias_radps", 0.0)
        x[BAX] = L.get("accel_x_bias_mps2", 0.0)
        x[BAY] = L.get("accel_y_bias_mps2", 0.0)
        x[KW] = kw
        x[GAY] = L.get("accel_y_gain", 0.0)
        x[VY] = self.single_track.pseudo_measurement(vx, r_m - x[BR], ay_m - x[BAY], 0.0)[0]
        have = "yaw_rate_bias_radps" in L
        kw_std = 0.005 if "wheel_scale" in L else 0.03
        std = np.array([math.hypot(0.3, kw_std * vx), 0.1 + math.radians(1.5) * abs(vx) + abs(x[VY]) * 0.3,
                        math.pi, math.radians(0.3 if have else 1.0), 0.3, 0.3, kw_std,
                        0.02 if "accel_y_gain" in L else 0.05])
        carry = self.bias_carry
        if carry is not None:  # after a spin: the bias as learned before the slide (_after_spin)
            self.bias_carry = None
            x[BR] = carry[0]
            std[BR] = math.sqrt(carry[1])
        h.P[i] = np.diag(std ** 2)
        h.A[i] = np.eye(NX)
        # the heading will come from GNSS courses of the turn the car is in now: their latency error
        # is r x (latency error) from the first fix, not after the low-pass has caught up (a restart
        # mid-corner would otherwise publish a heading std without it for its first seconds)
        # (x.item: a Python float, so the every-step low-pass of |r| is float arithmetic from here on)
        self.turn_lp = abs(r_m - x.item(BR))
        self.align_lat_var = 0.0
        self.model_unsteady_t = math.inf  # the model's bound waits for a steady stretch (MODEL_STEADY_S)
        self.law_var_held = 0.0  # no misfit measured on this state yet (LAW_EXCESS_HOLD)
        self.law_steady_t = math.inf
        self.law_var_min = math.inf
        if SLIDE_RATE:
            self.slide_rate.reset()  # the model's mismatch is measured on this state from here
        if COURSE_SLIDE:
            self.course_slide.reset()
            self.course_slide_k = -1
        # the drive-slip low-pass (0.1 s) holds the wheels before the re-initialisation: after a spin
        # the slide's slip ratio, after a gap or a divergence wheels no longer of this car state
        self.drive_slip.reset()
        if DRIVE_SLIP_TYRE_FORCE:
            self.rear_fy.reset()
        if BRAKE_GRIP:
            self.brake_grip.reset()
        if SLIP_RATIO_LIMIT:
            self.slip_ratio_limit.reset()
        self.initialized = True
        self.aligned = False

    def _new_fault_detector(self) -> FaultDetector:
        veh = self.cfg.vehicle
        return FaultDetector(self.dt, veh.track_m, veh.cg_to_front_axle_m, veh.driven_axle,
                             self.wheels.measured_speed, self._model_vy, veh.cg_to_rear_axle_m,
                             GYRO_WITNESSES_AGREE)

    def _after_spin(self, k: int) -> None:
        """The car grips again after a spin (spin_check.py): re-initialise the filter from the
        wheels (the divergence path) and start the fault detector afresh. Its verdicts while the
        car slid (wheels, ax, gyro, GNSS isolated in turn: random seeds 89, 166, 205, 239) were
        votes through a gripping car's kinematics, which the spin broke; kept, they held the good
        wheels out for good. Its event counts (EST_DIAG) and left/right radius learning carry on."""
        old = self.fdi
        fdi = self.fdi = self._new_fault_detector()
        fdi.events = old.events
        fdi.lr = old.lr
        log.warning("spin: the car grips again (%.1f s after the slide began): filter and fault "
                    "detector re-initialised", (k * self.dt) - self.spin.fired_t)
        self._reset(k)
        sb = self.spin_bias
        if SPIN_KEEPS_GYRO_BIAS and sb is not None:  # the gyro's offset did not slide (SPIN_KEEPS_GYRO_BIAS)
            self.bias_carry = (sb[0], sb[1] + self.yaw_bias_walk ** 2 * max(k * self.dt - sb[2], 0.0))
        self.spin_bias = None

    def _reset(self, k: int) -> None:
        """Re-initialise after divergence / non-finite state, keeping what was learned."""
        self.resets += 1
        self._reset_flag = True
        self.wheel_reject_t = math.inf
        self.wheels.consecutive_rejects = 0
        for fus in self.receivers:
            fus.consecutive_rejects = 0
        self.heading.consecutive_rejects = 0
        for chk in self.lever_checks:
            chk.restart()
        for chk in self.yaw_scale_checks:
            chk.restart()
        self._learned0 = self._check_learned(self.learned_state()) if self.initialized else self._learned0
        self.initialized = False

    # ----------------------------------------------------------------------------------------
    def _step(self, k: int, t: float) -> Estimate:
        # hot path (every 6 ms): row views instead of numpy indexing, Python floats from one
        # tolist() instead of numpy scalars, locals instead of repeated attribute look-ups
        held = self.held
        held_t = self.held_t
        r_m = held[I_YAW]
        ax_m = held[I_AX]
        ay_m = held[I_AY]
        ysa = self.yaw_scale_applied
        if ysa:  # the learned scale error, off the raw gyro (yaw_scale_check.py)
            r_m *= 1.0 - ysa
        tmo = self.timeouts
        imu_ok = (t - held_t[I_YAW] <= tmo[I_YAW] and t - held_t[I_AX] <= tmo[I_AX]
                  and t - held_t[I_AY] <= tmo[I_AY])
        fl, fr, rl, rr = held[0], held[1], held[2], held[3]
        wheels_ok = (t - held_t[0] <= tmo[0] and t - held_t[1] <= tmo[1] and t - held_t[2] <= tmo[2]
                     and t - held_t[3] <= tmo[3])
        fdi = self.fdi
        h = self.hist
        if not self.initialized:
            wheel_z = self.wheels.measured_speed(fl, fr, rl, rr) if wheels_ok else math.nan
            # velocity comes from the wheels at once, so the filter waits for them: starting at
            # vx = 0 while the car moves puts every wheel sample outside its gate (the divergence
            # of issue 7) and a flying start looks like a standstill
            if not (imu_ok and math.isfinite(wheel_z)) or fdi.isolated & WHEELS:
                return self._invalid(t)
            self._initialize(k, wheel_z, r_m, ay_m)
            # Python floats (one tolist()), not numpy scalars: r_lp and rdot are low-passes, so a
            # numpy scalar here made every later value of both, and everything computed from them
            # (the model's inputs, the fault detector's yaw checks, the tyre laws), numpy scalar
            # arithmetic for the whole drive (issue 10: the same IEEE operations, the same bits)
            xk = h.Xr[k % h.n].tolist()
            self.r_lp = r_m - xk[BR]
            self.model_inputs.start(self.r_lp, ay_m - xk[BAY] - xk[GAY] * ay_m)
        n = h.n
        i = k % n
        self.yaw_scale_ring[i] = ysa
        predict = h.last >= h.first
        ip = (k - 1) % n if predict else i
        xp = h.Xr[ip]
        Pp = h.Pr[ip]
        steer_sw = held[I_STEER]
        steer_ok = t - held_t[I_STEER] <= tmo[I_STEER]
        delta = (steer_sw - self.steer_offset) / self.steer_ratio if steer_ok else math.nan
        xpl = xp.tolist()
        wheels_out = fdi.isolated & WHEELS
        iso = fdi.step(k, (fl, fr, rl, rr), wheels_ok, r_m, ax_m, ay_m, imu_ok, xpl,
                       Pp.item(VX, VX), self.wheels.noise2, delta,
                       0.0 if fdi.isolated & YAW_RATE else self.rdot)
        if WHEELS_RETURN_LEVEL and wheels_out and not iso & WHEELS and self.wheels.use_all and self.receivers:
            self.return_level_sd = max(self.return_level_sd, math.sqrt(max(Pp.item(VX, VX), 0.0)))
            self.return_level_k = k
        wheel_z = fdi.wheel_z
        # ay alone stale (its samples dropped: a g scale on a signal already in m/s^2 reads a 3 m/s^2
        # turn past the 30 m/s^2 range): the gyro and ax are fresh, so the step still integrates
        # them, ay substituted (r vx) as when isolated. Holding the whole IMU instead left the
        # heading unrotated through each turn, 3.7-6.8 deg off and promised again after it (the
        # demo drive). Nothing else changes: the fault detector saw imu_ok false (it judges
        # nothing on a stale sample), and what is published is held to that imu_ok.
        imu_published = imu_ok
        iso_fdi = iso
        ay_out = (not imu_ok and t - held_t[I_YAW] <= tmo[I_YAW] and t - held_t[I_AX] <= tmo[I_AX])
        self.ay_out_new = ay_out and not self.ay_out
        self.ay_out = ay_out
        if ay_out:
            imu_ok = True
            iso = iso | ACCEL_Y
        if iso & (WHEELS | ACCEL_X):  # a sensor fault the fault detector has isolated
            self.lon_scale.reset()
        else:
            # GNSS, fresh and fused, last found the wheels right: an independent witness
            # (input_consistency.py: a steady speed's failing window is then ax's bias)
            self.lon_scale.step(k, wheel_z * xpl[KW] if wheels_ok else math.nan,
                                ax_m - xpl[BAX] if imu_ok else math.nan,
                                self.gnss_agrees and t - self.gnss_checked_t <= GNSS_CHECK_FRESH_S
                                and t - self.last_gnss_fused_t <= GNSS_FRESH_S)
        if not self.wheel_scale_check.confirmed:
            self._check_wheels_without_gnss(k, fl, fr, rl, rr, wheels_ok and imu_published
                                            and not iso_fdi & (WHEELS | YAW_RATE | ACCEL_X),
                                            r_m - xpl[BR], ax_m - xpl[BAX], float(Pp[BAX, BAX]), xpl[VX])
        # ay against r vx at any speed; nothing to judge while the gyro's or ay's substitute is fused
        self.lat_scale.step(k, ay_m - xpl[BAY] - xpl[GAY] * ay_m
                            if imu_ok and not iso & (YAW_RATE | ACCEL_Y) else math.nan,
                            r_m - xpl[BR], xpl[VX], self.rdot)
        # ax and ay as mapped (not bias-corrected: a swap's error is what the biases absorb) against
        # the wheels' dv/dt and r vx, r the gyro's or, while the gyro is isolated (a swap makes the
        # fault detector blame it: ay does not turn with it), the rear wheels'; no witness while
        # the wheels are isolated. An isolated ax or ay is still judged: no single-sensor fault
        # makes ax read r vx and ay dv/dt.
        r_sw = fdi.r_wheels if iso & YAW_RATE else r_m - xpl[BR]
        # the witness leaves r vy out: a window over a slide (the filter's |vy| + 3 std, times r,
        # beyond the check's tolerance) is no evidence either way (AXIS_SWAP_SLIDE)
        rvy = abs(r_sw) * (abs(xpl[VY]) + 3.0 * math.sqrt(max(Pp.item(VY, VY), 0.0))) if AXIS_SWAP_SLIDE else 0.0
        if self.axis_swap.step(k, wheel_z * xpl[KW] if wheels_ok and not iso & WHEELS else math.nan,
                               ax_m if imu_published else math.nan, ay_m, r_sw, xpl[VX], rvy):
            log.warning("%s", self.axis_swap.message())
        # the gyro's scale against the rear wheels' and ay's yaw rates (gyro_scale_gate.py): inputs
        # as mapped (a unit error is what is judged; the bias states absorb a wrong mapping), each
        # witness only while not a known fault (a stale or isolated gyro: nothing judged, and the
        # filter does not integrate it)
        if k % GSC_EVERY == 0 and not self.gyro_gate.confirmed:
            wok = wheels_ok and not iso_fdi & WHEELS
            if self.gyro_gate.step(rl if wok else math.nan, rr if wok else math.nan,
                                   r_m - xpl[BR] if imu_published and not iso_fdi & YAW_RATE else math.nan,
                                   ay_m if not iso_fdi & ACCEL_Y else math.nan, xpl[VX], ax_m, r_m):
                log.warning("%s", self.gyro_gate.message())
        if fdi.heading_repair is not None:
            self._repair_heading(*fdi.heading_repair)
            fdi.heading_repair = None
        if fdi.bias_relearn is not None:  # the gyro returns with the bias it was isolated for
            db, var = fdi.bias_relearn
            fdi.bias_relearn = None
            xp[BR] += db
            Pp[BR, BR] += var
        # Each held IMU sample at this step's middle, as the step integrates it (input_age.py); the
        # cross-checks above compare it as sampled with the wheels, sampled alike (carried forward
        # alone, the gyro ran ahead of the wheels in a slide: mu05_outage_30s isolated it)
        age = self.input_age
        if GYRO_AGE_COMPENSATION:
            r_m = age.at_mid(0, r_m, t)
        if ACCEL_AGE_COMPENSATION:
            ax_m = age.at_mid(I_AX - I_YAW, ax_m, t)
            ay_m = age.at_mid(I_AY - I_YAW, ay_m, t)
        r_g = r_m  # the gyro and ay as measured, for the spin check (a spin makes the fault detector
        ay_g = ay_m  # isolate a good gyro: its substitute, the wheels' yaw rate, is no witness then)
        ax_g = ax_m  # (and ax, for the tyres' force the spin's grip is measured by: SPIN_GRIP)
        if iso & (YAW_RATE | ACCEL_X | ACCEL_Y):
            r_m, ax_m, ay_m = self._substitute(iso, xpl, r_m, ax_m, ay_m)
        x = h.Xr[i]
        A = h.Ar[i]
        P = h.Pr[i]
        if predict:  # predict from the previous step (x <- xp, predict, A <- F: one compiled call)
            density = self.lat_noise.density
            if density != self._vy_density:
                self._set_vy_noise(density)
            if imu_ok:
                self.model.predict_from(xp, x, Pp, P, A, r_m, ax_m, ay_m)
            else:  # hold: no rotation, no acceleration, covariance still grows
                self.model.predict_from(xp, x, Pp, P, A, xp[BR], xp[BAX], xp[BAY])
                # ... and the heading by the rotation the hold leaves out (hold_heading_step)
                e = hold_heading_step(t - held_t[I_YAW], tmo[I_YAW], r_m - xp[BR], xp[VX], self.dt)
                P[PSI, PSI] = (math.sqrt(max(P[PSI, PSI], 0.0)) + e) ** 2
            if imu_ok:
                # the coloured lateral errors the states do not hold (IMU_LEVER_STD_M, YAW_SCALE_STD)
                # vx read once as a Python float (x.item): this term and the bank walk's low-pass do
                # float arithmetic, not numpy scalar arithmetic (the same doubles; issue 10)
                vx_p = x.item(VX)
                e = IMU_LEVER_STD_M * abs(self.rdot) + self.yaw_scale_std * abs(self.r_lp * vx_p)
                P[VY, VY] = (math.sqrt(max(P.item(VY, VY), 0.0)) + e * self.dt) ** 2
                self.bank_walk.step(P, BAY, vx_p, self.r_lp)  # the road's bank moves where it curves
                # the gyro turns with the road's plane: the heading (about the vertical) at r / cos(bank)
                sb = min(abs(math.sin(self.road.bank.x.item(0))), MAX_TILT_SIN)
                # (float % is numpy's scalar remainder operation for operation: the same bits)
                x[PSI] = wrap_pi(x.item(PSI) - (r_m - x.item(BR)) * self.dt * (1.0 / math.sqrt(1.0 - sb * sb) - 1.0))
        if iso:
            self._widen(iso, P, x[VX])
        if fdi.yaw_disagreement > 0.0 and not iso & YAW_RATE:
            self._widen_unverified(P, x[VX], fdi.yaw_disagreement + fdi.yaw_catch_up / self.dt)
        if fdi.lat_excess > 0.0 and not iso & ACCEL_Y:
            self._widen_lateral(P, fdi.lat_excess)
        elif fdi.lat_unexplained > self.lat_drift_tol and not iso & ACCEL_Y:
            self._widen_lateral(P, fdi.lat_unexplained - self.lat_drift_tol, bias=False)
        xl = x.tolist()
        vx = xl[VX]
        if imu_ok:
            r = r_m - xl[BR]
            ay = ay_m - xl[BAY] - xl[GAY] * ay_m
            ax = ax_m - xl[BAX]
        else:
            r = ay = ax = 0.0
        r_lp_prev = self.r_lp
        r_lp = self.r_lp = r_lp_prev + self._lp_r * (r - r_lp_prev)
        rdot = self.rdot = self.rdot + self._lp_rdot * ((r_lp - r_lp_prev) / self.dt - self.rdot)
        kw = xl[KW]
        spin = self.spin
        if spin.step(t, vx, r_g - xl[BR], ay_g - xl[BAY] - xl[GAY] * ay_g,
                     wheel_z * kw if wheels_ok else math.nan, rl * kw, rr * kw, imu_published, delta,
                     fl * kw, fr * kw):
            if spin.fired_t == t:
                # the bias the filter has learned up to the slide (the slide's own steps may teach it wrong)
                self.spin_bias = (xl[BR], float(P[BR, BR]), t)
                log.warning("spin: sideslip %+.0f deg within ~0.5 s at r vx %.1f m/s^2: the car slides beyond its "
                            "grip; vx, sideslip and heading invalid until it grips again",
                            math.degrees(spin.dbeta), (r_g - xl[BR]) * vx)
        elif spin.released:
            self._after_spin(k)
            return self._invalid(t)
        r_c, ay_c, vy_shift = self.model_inputs.step(r_lp, r, ay, vx)
        self.turn_lp += self._lp_turn * (abs(r) - self.turn_lp)
        # the rear slip angle a driven rear axle on its friction limit takes (DRIVE_SLIP, drive_slip.py)
        drive_alpha = 0.0
        # read once for the rules below (the drive slip, the brake grip, the slip witness): the grade
        # and bank filters' offsets as Python floats, and the axles' force regressors (pure functions of
        # ay_c and rdot; nothing below changes them before the slip witness)
        ax_off = self.road.grade.x.item(1)
        ay_off = self.road.bank.x.item(1)
        # the tyres at the grip a spin has shown (SPIN_GRIP, fusion/spin_grip.py): the model is no witness
        # (the offsets' std is read by SpinGrip.step only once a spin has shown a grip: 0.0 until then,
        # two P reads and a sqrt a step less on a drive without a spin; perf48, issue 10)
        sg = self.spin_grip
        spin_limit = (SPIN_GRIP and imu_ok
                      and sg.step(spin.active, ax_g - ax_off, ay_g - ay_off,
                                  math.sqrt(max(self.road.grade.P.item(1, 1), 0.0)
                                            + max(self.road.bank.P.item(1, 1), 0.0)) if sg.grip > 0.0 else 0.0))
        if imu_ok:
            st = self.single_track
            reg_f = -st.regressor_front(1.0, ay_c, rdot)
            reg_r = -st.regressor_rear(1.0, ay_c, rdot)
        if DRIVE_SLIP and self.drive_slip.on:
            if iso & WHEELS:
                # a wheel sensor the fault detector has isolated measures no slip: its speed against
                # the other axle is its fault (a rear pair reading high is a drive at its limit to
                # the rule), and the low-pass it fed holds that fault until it is emptied
                self.drive_slip.reset()
                if DRIVE_SLIP_TYRE_FORCE:
                    self.rear_fy.reset()
            elif wheels_ok and imu_ok:
                fy_rear = reg_r
                if DRIVE_SLIP_TYRE_FORCE:  # the tyres' lateral force, bank in (tyre_lateral_force.py)
                    fy_rear = self.rear_fy.step(ay_m - ay_off, rdot,
                                                math.sqrt(max(self.road.bank.P.item(1, 1), 0.0)))
                drive_alpha = self.drive_slip.step(
                    vx, fl, fr, rl, rr, delta, ax_m - ax_off, fy_rear,
                    resistance(reg_f, delta) if DRIVE_RESISTANCE else 0.0)
        # how far the rear may slip beyond its law while braking in a corner (BRAKE_GRIP, brake_grip.py)
        brake_ratio = 1.0
        if BRAKE_GRIP and imu_ok:
            brake_ratio = self.brake_grip.step(vx, ax_m - ax_off, reg_f, reg_r)
        # the car's vy rate against the model's: a slide the steering's misfit cannot see (slide_rate.py)
        slide_var = 0.0
        if SLIDE_RATE:
            if imu_ok and not iso & (YAW_RATE | ACCEL_Y):
                vy_mod, std_mod = self.single_track.model_error(vx, r_c, ay_c, rdot)
                slide_var = self.slide_rate.step(vx, r, ay, vy_mod + vy_shift, std_mod)
            else:
                self.slide_rate.reset()
        # what the steering says the tyre law is off by, with fresh GNSS (LAW_EXCESS)
        law_var = 0.0
        oversteer = math.nan  # the steering's misfit on the oversteer side, in sigmas (FRICTION_REAR)
        if LAW_EXCESS and imu_ok and (LAW_EXCESS_IN_OUTAGE or t - self.last_gnss_fused_t <= GNSS_FRESH_S
                                      or (LAW_EXCESS_GNSS_ISOLATED and fdi.gnss_isolated)):
            if abs(rdot) <= MODEL_STEADY_RDOT:
                if FRICTION_REAR:  # both from one misfit (law_excess_var's and oversteer_sigmas')
                    law_var, oversteer = self.single_track.law_excess_and_oversteer(vx, r_c, ay_c, rdot, delta)
                else:
                    law_var = self.single_track.law_excess_var(vx, r_c, ay_c, rdot, delta)
                if drive_alpha > 0.0:  # the driven rear on its limit: the law's slip angle, not its noise
                    dv = self.single_track.drive_excess_var(vx, ay_c, rdot, drive_alpha)
                    if DRIVE_SLIP_TYRE_FORCE:  # ... and the doubt of the force it rests on (tyre_lateral_force.py)
                        dv += self.rear_fy.angle_var(vx, self.drive_slip.kappa, self.drive_slip.fx)
                    law_var = max(law_var, dv)
                # what held throughout a steady stretch of LAW_HOLD_STEADY_S (its least) is what a
                # transient keeps: a turn-in's first steps, the yaw rate not yet moving, are no slide
                self.law_var_min = min(self.law_var_min, law_var)
                self.law_steady_t = min(self.law_steady_t, t)  # a stretch begins (inf after a restart)
                if t - self.law_steady_t >= LAW_HOLD_STEADY_S:
                    self.law_var_held = self.law_var_min
                    self.law_var_min = math.inf
                    self.law_steady_t = t
            else:
                self.law_steady_t = t
                self.law_var_min = math.inf
                if LAW_EXCESS_HOLD:
                    # a transient hides the misfit (relaxation lag), it does not end a slide (LAW_EXCESS_HOLD)
                    law_var = self.law_var_held
            if FRICTION_MEMORY:
                # the rear at the limit the steering has shown the road's friction at (friction_limit.py),
                # for the gyro's scale fit only (_check_lever_arm): the pseudo-measurement keeps the
                # present misfit (held through the whole limit, slaloms on snow lost 60 points of
                # sideslip validity at 0.5 deg error; the model's bound is off while it is nonzero)
                self.friction_var = self.friction.step(t, vx, ay_c, law_var, oversteer)
            if brake_ratio > 1.0:
                # the rear braking in a corner may slip this far beyond its law; from the measured forces
                # (no steering, no relaxation lag), so in a transient too: the speed falls, the yaw rate
                # with it (drive 507: |rdot| beyond MODEL_STEADY_RDOT through the braking's second half)
                law_var = max(law_var, self.single_track.brake_excess_var(vx, ay_c, rdot, brake_ratio))
            law_var_seen = law_var  # what the steering, drive and brake rules saw (the witness's at_limit)
            if FRICTION_REAR and FRICTION_MEMORY and self.friction.rear_var > law_var:
                law_var = self.friction.rear_var  # the rear let go at the limit the front showed
            # the kinematics against the model (SLIDE_RATE), in a transient too, while the steering has shown
            # the road's friction at this |ay| (friction_limit.py): off the limit a mismatch is the bank's
            # step the accelerometer states have not followed yet (road_handling), not a slide
            if slide_var > law_var and FRICTION_MEMORY and self.friction.a_lim < math.inf:
                law_var = slide_var
            if COURSE_SLIDE:  # the courses against the gyro: the sideslip's change the model missed
                course_var = self.course_slide.excess_var(t)
                if course_var > law_var:
                    law_var = course_var
            if SLIP_RATIO_LIMIT:
                # the tyres near their limit longitudinally: the wheels' slip ratio (the witness's, as of
                # the step before) over a linear tyre's is the factor the rear's angle exceeds its law
                # by (slip_ratio_limit.py); from the wheels and ax, no steering: in a transient too
                if SLIP_RATIO_TYRE_FORCE and not iso & (YAW_RATE | ACCEL_Y):
                    # the tyres' force, the bank's share of b_ay back in (SLIP_RATIO_TYRE_FORCE)
                    fy_t = ay_c + (xl[BAY] - ay_off)
                    slip_ratio = self.slip_ratio_limit.step(vx, self.slip_witness.ratio, ax_m - ax_off, fy_t)
                    if slip_ratio > 1.0:
                        # the angle the tyres take for that force, against the law as it is fused (the
                        # kinematic ay's, or MODEL_TYRE_FORCE's), and the bank/offset split's doubt of the
                        # part of that angle the law as fused does not carry (SingleTrackFusion.split_var)
                        law_var = max(law_var, self.single_track.brake_excess_var(
                            vx, fy_t, rdot, slip_ratio, fy_t if MODEL_TYRE_FORCE else ay_c)
                            + self.single_track.split_var(vx, self.road.bank.P.item(1, 1), slip_ratio,
                                                          MODEL_TYRE_FORCE))
                else:
                    slip_ratio = self.slip_ratio_limit.step(vx, self.slip_witness.ratio, ax_m - ax_off, ay_c)
                    if slip_ratio > 1.0:
                        law_var = max(law_var, self.single_track.brake_excess_var(vx, ay_c, rdot, slip_ratio))
        else:
            self.law_var_held = 0.0
            self.law_var_min = math.inf
            self.law_steady_t = t
            self.friction_var = 0.0
            law_var_seen = law_var
        if LAW_EXCESS_BOUND:  # the excess widens the model's bound (law_excess_bound.py), it does not end it
            self.law_bound.step(t, law_var)
            law_off = False
        else:
            law_off = law_var > 0.0
        if (not imu_ok or iso & (YAW_RATE | ACCEL_Y) or abs(rdot) > MODEL_STEADY_RDOT or fdi.lat_excess > 0.0
                or fdi.lat_unexplained > self.lat_drift_tol or fdi.yaw_disagreement > 0.0 or law_off
                or (t - self.last_gnss_fused_t > GNSS_FRESH_S
                    and not self.single_track.law_holds(vx, r_c, ay_c, rdot, delta))
                or self.model_unsteady_t == math.inf or spin_limit):
            self.model_unsteady_t = t
            if LAW_EXCESS_BOUND:
                self.law_bound.reset(t, law_var)
        if self.yaw_integral is not None:
            self.yaw_integral.step(k, r)
        # forwards (its fixes are observed only then) or standing (vx ~ 0 either side): a run kept
        # through a reversal integrates ax, not d|v|/dt, below 1 m/s, and the first fix after it read
        # as a 0.2 s latency error (reversing, once vy's std no longer broke the run off at every turn)
        # The integral takes the grade's g sin(grade) for speed change; its fit's ramp holds one
        # grade (and the sensor's offset), not one that changes along the road: road_country's
        # +-5 % on 500 m (+-0.5 m/s^2) bent it until its best delay sat at the range's end (0.80 s
        # for 0.40) and let the braked wheels' long delay through as agreeing (+0.047 s). So a run
        # breaks off once road.py's grade has changed by GRADE_RUN_CHANGE since it began. Not
        # subtracted instead: that estimate follows the filter's b_ax, which takes up wheel slip
        # and latency errors on flat roads (latency_0.1: 0.142 s for 0.100 with it subtracted).
        si = self.speed_integral
        grade = self.road.grade.x.item(0)
        if si.first >= k:
            self.speed_run_grade = grade
        # vx, xl: x as it stands here (Python floats, not numpy scalar reads; step's locals are C doubles)
        si.step(k, vx, xl[VY], r, ax_m, ay, math.sqrt(max(P.item(VY, VY), 0.0)),
                imu_ok and not iso & (YAW_RATE | ACCEL_X | ACCEL_Y) and vx > -0.1
                and G * abs(grade - self.speed_run_grade) <= GRADE_RUN_CHANGE)
        wheels = self.wheels
        # b_ax's variance as a Python float (P.item), read once for the slip witness and the
        # standstill test (nothing between them changes P; issue 10: float arithmetic in both)
        p_bax = P.item(BAX, BAX)
        # the slip the wheels show against the integrated ax (wheel_slip.py), beside the linear law's
        v_wheels = (wheels.as_vx(wheel_z, xl[KW], xl[VY], r, delta if steer_ok else 0.0)
                    if wheels_ok and imu_ok and not iso & (WHEELS | ACCEL_X) else math.nan)
        wheels_locked = WHEEL_LOCK_SKIP and self.wheel_lock.step(v_wheels, ax_m, xl[BAX], p_bax, r * xl[VY],
                                                                 ax_m - ax_off)
        seen = self.slip_witness.step(
            v_wheels,
            ax_m, xl[BAX], p_bax, r * xl[VY],
            # the tyres' force: the specific force less the sensor's offsets (road.py's split); and
            # whether the steering says a tyre has left its law (then a small force is no release)
            # (not this rule's own widening: it rests on the slip the witness holds, and holding it for
            # that would latch both for good, SLIP_RATIO_LIMIT)
            ax_m - ax_off, ay_m - ay_off, law_var_seen > 0.0)
        self.slip_hold = max(wheels.slip_bound(vx, ax), seen, self.slip_hold * self._slip_decay)
        if SLIP_SPLIT:  # wheels slow under braking: the fixes' speed excess goes to vy (slip_heading.py)
            self.brake_slip_hold = max(max(wheels.slip_bound(vx, ax), seen) if ax < 0.0 else 0.0,
                                       self.brake_slip_hold * self._slip_decay)
        if STEERED_WHEEL_VY:
            sv = (steered_wheel_vx.vx_error_bound(wheels.frac, vx, r, delta, self.wheelbase,
                                                  self.mass_lf * ay - self.yaw_inertia * rdot,
                                                  not (ISOLATED_GYRO_PLOUGH and iso & YAW_RATE))
                  if wheels_ok and steer_ok and not iso & WHEELS and not self.sideslip_vouched else 0.0)
            self.steer_vy_hold = max(sv, self.steer_vy_hold * self._slip_decay)
        if AWD_LIMIT_SLIP and wheels.use_all:  # no free axle: the drive slip at the tyres' limit (awd_limit_slip.py)
            aw = (awd_limit_slip.slip_bound(vx, ax_m - ax_off, resistance(reg_f, delta if steer_ok else 0.0))
                  if wheels_ok and imu_ok and not iso & WHEELS and law_var_seen > 0.0 else 0.0)
            self.awd_slip_hold = max(aw, self.awd_slip_hold * self._slip_decay)
        if GNSS_SPEED_GAP:  # the filter's antenna speed against the last fix's bound (gnss_speed_gap.py)
            fus0 = self.receivers[0]
            self.speed_gap.step(vx - r * fus0.lever_y, xl[VY] + r * fus0.lever_x, math.hypot(ax_m, ay_m),
                                self.dt, self.sideslip_vouched)

        # --- aiding sources at this step -------------------------------------------------
        status = 0
        wheels_max = max(abs(fl), abs(fr), abs(rl), abs(rr)) if wheels_ok else math.inf
        if (self.standstill.detect(wheels_max, ax, p_bax) and imu_ok and not iso & (YAW_RATE | ACCEL_X | ACCEL_Y)
                and fdi.standstill_plausible(vx, self._fresh_gnss_speed(t))):
            status |= STATUS_STANDSTILL
            self.standstill.fuse(x, P, r_m, ax_m, ay_m, A, held_t[I_YAW])  # the gyro sample's stamp
            r = r_m - x[BR]
        else:
            if wheels_ok and self.wheel_new and not iso & WHEELS and not wheels_locked:
                # slip seen beyond the witness's own errors is the wheels' error, not vx's: widened by it
                if wheels.fuse(x, P, wheel_z, delta if steer_ok else 0.0, r, ax, A,
                               fdi.wheel_z_excess_var + self.slip_witness.excess ** 2):
                    self.wheel_reject_t = math.inf
                elif self._wheels_diverged(t):
                    self._reset(k)
                    return self._invalid(t)
            if imu_ok and k % MODEL_EVERY == 0 and not spin_limit:
                # with an IMU signal isolated the model still holds vy, from its substitute (the
                # wheels' yaw rate, ay = r vx), widened for it: vy has no other anchor then
                fy_c = ay_c
                fy_var = 0.0
                if MODEL_TYRE_FORCE and not iso & (YAW_RATE | ACCEL_Y):
                    # the tyres' force: the bank's share of b_ay back in, the offset's doubt with it
                    fy_c = ay_c + (xl[BAY] - ay_off)
                    fy_var = self.single_track.force_var(vx, self.road.bank.P.item(1, 1))
                if self.single_track.fuse(x, P, r_c, fy_c, rdot, A, MODEL_EVERY,
                                          SUBSTITUTE_MODEL_VAR_SCALE if iso & (YAW_RATE | ACCEL_Y) else 1.0,
                                          vy_shift, law_var + fy_var):
                    self.model_t = t
                    self.model_ay = fy_c
                    self.model_fy_var = fy_var
            if (steer_ok and imu_ok and not iso and abs(r) < STEER_LEARN_MAX_R
                    and self.steer_learner.observe(steer_sw, r, vx, ay, math.sqrt(max(P[BR, BR], 0.0)))):
                self.steer_offset = self.steer_learner.offset
        self.wheel_new = False
        if self.mag_new:
            self.mag_new = False
            if self.mag is not None and imu_ok and not iso & (YAW_RATE | ACCEL_X | ACCEL_Y):
                self._on_mag(t, x, P, A, ay_m)
        frozen = fdi.frozen
        if frozen:
            for j, v in frozen.items():
                x[j] = v
        if ay_out:  # ay's bias and gain have nothing to be learned from while its substitute is fused
            x[BAY] = xpl[BAY]
            x[GAY] = xpl[GAY]
        xl = x.tolist()
        for j, lo, hi in self.learned_bounds:  # clamp_learned, on the list and the row together
            v = xl[j]
            if v < lo:
                x[j] = xl[j] = lo
            elif v > hi:
                x[j] = xl[j] = hi
        road_ok = imu_ok and not iso & (ACCEL_X | ACCEL_Y)
        # every step: the road's grade and bank move on while the accelerometers cannot be heard (walks only)
        # the state from xl (clamped with x above: the same values, as Python floats instead of
        # numpy scalar reads; road.step only adds, multiplies and divides by nonzero constants)
        # and P's road variances as Python floats (P.item: float arithmetic in the road filters;
        # issue 10), g_ay's read once for both calls
        p_gay = P.item(GAY, GAY)
        self.road.step(k, xl[BAX], P.item(BAX, BAX), xl[BAY], P.item(BAY, BAY), xl[GAY], xl[VX],
                       self.bank_walk.total, p_gay, road_ok)
        if road_ok:
            if self.road.roll_gyro_params is None:
                self.road.set_roll(ay_m, xl[GAY], p_gay, abs(self.fdi.e_a) * xl[VX])
            else:
                self.road.set_roll_gyro(ay_m, xl[GAY], p_gay, abs(self.fdi.e_a) * xl[VX],
                                        held[I_ROLL] if t - held_t[I_ROLL] <= tmo[I_ROLL] else math.nan, r)
        aux = h.auxr[i]  # element by element: a slice assignment from a tuple builds an array first
        aux[0] = r
        aux[1] = ay
        aux[2] = rdot
        aux[3] = wheel_z
        aux[4] = delta
        aux[5] = ax
        if GNSS_SPEED_GAP:  # aux's ax and ay as _on_gnss's loop summed them (gnss_speed_gap.py)
            self.gap_terms[i] = gnss_speed_gap.term(ax, ay, self.dt)
        h.last = k
        for cons in self.considers:
            if cons.var:  # never a state yet (no dual-antenna heading): C is zero and stays so
                cons.step(i, ip, A, predict)
        if self.lat_sens is not None:
            self.lat_sens.step(i, ip, A, predict)
        self.scale_sens.step(i, ip, A, predict, r)
        kalman.symmetrize(P)  # exactly symmetric at every step (what is stored, published, rewound)
        pd = P.diagonal().tolist()
        if not (math.isfinite(sum(xl)) and pd[VX] < 1e4 and pd[VY] < 1e4 and pd[PSI] >= 0):
            self._reset(k)
            return self._invalid(t)
        # (P.item: the vx-vy covariance as a Python float; _estimate's sideslip variance in floats)
        if BANK_LAG_STD:  # b_ay's lag behind a changing bank, in vy (bank_lag.py); not while ay is out
            # (b_ay frozen, ay not integrated) nor the gyro (the residual then measures its fault)
            self.bank_lag_var = (0.0 if iso & (ACCEL_Y | YAW_RATE) else
                                 bank_lag.vy_var(self.fdi.e_as, self.fdi.rdot_abs, xl[VX],
                                                 P.item(VY, BAY), pd[BAY]))
        return self._estimate(t, xl, pd, P.item(VX, VY), r, status | iso_fdi, imu_published, wheels_ok, iso)

    def _on_mag(self, t: float, x, P, A, ay_m: float) -> None:
        """The magnetometer's sample (all three axes of one frame) at this step: tilt-compensated
        heading, disturbance check, offset learning while GNSS backs the heading, then fusion."""
        held, held_t = self.held, self.held_t
        tm = held_t[I_MX]
        if not (held_t[I_MY] == tm and held_t[I_MZ] == tm):  # axes from different frames
            return
        mag = self.mag
        roll, pitch = mag.tilt_angles(x[BAX], x[BAY], x[GAY], ay_m)
        psi_mag = mag.measure(tm, held[I_MX], held[I_MY], held[I_MZ], roll, pitch)
        if not mag.undisturbed(tm):
            mag.rejected += 1
            return
        filter_tilt = math.sqrt(max(P[BAY, BAY], 0.0)) / G
        slow = mag.slow_var(filter_tilt)
        if (self.aligned and t - self.last_gnss_fused_t <= GNSS_FRESH_S and x[VX] > MAG_LEARN_SPEED
                and P[PSI, PSI] < MAG_LEARN_STD ** 2):
            mag.learn_offset(tm, psi_mag, x[PSI], P[PSI, PSI], slow)
        if not (self.aligned and mag.offset_known(tm)):
            mag.state = MAG_LEARNING
            mag.last_reason = "offset not learned yet (needs a GNSS heading)"
            return
        mag.fuse(tm, x, P, A, psi_mag, slow, t - self.last_gnss_fused_t > HEADING_FRESH_S
                 and t - self.last_heading_fused_t > HEADING_FRESH_S)

    def _substitute(self, iso: int, x, r_m: float, ax_m: float, ay_m: float) -> tuple[float, float, float]:
        """Stand-ins for isolated IMU signals (as raw readings): yaw rate from the rear wheels,
        ax from d(wheel speed)/dt, ay from r * vx; zero rate / acceleration when none is left."""
        fdi = self.fdi
        if iso & YAW_RATE:
            r_m = (fdi.r_wheels if math.isfinite(fdi.r_wheels) else 0.0) + x[BR]
        if iso & ACCEL_X:
            ax_m = (0.0 if iso & WHEELS else fdi.ax_wheels) + x[BAX]
        if iso & ACCEL_Y:
            ay_m = (r_m - x[BR]) * x[VX] + x[BAY]
        return r_m, ax_m, ay_m

    def _repair_heading(self, onset: int, corrections: list) -> None:
        """Take the drift a faulty gyro put into the heading before it was isolated out of the
        stored steps from ``onset`` on (the next step predicts from the last of them)."""
        h = self.hist
        X = h.X
        for j, c in enumerate(corrections, onset):
            if h.oldest() <= j <= h.last:
                i = h.slot(j)
                X[i, PSI] = (X[i, PSI] + c) % (2.0 * math.pi)

    def _widen(self, iso: int, P: np.ndarray, vx: float) -> None:
        """Covariance for the states a substitute (or nothing) now drives; a step on isolation
        (the fault acted before it was caught), a random walk while it lasts."""
        new = self.fdi.new_isolation | (ACCEL_Y if self.ay_out_new else 0)
        dt = self.dt
        if iso & (ACCEL_X | WHEELS):
            # the random walk only while ax is substituted: with the wheels out and a trusted
            # accelerometer, vx is dead reckoning at its own noise between GNSS fixes (a wide vx
            # std here also let wheels 2 m/s off pass the return test, fault_wheels_offset)
            P[VX, VX] += (1.0 if new & (ACCEL_X | WHEELS) else 0.0) + (ISO_ACCEL_NOISE ** 2 * dt
                                                                      if iso & ACCEL_X else 0.0)
        if iso & (YAW_RATE | ACCEL_Y):
            # vy integrates ay - r vx: a substituted ay errs by up to ISO_ACCEL_NOISE, a substituted
            # yaw rate by ISO_YAW_RATE_NOISE times the speed
            if iso & ACCEL_Y and not iso & YAW_RATE:
                # the substitute r vx leaves out only dvy/dt, which the model bounds from the
                # gyro's yaw acceleration: a straight does not widen vy as a lane change does
                q = ISO_LATERAL_FLOOR ** 2 + self.single_track.substitute_vy_rate(vx, self.rdot) ** 2
            else:
                q = ISO_ACCEL_NOISE ** 2 if iso & ACCEL_Y else (ISO_YAW_RATE_NOISE * vx) ** 2
            P[VY, VY] += (0.25 if new & (YAW_RATE | ACCEL_Y) else 0.0) + q * dt
        if iso & YAW_RATE:
            P[PSI, PSI] += (ISO_HEADING_STEP ** 2 if new & YAW_RATE else 0.0) + ISO_YAW_RATE_NOISE ** 2 * dt
            # ... and linearly by what the fault detector says the substitute may be off
            # (FaultDetector.substitute_yaw_error): a bias integrates into the heading, so its std
            # must carry it when the gyro returns and the flag with it (random seed 21: 7.9 deg off
            # at a std of 1.45 deg, valid at the return)
            e = self.fdi.substitute_yaw_error * dt
            if e > 0.0:
                P[PSI, PSI] = (math.sqrt(max(P[PSI, PSI], 0.0)) + e) ** 2

    def _widen_unverified(self, P: np.ndarray, vx: float, e: float) -> None:
        """While the gyro disagrees by ``e`` (rad/s) with a witness and the vote is not clear, the
        heading and vy it drives may drift by e and e * vx per second: a bias, so the stds grow
        linearly (not as a random walk), and stay grown until GNSS brings them back."""
        dt = self.dt
        for j, rate in ((PSI, e), (VY, e * abs(vx))):
            P[j, j] = (math.sqrt(max(P[j, j], 0.0)) + rate * dt) ** 2

    def _set_vy_noise(self, density: float) -> None:
        """vy's process noise from the measured accelerometer noise density (lateral_noise.py);
        the lateral cross-check's drift tolerance is that noise over its window."""
        self._vy_density = density
        q = density * density * self.dt
        self.model.q[VY] = q
        self.model.Qd[VY, VY] = q
        self.lat_drift_tol = density / math.sqrt(LAT_WINDOW_S)

    def _widen_lateral(self, P: np.ndarray, e: float, bias: bool = True) -> None:
        """ay disagrees with r * vx and the model's vy by ``e`` (m/s^2) more than bank, roll and
        model errors explain: vy may be drifting that fast unseen (an ay offset, a steep bank), a
        bias, so its std grows linearly until GNSS brings it back; the ay bias may move too."""
        dt = self.dt
        P[VY, VY] = (math.sqrt(max(P[VY, VY], 0.0)) + e * dt) ** 2
        if bias:
            P[BAY, BAY] += (e * dt) ** 2 / LAT_BIAS_STEPS

    def _model_vy(self, vx: float, r: float, ay: float, rdot: float) -> float:
        """The single-track model's vy (the lateral cross-check's third voter)."""
        return self.single_track.model_vy(vx, r, ay, rdot)

    def _fresh_gnss_speed(self, t: float) -> float:
        return self.last_gnss_speed if t - self.last_gnss_fused_t <= GNSS_FRESH_S else math.nan

    def _wheels_diverged(self, t: float) -> bool:
        """A run of wheel rejections: re-initialise from the wheels unless GNSS says they lie.

        The wheels are four independent sensors, the filter's vx an integral of one
        accelerometer; when they disagree for long the filter is the likelier culprit, except
        when the latest GNSS speed check sided against the wheels (all wheels stuck or zero).
        """
        self.wheel_reject_t = min(self.wheel_reject_t, t)
        if t - self.wheel_reject_t < WHEEL_DIVERGED_S:
            return False
        gnss_recent = t - self.gnss_checked_t <= GNSS_CHECK_FRESH_S
        return self.gnss_agrees or not gnss_recent

    def _gnss_conflict(self, t: float) -> bool:
        """GNSS has been rejected as inconsistent for longer than a glitch lasts, and still is
        (its fixes keep coming): see ``GNSS_CONFLICT_S``."""
        return (t - self.gnss_conflict_t > GNSS_CONFLICT_S
                and t - self.gnss_conflict_last_t <= GNSS_CHECK_FRESH_S)

    def _invalid(self, t: float) -> Estimate:
        """No filter yet (or just reset): finite, neutral values, every validity bit false.

        Finite on purpose: a downstream tool that averages a column must not be poisoned by a NaN
        from the first step before the IMU's first frame; the validity bits say "do not use".
        """
        self.sideslip_vouched = False  # (GNSS_SPEED_GAP)
        self.velocity_vouched = False  # (GNSS_READMIT_CHECK)
        status = STATUS_INPUT_STALE
        if self._reset_flag:
            status |= STATUS_RESET
            self._reset_flag = False
        L = self._learned0
        big = 1e3
        return Estimate(t, 0.0, math.pi, 0.0, math.pi, 0.0, 0.0, big, big, 0.0,
                        L.get("yaw_rate_bias_radps", 0.0), 1.0, L.get("accel_x_bias_mps2", 0.0), big,
                        L.get("accel_y_bias_mps2", 0.0), big,
                        self.latency.delay_s, L.get("wheel_scale", 1.0), self.steer_offset,
                        self.single_track.cornering_stiffness_front,
                        self.single_track.cornering_stiffness_rear, False, False, False, False, status,
                        *self.gnss_counts())

    def _estimate(self, t, x, pd, p_vxvy, r, status, imu_ok, wheels_ok, iso) -> Estimate:
        """x: state as a list, pd: covariance diagonal as a list (Python floats are cheaper)."""
        sqrt = math.sqrt
        vx = x[VX]
        vy = x[VY]
        sp2 = vx * vx + vy * vy
        if sp2 > 0.25:
            beta = math.atan2(vy, vx)
            var_b = (vx * vx * pd[VY] - 2.0 * vx * vy * float(p_vxvy) + vy * vy * pd[VX]) / (sp2 * sp2)
            beta_std = math.sqrt(var_b) if var_b > 0 else 0.0
        else:
            beta = 0.0
            beta_std = math.pi
        vy_std = math.sqrt(pd[VY]) if pd[VY] > 0.0 else 0.0
        if BANK_LAG_STD and self.bank_lag_var > 0.0 and sp2 > 0.25:  # (bank_lag.py): vy's share only
            lag_var = self.bank_lag_var
            var_b += vx * vx * lag_var / (sp2 * sp2)
            beta_std = math.sqrt(var_b) if var_b > 0 else 0.0
            vy_std = math.sqrt(pd[VY] + lag_var)
        if SIDESLIP_SCALE_SENS and sp2 > 0.25:  # the heading's scale term, the sideslip's share (SIDESLIP_SCALE_SENS)
            # the fit's scale not applied yet; not the gyro gate's unconfirmed-gyro scale (a flipped
            # sign's 100 %): the gate withholds the sideslip of an exercised, unconfirmed gyro itself
            # (GyroScaleGate.sideslip_ok)
            sc = self.yaw_scale_heading
            e = sc * self.scale_sens.sideslip(self.hist.last, vx, vy)
            if e > 0.0:
                var_b += e * e
                beta_std = math.sqrt(var_b)
                vy_std = math.hypot(vy_std, sc * self.scale_sens.vy(self.hist.last))
        if SIDESLIP_LATENCY_SENS and sp2 > 0.25 and self.lat_sens is not None and not self.augmented:
            # the heading's latency term, the sideslip's share (SIDESLIP_LATENCY_SENS)
            sd = self._latency_std()
            e = sd * self.lat_sens.sideslip(self.hist.last, vx, vy)
            if e > 0.0:
                var_b += e * e
                beta_std = math.sqrt(var_b)
                vy_std = math.hypot(vy_std, sd * self.lat_sens.vy(self.hist.last))
        if beta_std >= SIDESLIP_STD_VALID and sp2 > 0.25 and MODEL_BOUND:
            b = self._model_bound(t, vx, vy, r, iso)
            if b < vy_std:
                c = b / vy_std  # same correlation with vx, smaller vy std
                var_b = (vx * vx * b * b - 2.0 * vx * vy * float(p_vxvy) * c + vy * vy * pd[VX]) / (sp2 * sp2)
                beta_std = math.sqrt(var_b) if var_b > 0 else 0.0
                vy_std = b
        gnss_fresh = t - self.last_gnss_fused_t <= GNSS_FRESH_S
        if gnss_fresh:
            status |= STATUS_GNSS_FRESH
        if abs(r) > 0.17:  # 10 deg/s: the two-GPS / kinematic observability rule of 000/003
            status |= STATUS_KINEMATIC_OBSERVABLE
        else:
            status |= STATUS_MODEL_FALLBACK
        if not (imu_ok and wheels_ok):
            status |= STATUS_INPUT_STALE
        if self.aligned:
            status |= STATUS_HEADING_ALIGNED
        if self.last_gnss_rejected:
            status |= STATUS_GNSS_REJECTED
        if t - self.last_heading_fused_t <= GNSS_FRESH_S:
            status |= STATUS_GNSS_HEADING
        if self._reset_flag:
            status |= STATUS_RESET
            self._reset_flag = False
        # the five stds published (of the eight: issue 10), each as the list comprehension had it
        sd_vx = sqrt(pd[VX]) if pd[VX] > 0.0 else 0.0
        sd_psi = sqrt(pd[PSI]) if pd[PSI] > 0.0 else 0.0
        sd_br = sqrt(pd[BR]) if pd[BR] > 0.0 else 0.0
        sd_bax = sqrt(pd[BAX]) if pd[BAX] > 0.0 else 0.0
        sd_bay = sqrt(pd[BAY]) if pd[BAY] > 0.0 else 0.0
        # A latency error dd turns every GNSS velocity by r * dd while turning: a bias, not noise,
        # so the filter averages it into the heading however many fixes it fuses. Its size is
        # published on top of the filter's own heading std (a 0.2 s error at 38 deg/s is 7.6 deg).
        # The heading is GNSS course less sideslip, so it is never better than the course's own
        # error floor either (multipath; sideslip model errors that last a whole corner): a
        # filter that has fused hundreds of fixes believes 0.09 deg where Revs shows 0.3. A
        # dual-antenna heading fused in the last seconds measures the heading itself: no floor.
        hd = self.heading
        floor = 0.0 if (hd.fused and hd.last is not None and t - hd.last.t < HEADING_FRESH_S
                        and hd.consecutive_rejects == 0) else COURSE_FLOOR_RAD
        mag = self.mag
        if mag is not None:
            if t - mag.last_fused_t <= GNSS_FRESH_S:
                status |= STATUS_MAGNETOMETER
            # The magnetometer holds the heading (fused since GNSS went stale): its slow error is a
            # bias the filter cannot average away (module docstring of fusion/magnetometer.py), and
            # the heading keeps it after the magnetometer stops (a disturbance, the gyro alone in a
            # corner) until GNSS courses have corrected it: the first HEADING_FRESH_S of GNSS after
            # an outage the magnetometer bridged. (Before, a 5 s low-pass of |r| x latency std
            # happened to cover that: 1.2-1.4 deg off against 0.40 in mag_outage_30s's corner without it.)
            if floor and ((t - self.last_gnss_fused_t > HEADING_FRESH_S and mag.last_fused_t > self.last_gnss_fused_t)
                          or (self.mag_bridged and t - self.gnss_run_t < HEADING_FRESH_S)):
                floor = math.sqrt(COURSE_FLOOR_RAD ** 2 + mag.last_slow_var)
        # with the latency error a state, what the filter still does not know of it (its variance)
        # turns the heading the same way on every fix, so it stays in the published std
        # (without it, one receiver: what the filter's heading still carries of that error, tracked
        # through its own gains, latency_sensitivity.py, instead of a low-pass of |r|)
        if self.augmented:
            turn = self.turn_lp * math.sqrt(self.considers[0].var)
        elif self.lat_sens is not None:
            turn = self.lat_sens.heading(self.hist.last) * self._latency_std()
        else:
            turn = self.turn_lp * self._latency_std()
        # After a course alignment P holds that course's latency error too (it must: later fixes
        # and the model correct the heading by it), the same error as this term: published once,
        # as the larger of the two. P's part shrinks as fixes shrink P (its share at alignment).
        turn_var = turn * turn
        if self.align_lat_var > 0.0:
            turn_var = max(turn_var - self.align_lat_var * min(1.0, pd[PSI] / self.align_psi_var), 0.0)
        if self.lever_flagged:  # a wrong antenna lever arm turns the course by |dx| r / vx
            for chk in self.lever_checks:
                e = chk.heading_std(t)
                turn_var += e * e
        # A yaw-rate scale error turns the heading by scale x r until GNSS courses correct it: as
        # the latency error's, for TURN_MEMORY_S after a turn (yaw_scale_check.py; published, not
        # grown in P: grown there with vy along the direction course cannot see, the single-track
        # model's errors reached the heading through the correlation, Revs heading RMS 0.153 -> 0.33)
        e = self.yaw_scale_std * self.turn_lp * TURN_MEMORY_S
        # What the heading still carries of a scale error, d psi / d s tracked through the filter's
        # own gains (scale_sensitivity.py: in a long corner about the rotation since the heading was
        # last constrained, on a straight falling as its courses take the heading back), times the
        # scale over both priors not yet applied to the gyro and the state (_shift_for_scale,
        # YawScaleCheck.heading_scale)
        # (while the gyro gate has not confirmed the gyro, its scale error may be a flipped sign's:
        # GyroScaleGate.heading_scale_sd, the larger of the two)
        if HEADING_SLOW_TURN_FORGOTTEN:  # a forgiven slow turn: the wheels' measured scale (slow_turn_heading.py)
            gsd = self.gyro_gate.heading_scale_sd_counted()
        else:
            gsd = self.gyro_gate.heading_scale_sd()
        e = max(e, max(self.yaw_scale_heading, gsd) * self.scale_sens.heading(self.hist.last))
        # and the slow turns an unconfirmed gyro and the rear wheels disagreed on (GyroScaleGate.heading_std)
        e = max(e, self.gyro_gate.heading_std())
        psi_std = math.sqrt(sd_psi ** 2 + turn_var + floor * floor + e * e)  # not floor ** 2: road.pxd
        # Wheel slip under braking: a bias over the whole manoeuvre that the wheel updates pass
        # into vx; published as a uniform bias up to its bound (std = bound / sqrt 3).
        slip_std = self.slip_hold / math.sqrt(3.0)
        beta_held = beta_std  # the sideslip std that says whether the fixes hold the heading
        if SLIP_SPLIT and floor and sp2 > 0.25 and self.brake_slip_hold / math.sqrt(3.0) > sd_vx:
            room = abs(vy - self.single_track.model_vy(vx, r, self.model_ay, self.rdot))  # the fixes' departure
            e = slip_heading.split_sideslip_error(self.brake_slip_hold, vx, vy, room) / math.sqrt(3.0)
            if e > 0.0:
                var_b += e * e
                beta_std = math.sqrt(var_b)
                vy_std = math.hypot(vy_std, e * sp2 / abs(vx))
        if SLIP_HEADING and floor:  # wheel slip in vx split into the sideslip and heading (slip_heading.py)
            if slip_heading.heading_floor(slip_std, sd_vx, beta_held, sd_psi) > 0.0:
                psi_std = max(psi_std, beta_std)
            if WHEEL_BIAS_HEADING:  # every wheel bias vx's std carries and P does not, turning it fix by fix
                bias_std = math.hypot(math.hypot(slip_std, self.steer_vy_hold if STEERED_WHEEL_VY else 0.0),
                                      self.awd_slip_hold / math.sqrt(3.0) if AWD_LIMIT_SLIP else 0.0)
                if bias_std > sd_vx:
                    if t - self.wheel_bias_t > TURN_MEMORY_S:
                        self.fix_turn = 0.0  # a new bias: its turn starts now
                    self.wheel_bias_t = t
                if t - self.wheel_bias_t <= TURN_MEMORY_S:
                    psi_std = max(psi_std, min(beta_std, abs(self.fix_turn)))
        if COURSE_SLIDE_HEADING and COURSE_SLIDE:  # the model shown off by the courses (course_slide.py)
            if self.course_slide.excess_var(t) > 0.0:
                self.course_slide_psi = max(self.course_slide_psi, beta_std)
                self.course_slide_psi_t = t
            elif t - self.course_slide_psi_t > TURN_MEMORY_S:
                self.course_slide_psi = 0.0
            psi_std = max(psi_std, self.course_slide_psi)
        if (MODEL_BIAS_FLOOR and gnss_fresh and floor and sp2 > 0.25 and len(self.receivers) == 1
                and (MODEL_BIAS_FLOOR_VALID_HEADING or psi_std >= HEADING_STD_VALID)):
            b = self._model_bias_floor(t, vx, r, sp2, psi_std)
            if b > beta_std:  # the model's bias counted once, with the heading (MODEL_BIAS_FLOOR)
                beta_std = b
                vy_std = max(vy_std, b * sp2 / abs(vx))
        vx_std = math.hypot(sd_vx, slip_std)
        # the scale error GNSS shows the wheels' to have (WheelScaleSeed.gap), times the raw wheel
        # speed that vx follows: nonzero while the state cannot (yet) learn it
        vx_std = math.hypot(vx_std, self.wheel_scale_seed.gap * vx / x[KW])
        if STEERED_WHEEL_VY:  # a vy the model missed, through the steered wheels (steered_wheel_vx.py)
            vx_std = math.hypot(vx_std, self.steer_vy_hold)
        if AWD_LIMIT_SLIP:  # an AWD's drive slip at its tyres' limit, a uniform bias (awd_limit_slip.py)
            vx_std = math.hypot(vx_std, self.awd_slip_hold / math.sqrt(3.0))
        if WHEELS_RETURN_LEVEL and self.return_level_sd:  # an AWD's returned wheels, level unchecked
            vx_std = math.hypot(vx_std, self.return_level_sd)
        if GNSS_SPEED_GAP:  # GNSS speed shows the velocity this far off (gnss_speed_gap.py)
            vx_std = max(vx_std, self.speed_gap.gap)
        if STANDSTILL_CREEP_STD and status & STATUS_STANDSTILL:  # "every wheel 0": |v| below their floor
            vx_std = max(vx_std, WHEEL_PULSE_FLOOR_MPS / 3.0)
        # a re-seeded scale not yet checked across speeds: what an offset seen as that scale would
        # make vx wrong by here (WheelScaleSeed.offset_bound: a missing DBC offset looks like a tyre)
        vx_std = math.hypot(vx_std, self.wheel_scale_seed.offset_bound(vx))
        if self.lever_flagged:  # a wrong antenna lever arm y moves the GNSS speed by |dy| r
            for chy in self.lever_y_checks:
                vx_std = math.hypot(vx_std, chy.vx_std(t))
        wsc = self.wheel_scale_check
        if not wsc.confirmed:  # no fix has checked the wheels' scale yet (WheelScaleCheck)
            vx_std = math.hypot(vx_std, WSC_UNCHECKED_REL * vx)
        elif wsc.witness_rel > 0.0 and not self.wheel_scale_seed.measured:
            # confirmed without GNSS (a launch, the gyro): a tyre-size error is still possible, by
            # as much as that witness saw and its precision; the first fix above 2 m/s measures it
            vx_std = math.hypot(vx_std, wsc.witness_rel * vx)
        # valid only from sources that agree: wheels fused with no run of rejections, or fresh
        # GNSS (with the wheels out, vx is dead reckoning from ax between GNSS fixes)
        wheels_trusted = wheels_ok and not iso & WHEELS and self.wheel_reject_t == math.inf
        # with the gyro isolated, sideslip rests on the wheels' yaw rate and the model: promised
        # only while ay vouches for that substitute and the wheels are trusted (its std says how well);
        # with ay isolated, on the gyro (ay = r vx) and the model: promised while the wheels vouch
        # for the gyro (the isolated ay's own yaw check still fails) and the std allows
        fdi = self.fdi
        if iso & YAW_RATE:
            imu_trusted = not iso & ACCEL_Y and wheels_trusted and fdi.witnesses_agree
        elif iso & ACCEL_Y:
            imu_trusted = wheels_trusted and fdi.wheels_vouch_gyro
        else:
            imu_trusted = not fdi.yaw_suspect
        gnss_vx = gnss_fresh
        if GNSS_VX_NEEDS_SIDESLIP and gnss_fresh and not wheels_trusted:  # vx = speed x cos(sideslip)
            gnss_vx = (imu_trusted and beta_std < SIDESLIP_STD_VALID) or sp2 <= VX_STD_VALID * VX_STD_VALID
        # a sliding / spinning car (spin_check.py): no source measures vx, vy or the heading's
        # kinematics then, so velocity, sideslip (through vel_valid) and heading are not promised
        spinning = self.spin.active
        vel_valid = (imu_ok and not spinning and (wheels_trusted or gnss_vx)
                     and (iso & (WHEELS | ACCEL_X)) != WHEELS | ACCEL_X
                     and not self._gnss_conflict(t) and not self.lon_scale.failing and not wsc.wrong
                     and not self.wheel_scale_seed.offset_found
                     and not self.axis_swap.swapped and self.gyro_gate.motion_ok())
        st = self.single_track
        rx_ok = True  # every receiver's last fix fused (a loop: no generator object per step)
        for f in self.receivers:
            if f.consecutive_rejects != 0:
                rx_ok = False
                break
        gg = self.gyro_gate
        if HEADING_SLOW_TURN_FORGOTTEN:  # the same forgetting for the heading (slow_turn_heading.py)
            gyro_psi_ok = gg.heading_ok_forgetting()
        else:
            gyro_psi_ok = gg.heading_ok()
        if SLOW_TURN_FORGOTTEN:  # a slow turn the rear wheels counted alike, forgotten in time (slow_exercise.py)
            gyro_ss_ok = gg.sideslip_ok_forgetting()
        else:
            gyro_ss_ok = gg.sideslip_ok()
        ss_valid = (vel_valid and imu_trusted and vx > MIN_SPEED_SIDESLIP and beta_std < SIDESLIP_STD_VALID
                    and not self.lat_scale.failing and wsc.confirmed
                    and (iso & YAW_RATE != 0 or gyro_ss_ok)
                    and not (GNSS_READMIT_CHECK and self.readmit.pending))
        self.sideslip_vouched = ss_valid
        self.velocity_vouched = vel_valid
        return _new_estimate(Estimate, (
            t, beta, beta_std, x[PSI], psi_std, vx, vy, vx_std, vy_std,
            r, x[BR], sd_br, x[BAX], sd_bax, x[BAY], sd_bay, self._published_delay(), x[KW],
            self.steer_offset, st.cornering_stiffness_front, st.cornering_stiffness_rear,
            ss_valid,
            imu_ok and not spinning and not iso & YAW_RATE and self.aligned and psi_std < HEADING_STD_VALID
            and not self.axis_swap.swapped and gyro_psi_ok
            and rx_ok and self.heading.consecutive_rejects < 2
            and (mag is None or mag.consecutive_rejects < 2),
            vel_valid and vx_std <= VX_STD_VALID,  # promised only what the frame can carry
            imu_ok and not iso & (YAW_RATE | ACCEL_X | ACCEL_Y) and sd_br < BIAS_STD_VALID,
            status, *self.gnss_counts(), *self._road(imu_ok, iso)))

    def _model_bound(self, t: float, vx: float, vy: float, r: float, iso: int) -> float:
        """The vy std the single-track model vouches for (``MODEL_BOUND``), inf when it does not."""
        if t - self.model_t > (MODEL_EVERY + 0.5) * self.dt or t - self.model_unsteady_t < MODEL_STEADY_S:
            return math.inf
        if MODEL_BOUND_GRIP_SHOWN and (self.model_ay / MODEL_G) ** 2 > self.single_track.rear.n2_shown:
            return math.inf  # beyond the grip the drive has shown the law at (MODEL_BOUND_GRIP_SHOWN)
        vy_m, s_m = self.single_track.model_error(vx, r, self.model_ay, self.rdot)
        if MODEL_TYRE_FORCE and self.model_fy_var > 0.0:  # the bank/offset split's doubt (MODEL_TYRE_FORCE)
            s_m = math.hypot(s_m, math.sqrt(self.model_fy_var))
        if LAW_EXCESS_BOUND:  # the tyre law's excess since the model was last unsteady (law_excess_bound.py)
            s_m = s_m + self.law_bound.std()
        # a Python float (vy_m is a numpy scalar): it may become the published vy std, a float in
        # both the compiled _estimate (a C double, core.pxd) and the plain-Python one
        return float(s_m + abs(vy - vy_m) / 3.0)

    def _model_bias_floor(self, t: float, vx: float, r: float, sp2: float, psi_std: float) -> float:
        """The least sideslip std (rad) the filter may claim while the single-track model is vy's
        sole witness (``MODEL_BIAS_FLOOR``: one antenna, no fresh dual-antenna heading, GNSS fresh),
        0 while the model is not being fused. One antenna measures course = heading + sideslip, so
        besides the model only the heading tells the sideslip: the two combined, the model's bias
        counted once (``SingleTrackFusion.bias_std``, widened by the tyre law's excess as the
        model's bound is) and the heading by its published std (its latency, scale and course
        floors are what the filter's P leaves out). Why not P's heading: in a long corner P's
        heading learned from course minus the model's sideslip, the same bias over again."""
        if t - self.model_t > (MODEL_EVERY + 0.5) * self.dt or not psi_std > 0.0:
            return 0.0
        if MODEL_BIAS_FLOOR_BEYOND_LEARNED and not abs(self.model_ay) > LEARNED_MAX_N * MODEL_G:
            return 0.0
        s = self.single_track.bias_std(vx, r, self.model_ay, self.rdot)
        if MODEL_TYRE_FORCE and self.model_fy_var > 0.0:  # the bank/offset split's doubt: a bias too
            s = math.hypot(s, math.sqrt(self.model_fy_var))
        if LAW_EXCESS_BOUND:
            s = math.hypot(s, self.law_bound.std())
        sb = s * abs(vx) / sp2  # as a sideslip angle
        if not sb > 0.0:
            return 0.0
        return 1.0 / math.sqrt(1.0 / (sb * sb) + 1.0 / (psi_std * psi_std))

    def _published_delay(self) -> float:
        """The primary receiver's latency: ``latency.py``'s, plus the filter's estimate of its
        error while that is a state (a fresh dual-antenna heading: course against baseline heading
        times the yaw rate measures it, ``latency_consider.py``), which is the better informed."""
        return self.latency.delay_s + (self.considers[0].d if self.augmented else 0.0)

    def _road(self, imu_ok: bool, iso: int) -> tuple:
        """The road / roll fields of an Estimate: values, stds and validity (road.py)."""
        rd = self.road
        g, b = rd.grade, rd.bank
        lat_ok = imu_ok and not iso & ACCEL_Y
        # each channel's std once (RoadAttitude.valid's test inline: it read the std again)
        b_std = b.std
        g_std = g.std
        # the angles as Python floats by ndarray.item (the same doubles as float() of a numpy scalar,
        # without the scalar object; perf48)
        return (b.x.item(0), b_std, g.x.item(0), g_std, float(rd.roll), rd.roll_std,
                lat_ok and b.updates > 0 and b_std < ANGLE_STD_VALID,
                imu_ok and not iso & ACCEL_X and g.updates > 0 and g_std < ANGLE_STD_VALID,
                # roll is ay through a gain: not promised while ay's yaw-rate witnesses disagree
                lat_ok and not self.fdi.yaw_suspect and rd.roll_std < ANGLE_STD_VALID)

    def gnss_counts(self) -> tuple[int, int, int]:
        """GNSS velocity samples fused, rejected and late, over every receiver."""
        if len(self.receivers) == 1:  # every step: no generators for the usual single receiver
            f = self.receivers[0]
            return f.fused, f.rejected, f.late
        fused = rejected = late = 0  # a loop, not sum() of generators: cpdef in core.pxd (no closures)
        for f in self.receivers:
            fused += f.fused
            rejected += f.rejected
            late += f.late
        return fused, rejected, late

    def _latency_std(self) -> float:
        """The largest latency uncertainty of the velocity receivers (the heading error it causes
        while turning is a bias, whichever receiver it comes from); a fixed delay its monitor named
        wrong counts with the receiver's range (``timing_trust.timing_std``)."""
        vel = self._velocity_latencies
        if len(vel) == 1:
            return timing_std(vel[0])
        m = timing_std(vel[0])  # max() as a loop (cpdef in core.pxd: no generator); max keeps the first of equals
        for lat in vel[1:]:
            v = timing_std(lat)
            if v > m:
                m = v
        return m

    def _vy_seen_by_data(self, k: int, vx: float, ay: float, rdot: float) -> bool:
        """Whether this fix's vy is the data's rather than the model's (LEARN_EXCITE_FIXES)."""
        phi = self.single_track.regressor_rear(vx, ay, rdot)
        hist = self.learn_phi
        hist.append(phi)
        if k * self.dt - self.last_heading_fused_t <= GNSS_FRESH_S:
            return True
        return len(hist) == hist.maxlen and max(hist) - min(hist) >= LEARN_EXCITE_REL * abs(phi)

    def _consider(self, rx: int, lat: LatencyEstimator) -> LatencyConsider | None:
        """Receiver rx's latency-error state, synchronised with its latency estimate (None without
        delay compensation: then the error is the whole latency, not a small unknown)."""
        cons = self.considers[rx]
        hd = self.heading
        if (not self.delay_compensation or not hd.fused or hd.last is None or hd.last.source != rx
                or self.hist.last * self.dt - self.last_heading_fused_t > HEADING_FRESH_S
                or (cons.var == 0.0 and lat.std_s > AUGMENT_MAX_STD_S)):
            return None
        cons.sync(self.hist, lat.delay_s, lat.std_s)
        return cons

    # ----------------------------------------------------------------------------------------
    def _on_gnss(self, g: GnssSample, k: int) -> None:
        """Fuse a GNSS sample received just before step k (history holds steps up to k-1), with
        the lever arm and latency of the receiver it came from."""
        h = self.hist
        if not self.initialized or h.last < h.first or g.source >= len(self.receivers) \
                or not self.uses_velocity[g.source]:
            return
        fus = self.receivers[g.source]
        lat = self.latencies[g.source]
        if not fus.usable(g):
            fus.rejected += 1
            self.last_gnss_rejected = True
            if fus.last_reason == IMPLAUSIBLE:
                self.fdi.gnss_implausible()
            return
        speed = g.speed_mps  # NaN course: speed only (GnssSample.course_known)
        delay = lat.delay_s if self.delay_compensation else 0.0
        k_tv = round((g.t - delay) / self.dt)
        if k_tv < h.first:  # measured before the filter started: see BEFORE_START
            fus.late += 1
            return
        s, late = h.clamp_step(k_tv)
        self.fix_steps[g.source] = (g.fix_time_utc_s, s)
        js = h.slot(s)
        agree = self._gnss_agrees_with_wheels(s, speed)
        if GNSS_SPEED_GAP:  # the speed the fix allows, widened by the acceleration since (gnss_speed_gap.py)
            # each step's term as _step stored it beside aux (gap_terms), summed in step order as
            # the loop over aux rows summed them (spread_from_rows): the same bits, no numpy reads
            self.speed_gap.fix(speed, gnss_speed_gap.spread_since(self.gap_terms, s, h.last, h.n))
        if not self.fdi.isolated & WHEELS:  # a wheel-speed unit error (input_consistency.WheelScaleCheck)
            wsc = self.wheel_scale_check
            # (ndarray.item: Python floats, so the check's ratio is float arithmetic; issue 10)
            if wsc.observe(h.aux.item(js, AUX_WHEEL) * h.X.item(js, KW), speed, h.aux.item(js, AUX_AX)):
                log.warning("%s", wsc.message())
            self._observe_wheel_scale(s, js, speed, fus)
        tol = GNSS_WHEEL_TOL_MPS + GNSS_WHEEL_TOL_REL * speed
        was_isolated = self.fdi.gnss_isolated  # (GNSS_READMIT_CHECK)
        verdict = self.fdi.check_gnss(
            s, agree if math.isfinite(h.aux[js, AUX_WHEEL]) else None,
            abs(speed - h.X[js, VX]) <= max(tol, 5.0 * math.sqrt(max(h.P[js][VX, VX], 0.0))))
        if GNSS_READMIT_CHECK and was_isolated and not self.fdi.gnss_isolated:
            self.readmit.released(self.velocity_vouched)  # back: checked against what? (gnss_readmit.py)
        if verdict is False or self.fdi.gnss_isolated:  # never fused, never learned from
            t_k = k * self.dt
            self.gnss_conflict_t = min(self.gnss_conflict_t, t_k)
            self.gnss_conflict_last_t = t_k
            fus.rejected += 1
            fus.last_reason = "inconsistent with the wheels / IMU"
            self.last_gnss_rejected = True
            return
        agree = agree and not self.fdi.isolated & WHEELS
        # the step the sample was received at, not the one it is applied at: live, a sample read
        # late is applied at a later step, and that lateness is not the receiver's latency
        k_rx = min(k, step_of(g.t, self.dt))
        # what every timing reference's residual shares: this fix's own speed noise (latency.information_share)
        lat.gnss_var = fus.sigma(g) ** 2
        if not self.fdi.isolated & WHEELS:  # the identification regresses GNSS on the wheels
            lat.observe(k_rx, speed, h, (fus.lever_x, fus.lever_y), self.wheels)
        if h.X[h.slot(h.last), VX] > 0:
            self.speed_integral.observe(g.source, k_rx, speed, self.speed_latencies[g.source], (fus.lever_x, fus.lever_y))
        if late:
            fus.late += 1
        if self.aligned and fus.consecutive_rejects >= MAX_CONSECUTIVE_REJECTS and agree \
                and self.wheels.consecutive_rejects == 0 and g.course_known \
                and k * self.dt - self.last_heading_fused_t > GNSS_FRESH_S:  # a baseline outranks a course
            # GNSS and the wheels agree with each other and not with the filter: its heading
            # (or vy) has diverged. Drop the heading and align again from this fix's course.
            # A GNSS that disagrees with the wheels stays rejected instead (a glitch).
            self.aligned = False
            self.realignments += 1
        if g.course_known and speed >= ALIGN_SPEED:
            self.course_heading = (s, *self._course_heading(s, g, fus, lat))
        if g.course_known:
            self._check_lever_arm(g, s, fus, lat)
        if COURSE_SLIDE and g.source == 0:
            self._check_course_slide(g, s, k, fus, lat)
        self._check_lever_arm_y(g, s, fus, lat)
        if not self.aligned or not g.course_known:  # heading unknown, or no course: |v| only
            D, a_t = self._along_timing(s, g, lat)
            ok = agree and fus.fuse_speed(h, s, g, delay_std_s=timing_std(lat), along_std_s=D, along_accel=a_t)
            if not agree:
                fus.rejected += 1
                fus.last_reason = "speed disagrees with the wheels"
            if ok and g.course_known and align_speed_ok(speed, h.X[h.slot(s), VX]):
                self._align(s, g, fus, lat)
        else:
            cons = self._consider(g.source, lat)
            sens = self.lat_sens
            P_pre = h.P[js].copy()
            # along the track, a latency the data have not identified is off by as much as a
            # receiver's can be, not by the prior's claim (timing_trust.py: the wheel scale)
            D, a_t = self._along_timing(s, g, lat)
            ok = fus.fuse(h, s, g, delay_std_s=timing_std(lat), consider=cons, along_std_s=D, along_accel=a_t)
            if ok:
                self.scale_sens.fused(h, s, P_pre, fus._H2, fus._R2)
            if ok and sens is not None:
                self._sensitivity_fused(sens, s, P_pre, fus, g)
            if g.source == 0:
                self.augmented = cons is not None
            if ok and not self.fdi.isolated:
                i = h.slot(s)
                # the stored row and state as Python floats (tolist, item): the model's learning
                # below in float arithmetic, not numpy scalar arithmetic (issue 10; the same doubles)
                a = h.aux[i].tolist()
                xs = h.X[i].tolist()
                # the law is learned on the force it is used with (MODEL_TYRE_FORCE: the tyres', the
                # bank's share of b_ay back in; learned on the kinematic ay, the law was fitted to the
                # other force and the model missed by the share)
                fy_shift = xs[BAY] - self.road.bank.x.item(1) if MODEL_TYRE_FORCE else 0.0
                fy_s = a[AUX_AY] + fy_shift
                self.single_track.adapt_from(xs[VX], xs[VY], h.P.item(i, VY, VY), a[AUX_R], fy_s,
                                             a[AUX_RDOT], a[AUX_DELTA],
                                             self._vy_seen_by_data(k, xs[VX], fy_s, a[AUX_RDOT]))
                # The first velocity receiver's samples only: the regression considers one latency (a
                # state every estimate moves with, S per second of it), and each receiver has its own
                # clock. Fed by two (two_rx_slalom: 0.33 s and 0.39 s identified), every other fix
                # moved the estimate by S x 0.06 s and back: k_r 16 % (lat13) or 31 % (main) off.
                if g.source == self.stiffness_source:
                    self.stiffness.observe(h, s, fus.course(g), speed, fus.sigma(g), fus.lever_x, lat.delay_s,
                                           lat.std_s, self.steer_offset / self.steer_ratio, self.yaw_scale_std,
                                           fy_shift)
                if self.delay_compensation:  # the regression is only right where samples sit at their time
                    self.single_track.take_drive_estimate(self.stiffness.model_parameters())
        self.last_gnss_rejected = not ok
        if ok:
            if GNSS_READMIT_CHECK:  # a fix checked against a vouched velocity ends the wait
                self.readmit.fused(self.velocity_vouched)
            self.gnss_conflict_t = math.inf
            if k * self.dt - self.last_gnss_fused_t > HEADING_FRESH_S:  # GNSS back after a gap
                self.mag_bridged = (self.mag is not None and self.last_gnss_fused_t > -math.inf
                                    and self.mag.last_fused_t > self.last_gnss_fused_t)
                self.gnss_run_t = k * self.dt
            self.last_gnss_fused_t = k * self.dt
            self.last_gnss_speed = speed
            if not self.fdi.isolated & ACCEL_X:
                self.road.fuse_vertical(g.vel_d_mps, speed, fus.sigma(g))
                # an altitude (NMEA GGA): grade from the climb over the distance travelled
                self.road.fuse_altitude(g, speed, h.X[h.slot(h.last), VX] > 0)

    def _observe_wheel_scale(self, s: int, js: int, speed: float, fus: GnssVelocityFusion) -> None:
        """Feed the fix to the wheel-scale average (input_consistency.WheelScaleSeed); when it finds
        the scale beyond where the state may learn, re-seed the state once at the fix's step and
        carry it to the present: x[KW] to the average, vx with it (vx follows the raw wheel speed
        times the scale), the variance along that direction the average's, the bounds re-centred."""
        h = self.hist
        a = h.aux[js]
        x = h.X[js]
        b = self.learned_bounds
        bounds = next((lo, hi) for j, lo, hi in b if j == KW)
        # the stored step's scale as the present holds it: a late fix's update may leave a stored
        # step beyond the bounds that every new step clamps to
        kw = min(max(float(x[KW]), bounds[0]), bounds[1])
        seed = self.wheel_scale_seed
        raw = float(a[AUX_WHEEL])
        refuted = seed.offset_found
        seeded = seed.observe(s * self.dt, raw, speed, float(x[VY]), float(a[AUX_R]), float(a[AUX_AX]),
                              fus.lever_x, fus.lever_y, kw, float(h.P[js][KW, KW]), bounds)
        if self.return_level_sd and s >= self.return_level_k and seed.gap_t == s * self.dt:
            self.return_level_sd = 0.0  # a fix since the return compared the wheels' level (WHEELS_RETURN_LEVEL)
        if seed.offset_found and not refuted:  # the fixes across speeds show an offset, not a scale
            log.warning("%s", seed.offset_message())
        if not seeded:
            return
        m = seed.scale
        dx = np.zeros(NX)
        dx[KW] = m - kw
        dx[VX] = raw * (m - kw)
        u = np.zeros(NX)
        u[KW] = seed.std
        u[VX] = raw * seed.std
        self._set_wheel_scale_bounds(recentred_bounds(m))
        if h.correct(s, dx, -np.outer(u, u)):
            seed.gap = 0.0
            log.warning("%s", seed.message())
        else:  # not positive definite: leave the state, keep the published gap
            self._set_wheel_scale_bounds(bounds)
            seed.seeded = False
            seed.v_seed = math.nan

    def _set_wheel_scale_bounds(self, bounds: tuple[float, float]) -> None:
        self.learned_bounds = tuple((j, *(bounds if j == KW else (lo, hi))) for j, lo, hi in self.learned_bounds)

    def _yaw_sum_since(self, k_last: int, s: int, ring=None):
        """The sum of the stored bias-corrected yaw rates of steps k_last+1 .. s (each divided by its
        applied 1 - scale if ``ring`` is the applied scales' ring), the gyro turn a course check
        integrates between two fixes (None if there is no previous fix or the history no longer
        holds it). One ``lever_arm_check.yaw_sum`` call: np.sum's bits."""
        h = self.hist
        k0 = k_last + 1
        if k_last >= 0 and h.oldest() <= k0 <= s:
            return lever_arm_check.yaw_sum(h.aux, AUX_R, k0, s, ring)
        return None

    def _check_lever_arm(self, g: GnssSample, s: int, fus: GnssVelocityFusion, lat: LatencyEstimator) -> None:
        """Feed this fix's course to its receiver's lever-arm check (lever_arm_check.py) with the
        gyro's yaw rates since that receiver's previous fix; one log line when it finds the lever arm wrong."""
        h = self.hist
        chk = self.lever_checks[g.source]
        i = h.slot(s)
        x = h.X[i]
        was = chk.flagged
        chk.observe(s * self.dt, s, self.dt, self._yaw_sum_since(chk.k_last, s), fus.course(g), fus.sigma(g),
                    g.speed_mps, float(x[VX]), float(x[VY]), float(h.aux[i, AUX_R]), fus.lever_y, lat.std_s,
                    lat.delay_s if self.delay_compensation else 0.0)
        ysc = self.yaw_scale_checks[g.source]
        if self.fdi.isolated & YAW_RATE:  # a substituted yaw rate says nothing of the gyro's scale
            ysc.restart()
        else:
            # the raw gyro (each step / its applied 1 - scale): no feedback loop
            r_sum = self._yaw_sum_since(ysc.k_last, s, self.yaw_scale_ring)
            # the sideslip it reads the course against is the single-track model's, not the
            # filter's: the filter's vy takes part of a scale error (the fit saw a third of it)
            a = h.aux[i]
            vx_s = float(x[VX])
            vy_m, vy_m_std = self.single_track.model_error(vx_s, float(a[AUX_R]), float(a[AUX_AY]), float(a[AUX_RDOT]))
            if LAW_EXCESS:
                # at a tyre's limit the model's vy is off beyond its own law (law_excess_var, the
                # steering's misfit): a course read against it there is the sideslip's change, not the
                # gyro's scale (random drive 35: a plough on mu 0.42 fitted 0.9 %, applied, the heading
                # moved 1.9 deg and was promised to 0.7 deg while 2-3.6 deg off)
                ex = self.single_track.law_excess_var(vx_s, float(a[AUX_R]), float(a[AUX_AY]), float(a[AUX_RDOT]),
                                                      float(a[AUX_DELTA]))
                if FRICTION_MEMORY:  # the rear at the road's limit (friction_limit.py): held at the present step
                    ex = max(ex, self.friction_var)
                if ex > 0.0:
                    vy_m_std = math.sqrt(vy_m_std * vy_m_std + ex)
            ysc.observe(s * self.dt, s, self.dt, r_sum, fus.course(g), fus.sigma(g), g.speed_mps,
                        vx_s, vy_m, float(a[AUX_R]), fus.lever_y, lat.std_s,
                        math.sqrt(max(h.P[i][BR, BR], 0.0)), vy_m_std,
                        lat.delay_s if self.delay_compensation else 0.0)
            e = ysc.take_change()
            if e:  # the gyro's scale changed (yaw_scale_check.py): what it turned wrong is in the state
                self._widen_for_scale_change(s, e, vx_s)
            was_applied = self.yaw_scale_applied
            self._set_yaw_scale()
            if self.yaw_scale_applied != was_applied:  # (back to none too: a shift once more on
                # re-application would count the first one twice)
                self._shift_for_scale(self.yaw_scale_applied - was_applied)
            if self.yaw_scale_applied:
                self.yaw_scale_realigned = True
                self._set_yaw_scale()
        if chk.suspected:
            self.lever_flagged = True
        if chk.flagged and not was:
            log.warning("GNSS receiver %d: courses against the gyro say the configured antenna lever arm x = %.2f m "
                        "is %.2f m (+- %.2f) off, or the latency (%.2f s) is far off: heading not promised in corners",
                        g.source, fus.lever_x, chk.dx, chk.dx_std, lat.delay_s)

    def _check_course_slide(self, g: GnssSample, s: int, k: int, fus: GnssVelocityFusion,
                            lat: LatencyEstimator) -> None:
        """Feed this fix's course, the gyro's turn since the previous one and the model's sideslip at
        its time of validity to the course-slide check (fusion/course_slide.py, COURSE_SLIDE)."""
        cs = self.course_slide
        k_last = self.course_slide_k
        if not g.course_known or self.fdi.isolated & YAW_RATE or s <= k_last:
            cs.reset()
            self.course_slide_k = s
            return
        h = self.hist
        y = self._yaw_sum_since(k_last, s)
        self.course_slide_k = s
        i = h.slot(s)
        xs = h.X[i].tolist()
        a = h.aux[i].tolist()
        vx = xs[VX]
        if not vx > 0.0:
            cs.reset()
            return
        r = a[AUX_R]
        vy_m, std_m = self.single_track.model_error(vx, r, a[AUX_AY], a[AUX_RDOT])
        beta_m = math.atan2(vy_m + r * fus.lever_x, vx - r * fus.lever_y)
        speed = g.speed_mps
        lat_std = lat.std_s
        r_lo = r_hi = r
        if COURSE_SLIDE_TIMING:
            # the course is from the true instant, anywhere the latency may put it: within 3 of its
            # std as far as the data vouch for it (timing_trust), never outside the receiver's range
            lat_std = along_track_std(lat)
            n = int(math.ceil(3.0 * lat_std / self.dt))
            a0 = max(s - n, k - 1 - lat.max_steps, h.oldest())
            b0 = min(s + n, h.last)
            if a0 < b0:
                rr = h.aux[np.arange(a0, b0 + 1) % h.n, AUX_R]
                r_lo = min(r, float(rr.min()))
                r_hi = max(r, float(rr.max()))
        scale_sd = self.yaw_scale_std
        s_br = None
        if COURSE_SLIDE_SCALE_SENS:
            # the scale not applied yet, over both priors (the heading std's), and what of it the
            # bias state took as of this fix (course_slide.py: the two signed together)
            scale_sd = self.yaw_scale_heading
            s_br = float(self.scale_sens.S[i, BR])
        cs.observe(s * self.dt, fus.course(g), fus.sigma(g) / max(speed, 0.1),
                   None if y is None else float(y) * self.dt, (s - k_last) * self.dt, xs[BR],
                   math.sqrt(max(h.P.item(i, BR, BR), 0.0)), beta_m, std_m / vx, r, vx, speed, lat_std,
                   scale_sd, k * self.dt, r_lo, r_hi, s_br)

    def _widen_for_scale_change(self, s: int, e: float, vx: float) -> None:
        """A detected scale change left a heading error of about e (rad, the fit's residual) in
        heading and vy together: a yaw-rate error moves psi by -d dt and vy by -d vx dt, the
        direction a steady corner's course cannot see. Grown once along it at the fix's step (and
        carried to the present); later courses and the single-track model take it out again."""
        u = np.zeros(NX)
        u[PSI] = e
        u[VY] = e * vx
        self.hist.correct(s, np.zeros(NX), -np.outer(u, u))
        self.yaw_scale_changes += 1
        log.warning("gyro: courses say the yaw-rate scale changed (heading %.2f deg off): relearning it",
                    math.degrees(e))

    def _shift_for_scale(self, da: float) -> None:
        """The applied scale changed by da (r = r_m (1 - applied)): from now on the gyro is
        integrated with it, and what the old one turned wrong is in every stored state. That part
        is linear in the scale (scale_sensitivity.py: x_err = -S s, S through the filter's own
        gains), so each stored step moves by S_k da: the state is what it would be had the new
        scale been applied all along, to first order. Not the fit's heading: early in a drive that
        heading is the narrow prior's (a 3 % gyro fitted 0.76 +- 0.25 % 7 s after a flying start's
        corner), and the offset the fit draws with the shrunk scale put it 1.8 deg off while it
        claimed 0.44 (flying_6 x1.03: the realignment moved the heading from 0.84 to 1.56 deg off
        and published 0.44-0.6). What is left, -S (s - applied), stays on the heading std
        (``_set_yaw_scale``: the scale's residual over both priors times |S_psi|)."""
        h = self.hist
        idx = np.arange(h.oldest(), h.last + 1) % h.n
        X = h.X[idx]
        X += self.scale_sens.S[idx] * da
        X[:, PSI] %= 2.0 * math.pi
        h.X[idx] = X
        log.info("gyro: scale %.2f %% applied, the state moved by %.2f deg of heading (the scale's share of it)",
                 100.0 * self.yaw_scale_applied, math.degrees(float(self.scale_sens.S[h.last % h.n, PSI]) * da))

    def _set_yaw_scale(self) -> None:
        """The receiver whose fit knows the scale best sets what is applied to the gyro and the
        residual term vy's and the heading's std grow by (yaw_scale_check.py)."""
        best = min(self.yaw_scale_checks, key=lambda c: c.scale_sd)
        self.yaw_scale_applied = best.applied()
        if not self.yaw_scale_applied:
            self.yaw_scale_realigned = False
        # Until the state is realigned to the fit's heading (_realign_to_scale_fit) the whole
        # |s_hat| + std: what the scale put into heading and vy before it was applied stays in the
        # state until courses and the model have separated it (narrowed to the residual without the
        # realignment, the 3 % cases were 50 % within 3 sigma). Realigned, that is gone and what is
        # left is the residual: the fit's std and what it reads low (YAW_SCALE_FIT_LOW).
        self.yaw_scale_std = best.scale_std(self.yaw_scale_applied * (1.0 - YAW_SCALE_FIT_LOW)
                                            if self.yaw_scale_realigned else 0.0)
        # the heading's term: S_psi times the scale not yet applied to the gyro and the state
        # (_shift_for_scale), over both priors (the applied scale may be the narrow prior's,
        # shrunk). Not less YAW_SCALE_FIT_LOW: S_psi grows with the whole rotation on a circle, where
        # the fit reads its scale to ~0.1 % (suite circle -3 %: -3.05 of -3.09 % at 30 s); a quarter
        # of the scale times that rotation held the heading invalid at 0.1 deg off (95 -> 25 % valid)
        self.yaw_scale_heading = best.heading_scale(self.yaw_scale_applied if self.yaw_scale_realigned else 0.0)

    def _check_lever_arm_y(self, g: GnssSample, s: int, fus: GnssVelocityFusion, lat: LatencyEstimator) -> None:
        """Feed this fix's speed to its receiver's lever-arm y check (against the wheels)."""
        h = self.hist
        i = h.slot(s)
        x = h.X[i]
        if self.fdi.isolated & WHEELS or not x[VX] > 0.0:
            return
        a = h.aux[i]
        chk = self.lever_y_checks[g.source]
        was = chk.flagged
        chk.observe(s * self.dt, g.speed_mps, fus.sigma(g), float(a[AUX_WHEEL]), float(x[VY]), float(a[AUX_R]),
                    float(a[AUX_AX]), lat.std_s)
        if chk.suspected:
            self.lever_flagged = True
        if chk.flagged and not was:
            log.warning("GNSS receiver %d: configured antenna lever arm y = %.2f m disagrees with the speeds "
                        "against the wheels by %.2f m (+- %.2f): speed not promised to its std in corners",
                        g.source, fus.lever_y, chk.dy, chk.dy_std)

    def _on_heading(self, g: GnssHeadingSample, k: int) -> None:
        """Fuse a dual-antenna heading received just before step k, at its time of validity (the
        receiver's latency: the same as its velocity's); set the heading when the filter has
        none, or when a run of rejections says the filter's heading, not the baseline, is wrong."""
        fus = self.heading
        h = self.hist
        if not self.initialized or h.last < h.first:
            return
        if not fus.usable(g):
            fus.rejected += 1
            return
        rx = min(g.source, len(self.latencies) - 1)
        lat = self.latencies[rx]
        if self.yaw_integral is not None and g.source < len(self.uses_velocity) and not self.uses_velocity[g.source]:
            self.yaw_integral.pair(g.source, k, fus.vehicle_heading(g), lat)
        delay = lat.delay_s if self.delay_compensation else 0.0
        same = self.fix_steps.get(g.source)
        if same is not None and abs(g.fix_time_utc_s - same[0]) < SAME_EPOCH_S:  # NaN: not dated
            s, _ = h.clamp_step(same[1])  # the velocity fix of its epoch: the same time of validity
            stagger = 0.0
        else:  # received a few ms after its epoch's velocity: its own receive time
            k_tv = round((g.t - delay) / self.dt)
            if k_tv < h.first:  # measured before the filter started: see BEFORE_START
                fus.late += 1
                return
            s, _ = h.clamp_step(k_tv)
            stagger = STAGGER_S
        if self.road.baselines and not self.fdi.isolated & ACCEL_Y:  # the baseline's tilt: road.py
            self.road.fuse_elevation(s, g)
        std = lat.std_s
        if self.aligned and fus.consecutive_rejects + 1 >= REALIGN_REJECTS and self._course_confirms(s, g):
            self.realignments += 1
            self.aligned = False
        sens = self.lat_sens
        if self.aligned:
            P_pre = h.P[h.slot(s)].copy()
            if not fus.fuse(h, s, g, std, self._consider(rx, lat), stagger):
                return
            self.scale_sens.fused(h, s, P_pre, fus._H, fus._R)
            if sens is not None:  # the heading reads psi + r d (gnss_heading.py)
                sens.fused(h, s, P_pre, fus._H, fus._R, np.array((h.aux[h.slot(s), AUX_R],)))
        else:
            fus.align(h, s, g, std, self.model.Qd[PSI, PSI])
            self.align_lat_var = 0.0  # a baseline heading has no latency error
            for cons in self.considers:
                cons.zero_heading(h)
            if sens is not None:
                sens.zero_heading(h)
            self.scale_sens.zero_heading(h)
            self.gyro_gate.heading_set()
            self.aligned = True
            for f in self.receivers:
                f.consecutive_rejects = 0
        self.last_heading_fused_t = k * self.dt

    def _sensitivity_fused(self, sens: LatencySensitivity, s: int, P_pre: np.ndarray,
                           fus: GnssVelocityFusion, g: GnssSample) -> None:
        """A velocity fix fused at stored step s: what a latency error d does to it is the
        antenna's acceleration across the track times -d (v(t_s - d) = v - a d; along the track
        the speed is what latency.py identifies the latency from, as in latency_consider.py)."""
        h = self.hist
        i = h.slot(s)
        a = h.aux[i].tolist()  # Python floats: the acceleration below in float arithmetic (issue 10)
        an, ae = antenna_acceleration_ned(h.X.item(i, PSI), a[AUX_AX], a[AUX_AY], a[AUX_R], a[AUX_RDOT],
                                          fus.lever_x, fus.lever_y)
        vn, ve = g.vel_n_mps, g.vel_e_mps  # the track's direction: this fix's
        sp = math.hypot(vn, ve)
        u0, u1 = (vn / sp, ve / sp) if sp > 0.5 else (1.0, 0.0)
        across = u1 * an - u0 * ae
        # the secant over the instants the fix may be from (``timing_secant``), not the tangent
        # (the velocity change integrated from the stored accelerations: the stored velocities
        # step where earlier fixes corrected them, which is no motion)
        lo, hi, span = self._timing_window(s, g, self.latencies[g.source])
        rows = timing_window.rows(h.n, lo, hi)
        c, sn = np.cos(h.X[rows, PSI]), np.sin(h.X[rows, PSI])
        across = latency_sensitivity.across_secant(h.aux[rows], c, sn, u0, u1, fus.lever_x, fus.lever_y,
                                                   self.dt, s - lo, span, across)
        sens.fused(h, s, P_pre, fus._H2, fus._R2, np.array((-across * u1, across * u0)))

    def _course_heading(self, s: int, g: GnssSample, fus: GnssVelocityFusion,
                        lat: LatencyEstimator) -> tuple[float, float]:
        """The heading a GNSS course implies at stored step s (course + the antenna's sideslip, as
        in :meth:`_align`) and its variance (the course's, the timing's, the sideslip's)."""
        h = self.hist
        i = h.slot(s)
        # the stored state, covariance and yaw rate as Python floats (ndarray.item): float
        # arithmetic, the same IEEE operations on the same doubles (issue 10)
        X = h.X
        P = h.P
        r = h.aux.item(i, AUX_R)
        vax = X.item(i, VX) - r * fus.lever_y
        vay = X.item(i, VY) + r * fus.lever_x
        sp2 = max(vax * vax + vay * vay, 1.0)
        jx, jy = -vay / sp2, vax / sp2
        var_beta = jx * jx * P.item(i, VX, VX) + 2.0 * jx * jy * P.item(i, VX, VY) + jy * jy * P.item(i, VY, VY)
        var = ((fus.sigma(g) / g.speed_mps) ** 2 + (r * lat.std_s) ** 2 + COURSE_FLOOR_RAD ** 2
               + max(var_beta, 0.0))
        return (fus.course(g) + math.atan2(vay, vax)) % (2.0 * math.pi), var

    def _course_confirms(self, s: int, g: GnssHeadingSample) -> bool:
        """Does a recent GNSS course (moving) agree with this baseline heading at step s? Only then
        may a run of baseline rejections re-set the filter's heading: at standstill, or against
        the course, the baseline (a wrong carrier fix) is the likelier culprit, and the heading
        stays invalid while they disagree."""
        c = self.course_heading
        h = self.hist
        if c is None or not h.oldest() <= c[0] <= h.last or abs(s - c[0]) * self.dt > GNSS_FRESH_S:
            return False
        cs, psi_c, var = c
        psi_c += h.X[h.slot(s), PSI] - h.X[h.slot(cs), PSI]  # turned between the two instants
        diff = abs(wrap_pi(self.heading.vehicle_heading(g) - psi_c))
        return diff <= 3.0 * math.sqrt(var + self.heading.sigma(g) ** 2) + COURSE_CONFIRM_RAD

    def _timing_window(self, s: int, g: GnssSample, lat: LatencyEstimator) -> tuple[int, int, float]:
        """The stored steps lo..hi a fix fused at step s may truly be from, and the span of 3
        latency sigmas (``timing_secant``): s +- that span, and while an estimated latency is still
        at its prior (``timing_trust.at_prior``: a configured delay is the user's guess) anywhere
        from max_delay_s before the fix's reception to the reception (never after it;
        ``timing_window.steps``)."""
        h = self.hist
        k_rx = step_of(g.t, self.dt)
        span = 3.0 * lat.std_s
        n = int(math.ceil(span / self.dt))
        lo, hi = timing_window.steps(h.oldest(), h.last, s, k_rx, n, lat.max_steps if at_prior(lat) else None)
        return lo, hi, span

    def _along_timing(self, s: int, g: GnssSample, lat: LatencyEstimator) -> tuple[float, float | None]:
        """(std, acceleration) of a speed fix's along-track timing term (``timing_trust.py``):
        latency.py's std and the stored ax once the latency is identified (None: as before);
        before, the wider std and the secant of the speed (integrated stored ax) over every
        instant the fix may be from, max_delay_s before its reception to the reception. The
        tangent at the fused step is not enough: at the end of an acceleration a fix read 0.7 s
        late still carries the acceleration's speed change where the stored ax is already 0, and
        those fixes took the wheel scale 2 % off in one second (dlc_lat08)."""
        D = along_track_std(lat)
        if D == lat.std_s:
            return D, None
        h = self.hist
        # the receiver's whole range (n = 0: nothing about s beyond it), every lag counted in full
        lo, hi = timing_window.steps(h.oldest(), h.last, s, step_of(g.t, self.dt), 0, lat.max_steps)
        return D, timing_window.secant(h.aux, h.n, AUX_AX, lo, hi, s, self.dt, (hi - lo + 1) * self.dt,
                                       float(h.aux[h.slot(s), AUX_AX]))

    def _course_timing_slope(self, s: int, g: GnssSample, lat: LatencyEstimator, r: float) -> float:
        """d psi / d d of a heading aligned from the course fused at stored step s: the heading's
        turn (the gyro's) between s and the course's possible true instants, as a secant."""
        lo, hi, span = self._timing_window(s, g, lat)
        return timing_window.secant(self.hist.aux, self.hist.n, AUX_R, lo, hi, s, self.dt, span, r)

    def _gnss_agrees_with_wheels(self, s: int, speed: float) -> bool:
        """GNSS speed against the wheel speed at its time of validity (scaled by the learned
        wheel scale); remembered for the wheel-divergence check in ``_step``."""
        i = self.hist.slot(s)
        ws = abs(self.hist.aux[i, AUX_WHEEL] * self.hist.X[i][KW])
        agree = not math.isfinite(ws) or abs(speed - ws) <= GNSS_WHEEL_TOL_MPS + GNSS_WHEEL_TOL_REL * speed
        self.gnss_agrees = agree
        self.gnss_checked_t = s * self.dt
        return agree

    def _align(self, s: int, g: GnssSample, fus: GnssVelocityFusion, lat: LatencyEstimator) -> None:
        """Set the heading from the GNSS course at stored step s and carry it to the present.

        psi = course + beta_antenna(x): the new heading is a function of the velocity states, so
        its covariance row is J P (J = d beta_antenna / dx) and its variance J P J' plus the
        course's own: speed accuracy / speed, and the yaw rate times the latency's uncertainty
        (the course is from a slightly different instant than we think). Keeping the
        correlation with vy is what lets later GNSS fixes correct sideslip and heading together
        instead of trusting a heading that carries the initial sideslip error.
        """
        h = self.hist
        i = h.slot(s)
        # the state at s and its yaw rate as Python floats (tolist, item): float arithmetic here, and
        # the every-step turn low-pass and latency term set from them stay floats (issue 10)
        x = h.X[i].tolist()
        r = h.aux.item(i, AUX_R)
        lx, ly = fus.lever_x, fus.lever_y
        vax = x[VX] - r * ly
        vay = x[VY] + r * lx
        psi = (fus.course(g) + math.atan2(vay, vax)) % (2.0 * math.pi)
        dpsi = psi - x[PSI]
        speed = math.hypot(g.vel_n_mps, g.vel_e_mps)
        var_course = (fus.sigma(g) / speed) ** 2 + (r * lat.std_s) ** 2 + COURSE_FLOOR_RAD ** 2
        old = h.oldest()
        idx = np.arange(old, h.last + 1) % h.n
        X = h.X[idx]
        rr = h.aux[idx, AUX_R]
        vax = X[:, VX] - rr * ly
        vay = X[:, VY] + rr * lx
        sp2 = np.maximum(vax * vax + vay * vay, 1.0)
        J = np.zeros((len(idx), NX))
        J[:, VX] = -vay / sp2
        J[:, VY] = vax / sp2
        J[:, BR] = (-vay * ly - vax * lx) / sp2
        P = h.P[idx]
        JP = np.einsum("ki,kij->kj", J, P)
        var = np.einsum("kj,kj->k", JP, J) + var_course
        h.X[idx, PSI] = (X[:, PSI] + dpsi) % (2.0 * math.pi)
        for cons in self.considers:
            cons.set_heading(idx, J)
        if self.lat_sens is not None:
            self.lat_sens.set_heading(h, idx, J, self._course_timing_slope(s, g, lat, float(r)))
        self.scale_sens.set_heading(idx, J)
        self.gyro_gate.heading_set()
        P[:, PSI, :] = JP
        P[:, :, PSI] = JP
        P[:, PSI, PSI] = var
        h.P[idx] = P
        # the heading is now this course's, with its latency error r x (latency error) at that turn
        self.turn_lp = max(self.turn_lp, abs(r))
        self.align_lat_var = (r * lat.std_s) ** 2
        self.align_psi_var = float(var[-1])
        self.aligned = True
        for f in self.receivers:
            f.consecutive_rejects = 0
