"""The joint's protocol vocabulary and parameter table, read from the C
sources that define them (firmware/hd_protocol.def, firmware/hd_params.def),
and the DBC generated from them.

Nothing here is typed twice: frame types, opcodes, results, fault bits,
states, record statuses, info items and parameters come from the .def files;
the byte layouts of the frames are written once, below (DBC_LAYOUT), and
firmware/hdjoint.dbc is generated from them (`python -m hdtools.protocol
--write-dbc`).  tests/firmware/test_protocol_tables.py checks that the
committed DBC equals the generated one and that the C encoder's bytes decode
through it.
"""
from __future__ import annotations

import argparse
import csv
import re
import struct
import sys
import zlib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from . import paths  # noqa: E402 - the source tree or the installed copies

ROOT = paths.source_root() or paths.PACKAGE
PROTOCOL_DEF = paths.firmware_file("hd_protocol.def")
PARAMS_DEF = paths.firmware_file("hd_params.def")
DBC_PATH = paths.firmware_file("hdjoint.dbc")
FIRMWARE = PARAMS_DEF.parent

ID_PREFIX = 0x01D00000
EXT_FLAG_DBC = 0x80000000          # how a DBC marks a 29-bit identifier
NODE_MIN, NODE_MAX = 1, 127


class DefError(ValueError):
    """A .def file this module cannot read (a malformed row)."""


def _rows(path: Path, macro: str) -> list[list[str]]:
    """Arguments of every `MACRO(...)` row of a .def file, as strings."""
    rows = []
    pat = re.compile(rf"^{macro}\((.*)\)\s*$")
    for lineno, line in enumerate(path.read_text().splitlines(), start=1):
        m = pat.match(line.strip())
        if not m:
            continue
        args = next(csv.reader([m.group(1)], skipinitialspace=True))
        if not args:
            raise DefError(f"{path.name}:{lineno}: empty {macro} row")
        rows.append([a.strip() for a in args])
    return rows


@dataclass(frozen=True)
class Entry:
    code: int
    name: str
    doc: str


@dataclass(frozen=True)
class Frame:
    type: int
    name: str
    direction: str
    dlc: int
    doc: str

    def can_id(self, node: int) -> int:
        return ID_PREFIX | (self.type << 8) | node


@dataclass(frozen=True)
class Param:
    id: int
    name: str
    key: str
    type: str          # F32 U32 U16 U8 BOOL
    lo: float
    hi: float
    flags: frozenset   # LIVE REBUILD RO CONFIG CALIB LO_OPEN
    unit: str
    doc: str

    @property
    def read_only(self) -> bool:
        return "RO" in self.flags

    @property
    def integer(self) -> bool:
        return self.type != "F32"

    def check(self, value: float) -> str | None:
        """None if the firmware accepts value, else why not (hd_param_check)."""
        v = float(value)
        if v != v or v in (float("inf"), float("-inf")):
            return "not a finite number"
        lo_ok = v > self.lo if "LO_OPEN" in self.flags else v >= self.lo
        if not lo_ok or v > self.hi:
            lo = "(" if "LO_OPEN" in self.flags else "["
            return f"outside {lo}{self.lo:g}, {self.hi:g}]"
        if self.integer and v != int(v):
            return "not a whole number"
        # the firmware receives float32: the value must survive the trip
        if self.integer and f32(v) != v:
            return "not representable"
        return None


def f32(value: float) -> float:
    """value as the float32 the bus carries and the firmware computes with."""
    return struct.unpack("<f", struct.pack("<f", float(value)))[0]


def _int(text: str) -> int:
    return int(text, 0)


@lru_cache(maxsize=None)
def frames() -> tuple[Frame, ...]:
    return tuple(Frame(_int(t), n, d, _int(dlc), doc)
                 for t, n, d, dlc, doc in _rows(PROTOCOL_DEF, "HD_FRAME"))


def _entries(macro: str) -> tuple[Entry, ...]:
    return tuple(Entry(_int(c), n, doc) for c, n, doc in _rows(PROTOCOL_DEF, macro))


@lru_cache(maxsize=None)
def opcodes() -> tuple[Entry, ...]:
    return _entries("HD_OPCODE")


