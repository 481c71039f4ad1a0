"""The firmware configuration text (docs/design/firmware.md), parsed by the
firmware's own parser (firmware/hd_config_text.c) through ctypes.

The tools keep no second parser: what a text means, and why it is refused,
is what the joint itself would say.  parse() applies the text on top of the
firmware defaults (hd_fw_config_default) and returns the keys the text gave
with their values as the firmware parsed them, and its blocks if it has any.
"""
from __future__ import annotations

import ctypes
from ctypes import POINTER, c_bool, c_char_p, c_float, c_int, c_size_t, c_uint, c_uint8, c_uint16
from dataclasses import dataclass
from functools import lru_cache

from . import native, protocol

LOCKS = ("motor", "output", "fixed")  # hd_kf_lock_t


class _ParamInfo(ctypes.Structure):
    """hd_param_info_t (firmware/hd_params.h)"""
    _fields_ = [("id", c_uint8), ("type", c_uint8), ("flags", c_uint8), ("offset", c_uint16),
                ("lo", c_float), ("hi", c_float), ("key", c_char_p), ("name", c_char_p),
                ("unit", c_char_p), ("dflt", c_float)]


class _Error(ctypes.Structure):
    """hd_cfgtxt_error_t (firmware/hd_config_text.h)"""
    _fields_ = [("code", c_int), ("line", c_uint), ("message", c_char_p),
                ("first_line", c_uint), ("param_id", c_uint)]


@lru_cache(maxsize=None)
def _keys_type():
    """hd_cfgtxt_keys_t: one line number per row of the parameter table."""
    return type("Keys", (ctypes.Structure,),
                {"_fields_": [("blocks", c_bool), ("line_of", c_uint * len(protocol.params()))]})


@lru_cache(maxsize=None)
def lib() -> ctypes.CDLL:
    """libhd_emu.so (the firmware core, hdfw, is linked into it)."""
    L = native.load_library("hd_emu")
    L.hd_config_text_config_size.restype = c_size_t
    L.hd_config_text_config_size.argtypes = []
    L.hd_fw_config_default.restype = None
    L.hd_fw_config_default.argtypes = [ctypes.c_void_p]
    L.hd_config_text_parse_keys.restype = c_int
    L.hd_config_text_parse_keys.argtypes = [c_char_p, c_size_t, ctypes.c_void_p, POINTER(_Error),
                                            POINTER(_keys_type())]
    L.hd_config_text_block.restype = c_int
    L.hd_config_text_block.argtypes = [ctypes.c_void_p, c_uint, POINTER(c_uint), POINTER(c_float),
                                       POINTER(c_float), POINTER(c_uint)]
    L.hd_param_count.restype = c_size_t
    L.hd_param_count.argtypes = []
    L.hd_param_at.restype = POINTER(_ParamInfo)
    L.hd_param_at.argtypes = [c_size_t]
    L.hd_param_by_id.restype = POINTER(_ParamInfo)
    L.hd_param_by_id.argtypes = [c_uint]
    L.hd_param_get.restype = c_float
    L.hd_param_get.argtypes = [POINTER(_ParamInfo), ctypes.c_void_p]
    if L.hd_param_count() != len(protocol.params()):
        raise RuntimeError(f"{L._name}: {L.hd_param_count()} parameter rows, hd_params.def has "
                           f"{len(protocol.params())}: rebuild the C libraries")
    return L


@dataclass(frozen=True)
class Block:
    kind: str          # motor | output | fixed
    order: float       # order, or frequency in Hz of a fixed block
    q_nm2: float
    enabled: bool


@dataclass(frozen=True)
class Parsed:
    values: list       # (line, protocol.Param, value) in the text's order
    blocks: list | None  # the text's blocks, None if it has no block line


def _blocks(cfg, L) -> list[Block]:
    out = []
    lock, enabled, order, q = c_uint(), c_uint(), c_float(), c_float()
    while L.hd_config_text_block(cfg, len(out), ctypes.byref(lock), ctypes.byref(order),
                                 ctypes.byref(q), ctypes.byref(enabled)) == 0:
        out.append(Block(LOCKS[lock.value], float(order.value), float(q.value), bool(enabled.value)))
    return out


def parse(text: str) -> Parsed:
    """The text as the firmware parses it, on top of its defaults.  ValueError
    with the firmware's message, naming the line ("line 3: key given twice
    (first on line 1)"), if the firmware refuses it."""
    L = lib()
    data = text.encode("utf-8", "surrogateescape")
    cfg = ctypes.create_string_buffer(L.hd_config_text_config_size())
    L.hd_fw_config_default(cfg)
    err, keys = _Error(), _keys_type()()
    if L.hd_config_text_parse_keys(data, len(data), cfg, ctypes.byref(err), ctypes.byref(keys)):
        why = err.message.decode()
        if why == "unknown key":  # the C message is static: name the key
            key = text.split("\n")[err.line - 1].split("#", 1)[0].split("=", 1)[0].split()
            why += f" {key[0]!r}" if key else ""
        if err.first_line:
            why += f" (first on line {err.first_line})"
        if err.param_id:
            p = protocol.param_by_id(err.param_id)
            lo = "(" if "LO_OPEN" in p.flags else "["
            why += f" {lo}{p.lo:g}, {p.hi:g}]" if err.line else f": {p.key}"
        raise ValueError(f"line {err.line}: {why}" if err.line else why)
    values = []
    for row, line in enumerate(keys.line_of):
        if line:
            info = L.hd_param_at(row)
            values.append((line, protocol.param_by_id(info.contents.id),
                           float(L.hd_param_get(info, cfg))))
    values.sort(key=lambda v: v[0])
    return Parsed(values, _blocks(cfg, L) if keys.blocks else None)


def param_value(param: protocol.Param, text: str) -> float:
    """One value for param as the firmware's parser reads it (ValueError
    naming the key, not the line)."""
    if "\n" in text or "#" in text:
        raise ValueError(f"{param.key}: {text!r} is not one value")
    try:
        parsed = parse(f"{param.key} = {text}\n")
    except ValueError as exc:
        raise ValueError(f"{param.key} = {text}: {str(exc).removeprefix('line 1: ')}") from None
    return parsed.values[0][2]
