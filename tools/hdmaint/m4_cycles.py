"""Cortex-M4 cycle estimates of counted instructions: each executed
instruction's best and worst cycles from the Cortex-M4 TRM tables, over an
image's disassembly.  Standard library only."""
from __future__ import annotations

import re
from pathlib import Path

from .board import need, sh


def disassembly(elf: Path) -> dict:
    """address -> (mnemonic, operands) from objdump."""
    out = sh([need("arm-none-eabi-objdump"), "-d", "--no-show-raw-insn", elf],
             capture_output=True, text=True).stdout
    insns = {}
    for line in out.splitlines():
        m = re.match(r"^\s+([0-9a-f]+):\s+(\S+)\s*(.*)$", line)
        if m:
            insns[int(m.group(1), 16)] = (m.group(2), m.group(3))
    return insns


def reg_count(ops: str) -> int:
    m = re.search(r"\{([^}]*)\}", ops)
    if not m:
        return 1
    n = 0
    for part in m.group(1).split(","):
        part = part.strip()
        r = re.match(r"([a-z]+)(\d+)-[a-z]+(\d+)", part)
        n += int(r.group(3)) - int(r.group(2)) + 1 if r else 1
    return n


CONDS = ("eq", "ne", "cs", "cc", "hs", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt",
         "gt", "le")


def m4_cycles(mnem: str, ops: str) -> tuple:
    """(best, worst) cycles of one instruction, Cortex-M4 TRM (r0p1) tables
    3-1 (processor) and 7-1 (FPU), zero-wait-state memory.  P (pipeline
    refill after a taken branch) is 1..3; a load/store that follows another
    can pipeline to 1 cycle."""
    base = mnem.split(".")[0]
    if base.startswith("v"):
        if base.startswith(("vdiv", "vsqrt")):
            return (14, 14)
        if base.startswith(("vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms")):
            return (3, 3)
        if base.startswith(("vldr", "vstr")):
            return (2, 2)
        if base.startswith(("vldm", "vstm", "vpush", "vpop")):
            n = reg_count(ops)
            return (1 + n, 1 + n)
        if base.startswith("vmov") and ops.count(",") >= 2:
            return (2, 2)  # two core registers <-> two singles / a double
        return (1, 1)
    if base.startswith("it"):
        return (0, 1)  # usually folded into the preceding instruction
    if base in ("b", "bl", "bx", "blx") or (base.startswith("b") and base[1:] in CONDS):
        if base[1:] in CONDS:
            return (1, 4)   # not taken: 1; taken: 1 + P
        return (2, 4)       # 1 + P
    if base in ("cbz", "cbnz"):
        return (1, 4)
    if base in ("tbb", "tbh"):
        return (3, 5)
    if base.startswith(("push", "stm")):
        n = reg_count(ops)
        return (1 + n, 1 + n)
    if base.startswith(("pop", "ldm")):
        n = reg_count(ops)
        if "pc" in ops:
            return (1 + n + 1, 1 + n + 3)
        return (1 + n, 1 + n)
    if base.startswith(("ldrd", "strd")):
        return (3, 3)
    if base.startswith("ldr"):
        if re.match(r"\s*pc\b", ops):
            return (3, 5)
        return (1, 2)
    if base.startswith("str"):
        return (1, 2)
    if base.startswith(("sdiv", "udiv")):
        return (2, 12)
    if base.startswith(("mla", "mls")):
        return (2, 2)
    return (1, 1)  # data processing, MUL, long multiplies, moves, compares


def cycle_estimate(hist: dict, insns: dict, calls: int) -> tuple:
    """(best, worst) cycles per call; an address objdump did not list
    counts one cycle."""
    lo = hi = 0
    for pc, n in hist.items():
        c_lo, c_hi = m4_cycles(*insns[pc]) if pc in insns else (1, 1)
        lo += n * c_lo
        hi += n * c_hi
    return lo / calls, hi / calls


# ------------------------------------------------------------------- budget