@lru_cache(maxsize=None)
def results() -> tuple[Entry, ...]:
    return _entries("HD_RESULT")


@lru_cache(maxsize=None)
def faults() -> tuple[Entry, ...]:
    """Fault bits: code is the bit number."""
    return _entries("HD_FAULT")


@lru_cache(maxsize=None)
def states() -> tuple[Entry, ...]:
    return _entries("HD_STATE")


@lru_cache(maxsize=None)
def record_statuses() -> tuple[Entry, ...]:
    return _entries("HD_RECORD_STATUS")


@lru_cache(maxsize=None)
def info_items() -> tuple[Entry, ...]:
    return _entries("HD_INFO_ITEM")


@lru_cache(maxsize=None)
def retired_params() -> tuple[Entry, ...]:
    """HD_PARAM_RETIRED rows: ids no firmware sets any more (a saved record
    may hold them; the loader skips them)."""
    return tuple(Entry(_int(pid), key.strip('"'), why)
                 for pid, key, why in _rows(PARAMS_DEF, "HD_PARAM_RETIRED"))


@lru_cache(maxsize=None)
def params() -> tuple[Param, ...]:
    out = []
    for row in _rows(PARAMS_DEF, "HD_PARAM"):
        if len(row) != 10:
            raise DefError(f"hd_params.def: row {row[:3]} has {len(row)} columns, wants 10")
        pid, name, key, typ, _field, lo, hi, flags, unit, doc = row
        out.append(Param(_int(pid), name, key.strip('"'), typ, float(lo), float(hi),
                         frozenset(f.strip() for f in flags.split("|")), unit.strip('"'), doc))
    reused = {p.id for p in out} & {r.code for r in retired_params()}
    if reused:
        raise DefError(f"hd_params.def: retired id(s) {sorted(reused)} reused")
    return tuple(out)


def frame(name: str) -> Frame:
    return next(f for f in frames() if f.name == name)


def by_name(entries, name: str) -> Entry:
    for e in entries:
        if e.name == name:
            return e
    raise KeyError(name)


def name_of(entries, code: int) -> str:
    """The name of the entry with this code, or the code itself (a value
    this table does not know, from a newer firmware)."""
    for e in entries:
        if e.code == code:
            return e.name
    return str(code)


def param_by_key(key: str) -> Param:
    for p in params():
        if p.key == key:
            return p
    raise KeyError(key)


def param_by_id(pid: int) -> Param:
    for p in params():
        if p.id == pid:
            return p
    raise KeyError(pid)


def fault_names(bits: int) -> list[str]:
    return [f.name for f in faults() if bits & (1 << f.code)]


_TYPE_CODE = {"F32": 0, "U32": 1, "U16": 2, "U8": 3, "BOOL": 4}
_FLAG_BITS = {"LIVE": 0x01, "REBUILD": 0x02, "RO": 0x04, "CONFIG": 0x08, "CALIB": 0x10,
              "LO_OPEN": 0x20}


def param_table_crc() -> int:
    """hd_param_table_crc(): what VERSION item PARAM_TABLE_CRC answers."""
    crc = 0
    for p in params():
        flags = sum(_FLAG_BITS[f] for f in p.flags)
        row = struct.pack("<BBBBff", p.id, _TYPE_CODE[p.type], flags, 0, p.lo, p.hi)
        crc = zlib.crc32(row, crc)
        crc = zlib.crc32(p.key.encode() + b"\0", crc)
    return crc


