"""ctypes binding of the firmware's filter pipeline (filter/hd_pipeline.h).

The analysis never re-implements the filter: it replays data through the
same C code the firmware runs (libhdfilter.so, target hdfilter_shared).

The Structure classes below mirror the C structs field by field, in
declaration order, so ctypes applies the same layout rules as the C
compiler.  tests/tools/test_cfilter.py compiles a tiny C program that prints
sizeof/offsetof of the real structs and compares them with these mirrors.

Typical use:

    from hdtools.analysis import cfilter
    kf = cfilter.recommended_config(1e-3, 0.02, 0.05, 0.005)   # C defaults
    kf.add_block(cfilter.LOCK_MOTOR, 6.0, kf.blocks[0].q_nm2)   # optional extra line
    out = cfilter.run(kf, cfilter.ExpectedConfig(), torque, d_motor, d_output)
    out["torque_filtered_nm"], out["innovation_nm"], ...

If filter/hd_kf.h changes a struct, update the mirror here; the layout test
fails until it matches.
"""
from __future__ import annotations

import ctypes
from ctypes import POINTER, c_float, c_int, c_size_t, c_uint, c_uint8, c_uint32

import numpy as np

from .. import native, profile_record

# Compile-time capacity of filter/hd_kf.h (HD_KF_MAX_BLOCKS default).
MAX_BLOCKS = profile_record.MAX_LINES  # read from filter/hd_kf.h, not typed again
MAX_STATES = 2 * MAX_BLOCKS + 1
MAX_POWER = 8  # HD_KF_MAX_POWER
PHASORS = 2 * (MAX_POWER + 1) + MAX_BLOCKS
P_ENTRIES = MAX_STATES * (MAX_STATES + 1) // 2
DEFAULT_TRACK_BANDWIDTH_HZ = 20.0

LOCK_MOTOR, LOCK_OUTPUT, LOCK_FIXED = 0, 1, 2
LOCK_NAMES = {LOCK_MOTOR: "motor", LOCK_OUTPUT: "output", LOCK_FIXED: "fixed"}
LOCK_BY_NAME = {v: k for k, v in LOCK_NAMES.items()}

# hd_kf_output_t.status bits (HD_KF_STATUS_* in filter/hd_kf.h).  The names
# are the C library's (hd_kf_status_name); tests/filter/test_cfilter_names.py
# checks every bit against it.
(STATUS_FROZEN, STATUS_BAD_INPUT, STATUS_RESET, STATUS_P_CLAMPED, STATUS_OFFSET_JUMP,
 STATUS_LIMITED, STATUS_UNMODELLED, STATUS_LOAD_BOUND) = (1, 2, 4, 8, 16, 32, 64, 128)
STATUS_BITS = {"FROZEN": STATUS_FROZEN, "BAD_INPUT": STATUS_BAD_INPUT, "RESET": STATUS_RESET,
               "P_CLAMPED": STATUS_P_CLAMPED, "OFFSET_JUMP": STATUS_OFFSET_JUMP,
               "LIMITED": STATUS_LIMITED, "UNMODELLED": STATUS_UNMODELLED,
               "LOAD_BOUND": STATUS_LOAD_BOUND}


class BlockConfig(ctypes.Structure):
    """hd_kf_block_config_t"""
    _fields_ = [("lock", c_uint8), ("enabled", c_uint8),
                ("order", c_float), ("q_nm2", c_float)]


