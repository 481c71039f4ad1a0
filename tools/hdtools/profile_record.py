"""The firmware's profile record on the host: profile.json (the schema of
`hdsense analyze`, tools/hdtools/analysis/profile.py) <-> the record file
hdjoint-host --profile stores <-> the CAN commands that upload it.

Payload (firmware/hd_fw_records.h, HD_PROFILE_RECORD_VERSION), little-endian:
  f32 gear_ratio, u32 motor_cpr, u32 output_cpr, f32 load_nm, u8 n,
  n x {u8 lock (0 motor, 1 output), u8 order, f32 a_nm, f32 b_nm}
load_nm: |T| the lines were learned at, negative when unknown; version 1
(HD_PROFILE_RECORD_VERSION_V1) had no load_nm and is still read.
Record file: b"HDPF", u16 format version, u16 payload length, payload, u32
CRC-32 (zlib) of everything before it.  A line predicts
a cos(order alpha) + b sin(order alpha), alpha the absolute motor or output
angle; docs/design/slow-torque.md.
"""
from __future__ import annotations

import math
import re
import struct
import zlib
from dataclasses import dataclass, field

from . import canproto, paths, protocol
from .safeio import UsageError

ROOT = protocol.ROOT
MAGIC = b"HDPF"
LOCKS = ("motor", "output")      # hd_kf_lock_t 0 and 1
GEAR_TOLERANCE = 0.005           # a profile.json's gear ratio vs the joint's (relative)
SCHEMA = "hdjoint-profile/1"     # profile.json (tools/hdtools/analysis/profile.py writes it)


def _define(path: str, name: str) -> int:
    """An integer #define of a C header (one fact, one place)."""
    text = paths.source_file(path).read_text()
    m = re.search(rf"#define {name} \(?(\d+)u?\)?", text)
    if m is None:
        raise RuntimeError(f"{path}: no #define {name}")
    return int(m.group(1))


def _define_float(path: str, name: str) -> float:
    """A float #define of a C header (one fact, one place)."""
    m = re.search(rf"#define {name} ([0-9.eE+-]+)f?\b", paths.source_file(path).read_text())
    if m is None:
        raise RuntimeError(f"{path}: no #define {name}")
    return float(m.group(1))


VERSION = _define("firmware/hd_fw_records.h", "HD_PROFILE_RECORD_VERSION")
MAX_LOAD_NM = _define_float("filter/hd_kf.h", "HD_KF_MAX_ABS_Y_NM")   # the firmware refuses more
VERSION_V1 = _define("firmware/hd_fw_records.h", "HD_PROFILE_RECORD_VERSION_V1")
MAX_LINES = _define("filter/hd_kf.h", "HD_KF_MAX_BLOCKS")
_HEAD = struct.Struct("<fIIfB")
_HEAD_V1 = struct.Struct("<fIIB")
_LINE = struct.Struct("<BBff")


@dataclass
class Line:
    lock: str      # "motor" | "output"
    order: int     # 1..255
    a_nm: float
    b_nm: float


@dataclass
class Record:
    gear_ratio: float
    motor_cpr: int
    output_cpr: int
    lines: list[Line] = field(default_factory=list)
    load_nm: float = -1.0   # |T| the lines were learned at; negative: unknown


def check_joint(gear_ratio: float, motor_cpr: int, output_cpr: int) -> None:
    """The joint's constants against the parameter table's ranges."""
    for key, value in (("gear_ratio", gear_ratio), ("motor_cpr", motor_cpr),
                       ("output_cpr", output_cpr)):
        why = protocol.param_by_key(key).check(float(value))
        if why is not None:
            raise UsageError(f"{key} = {value:g}: {why}")


def check_lines(lines: list[Line], where: str) -> None:
    if not lines:
        raise UsageError(f"{where}: no lines")
    if len(lines) > MAX_LINES:
        raise UsageError(f"{where}: {len(lines)} lines, the firmware holds at most {MAX_LINES}")
    for i, ln in enumerate(lines):
        if ln.lock not in LOCKS:
            raise UsageError(f"{where}: line {i + 1}: lock {ln.lock!r} (motor or output)")
        if not 1 <= ln.order <= 255:
            raise UsageError(f"{where}: line {i + 1}: order {ln.order} outside 1..255")
        if not (math.isfinite(ln.a_nm) and math.isfinite(ln.b_nm)):
            raise UsageError(f"{where}: line {i + 1}: a_nm and b_nm must be finite numbers")


def payload(rec: Record) -> bytes:
    check_joint(rec.gear_ratio, rec.motor_cpr, rec.output_cpr)
    check_lines(rec.lines, "profile")
    if not math.isfinite(rec.load_nm):
        raise UsageError(f"profile: load_nm {rec.load_nm} is not a finite number")
    out = [_HEAD.pack(rec.gear_ratio, rec.motor_cpr, rec.output_cpr, rec.load_nm,
                      len(rec.lines))]
    out += [_LINE.pack(LOCKS.index(ln.lock), ln.order, ln.a_nm, ln.b_nm) for ln in rec.lines]
    return b"".join(out)


def file_bytes(rec: Record) -> bytes:
    body = payload(rec)
    head = MAGIC + struct.pack("<HH", VERSION, len(body)) + body
    return head + struct.pack("<I", zlib.crc32(head))


