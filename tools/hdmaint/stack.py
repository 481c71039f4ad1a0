"""The worst-case stack of an image, from GCC's -fstack-usage and
-fcallgraph-info=su files (.ci) of its build tree, with the frames of
library functions without .ci data read from the disassembly.  Standard
library only."""
from __future__ import annotations

import re
from pathlib import Path

from .board import Board, TargetError, need, sh, symbols
from .m4_cycles import reg_count

NODE_RE = re.compile(r'node: \{ title: "([^"]+)" label: "([^"]*)"')
EDGE_RE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')


def load_callgraph(build: Path, images: tuple, image_dirs: list) -> tuple:
    frames, qualifiers, edges, origin = {}, {}, {}, {}
    ci_files = [p for p in build.rglob("*.ci")
                if "CMakeFiles" in p.parts and
                (not any(".dir" in part and part.split(".dir")[0] in images
                         for part in p.parts) or any(d in str(p) for d in image_dirs))]
    for ci in ci_files:
        text = ci.read_text()
        for m in NODE_RE.finditer(text):
            title, label = m.group(1), m.group(2)
            sm = re.search(r"\\n(\d+) bytes \(([^)]*)\)", label)
            if sm:
                frames[title] = int(sm.group(1))
                qualifiers[title] = sm.group(2)
                origin[title] = ci
        for m in EDGE_RE.finditer(text):
            edges.setdefault(m.group(1), []).append(m.group(2))
    return frames, qualifiers, edges, origin


def library_frame(objdump_text: str, name: str) -> tuple:
    """(stack bytes, callees) of a function without .ci data (libgcc, the
    assembly markers), from its disassembly: pushes, sp decrements and
    pre-decrement stores to sp, and its bl targets."""
    m = re.search(rf"<{re.escape(name)}>:\n((?:\s+[0-9a-f]+:.*\n)+)", objdump_text)
    if not m:
        return 0, []
    total = 0
    callees = []
    for line in m.group(1).splitlines():
        if re.search(r"\bpush(\.w)?\s", line) or re.search(r"\bstmdb(\.w)?\s+sp!", line):
            total += 4 * reg_count(line)
        sm = re.search(r"\bsub(\.w)?\s+sp,\s*(?:sp,\s*)?#(\d+)", line)
        if sm:
            total += int(sm.group(2))
        sm = re.search(r"\[sp,\s*#-(\d+)\]!", line)
        if sm:
            total += int(sm.group(1))
        cm = re.search(r"\bbl(?:x)?(?:\.w)?\s+[0-9a-f]+\s+<([^>+]+)>", line)
        if cm and cm.group(1) != name:
            callees.append(cm.group(1))
    return total, callees


def worst_stack(board: Board, elf: Path, isrs: tuple = ("SysTick_Handler",), fault_entry: str = "HardFault_Handler",
                hal_funcs: tuple | None = None) -> dict:
    """Deepest stack of main, of each interrupt in isrs (listed from the
    lowest priority up: each may preempt the ones before it) and of the
    fault handler.  hal_funcs: the functions the image puts in its hal_t
    (default: the QEMU backends' functions)."""
    image_dir = f"{elf.stem}.dir"
    frames, qualifiers, edges, origin = load_callgraph(board.build_dir, board.targets, [image_dir])
    objdump = sh([need("arm-none-eabi-objdump"), "-d", elf], capture_output=True, text=True).stdout
    defined = set(symbols(elf))
    # Indirect calls go through the HAL vtables and the mock's transmit hook:
    # every function of the HAL backends linked into this image is a candidate.
    # Vtable entries are the backends' file-local functions (titled
    # "file:name"); the transmit hook is the one public one.
    if hal_funcs is None:
        hal_candidates = [t for t, ci in origin.items()
                          if ("hal_mock.dir" in str(ci) or "hal_semihost.dir" in str(ci))
                          and t.split(":")[-1] in defined
                          and (":" in t or t == "hal_sh_canlog_hook")]
    else:
        hal_candidates = [t for t in origin if t.split(":")[-1] in hal_funcs
                          and t.split(":")[-1] in defined]
    memo, on_path = {}, set()
    notes = set()

    def resolve(name: str) -> str:
        if name in frames:
            return name
        short = name.split(":")[-1]
        if short in frames:
            return short
        return name

    def cost(name: str) -> tuple:
        name = resolve(name)
        if name == "__indirect_call":
            # A function reached through a pointer never calls itself back
            # through one here (the hook is not a vtable entry and vice versa).
            best = max((cost(c) for c in hal_candidates if resolve(c) not in on_path),
                       default=(0, []))
            return best[0], ["(indirect: HAL backend)"] + best[1]
        if name in memo:
            return memo[name]
        if name in on_path:
            raise TargetError(f"recursion through {name}: stack depth unbounded")
        on_path.add(name)
        if name in frames:
            own = frames[name]
            if qualifiers[name] not in ("static",):
                notes.add(f"{name}: {qualifiers[name]} stack")
        else:
            own, lib_callees = library_frame(objdump, name.split(":")[-1])
            edges.setdefault(name, []).extend(c for c in lib_callees
                                              if c not in edges.get(name, []))
            if own:
                notes.add(f"{name.split(':')[-1]}: no .su data, {own} bytes from its "
                          "disassembly")
        best = (0, [])
        for callee in edges.get(name, []):
            c = cost(callee)
            if c[0] > best[0]:
                best = c
        on_path.discard(name)
        memo[name] = (own + best[0], [f"{name.split(':')[-1]} {own}"] + best[1])
        return memo[name]

    main = cost("main")
    reset = frames.get("Reset_Handler", 0)
    isr_costs = [cost(n) for n in isrs]
    fault = cost(fault_entry)
    # Exception entry with an active FP context: 26 words (+ 4 bytes alignment).
    frame = 26 * 4 + 4
    total = reset + main[0] + sum(frame + c[0] for c in isr_costs) + frame + fault[0]
    return {"main": main, "reset": reset, "tick": isr_costs[0], "isrs": isr_costs,
            "fault": fault, "frame": frame, "total": total, "notes": sorted(notes)}