class KfConfig(ctypes.Structure):
    """hd_kf_config_t"""
    _fields_ = [("blocks", BlockConfig * MAX_BLOCKS),
                ("block_count", c_uint8),
                ("offset_enabled", c_uint8),
                ("offset_is_sensor_error", c_uint8),
                ("offset_q_nm2", c_float),
                ("r_nm2", c_float),
                ("ts_s", c_float),
                ("p0_nm2", c_float),
                ("output_p0_nm2", c_float),
                ("q_motion_ref_rad", c_float),
                ("p_max_nm2", c_float),
                ("nyquist_fraction", c_float),
                ("offset_jump_nm", c_float),
                ("ripple_load_coeff_per_nm", c_float),
                ("output_learn_scale", c_float),
                ("correction_max_nm", c_float),
                ("offset_drift_q_nm2", c_float),
                ("output_row_follow", c_float),
                ("output_row_max", c_float),
                ("q_motion_ref_profiled_rad", c_float)]

    # Fields the analysis model carries one-to-one (see model.Model).
    SCALARS = ("offset_enabled", "offset_is_sensor_error", "offset_q_nm2", "r_nm2", "p0_nm2",
               "output_p0_nm2", "q_motion_ref_rad", "p_max_nm2", "nyquist_fraction",
               "offset_jump_nm", "ripple_load_coeff_per_nm", "correction_max_nm")

    def add_block(self, lock: int, order: float, q_nm2: float) -> int:
        if self.block_count >= MAX_BLOCKS:
            raise ValueError(f"at most {MAX_BLOCKS} oscillator blocks")
        b = self.blocks[self.block_count]
        b.lock, b.enabled, b.order, b.q_nm2 = lock, 1, order, q_nm2
        self.block_count += 1
        return self.block_count - 1


class KfSlot(ctypes.Structure):
    """hd_kf_slot_t"""
    _fields_ = [("lock", c_uint8), ("frame", c_uint8), ("enabled", c_uint8), ("reserved", c_uint8),
                ("theta_per_unit", c_float), ("motion_inv", c_float), ("motion_bias", c_float),
                ("q_nm2", c_float), ("p0_nm2", c_float), ("learn", c_float),
                ("fixed_cos", c_float), ("fixed_sin", c_float), ("full_rad", c_float),
                ("frozen_rad", c_float), ("full_shared_rad", c_float),
                ("full_profiled_rad", c_float)]


class KfState(ctypes.Structure):
    """hd_kf_t (treated as opaque; mirrored for its size/alignment and counters)."""
    _fields_ = [("cfg", KfConfig),
                ("n_states", c_uint8),
                ("n_blocks", c_uint8),
                ("offset_slot", c_uint8),
                ("offset_primed", c_uint8),
                ("load_ref_primed", c_uint8),
                ("motor_powers", c_uint32),
                ("output_powers", c_uint32),
                ("own_frames", c_uint32),
                ("motor_slots", c_uint32),
                ("output_slots", c_uint32),
                ("output_partial_slots", c_uint32),
                ("frozen_mask", c_uint32),
                ("offset_q_nm2", c_float),
                ("nyquist_limit_rad", c_float),
                ("motor_full_rad", c_float),
                ("motor_frozen_rad", c_float),
                ("output_frozen_rad", c_float),
                ("q_motion_inv_rad", c_float),
                ("load_ref_nm", c_float),
                ("load_scale", c_float),
                ("output_phase_hi_rad", c_float),
                ("output_phase_lo_rad", c_float),
                ("output_turns", c_uint32),
                ("slot", KfSlot * MAX_BLOCKS),
                ("phasor_cos", c_float * PHASORS),
                ("phasor_sin", c_float * PHASORS),
                ("x", c_float * MAX_STATES),
                ("p", c_float * P_ENTRIES),
                ("status_sticky", c_uint32),
                ("reset_count", c_uint32),
                ("bad_input_count", c_uint32),
                ("p_ceiling_count", c_uint32),
                ("p_negative_count", c_uint32),
                ("jump_rearm_steps", c_uint32),
                ("jump_hold_steps", c_uint32),
                ("jump_credit", c_uint32),
                ("jump_held_count", c_uint32),
                ("event_angle_rad", c_float),
                ("event_min_rad", c_float),
                ("event_max_rad", c_float),
                ("event_peak_nm2", c_float),
                ("rollback_count", c_uint32),
                ("event_x", c_float * (2 * MAX_BLOCKS)),
                ("limit_restart_steps", c_uint32),
                ("limit_steps", c_uint32),
                ("limit_count", c_uint32),
                ("drift_hold_total", c_uint32),
                ("drift_hold_steps", c_uint32),
                ("drift_count", c_uint32),
                ("output_follow", c_uint32),
                ("follow_slots", c_uint32),
                ("load_bound_count", c_uint32),
                ("output_row", c_float),
                ("output_row_alpha", c_float),
                ("motor_ref_inv", c_float),
                ("follow_min_rad", c_float),
                ("follow_primed", c_uint32),
                ("follow_mean_t", c_float),
                ("follow_mean_g", c_float),
                ("follow_var_t", c_float),
                ("follow_cov_tg", c_float),
                ("follow_weight", c_float),
                ("motor_ref", c_float * (2 * MAX_BLOCKS)),
                ("follow_load_nm", c_float),
                ("profiled_slots", c_uint32),
                ("follow_settle_steps", c_uint32),
                ("follow_settle_total", c_uint32),
                ("learn_load_nm", c_float),
                ("learn_load_weight", c_float)]


