"""The C codec of the CAN protocol, generated from the rows of
firmware/hd_protocol.def (hdtools.protocol reads them and calls generate()).

Out come firmware/hd_can_gen.h (a struct per frame, a typed argument struct
per command, the scales), firmware/hd_can_gen.c (pack / unpack of the 8
data bytes, encode / decode of whole frames), hd_can_gen_cmd.c (the same for
the command frames, CMD and ACK, and the opcode predicates) and
hd_can_gen_internal.h (the byte helpers both .c files inline).  The firmware build needs
nothing new: both files are committed, and tests/firmware/
test_protocol_tables.py fails when they differ from what this module makes
of the .def file.  Each signal is packed into one little-endian 64-bit word,
so a layout is only ever its start bit and width.

Pure text generation: no file access, no import of the reader (the reader
imports this module; an import the other way would be a cycle).
"""
from __future__ import annotations

GENERATED = ("Generated from firmware/hd_protocol.def by `cd tools && ../.venv/bin/python -m "
             "hdtools.protocol --write`: do not edit.")


def _c_float(text: str) -> str:
    v = float(text)
    r = repr(v)
    return (r if ("e" in r or "." in r) else r + ".0") + "f"


def _ctype(sig) -> str:
    if sig.type in ("I", "UQ", "F32", "F32_ANY"):
        return "float"
    if sig.bits == 1:
        return "bool"
    return "uint8_t" if sig.bits <= 8 else ("uint16_t" if sig.bits <= 16 else "uint32_t")


def _mask(bits: int) -> str:
    return f"0x{(1 << bits) - 1:X}u"


def _const(owner: str, field: str) -> str:
    return f"HD_CAN_{owner.upper()}_{field.upper()}"


def _member(sig) -> str:
    unit = f" [{sig.unit}]" if sig.unit else ""
    return f"    {_ctype(sig)} {sig.field}; /* {sig.name}{unit}: {sig.doc} */"


def _pack_expr(sig, src: str) -> str:
    """The signal's raw bits as a uint64_t at their place in the word."""
    if sig.type == "I":
        raw = (f"((uint32_t)hd_can_scale_int({src}, {_const(sig.owner, sig.field)}_LSB, "
               f"{(1 << (sig.bits - 1)) - 1}) & {_mask(sig.bits)})")
    elif sig.type == "UQ":
        raw = (f"hd_can_scale_uq({src}, {_const(sig.owner, sig.field)}_DIV, "
               f"{_c_float(str((1 << sig.bits) - 1))})")
    elif sig.is_float:
        raw = f"f32_bits({src})"
    elif sig.bits == 1:
        raw = f"({src} ? 1u : 0u)"
    else:
        raw = f"({src} & {_mask(sig.bits)})"
    return f"(uint64_t){raw} << {sig.start}"


def _unpack_lines(sig, dst: str, bit: int) -> list[str]:
    """Statements that set dst from the word w, and flag bit `bit` of na
    when the value is not available."""
    raw = f"(uint32_t)(w >> {sig.start}) & {_mask(sig.bits)}"
    if sig.type == "I":
        return [f"    {{ const int32_t r = sext({raw}, {sig.bits});",
                f"      {dst} = (float)r * {_const(sig.owner, sig.field)}_LSB;",
                f"      na |= (r == -{1 << (sig.bits - 1)}) ? (1u << {bit}) : 0u; }}"]
    if sig.type == "UQ":
        return [f"    {dst} = (float)({raw}) / {_const(sig.owner, sig.field)}_DIV;"]
    if sig.is_float:
        lines = [f"    {dst} = bits_f32({raw});"]
        if sig.type == "F32":
            lines.append(f"    na |= isfinite({dst}) ? 0u : (1u << {bit});")
        return lines
    if sig.bits == 1:
        return [f"    {dst} = (({raw}) != 0u);"]
    return [f"    {dst} = ({_ctype(sig)})({raw});"]


