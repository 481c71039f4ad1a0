"""ctypes binding of calib/hd_calib.h and calib/hd_calib_record.h."""
from __future__ import annotations

import ctypes as C
import math
from dataclasses import dataclass

from hdtools import native

MAX_POINTS = 64          # HD_CALIB_MAX_POINTS
MAX_EXPERIMENTS = 32     # HD_CALIB_MAX_EXPERIMENTS
RECORD_BYTES = 64        # HD_CALIB_RECORD_BYTES
DIR_LOAD, DIR_UNLOAD = 0, 1

ERR_SINGLE_EXPERIMENT = -7

REASONS = {0x01: "FEW_EXPERIMENTS", 0x02: "INCONSISTENT", 0x04: "NONLINEAR",
           0x08: "HYSTERESIS", 0x10: "POSITION", 0x20: "NOT_MEASURABLE"}
SERIAL_MAX = 15          # ASCII characters (16-byte field, NUL-terminated)
UNIX_S_MAX = 0xFFFFFFFF  # the record's date is a u32


class Experiment(C.Structure):
    _fields_ = [("n_points", C.c_uint32), ("position_deg", C.c_float),
                ("torque_nm", C.c_float * MAX_POINTS), ("bridge_v", C.c_float * MAX_POINTS),
                ("direction", C.c_uint8 * MAX_POINTS)]


class Fit(C.Structure):
    _fields_ = [("n_points", C.c_uint32), ("position_deg", C.c_float),
                ("full_scale_nm", C.c_float), ("gain_nm_per_v", C.c_float),
                ("gain_se_nm_per_v", C.c_float), ("offset_v", C.c_float),
                ("offset_se_v", C.c_float), ("residual_rms_v", C.c_float),
                ("nonlinearity_pct_fs", C.c_float), ("nonlinearity_p", C.c_float),
                ("hysteresis_pct_fs", C.c_float), ("hysteresis_p", C.c_float),
                ("nonlinearity_detected", C.c_uint8), ("hysteresis_detected", C.c_uint8),
                ("nonlinearity_measurable", C.c_uint8), ("hysteresis_measurable", C.c_uint8)]


class Thresholds(C.Structure):
    _fields_ = [("max_consistency", C.c_float), ("max_nonlinearity_pct_fs", C.c_float),
                ("max_hysteresis_pct_fs", C.c_float), ("max_position_pct", C.c_float),
                ("alpha", C.c_float), ("min_detect_pct_fs", C.c_float),
                ("min_experiments", C.c_uint32), ("allow_unmeasurable", C.c_uint32)]


class Report(C.Structure):
    _fields_ = [("n_experiments", C.c_uint32), ("fit", Fit * MAX_EXPERIMENTS),
                ("gain_mean_nm_per_v", C.c_float), ("gain_std_nm_per_v", C.c_float),
                ("consistency", C.c_float), ("offset_mean_v", C.c_float),
                ("nonlinearity_pct_fs", C.c_float), ("hysteresis_pct_fs", C.c_float),
                ("nonlinearity_detected", C.c_uint8), ("hysteresis_detected", C.c_uint8),
                ("nonlinearity_measurable", C.c_uint8), ("hysteresis_measurable", C.c_uint8),
                ("position_testable", C.c_uint8), ("position_detected", C.c_uint8),
                ("position_amplitude_pct", C.c_float), ("position_phase_deg", C.c_float),
                ("position_p", C.c_float), ("accepted", C.c_uint8),
                ("reject_reasons", C.c_uint32), ("error_experiment", C.c_int32)]


class Record(C.Structure):
    _fields_ = [("gain_nm_per_v", C.c_float), ("offset_v", C.c_float),
                ("calibrated_unix_s", C.c_uint32), ("serial", C.c_char * 16),
                ("consistency", C.c_float)]


class CalibError(Exception):
    """Bad input, with the C library's message."""


_lib = None


def lib() -> C.CDLL:
    global _lib
    if _lib is None:
        L = native.load_library("hdcalib")
        L.hd_calib_thresholds_default.argtypes = [C.POINTER(Thresholds)]
        L.hd_calib_analyze.argtypes = [C.POINTER(Experiment), C.c_uint32,
                                       C.POINTER(Thresholds), C.POINTER(Report)]
        L.hd_calib_analyze.restype = C.c_int
        L.hd_calib_strerror.argtypes = [C.c_int]
        L.hd_calib_strerror.restype = C.c_char_p
        L.hd_calib_reason_str.argtypes = [C.c_uint32]
        L.hd_calib_reason_str.restype = C.c_char_p
        L.hd_calib_record_encode.argtypes = [C.POINTER(Record), C.c_uint32,
                                             C.POINTER(C.c_uint8), C.c_size_t]
        L.hd_calib_record_encode.restype = C.c_size_t
        L.hd_calib_record_decode.argtypes = [C.POINTER(C.c_uint8), C.c_size_t,
                                             C.POINTER(Record), C.POINTER(C.c_uint32)]
        L.hd_calib_record_decode.restype = C.c_int
        L.hd_crc32.argtypes = [C.c_char_p, C.c_size_t]
        L.hd_crc32.restype = C.c_uint32
        L.hd_calib_f_pvalue.argtypes = [C.c_float, C.c_float, C.c_float]
        L.hd_calib_f_pvalue.restype = C.c_float
        for name, struct in (("experiment", Experiment), ("report", Report),
                             ("record", Record)):
            fn = getattr(L, f"hd_calib_sizeof_{name}")
            fn.restype = C.c_uint32
            if fn() != C.sizeof(struct):
                raise RuntimeError(f"ctypes layout of {name} ({C.sizeof(struct)} B) "
                                   f"does not match the C library ({fn()} B)")
        _lib = L
    return _lib