class Track(ctypes.Structure):
    """hd_track_t"""
    _fields_ = [("ts_s", c_float), ("l1", c_float), ("l2", c_float), ("l3", c_float),
                ("err_rad", c_float), ("vel_rad_s", c_float), ("acc_rad_s2", c_float)]


class ExpectedConfig(ctypes.Structure):
    """hd_expected_config_t (defaults: all zero, v_eps 0.01 rad/s)."""
    _fields_ = [("inertia_kgm2", c_float), ("viscous_nm_s_rad", c_float),
                ("coulomb_nm", c_float), ("coulomb_vel_eps_rad_s", c_float)]

    def __init__(self, inertia_kgm2=0.0, viscous_nm_s_rad=0.0, coulomb_nm=0.0,
                 coulomb_vel_eps_rad_s=0.01):
        super().__init__(inertia_kgm2, viscous_nm_s_rad, coulomb_nm, coulomb_vel_eps_rad_s)


class CurrentTerm(ctypes.Structure):
    """hd_expected_current_config_t (all zero: no current term)."""
    _fields_ = [("nm_per_a", c_float), ("coulomb_nm", c_float), ("viscous_nm_s_rad", c_float),
                ("inertia_kgm2", c_float), ("backdrive_nm_per_a", c_float),
                ("error_nm", c_float)]


class CurrentConfig(ctypes.Structure):
    """hd_slow_current_config_t; fill it with current_config() (the C code)."""
    _fields_ = [("term", CurrentTerm), ("alpha", c_float), ("lag_steps", c_float),
                ("gear_ratio", c_float), ("ts_s", c_float)]


class CurrentState(ctypes.Structure):
    """hd_slow_current_t (all zero: not primed)."""
    _fields_ = [("i1_a", c_float), ("i2_a", c_float), ("w1_rad_s", c_float),
                ("w2_rad_s", c_float), ("torque_nm", c_float), ("primed", c_uint8)]


class Pipeline(ctypes.Structure):
    """hd_pipeline_t"""
    _fields_ = [("kf", KfState), ("output_track", Track),
                ("expected", ExpectedConfig), ("torque_expected_nm", c_float)]


_FP = POINTER(c_float)


class ProfileLine(ctypes.Structure):
    """hd_kf_profile_line_t"""
    _fields_ = [("lock", c_uint8), ("order", c_uint8), ("a_nm", c_float), ("b_nm", c_float)]


class Profile(ctypes.Structure):
    """hd_kf_profile_t"""
    _fields_ = [("line_count", c_uint8), ("lines", ProfileLine * MAX_BLOCKS),
                ("load_nm", c_float)]


class PipelineIO(ctypes.Structure):
    """hd_pipeline_io_t"""
    _fields_ = [("n", c_size_t),
                ("torque_meas_nm", _FP), ("d_motor_angle_rad", _FP),
                ("d_output_angle_rad", _FP), ("feedforward_nm", _FP),
                ("feedforward_var_nm2", _FP),
                ("torque_filtered_nm", _FP), ("ripple_nm", _FP), ("offset_nm", _FP),
                ("innovation_nm", _FP), ("innovation_var_nm2", _FP),
                ("torque_expected_nm", _FP), ("output_velocity_rad_s", _FP),
                ("amplitude_nm", _FP), ("status", POINTER(c_uint)),
                ("motor_current_a", _FP), ("current", POINTER(CurrentConfig)),
                ("current_state", POINTER(CurrentState)), ("torque_expected_var_nm2", _FP)]


_LIB = None