# --------------------------------------------------------------------- DBC
# Signals per frame: (name, start bit, length, signed, scale, offset, min, max,
# unit, value table key or None, multiplexer spec or "").  Little-endian.
F32_MAX = "3.4E+038"
DBC_LAYOUT = {
    "SETPOINT": [
        ("SpMode", 0, 8, False, 1, 0, 0, 4, "", None, "", ""),
        ("SpSeq", 8, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("SpTorque", 16, 16, True, 0.002, 0, -65.534, 65.534, "Nm", None, "", ""),
        ("SpPosition", 32, 16, True, 0.001, 0, -32.767, 32.767, "rad", None, "", ""),
        ("SpVelocity", 48, 16, True, 0.001, 0, -32.767, 32.767, "rad/s", None, "", ""),
    ],
    "GAINS": [
        ("GainKp", 0, 32, True, 1, 0, 0, 2000, "Nm/rad", None, "", "float"),
        ("GainKd", 32, 32, True, 1, 0, 0, 50, "Nm s/rad", None, "", "float"),
    ],
    "CTRL_STATE": [
        ("CtrlModeAsked", 0, 4, False, 1, 0, 0, 15, "", None, "", ""),
        ("CtrlModeRun", 4, 4, False, 1, 0, 0, 15, "", None, "", ""),
        ("CtrlLimits", 8, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("CtrlTorqueRef", 16, 16, True, 0.01, 0, -327.68, 327.67, "Nm", None, "", ""),
        ("CtrlCurrent", 32, 16, True, 0.001, 0, -32.768, 32.767, "A", None, "", ""),
        ("CtrlSeq", 48, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("CtrlFlags", 56, 8, False, 1, 0, 0, 255, "", None, "", ""),
    ],
    "FEEDFORWARD": [
        ("FfTorque", 0, 32, True, 1, 0, f"-{F32_MAX}", F32_MAX, "Nm", None, "", "float"),
        ("FfSeq", 32, 8, False, 1, 0, 0, 255, "", None, "", ""),
    ],
    "TELEM_A": [
        ("TorqueFiltered", 0, 16, True, 0.01, 0, -327.68, 327.67, "Nm", None, "", ""),
        ("TorqueRaw", 16, 16, True, 0.01, 0, -327.68, 327.67, "Nm", None, "", ""),
        ("Ripple", 32, 16, True, 0.001, 0, -32.768, 32.767, "Nm", None, "", ""),
        ("SeqA", 48, 8, False, 1, 0, 0, 255, "", None, "", ""),
    ],
    "TELEM_B": [
        ("MotorVelocity", 0, 24, True, 0.001, 0, -8388.608, 8388.607, "rad/s", None, "", ""),
        ("Faults", 24, 24, False, 1, 0, 0, 16777215, "", None, "", ""),
        ("KfStatus", 48, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("SeqB", 56, 8, False, 1, 0, 0, 255, "", None, "", ""),
    ],
    "TELEM_C": [
        ("MotorCounts", 0, 32, False, 1, 0, 0, 4294967295, "counts", None, "", ""),
        ("OutputCounts", 32, 23, False, 1, 0, 0, 8388607, "counts", None, "", ""),
        ("OutputPresent", 55, 1, False, 1, 0, 0, 1, "", None, "", ""),
        ("SeqC", 56, 8, False, 1, 0, 0, 255, "", None, "", ""),
    ],
    "CMD": [
        ("Opcode", 0, 8, False, 1, 0, 0, 255, "", "opcode", "M", ""),
        ("Token", 8, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("FilterEnable", 16, 8, False, 1, 0, 0, 1, "", None, "FILTER_ENABLE", ""),
        ("MotorOrder", 16, 16, False, 0.01, 0, 0.01, 655.35, "1/rev", None, "ADD_MOTOR", ""),
        ("MotorQ", 32, 32, True, 1, 0, 0, F32_MAX, "Nm^2", None, "ADD_MOTOR", "float"),
        ("OutputOrder", 16, 16, False, 0.01, 0, 0.01, 655.35, "1/rev", None, "ADD_OUTPUT", ""),
        ("OutputQ", 32, 32, True, 1, 0, 0, F32_MAX, "Nm^2", None, "ADD_OUTPUT", "float"),
        ("FixedFrequency", 16, 16, False, 0.01, 0, 0.01, 499.99, "Hz", None, "ADD_FIXED", ""),
        ("FixedQ", 32, 32, True, 1, 0, 0, F32_MAX, "Nm^2", None, "ADD_FIXED", "float"),
        ("BlockIndex", 16, 8, False, 1, 0, 0, 7, "", None, "BLOCK_ENABLE", ""),
        ("BlockEnable", 24, 8, False, 1, 0, 0, 1, "", None, "BLOCK_ENABLE", ""),
        ("BlockGetIndex", 16, 8, False, 1, 0, 0, 7, "", None, "BLOCK_GET", ""),
        ("BlockGetField", 24, 8, False, 1, 0, 0, 3, "", "block_field", "BLOCK_GET", ""),
        ("SetParamId", 16, 8, False, 1, 0, 1, 255, "", "param", "SET_PARAM", ""),
        ("SetParamValue", 32, 32, True, 1, 0, f"-{F32_MAX}", F32_MAX, "", None, "SET_PARAM", "float"),
        ("GetParamId", 16, 8, False, 1, 0, 1, 255, "", "param", "GET_PARAM", ""),
        ("CalibUnixTime", 32, 32, False, 1, 0, 0, 4294967295, "s", None, "CALIB_SAVE", ""),
        ("VersionItem", 16, 8, False, 1, 0, 0, 15, "", "info", "VERSION", ""),
        ("InfoItem", 16, 8, False, 1, 0, 16, 255, "", "info", "INFO", ""),
        ("ProfileSaveSource", 16, 8, False, 1, 0, 0, 1, "", None, "PROFILE_SAVE", ""),
        ("ProfileLoadSource", 16, 8, False, 1, 0, 0, 1, "", None, "PROFILE_LOAD", ""),
        ("ProfilePutLine", 16, 8, False, 1, 0, 0, 63, "", None, "PROFILE_PUT", ""),
        ("ProfilePutOrder", 24, 8, False, 1, 0, 1, 255, "", None, "PROFILE_PUT", ""),
        ("ProfilePutValue", 32, 32, True, 1, 0, f"-{F32_MAX}", F32_MAX, "Nm", None,
         "PROFILE_PUT", "float"),
    ],
    "ACK": [
        ("AckOpcode", 0, 8, False, 1, 0, 0, 255, "", "opcode", "M", ""),
        ("AckToken", 8, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("AckResult", 16, 8, False, 1, 0, 0, 255, "", "result", "", ""),
        ("AckAux", 24, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("AckValue", 32, 32, True, 1, 0, f"-{F32_MAX}", F32_MAX, "", None, "FLOAT_ACKS", "float"),
        ("AckValueU32", 32, 32, False, 1, 0, 0, 4294967295, "", None, "U32_ACKS", ""),
    ],
    "HEARTBEAT": [
        ("State", 0, 8, False, 1, 0, 0, 3, "", "state", "", ""),
        ("HbFaults", 8, 24, False, 1, 0, 0, 16777215, "", None, "", ""),
        ("DeadlineMisses", 32, 16, False, 1, 0, 0, 65535, "", None, "", ""),
        ("CalibStatus", 48, 4, False, 1, 0, 0, 15, "", "record", "", ""),
        ("ConfigStatus", 52, 4, False, 1, 0, 0, 15, "", "record", "", ""),
        ("ProfileStatus", 56, 8, False, 1, 0, 0, 255, "", "record", "", ""),
    ],
    "BOOT": [
        ("ResetCause", 0, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("FaultRecord", 8, 1, False, 1, 0, 0, 1, "", None, "", ""),
        ("ConfigFromRecord", 9, 1, False, 1, 0, 0, 1, "", None, "", ""),
        ("FaultPc", 16, 32, False, 1, 0, 0, 4294967295, "", None, "", ""),
        ("ProtocolVersion", 48, 8, False, 1, 0, 0, 255, "", None, "", ""),
        ("BootConfigStatus", 56, 8, False, 1, 0, 0, 255, "", "record", "", ""),
    ],
}

U32_ACK_OPCODES = ("VERSION", "INFO")
BLOCK_FIELDS = ("LOCK", "ORDER", "Q_NM2", "ENABLED")   # BLOCK_GET's field byte (hd_fw_cmd.c)
KF_STATUS_DOC = "1 frozen, 2 bad input, 4 reset, 8 P clamped, 16 offset jump"


def _fmt(v) -> str:
    if isinstance(v, str):
        return v
    return format(v, ".10g") if isinstance(v, float) else str(v)


def _value_table(key: str) -> dict[int, str]:
    if key == "opcode":
        return {e.code: e.name for e in opcodes()}
    if key == "result":
        return {e.code: e.name for e in results()}
    if key == "state":
        return {e.code: e.name for e in states()}
    if key == "record":
        return {e.code: e.name for e in record_statuses()}
    if key == "info":
        return {e.code: e.name for e in info_items()}
    if key == "param":
        return {p.id: p.name for p in params()}
    if key == "block_field":
        return dict(enumerate(BLOCK_FIELDS))
    raise KeyError(key)


def _mux_ranges(spec: str) -> list[tuple[int, int]]:
    """Opcode ranges a multiplexed ACK value signal covers."""
    u32 = sorted(by_name(opcodes(), n).code for n in U32_ACK_OPCODES)
    if spec == "U32_ACKS":
        return [(c, c) for c in u32]
    ranges, lo = [], 0
    for c in u32:
        if c > lo:
            ranges.append((lo, c - 1))
        lo = c + 1
    ranges.append((lo, 255))
    return ranges


def generate_dbc() -> str:
    """firmware/hdjoint.dbc for node 1, from the .def files and DBC_LAYOUT."""
    node = 1
    out = ['VERSION "hdjoint protocol 2"', "", "", "NS_ :", "\tCM_", "\tBA_DEF_", "\tBA_",
           "\tVAL_", "\tSIG_VALTYPE_", "\tSG_MUL_VAL_", "", "BS_:", "", "BU_: HOST JOINT", "", ""]
    comments, vals, valtypes, muls = [], [], [], []
    for fr in frames():
        dbc_id = EXT_FLAG_DBC | fr.can_id(node)
        sender, receiver = ("JOINT", "HOST") if fr.direction == "tx" else ("HOST", "JOINT")
        out.append(f"BO_ {dbc_id} {fr.name}: {fr.dlc} {sender}")
        comments.append(f'CM_ BO_ {dbc_id} "{fr.doc}.";')
        for (name, start, length, signed, scale, offset, lo, hi, unit, table, mux,
             kind) in DBC_LAYOUT[fr.name]:
            if mux == "M":
                m = " M"
            elif mux in ("U32_ACKS", "FLOAT_ACKS"):
                ranges = _mux_ranges(mux)
                m = f" m{ranges[0][0]}"
                if len(ranges) > 1 or ranges[0][0] != ranges[0][1]:
                    spans = ", ".join(f"{a}-{b}" for a, b in ranges)
                    muls.append(f"SG_MUL_VAL_ {dbc_id} {name} AckOpcode {spans};")
            elif mux:
                m = f" m{by_name(opcodes(), mux).code}"
            else:
                m = ""
            sign = "-" if signed else "+"
            out.append(f" SG_ {name}{m} : {start}|{length}@1{sign} ({_fmt(scale)},{_fmt(offset)}) "
                       f"[{_fmt(lo)}|{_fmt(hi)}] \"{unit}\" {receiver}")
            if kind == "float":
                valtypes.append(f"SIG_VALTYPE_ {dbc_id} {name} : 1;")
            if table:
                items = " ".join(f'{k} "{v}"' for k, v in sorted(_value_table(table).items()))
                vals.append(f"VAL_ {dbc_id} {name} {items} ;")
            if name in ("Faults", "HbFaults"):
                bits = ", ".join(f"{f.code} {f.name}" for f in faults())
                comments.append(f'CM_ SG_ {dbc_id} {name} "HD_FAULT_* bits: {bits}.";')
            if name == "KfStatus":
                comments.append(f'CM_ SG_ {dbc_id} {name} "HD_KF_STATUS_* bits: {KF_STATUS_DOC}.";')
        out.append("")
    out += ["", 'CM_ "Harmonic-drive joint torque sensor, node 1: identifier = 0x01D00000 | '
                'type << 8 | node_id (29-bit). Generated by python -m hdtools.protocol '
                '--write-dbc from firmware/hd_protocol.def and hd_params.def; see '
                'docs/protocol.md.";']
    out += comments + [""] + vals + [""] + valtypes + [""] + muls
    return "\n".join(out) + "\n"


# ------------------------------------------------------------ doc tables
# Markdown tables generated from the .def files, kept in docs/*.md between
#   <!-- BEGIN generated:NAME -->  and  <!-- END generated:NAME -->
DOCS = ROOT / "docs"


def _md(header: list[str], rows: list[list]) -> str:
    def cell(v) -> str:
        return str(v).replace("|", "\\|")
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(cell(v) for v in r) + " |" for r in rows]
    return "\n".join(out)


def _range(p: Param) -> str:
    if p.type == "BOOL":
        return "on / off"
    lo = "(" if "LO_OPEN" in p.flags else "["
    return f"{lo}{p.lo:g}, {p.hi:g}]"


def _effect(p: Param) -> str:
    kind = "read only" if p.read_only else ("next tick" if "LIVE" in p.flags else
                                            "model rebuilt, filter restarts")
    store = "config" if "CONFIG" in p.flags else ("calibration" if "CALIB" in p.flags else "-")
    return f"{kind}; {store}"


def doc_tables() -> dict[str, str]:
    return {
        "params": _md(["id", "key (config text)", "CAN name", "type", "range", "unit",
                       "takes effect; record", "meaning"],
                      [[p.id, f"`{p.key}`", p.name, p.type, _range(p), p.unit, _effect(p), p.doc]
                       for p in params()]),
        "retired": _md(["id", "key", "why"],
                       [[r.code, f"`{r.name}`", r.doc] for r in retired_params()]),
        "faults": _md(["bit", "name", "meaning"], [[f.code, f.name, f.doc] for f in faults()]),
        "opcodes": _md(["opcode", "name", "arguments / answer"],
                       [[f"0x{e.code:02X}", e.name, e.doc] for e in opcodes()]),
        "results": _md(["code", "name", "meaning"], [[e.code, e.name, e.doc] for e in results()]),
        "frames": _md(["type", "identifier (node 1)", "name", "direction", "content"],
                      [[f"0x{f.type:02X}", f"0x{f.can_id(1):08X}", f.name,
                        "joint -> host" if f.direction == "tx" else "host -> joint", f.doc]
                       for f in frames()]),
        "records": _md(["code", "status", "meaning"],
                       [[e.code, e.name, e.doc] for e in record_statuses()]),
        "info": _md(["item", "name", "meaning"], [[e.code, e.name, e.doc] for e in info_items()]),
    }


_BLOCK = re.compile(r"(<!-- BEGIN generated:(\w+) -->\n)(?:.*?\n)?(<!-- END generated:\2 -->)", re.S)


def render_docs(text: str) -> str:
    """text with every generated block replaced by its current table."""
    tables = doc_tables()

    def sub(m):
        name = m.group(2)
        if name not in tables:
            raise DefError(f"unknown generated block {name!r}")
        return m.group(1) + tables[name] + "\n" + m.group(3)
    return _BLOCK.sub(sub, text)


def stale_docs() -> list[Path]:
    return [p for p in sorted(DOCS.glob("*.md")) if render_docs(p.read_text()) != p.read_text()]


def _write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m hdtools.protocol",
                                 description="Generate or check firmware/hdjoint.dbc and the "
                                             "generated tables in docs/*.md.")
    ap.add_argument("--write", action="store_true",
                    help="rewrite firmware/hdjoint.dbc and the docs' generated tables")
    ap.add_argument("--write-dbc", action="store_true", help="rewrite firmware/hdjoint.dbc only")
    ap.add_argument("--check", action="store_true",
                    help="exit 1 if the DBC or a doc table differs from the generated one")
    a = ap.parse_args(argv)
    text = generate_dbc()
    if a.write or a.write_dbc:
        _write(DBC_PATH, text)
        if a.write:
            for p in stale_docs():
                _write(p, render_docs(p.read_text()))
        return 0
    if a.check:
        bad = ([DBC_PATH] if DBC_PATH.read_text() != text else []) + stale_docs()
        if bad:
            print(f"{', '.join(str(p.relative_to(ROOT)) for p in bad)} out of date: "
                  f"run (cd tools && ../.venv/bin/python -m hdtools.protocol --write)",
                  file=sys.stderr)
            return 1
        return 0
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