def default_thresholds() -> Thresholds:
    t = Thresholds()
    lib().hd_calib_thresholds_default(C.byref(t))
    return t


@dataclass
class ExperimentData:
    name: str
    position_deg: float
    torque_nm: list[float]
    bridge_v: list[float]
    unload: list[bool]


def analyze(exps: list[ExperimentData], thresholds: Thresholds) -> tuple[Report, int]:
    """Runs hd_calib_analyze.  Raises CalibError on errors other than the
    single-experiment case, which is returned (the fit is still useful)."""
    if not exps:
        raise CalibError("no experiments in the input")
    if len(exps) > MAX_EXPERIMENTS:
        raise CalibError(f"{len(exps)} experiments; the library holds at most {MAX_EXPERIMENTS}")
    arr = (Experiment * len(exps))()
    for i, e in enumerate(exps):
        if len(e.torque_nm) > MAX_POINTS:
            raise CalibError(f"experiment {e.name}: {len(e.torque_nm)} points; "
                             f"at most {MAX_POINTS} per experiment")
        arr[i].n_points = len(e.torque_nm)
        arr[i].position_deg = e.position_deg
        for k, (t, v, u) in enumerate(zip(e.torque_nm, e.bridge_v, e.unload)):
            arr[i].torque_nm[k] = t
            arr[i].bridge_v[k] = v
            arr[i].direction[k] = DIR_UNLOAD if u else DIR_LOAD
    rep = Report()
    rc = lib().hd_calib_analyze(arr, len(exps), C.byref(thresholds), C.byref(rep))
    if rc not in (0, ERR_SINGLE_EXPERIMENT):
        msg = lib().hd_calib_strerror(rc).decode()
        where = (f"experiment {exps[rep.error_experiment].name}: "
                 if 0 <= rep.error_experiment < len(exps) else "")
        raise CalibError(where + msg)
    return rep, rc


def strerror(rc: int) -> str:
    return lib().hd_calib_strerror(rc).decode()


def reasons(mask: int) -> list[str]:
    return [lib().hd_calib_reason_str(bit).decode() for bit in sorted(REASONS) if mask & bit]


def check_serial(serial: str) -> bytes:
    """The serial as stored: printable ASCII, at most SERIAL_MAX characters."""
    if any(not (0x20 <= ord(c) <= 0x7E) for c in serial):
        raise CalibError(f"serial {serial!r}: printable ASCII only (0x20..0x7E)")
    if len(serial) > SERIAL_MAX:
        raise CalibError(f"serial {serial!r}: {len(serial)} characters, at most {SERIAL_MAX}")
    return serial.encode("ascii")


def check_unix_s(unix_s: int) -> int:
    if not isinstance(unix_s, int) or not 0 <= unix_s <= UNIX_S_MAX:
        raise CalibError(f"date {unix_s}: unix seconds must be in 0..{UNIX_S_MAX} "
                         "(the record stores an unsigned 32-bit number)")
    return unix_s


def encode_record(gain: float, offset_v: float, unix_s: int, serial: str,
                  consistency: float, sequence: int = 1) -> bytes:
    sb = check_serial(serial)
    check_unix_s(unix_s)
    if not 0 <= sequence <= 0xFFFFFFFF:
        raise CalibError(f"sequence {sequence} outside 0..{0xFFFFFFFF}")
    r = Record(gain, offset_v, unix_s, sb, 0.0 if math.isnan(consistency) else consistency)
    buf = (C.c_uint8 * RECORD_BYTES)()
    n = lib().hd_calib_record_encode(C.byref(r), sequence, buf, RECORD_BYTES)
    if n != RECORD_BYTES:
        raise CalibError("record not encodable (gain must be finite and > 0)")
    return bytes(buf)


def decode_record(data: bytes) -> tuple[int, Record, int]:
    buf = (C.c_uint8 * len(data)).from_buffer_copy(data)
    r = Record()
    seq = C.c_uint32()
    rc = lib().hd_calib_record_decode(buf, len(data), C.byref(r), C.byref(seq))
    return rc, r, seq.value


def crc32(data: bytes) -> int:
    return lib().hd_crc32(data, len(data))