def parse_file(data: bytes, name: str) -> Record:
    """A record file back into a Record (UsageError on anything else)."""
    if len(data) < 12 or data[:4] != MAGIC:
        raise UsageError(f"{name}: not a profile record file (no HDPF header)")
    version, length = struct.unpack_from("<HH", data, 4)
    if version not in (VERSION, VERSION_V1):
        raise UsageError(f"{name}: profile record format {version}, this tool reads "
                         f"{VERSION_V1} and {VERSION}")
    if length + 12 != len(data) or zlib.crc32(data[:-4]) != struct.unpack("<I", data[-4:])[0]:
        raise UsageError(f"{name}: damaged (length or CRC-32)")
    body = data[8:-4]
    head = _HEAD if version == VERSION else _HEAD_V1
    if len(body) < head.size:
        raise UsageError(f"{name}: damaged (payload shorter than its header)")
    if version == VERSION:
        gear, mcpr, ocpr, load, n = head.unpack_from(body, 0)
    else:
        (gear, mcpr, ocpr, n), load = head.unpack_from(body, 0), -1.0
    if len(body) != head.size + n * _LINE.size:
        raise UsageError(f"{name}: {n} lines do not fill the payload")
    if not math.isfinite(load):
        raise UsageError(f"{name}: load_nm is not a finite number")
    lines = []
    for i in range(n):
        lock, order, a, b = _LINE.unpack_from(body, head.size + i * _LINE.size)
        if lock >= len(LOCKS):
            raise UsageError(f"{name}: line {i + 1}: lock {lock} (0 motor, 1 output)")
        lines.append(Line(LOCKS[lock], order, a, b))
    rec = Record(gear, mcpr, ocpr, lines, load)
    check_lines(lines, name)
    return rec


def _number(doc: dict, key: str, where: str) -> float:
    v = doc.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise UsageError(f"{where}: {key} must be a finite number")
    return float(v)


def lines_from_json(doc, name: str) -> tuple[list[Line], float]:
    """(lines, gear ratio) of a profile.json document."""
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
        raise UsageError(f"{name}: not a profile ({SCHEMA!r} schema expected)")
    gear = _number(doc, "gear_ratio", name)
    raw = doc.get("lines")
    if not isinstance(raw, list):
        raise UsageError(f"{name}: lines must be a list")
    lines = []
    for i, ln in enumerate(raw):
        where = f"{name}: line {i + 1}"
        if not isinstance(ln, dict):
            raise UsageError(f"{where}: not an object")
        order = _number(ln, "order", where)
        if order != int(order):
            raise UsageError(f"{where}: order {order:g} is not whole (the firmware keeps "
                             "integral orders only)")
        lines.append(Line(ln.get("lock"), int(order), _number(ln, "a_nm", where),
                          _number(ln, "b_nm", where)))
    check_lines(lines, name)
    return lines, gear


def load_from_json(doc: dict, name: str) -> float:
    """A profile.json's optional load_nm (|T| its lines were learned at);
    -1 (unknown) when absent or null."""
    if doc.get("load_nm") is None:
        return -1.0
    load = _number(doc, "load_nm", name)
    if load < 0.0:
        raise UsageError(f"{name}: load_nm {load:g} is negative (leave it out when unknown)")
    if load > MAX_LOAD_NM:
        raise UsageError(f"{name}: load_nm {load:g} is above {MAX_LOAD_NM:g} N m, no joint's load")
    return load


def check_gear(profile_gear: float, joint_gear: float, name: str) -> None:
    if abs(profile_gear - joint_gear) > GEAR_TOLERANCE * joint_gear:
        raise UsageError(f"{name}: made for gear ratio {profile_gear:g}, the joint has "
                         f"{joint_gear:g}: the output angles would not line up")


def to_json(rec: Record, source: str) -> dict:
    return {"schema": SCHEMA, "gear_ratio": rec.gear_ratio,
            "angle_convention": "ripple_nm = sum over lines of a_nm cos(order alpha) + b_nm "
                                "sin(order alpha); alpha = the absolute motor angle (lock motor) "
                                "or output angle (lock output) in rad, 2 pi (counts mod cpr) / cpr",
            "ripple_load_coeff_per_nm": None,
            "load_nm": rec.load_nm if rec.load_nm >= 0.0 else None,
            "lines": [{"lock": ln.lock, "order": ln.order, "a_nm": ln.a_nm, "b_nm": ln.b_nm}
                      for ln in rec.lines],
            "source": {"record": source, "motor_cpr": rec.motor_cpr,
                       "output_cpr": rec.output_cpr}}


def commands(lines: list[Line], node_id: int = 1, save: bool = False,
             token: int = 0) -> list[tuple[int, bytes]]:
    """PROFILE_PUT a and b of every line in order, PROFILE_LOAD of the
    uploaded lines, and PROFILE_SAVE of them if save."""
    check_lines(lines, "profile")
    db = canproto.load_db(node_id)
    out = []
    for i, ln in enumerate(lines):
        base = i | (0x20 if ln.lock == "output" else 0)
        for flag, value in ((0, ln.a_nm), (0x10, ln.b_nm)):
            out.append(canproto.command(db, "PROFILE_PUT", token, ProfilePutLine=base | flag,
                                        ProfilePutOrder=ln.order,
                                        ProfilePutValue=protocol.f32(value)))
    out.append(canproto.command(db, "PROFILE_LOAD", token, ProfileLoadSource=1))
    if save:
        out.append(canproto.command(db, "PROFILE_SAVE", token, ProfileSaveSource=1))
    return out


def read_config_joint(text: str, name: str) -> dict:
    """gear_ratio, motor_cpr and output_cpr from a firmware configuration
    text (docs/design/firmware.md); keys it does not give are absent."""
    found = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        key, _, value = line.partition("=")
        key = key.strip()
        if key in ("gear_ratio", "motor_cpr", "output_cpr"):
            try:
                found[key] = float(value.strip())
            except ValueError:
                raise UsageError(f"{name}:{lineno}: {key}: {value.strip()!r} is not a number") \
                    from None
    return found