def _scales(sigs) -> list[str]:
    out = []
    for s in sigs:
        if s.type == "I":
            out.append(f"#define {_const(s.owner, s.field)}_LSB {_c_float(s.scale)} /* {s.unit} */")
        elif s.type == "UQ":
            out.append(f"#define {_const(s.owner, s.field)}_DIV "
                       f"{_c_float(str(round(1.0 / float(s.scale))))}")
    return out


def _na_bits(owner: str, sigs) -> list[str]:
    return [f"#define HD_CAN_NA_{owner.upper()}_{s.field.upper()} (1u << {i}u)"
            for i, s in enumerate(sigs) if s.type in ("I", "F32")]


COMMAND_FRAMES = ("CMD", "ACK")   # their codec goes to hd_can_gen_cmd.c


def _c_file(name: str, what: str) -> list[str]:
    return [f"/* {name}: {what}", f" * {GENERATED} */", '#include "hd_can_proto.h"', "",
            "#include <math.h> /* isfinite: a compiler builtin, no libm call */",
            "#include <string.h>", "", '#include "hd_can_gen_internal.h"', ""]


def generate(frames, frame_signals, commands, command_args, u32_replies) -> dict[str, str]:
    """{file name in firmware/: text} for hd_can_gen.h, hd_can_gen_internal.h,
    hd_can_gen.c and hd_can_gen_cmd.c.  frames: objects with name, type,
    direction, doc; frame_signals(name) / command_args(opcode): the rows;
    commands: opcode entries (code, name, doc) a host may send; u32_replies:
    the opcodes whose ACK value is a u32."""
    h = [f"/* hd_can_gen.h: the frames and commands of the CAN protocol as C types.",
         f" * {GENERATED} */", "#ifndef HD_CAN_GEN_H", "#define HD_CAN_GEN_H", "",
         "/* Included by hd_can_proto.h (hal.h, the enums and the helpers first). */", ""]
    c = _c_file("hd_can_gen.c", "pack / unpack / encode / decode of every frame but the "
                "commands' (hd_can_gen_cmd.c).")
    c_cmd = _c_file("hd_can_gen_cmd.c", "pack / unpack / encode / decode of the command "
                    "frames (CMD, ACK) and the opcode predicates.")
    inl = ["/* hd_can_gen_internal.h: the byte helpers of hd_can_gen.c and hd_can_gen_cmd.c.",
         f" * {GENERATED} */", "#ifndef HD_CAN_GEN_INTERNAL_H", "#define HD_CAN_GEN_INTERNAL_H",
         "", "#include <stdint.h>", "#include <string.h>", "",
         "static inline uint32_t f32_bits(float v) { uint32_t u; memcpy(&u, &v, sizeof u); return u; }",
         "static inline float bits_f32(uint32_t u) { float v; memcpy(&v, &u, sizeof v); return v; }",
         "static inline int32_t sext(uint32_t raw, unsigned bits)",
         "{", "    const uint32_t sign = 1u << (bits - 1u);",
         "    return (int32_t)(raw ^ sign) - (int32_t)sign;", "}",
         "/* Two 32-bit halves with constant shifts: a loop over a 64-bit",
         " * variable shift costs the Cortex-M4 a libgcc-style sequence per byte. */",
         "static inline uint32_t load_u32(const uint8_t *d)",
         "{", "    return (uint32_t)d[0] | (uint32_t)d[1] << 8 | (uint32_t)d[2] << 16 | (uint32_t)d[3] << 24;",
         "}",
         "static inline uint64_t load_word(const uint8_t *d)",
         "{", "    return (uint64_t)load_u32(d) | (uint64_t)load_u32(d + 4) << 32;", "}",
         "static inline void store_u32(uint8_t *d, uint32_t u)",
         "{", "    d[0] = (uint8_t)u;", "    d[1] = (uint8_t)(u >> 8);", "    d[2] = (uint8_t)(u >> 16);",
         "    d[3] = (uint8_t)(u >> 24);", "}",
         "static inline void store_word(uint8_t *d, uint64_t w)",
         "{", "    store_u32(d, (uint32_t)w);", "    store_u32(d + 4, (uint32_t)(w >> 32));", "}", "",
         "#endif /* HD_CAN_GEN_INTERNAL_H */"]

    # -- commands: a typed struct per command with arguments, one union
    cmd_with_args = [e for e in commands if command_args(e.name)]
    for e in cmd_with_args:
        a = command_args(e.name)
        h += _scales(a)
        h += [f"/* {e.name} (0x{e.code:02X}): {e.doc} */", "typedef struct {"]
        h += [_member(s) for s in a] + [f"}} hd_can_cmd_{e.name.lower()}_t;", ""]
    h += ["/* Is opcode one a host may send (an HD_OPCODE row below 0x80)? */",
          "bool hd_can_is_command(uint8_t opcode);",
          "/* Opcodes whose ACK carries a u32 (value_u32) instead of a float. */",
          "bool hd_can_ack_is_u32(uint8_t opcode);", ""]
    c_cmd += ["bool hd_can_is_command(uint8_t opcode)", "{", "    switch (opcode) {"]
    c_cmd += [f"    case 0x{e.code:02X}u: /* {e.name} */" for e in commands]
    c_cmd += ["        return true;", "    default:", "        return false;", "    }", "}", "",
              "bool hd_can_ack_is_u32(uint8_t opcode)", "{", "    switch (opcode) {"]
    c_cmd += [f"    case HD_CMD_{n}:" for n in u32_replies]
    c_cmd += ["        return true;", "    default:", "        return false;", "    }", "}", ""]

    codec = {False: c, True: c_cmd}
    for fr in frames:
        c = codec[fr.name in COMMAND_FRAMES]
        sigs = list(frame_signals(fr.name))
        low = fr.name.lower()
        t = f"hd_can_{low}_t"
        is_cmd = fr.name == "CMD"
        muxer = next((s for s in sigs if s.mux == "M"), None)
        arrow = "joint -> host" if fr.direction == "tx" else "host -> joint"
        h += _scales(sigs) + _na_bits(fr.name, sigs)
        h += [f"/* {fr.name} (type 0x{fr.type:02X}, {arrow}): {fr.doc} */", "typedef struct {"]
        h += [_member(s) for s in sigs]
        if is_cmd:
            h += ["    union {"]
            h += [f"        hd_can_cmd_{e.name.lower()}_t {e.name.lower()};" for e in cmd_with_args]
            h += ["    } arg; /* by opcode; commands without arguments have no member */"]
        h += [f"}} {t};", "",
              f"void hd_can_pack_{low}(const {t} *v, uint8_t data[HD_CAN_DLC]);",
              "/* Returns the HD_CAN_NA_* bits of values not available (an int at its",
              " * minimum, a checked float not finite); 0 if all are. */",
              f"uint32_t hd_can_unpack_{low}(const uint8_t data[HD_CAN_DLC], {t} *v);",
              f"void hd_can_encode_{low}(uint8_t node_id, const {t} *v, hal_can_frame_t *f);"]
        if fr.direction == "tx":
            h += ["/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */",
                  f"int hd_can_decode_{low}(const hal_can_frame_t *f, {t} *v);"]
        elif not is_cmd:
            h += ["/* HD_CAN_RES_OK, BAD_FRAME / BAD_LENGTH, or NOT_FINITE (a value not",
                  " * available); the ranges are the firmware's to check. */",
                  f"int hd_can_decode_{low}(const hal_can_frame_t *f, {t} *v);"]
        h += [""]

        def pack_sig(s, src):
            if s.mux in ("F32_REPLY", "U32_REPLY"):
                cond = "" if s.mux == "U32_REPLY" else "!"
                return [f"    if ({cond}hd_can_ack_is_u32(v->{muxer.field})) {{",
                        f"        w |= {_pack_expr(s, src)};", "    }"]
            return [f"    w |= {_pack_expr(s, src)};"]

        c += [f"void hd_can_pack_{low}(const {t} *v, uint8_t data[HD_CAN_DLC])", "{",
              "    uint64_t w = 0u;"]
        for s in sigs:
            c += pack_sig(s, f"v->{s.field}")
        if is_cmd:
            c += [f"    switch (v->{muxer.field}) {{"]
            for e in cmd_with_args:
                c += [f"    case HD_CMD_{e.name}:"]
                for s in command_args(e.name):
                    c += ["    " + ln for ln in pack_sig(s, f"v->arg.{e.name.lower()}.{s.field}")]
                c += ["        break;"]
            c += ["    default:", "        break;", "    }"]
        c += ["    store_word(data, w);", "}", ""]

        c += [f"uint32_t hd_can_unpack_{low}(const uint8_t data[HD_CAN_DLC], {t} *v)", "{",
              "    const uint64_t w = load_word(data);", "    uint32_t na = 0u;"]
        if is_cmd or any(s.mux for s in sigs):
            # fields only some frames carry (a command's arguments, an ACK's
            # reply) read as 0 otherwise; a frame whose every field is
            # assigned below needs no clearing (a memset per decode in the tick)
            c += ["    memset(v, 0, sizeof *v);"]
        for i, s in enumerate(sigs):
            lines = _unpack_lines(s, f"v->{s.field}", i)
            if s.mux in ("F32_REPLY", "U32_REPLY"):
                cond = "" if s.mux == "U32_REPLY" else "!"
                lines = [f"    if ({cond}hd_can_ack_is_u32(v->{muxer.field})) {{"] + \
                        ["    " + ln for ln in lines] + ["    }"]
            c += lines
        if is_cmd:
            c += [f"    switch (v->{muxer.field}) {{"]
            for e in cmd_with_args:
                c += [f"    case HD_CMD_{e.name}:"]
                for i, s in enumerate(command_args(e.name)):
                    c += ["    " + ln for ln in
                          _unpack_lines(s, f"v->arg.{e.name.lower()}.{s.field}", i)]
                c += ["        break;"]
            c += ["    default:", "        break;", "    }"]
        c += ["    return na;", "}", ""]

        c += [f"void hd_can_encode_{low}(uint8_t node_id, const {t} *v, hal_can_frame_t *f)", "{",
              f"    hd_can_frame_init(f, HD_CAN_FRAME_{fr.name}, node_id);",
              f"    hd_can_pack_{low}(v, f->data);", "}", ""]
        if fr.direction == "tx":
            c += [f"int hd_can_decode_{low}(const hal_can_frame_t *f, {t} *v)", "{",
                  f"    if (!hd_can_frame_is(f, HD_CAN_FRAME_{fr.name}, NULL)) {{",
                  "        return -1;", "    }", f"    (void)hd_can_unpack_{low}(f->data, v);",
                  "    return 0;", "}", ""]
        elif not is_cmd:
            c += [f"int hd_can_decode_{low}(const hal_can_frame_t *f, {t} *v)", "{",
                  "    const int rc = hd_can_rx_check(f);", "    if (rc != HD_CAN_RES_OK) {",
                  "        return rc;", "    }",
                  f"    return hd_can_unpack_{low}(f->data, v) == 0u ? HD_CAN_RES_OK "
                  f": HD_CAN_RES_NOT_FINITE;", "}", ""]
    h += ["#endif /* HD_CAN_GEN_H */"]

    def text(lines):
        return "\n".join(lines).rstrip("\n") + "\n"
    return {"hd_can_gen.h": "\n".join(h) + "\n", "hd_can_gen_internal.h": text(inl),
            "hd_can_gen.c": text(codec[False]), "hd_can_gen_cmd.c": text(codec[True])}
