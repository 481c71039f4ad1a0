"""The joint's protocol vocabulary and parameter table, read from the C
sources that define them (firmware/hd_protocol.def, firmware/hd_params.def),
and the DBC generated from them.

Nothing here is typed twice: frame types, opcodes, results, fault bits,
states, record statuses, info items, parameters and the frames' signal
layouts (HD_SIGNAL rows) come from the .def files; firmware/hdjoint.dbc
(hdtools.protocol_dbc), the C codec (hdtools.protocol_c) and the docs tables
are generated from them (`python -m hdtools.protocol --write`).
tests/firmware/test_protocol_tables.py checks that the committed DBC equals
the generated one and that the C encoder's bytes decode through it.
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

from .safeio import OutputError, Outputs

from . import paths  # noqa: E402 - the source tree or the installed copies
from . import protocol_c, protocol_dbc

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
    default: float | None = None  # hd_fw_config_default's; None: the library's (LIB)

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
        if len(row) != 11:
            raise DefError(f"hd_params.def: row {row[:3]} has {len(row)} columns, wants 11")
        pid, name, key, typ, _field, default, lo, hi, flags, unit, doc = row
        out.append(Param(_int(pid), name, key.strip('"'), typ, float(lo), float(hi),
                         frozenset(f.strip() for f in flags.split("|")), unit.strip('"'), doc,
                         None if default == "LIB" else float(default)))
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


# ------------------------------------------------------- frame layouts
# HD_SIGNAL / HD_ARG / HD_REPLY rows of hd_protocol.def: every signal of every
# frame and every command's arguments and reply.  The DBC, the C codec
# (hdtools.protocol_c) and the doc tables are generated from them.
SIGNAL_TYPES = ("U", "I", "UQ", "F32", "F32_ANY")


@dataclass(frozen=True)
class Signal:
    owner: str        # frame (HD_SIGNAL) or opcode (HD_ARG) name
    name: str         # DBC name
    field: str        # C struct member
    start: int
    bits: int
    type: str         # SIGNAL_TYPES
    scale: str        # as written (the DBC and C take the text)
    lo: str
    hi: str
    unit: str
    values: str       # value table or comment key, "" if none
    mux: str          # "", "M", "F32_REPLY", "U32_REPLY"; an HD_ARG: its opcode
    doc: str

    @property
    def signed(self) -> bool:
        return self.type in ("I", "F32", "F32_ANY")

    @property
    def is_float(self) -> bool:
        return self.type in ("F32", "F32_ANY")


@dataclass(frozen=True)
class Reply:
    opcode: str
    type: str         # F32 | U32
    aux: str
    value: str
    unit: str


def _signal(row: list[str], owner_is_opcode: bool) -> Signal:
    if owner_is_opcode:
        if len(row) != 12:
            raise DefError(f"hd_protocol.def: HD_ARG {row[:2]} has {len(row)} columns, wants 12")
        row = row[:11] + [row[0]] + row[11:]
    elif len(row) != 13:
        raise DefError(f"hd_protocol.def: HD_SIGNAL {row[:2]} has {len(row)} columns, wants 13")
    owner, name, field, start, bits, typ, scale, lo, hi, unit, values, mux, doc = row
    if typ not in SIGNAL_TYPES:
        raise DefError(f"hd_protocol.def: {owner}.{name}: type {typ!r} not one of {SIGNAL_TYPES}")
    sig = Signal(owner, name, field, _int(start), _int(bits), typ, scale, lo, hi,
                 unit.strip('"'), values, mux, doc)
    if sig.start < 0 or sig.bits < 1 or sig.start + sig.bits > 64 or \
            (sig.is_float and sig.bits != 32):
        raise DefError(f"hd_protocol.def: {owner}.{name}: bits {sig.start}+{sig.bits}")
    return sig


@lru_cache(maxsize=None)
def signals() -> tuple[Signal, ...]:
    """Every HD_SIGNAL row (frame signals, the command's arguments excluded)."""
    names = {f.name for f in frames()}
    out = tuple(_signal(r, False) for r in _rows(PROTOCOL_DEF, "HD_SIGNAL"))
    bad = [s.owner for s in out if s.owner not in names]
    if bad:
        raise DefError(f"hd_protocol.def: HD_SIGNAL of unknown frame(s) {sorted(set(bad))}")
    return out


@lru_cache(maxsize=None)
def args() -> tuple[Signal, ...]:
    """Every HD_ARG row: a command's arguments in CMD, multiplexed by its opcode."""
    names = {e.name for e in opcodes()}
    out = tuple(_signal(r, True) for r in _rows(PROTOCOL_DEF, "HD_ARG"))
    bad = [s.owner for s in out if s.owner not in names]
    if bad:
        raise DefError(f"hd_protocol.def: HD_ARG of unknown opcode(s) {sorted(set(bad))}")
    return out


def frame_signals(name: str) -> tuple[Signal, ...]:
    return tuple(s for s in signals() if s.owner == name)


def command_args(opcode: str) -> tuple[Signal, ...]:
    return tuple(s for s in args() if s.owner == opcode)


@lru_cache(maxsize=None)
def replies() -> dict[str, Reply]:
    out = {}
    for row in _rows(PROTOCOL_DEF, "HD_REPLY"):
        if len(row) != 5 or row[1] not in ("F32", "U32"):
            raise DefError(f"hd_protocol.def: HD_REPLY {row[:2]}: wants (opcode, F32|U32, aux, "
                           f"value, unit)")
        out[row[0]] = Reply(row[0], row[1], row[2], row[3], row[4].strip('"'))
    return out


def reply(opcode: str) -> Reply:
    """What the ACK of a command carries (aux and value 0 without a row)."""
    return replies().get(opcode, Reply(opcode, "F32", "-", "-", ""))


# Opcodes from 0x80 are answers without a command (hd_protocol.def).
ANSWER_ONLY_FROM = 0x80


def commands() -> tuple[Entry, ...]:
    """The opcodes a host may send."""
    return tuple(e for e in opcodes() if e.code < ANSWER_ONLY_FROM)


@lru_cache(maxsize=None)
def block_fields() -> tuple[Entry, ...]:
    return _entries("HD_BLOCK_FIELD")


# --------------------------------------------------------------------- DBC
F32_MAX = "3.4E+038"
U32_ACK_OPCODES = tuple(e.name for e in opcodes() if reply(e.name).type == "U32")
BLOCK_FIELDS = tuple(e.name for e in block_fields())   # BLOCK_GET's field byte


def generate_dbc() -> str:
    """firmware/hdjoint.dbc for node 1, from the .def files."""
    return protocol_dbc.generate_dbc(sys.modules[__name__])


DOCS = ROOT / "docs"


def doc_tables() -> dict[str, str]:
    """The generated tables of docs/**/*.md, by block name."""
    return protocol_dbc.doc_tables(sys.modules[__name__])


def render_docs(text: str) -> str:
    """text with every generated block replaced by its current table."""
    try:
        return protocol_dbc.render_docs(text, doc_tables())
    except ValueError as exc:
        raise DefError(str(exc)) from None


def stale_docs() -> list[Path]:
    return [p for p in sorted(DOCS.rglob("*.md")) if render_docs(p.read_text()) != p.read_text()]


def generate_c() -> dict[Path, str]:
    """firmware/hd_can_gen*.[ch] (hdtools.protocol_c): {path: text}."""
    files = protocol_c.generate(frames(), frame_signals, commands(), command_args,
                                U32_ACK_OPCODES)
    return {paths.firmware_file(name): text for name, text in files.items()}


def generated_files() -> dict[Path, str]:
    """Every file generated from the .def files, with its current text."""
    return {DBC_PATH: generate_dbc(), **generate_c()}


def stale_files() -> list[Path]:
    """Generated files (and docs) that differ from what the .def files give."""
    return [p for p, text in generated_files().items()
            if not p.exists() or p.read_text() != text] + stale_docs()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m hdtools.protocol",
                                 description="Generate or check what comes from "
                                             "firmware/hd_protocol.def and hd_params.def: the DBC, "
                                             "the C codec and the tables in docs/**/*.md.")
    ap.add_argument("--write", action="store_true",
                    help="rewrite firmware/hdjoint.dbc, hd_can_gen*.[ch] and the docs' tables")
    ap.add_argument("--write-dbc", action="store_true", help="rewrite firmware/hdjoint.dbc only")
    ap.add_argument("--check", action="store_true",
                    help="exit 1 if a generated file or doc table differs from the generated one")
    a = ap.parse_args(argv)
    try:
        if a.write or a.write_dbc:
            files = generated_files()
            with Outputs() as out:          # every file or none
                for path, text in files.items():
                    if a.write or path == DBC_PATH:
                        out.write_text(path, text)
                if a.write:
                    for p in stale_docs():
                        out.write_text(p, render_docs(p.read_text()))
                out.commit()
            return 0
        if a.check:
            bad = stale_files()
            if bad:
                print(f"{', '.join(str(p.relative_to(ROOT)) for p in bad)} out of date: "
                      f"run (cd tools && ../.venv/bin/python -m hdtools.protocol --write)",
                      file=sys.stderr)
                return 1
            return 0
        sys.stdout.write(generate_dbc())
    except (OSError, DefError, OutputError) as exc:
        print(f"hdtools.protocol: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