def lib() -> ctypes.CDLL:
    """libhdfilter.so with argument types declared (loaded once)."""
    global _LIB
    if _LIB is None:
        L = native.load_library("hdfilter")
        L.hd_pipeline_init.argtypes = [POINTER(Pipeline), POINTER(KfConfig),
                                       POINTER(ExpectedConfig), c_float]
        L.hd_pipeline_init.restype = c_int
        L.hd_pipeline_run.argtypes = [POINTER(Pipeline), POINTER(PipelineIO)]
        L.hd_pipeline_run.restype = None
        L.hd_slow_current_config.argtypes = [POINTER(CurrentConfig), POINTER(CurrentTerm),
                                             c_float, c_float, c_float]
        L.hd_slow_current_config.restype = None
        L.hd_kf_config_default.argtypes = [POINTER(KfConfig), c_float]
        L.hd_kf_config_default.restype = None
        L.hd_kf_config_recommended.argtypes = [POINTER(KfConfig), c_float, c_float, c_float,
                                               c_float]
        L.hd_kf_config_recommended.restype = None
        L.hd_kf_config_check.argtypes = [POINTER(KfConfig)]
        L.hd_kf_config_check.restype = c_int
        L.hd_kf_profile_import.argtypes = [POINTER(KfState), POINTER(Profile), c_float, c_float,
                                           c_float]
        L.hd_kf_profile_import.restype = c_int
        L.hd_kf_err_str.argtypes = [c_int]
        L.hd_kf_err_str.restype = ctypes.c_char_p
        L.hd_kf_err_name.argtypes = [c_int]
        L.hd_kf_err_name.restype = ctypes.c_char_p
        L.hd_kf_status_name.argtypes = [c_uint]
        L.hd_kf_status_name.restype = ctypes.c_char_p
        _LIB = L
    return _LIB


def default_config(ts_s: float) -> KfConfig:
    """hd_kf_config_default (from the C library): no blocks."""
    cfg = KfConfig()
    lib().hd_kf_config_default(ctypes.byref(cfg), ts_s)
    return cfg


def recommended_config(ts_s: float, noise_nm: float, ripple_settle_s: float,
                       offset_settle_s: float) -> KfConfig:
    """hd_kf_config_recommended (from the C library): the project's tuning."""
    cfg = KfConfig()
    lib().hd_kf_config_recommended(ctypes.byref(cfg), ts_s, noise_nm, ripple_settle_s,
                                   offset_settle_s)
    return cfg


def current_config(term: CurrentTerm, filter_hz: float, gear_ratio: float,
                   ts_s: float) -> CurrentConfig:
    """hd_slow_current_config (from the C library): the current term as the
    firmware forms it (current_* parameters, current_filter_hz, gear_ratio)."""
    cfg = CurrentConfig()
    lib().hd_slow_current_config(ctypes.byref(cfg), ctypes.byref(term), filter_hz, gear_ratio,
                                 ts_s)
    return cfg


def error_name(code: int) -> str:
    """The filter library's name for an error code (hd_kf_err_name), e.g.
    "HD_KF_ERR_NOISE"; the number itself if the library has no such code."""
    name = lib().hd_kf_err_name(code)
    return name.decode() if name is not None else str(code)


def error_text(code: int) -> str:
    """The filter library's description of an error code (hd_kf_err_str)."""
    return lib().hd_kf_err_str(code).decode()


def status_names() -> dict:
    """{name: bit mask} of every status bit the C library names."""
    names, bit = {}, 0
    while (name := lib().hd_kf_status_name(bit)) is not None:
        names[name.decode()] = 1 << bit
        bit += 1
    return names


class FilterError(ValueError):
    """A configuration the C library refused; .code is its error name."""

    def __init__(self, message: str, code: str = ""):
        super().__init__(message)
        self.code = code


def check(cfg: KfConfig) -> None:
    err = lib().hd_kf_config_check(ctypes.byref(cfg))
    if err != 0:
        raise FilterError(f"filter configuration rejected: {error_text(err)}", error_name(err))


OUTPUTS = ("torque_filtered_nm", "ripple_nm", "offset_nm", "innovation_nm",
           "innovation_var_nm2", "torque_expected_nm", "output_velocity_rad_s",
           "torque_expected_var_nm2")


def _fptr(a):
    return a.ctypes.data_as(_FP)


def _angle_f32(a: float) -> float:
    """a reduced to [0, 2 pi) as the float32 the filter receives: an angle
    just below 2 pi rounds up to 2 pi in float32, which the filter refuses
    (outside [0, 2 pi)); that is angle 0."""
    r = np.float32(np.mod(a, 2.0 * np.pi))
    return 0.0 if r >= np.float32(2.0 * np.pi) else float(r)


def run(cfg: KfConfig, expected: ExpectedConfig, torque_nm, d_motor_rad, d_output_rad,
        feedforward_nm=None, track_bandwidth_hz: float = DEFAULT_TRACK_BANDWIDTH_HZ,
        amplitudes: bool = False, profile=None, motor_current_a=None,
        current: CurrentConfig | None = None) -> dict:
    """Replays one contiguous, uniformly sampled segment through
    hd_pipeline_run (one C call).  Returns float32 arrays named as in
    hd_pipeline_io_t, plus "status" (uint32) and, if amplitudes, "amplitude_nm"
    (n x MAX_BLOCKS).  profile: (lines, motor_angle_rad, output_angle_rad,
    prior_var_nm2[, load_nm]) imported with hd_kf_profile_import before the first
    sample (lines: (lock, order, a_nm, b_nm); the angles of the first
    sample, absolute: the filter is given the angles of the sample before
    it, these minus the first increments, hd_kf.h "Which angle").
    motor_current_a with current (current_config()): the firmware's
    motor-current term, from an unprimed estimator."""
    L = lib()
    n = len(torque_nm)
    p = Pipeline()
    err = L.hd_pipeline_init(ctypes.byref(p), ctypes.byref(cfg), ctypes.byref(expected),
                             float(track_bandwidth_hz))
    if err != 0:
        raise FilterError(f"hd_pipeline_init failed ({error_name(err)}): {error_text(err)}",
                          error_name(err))
    if profile is not None:
        lines, th_m0, th_o0, prior, *load = profile
        pr = Profile()
        pr.load_nm = load[0] if load else -1.0     # the load the lines are at; -1: unknown
        pr.line_count = len(lines)
        for i, (lock, order, a, b) in enumerate(lines):
            pr.lines[i].lock, pr.lines[i].order = lock, int(order)
            pr.lines[i].a_nm, pr.lines[i].b_nm = a, b
        before_m = th_m0 - float(d_motor_rad[0]) if n else th_m0
        before_o = th_o0 - float(d_output_rad[0]) if n else th_o0
        err = L.hd_kf_profile_import(ctypes.byref(p.kf), ctypes.byref(pr),
                                     _angle_f32(before_m), _angle_f32(before_o), float(prior))
        if err < 0:
            raise FilterError(f"hd_kf_profile_import failed ({error_name(err)}): "
                              f"{error_text(err)}", error_name(err))
    ins = [np.ascontiguousarray(a, dtype=np.float32)
           for a in (torque_nm, d_motor_rad, d_output_rad)]
    for a in ins:
        if len(a) != n:
            raise ValueError("input arrays differ in length")
    ff = None if feedforward_nm is None else np.ascontiguousarray(feedforward_nm, np.float32)
    outs = {k: np.empty(n, np.float32) for k in OUTPUTS}
    status = np.empty(n, np.uint32)
    io = PipelineIO()
    io.n = n
    io.torque_meas_nm, io.d_motor_angle_rad, io.d_output_angle_rad = map(_fptr, ins)
    io.feedforward_nm = _fptr(ff) if ff is not None else None
    if current is not None and motor_current_a is not None:
        cur = np.ascontiguousarray(motor_current_a, np.float32)
        if len(cur) != n:
            raise ValueError("input arrays differ in length")
        state = CurrentState()
        io.motor_current_a, io.current = _fptr(cur), ctypes.pointer(current)
        io.current_state = ctypes.pointer(state)
    for k, a in outs.items():
        setattr(io, k, _fptr(a))
    if amplitudes:
        outs["amplitude_nm"] = np.empty((n, MAX_BLOCKS), np.float32)
        io.amplitude_nm = _fptr(outs["amplitude_nm"])
    io.status = status.ctypes.data_as(POINTER(c_uint))
    L.hd_pipeline_run(ctypes.byref(p), ctypes.byref(io))
    outs["status"] = status
    outs["reset_count"] = int(p.kf.reset_count)
    outs["bad_input_count"] = int(p.kf.bad_input_count)
    return outs
