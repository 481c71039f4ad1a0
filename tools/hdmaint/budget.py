"""tools/target budget on the mps2-an386 images: flash and RAM (by
component), heap, worst-case stack and the instruction counts of the bench
image's sections, measured into one dict (budget_render.py renders it; the
STM32F4 port's measure is stm32f4.py).  Standard library only."""
from __future__ import annotations

import json
import re
import statistics
from pathlib import Path

from hdtools.safeio import OutputError, Outputs

from .board import ROOT, Board, TargetError, build_images, need, sh, symbols
from .m4_cycles import cycle_estimate, disassembly
from .qemu_run import labelled_sections
from .stack import worst_stack

# Clock frequencies of the MCU classes the image targets (for microseconds).
MCU_CLOCKS_MHZ = [("STM32F4", 168), ("STM32G4", 170)]


def section_sizes(elf: Path) -> dict:
    out = sh([need("arm-none-eabi-size"), "-A", elf], capture_output=True, text=True).stdout
    sizes = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith(".") and parts[1].isdigit():
            sizes[parts[0]] = int(parts[1])
    return sizes


def component(obj: str) -> str:
    for key, name in (("libhdfilter", "filter/"), ("libhdcalib", "calib/"),
                      ("libhdfw", "firmware/ (hd_fw, CAN protocol)"),
                      ("libhal_mock", "hal/mock (NVM, CAN hook)"),
                      ("libhal_semihost", "hal/semihost"), ("libgcc", "libgcc (64-bit division)"),
                      ("dense_kf", "dense textbook KF (bench)"), (".dir/", "board/mps2_an386")):
        if key in obj:
            return name
    return "other"


def map_by_component(map_path: Path) -> tuple:
    """(flash bytes, RAM bytes) per component, from the linker map."""
    flash, ram = {}, {}
    text = map_path.read_text()
    text = text[text.find("Linker script and memory map"):]
    pending = None
    for line in text.splitlines():
        m = re.match(r"^ (\.[\w.$]+)\s*$", line)
        if m:
            pending = m.group(1)
            continue
        m = re.match(r"^ (\.[\w.$]+)?\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S+\.(?:obj|o|a\(.*\)))\s*$",
                     line)
        if m:
            name = m.group(1) or pending
            pending = None
            if name is None:
                continue
            size = int(m.group(3), 16)
            comp = component(m.group(4))
            if name.startswith((".text", ".rodata", ".vectors", ".ARM")):
                flash[comp] = flash.get(comp, 0) + size
            elif name.startswith((".bss", ".data", "COMMON")):
                ram[comp] = ram.get(comp, 0) + size
                if name.startswith(".data"):
                    flash[comp] = flash.get(comp, 0) + size
        else:
            pending = None if not line.startswith("  ") else pending
    return flash, ram


def ram_symbols(elf: Path) -> list:
    out = sh([need("arm-none-eabi-nm"), "-S", "--size-sort", elf],
             capture_output=True, text=True).stdout
    rows = []
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2].lower() in ("b", "d"):
            rows.append((parts[3], int(parts[1], 16)))
    return sorted(rows, key=lambda r: -r[1])


def fw_tick_limits() -> tuple:
    """HD_FW_RX_PER_TICK and HD_FW_ACKS_PER_TICK from firmware/hd_fw.h (the
    one place they are set)."""
    text = (ROOT / "firmware" / "hd_fw.h").read_text()
    values = []
    for name in ("HD_FW_RX_PER_TICK", "HD_FW_ACKS_PER_TICK"):
        m = re.search(rf"^#define {name} (\d+)u?\b", text, re.M)
        if m is None:
            raise TargetError(f"firmware/hd_fw.h: no #define {name}")
        values.append(int(m.group(1)))
    return tuple(values)


# The filter models of the bench image (main_bench.c): label key, what the
# row adds to its state count.
MODELS = [("4", ""), ("6", ""), ("8", ""), ("default", " (firmware default)"),
          ("max", " (max)")]
# hd_kf_step's slow paths in the bench image (main_bench.c), worst last.
KF_PATHS = [("kfpartial", "partial gains"), ("kffrozen", "over Nyquist"),
            ("kflost", "phase lost"), ("kfclamp", "clamp"), ("kfreset", "reset"),
            ("kfrollback", "transient rolled back"), ("kfworst", "all at once")]
TICK_PERIOD_US = 1000
ALLOCATORS = ("malloc", "_malloc_r", "calloc", "realloc", "free", "_free_r", "_sbrk",
              "_sbrk_r", "sbrk")


def worst_us(c: dict, mhz: float) -> float:
    """Worst-case time of a counted section: its max instructions x the
    worst-case cycles per instruction of the section (cycles_worst / mean)."""
    return c["max"] * (c["cycles_worst"] / c["mean"]) / mhz


def section_counts(sections: list, insns: dict) -> tuple:
    """Labelled sections -> ({label: {states, calls, mean, max, cycles_best,
    cycles_worst}} per call, marker overhead subtracted; counter check:
    hd_bench_loop(1010) - hd_bench_loop(10), None if not counted)."""
    by = {s["label"]: s for s in sections}
    overhead = min(by["empty:-"]["intervals"])
    loop = by["loop:-"]["intervals"]
    counts = {}
    for s in sections:
        if not s["intervals"]:
            continue
        iv = [n - overhead for n in s["intervals"]]
        lo, hi = cycle_estimate(s["hist"], insns, len(iv))
        counts[s["label"]] = {"states": s["states"], "calls": len(iv),
                              "mean": statistics.mean(iv), "max": max(iv),
                              "cycles_best": lo - overhead * 2,  # the marker's bl (1 + P)
                              "cycles_worst": hi - overhead * 4}
    return counts, (loop[1] - loop[0] if len(loop) == 2 else None), overhead


def kf_paths_of(counts: dict) -> dict:
    """{model: {"typical", PATH..., "worst", "worst_path", "dense_ratio"}}:
    max instructions per call of hd_kf_step's typical and slow paths;
    dense_ratio = dense mean / typical mean.  Empty if the image counts no
    filter step at all; a path missing beside the others (a label renamed in
    main_bench.c) is an error, not a row that silently drops out."""
    if not any(k.startswith("kf:") for k in counts):
        return {}
    missing = [f"{kind}:{key}" for kind in ["kf", "dense"] + [k for k, _ in KF_PATHS]
               for key, _ in MODELS if f"{kind}:{key}" not in counts]
    if missing:
        raise TargetError(f"the bench image counts no {', '.join(missing[:4])}"
                          f"{' ...' if len(missing) > 4 else ''} (labels of main_bench.c?)")
    result = {}
    for key, _ in MODELS:
        r = {"typical": counts[f"kf:{key}"]["max"]}
        for kind, _ in KF_PATHS:
            r[kind] = counts[f"{kind}:{key}"]["max"]
        worst = max(KF_PATHS, key=lambda k: r[k[0]])
        r["worst"], r["worst_path"] = max(r["typical"], r[worst[0]]), worst[1]
        r["dense_ratio"] = round(counts[f"dense:{key}"]["mean"] / counts[f"kf:{key}"]["mean"], 2)
        result[key] = r
    return result


def stack_numbers(st: dict, isr_names: list) -> dict:
    """worst_stack's result as the budget keeps it: [bytes, path] of main
    (with Reset_Handler), each interrupt (named) and the fault handler."""
    return {"main": [st["reset"] + st["main"][0], st["main"][1]], "frame": st["frame"],
            "isrs": [[name, c[0], c[1]] for name, c in zip(isr_names, st["isrs"])],
            "fault": [st["fault"][0], st["fault"][1]], "notes": st["notes"]}


def check_failures(heap: list, stack_total: int, stack_reserved: int, check) -> list:
    """The checks every budget makes: no allocator, the worst-case stack
    within the reserve, the counter's closed form."""
    failures = [f"allocator symbols linked: {', '.join(heap)}"] if heap else []
    if stack_total > stack_reserved:
        failures.append(f"worst-case stack {stack_total} B exceeds the reserved "
                        f"{stack_reserved} B")
    if check != 2000:
        failures.append(f"the instruction counter check failed: {check} instead of 2000")
    return failures


def budget(board: Board) -> dict:
    """Builds the mps2-an386 images, measures them and returns the budget's
    numbers: {flash_bytes, ram_bytes, stack_reserved_bytes, stack_worst_bytes,
    heap_symbols, counter_check, instructions: {LABEL: {states, calls, mean,
    max, cycles_best, cycles_worst}}, kf_paths, memory, stack, tick_limits,
    clock_mhz, failures: [...]} (failures: what failed, empty when all checks
    passed).  Raises TargetError on a setup problem."""
    build_images(board)
    run_elf, bench_elf = board.image("hd_image"), board.image("hd_bench")
    sizes = section_sizes(run_elf)
    flash = sizes.get(".text", 0) + sizes.get(".ARM.exidx", 0) + sizes.get(".data", 0)
    stack_reserved = sizes.get(".stack", 0)
    ram = sizes.get(".data", 0) + sizes.get(".bss", 0) + stack_reserved
    fl, rm = map_by_component(run_elf.with_suffix(".map"))
    comps = sorted(set(fl) | set(rm), key=lambda c: -(fl.get(c, 0) + rm.get(c, 0)))
    linked = set(symbols(run_elf)) | set(symbols(bench_elf))
    heap = [s for s in ALLOCATORS if s in linked]
    st = worst_stack(board, run_elf)
    counts, check, overhead = section_counts(labelled_sections(board, bench_elf, []),
                                             disassembly(bench_elf))
    rx, acks = fw_tick_limits()
    return {
        "flash_bytes": flash, "ram_bytes": ram, "stack_reserved_bytes": stack_reserved,
        "stack_worst_bytes": st["total"], "heap_symbols": heap, "counter_check": check,
        "instructions": counts, "kf_paths": kf_paths_of(counts),
        "memory": {"data": sizes.get(".data", 0), "bss": sizes.get(".bss", 0),
                   "components": [[c, fl.get(c, 0), rm.get(c, 0)] for c in comps],
                   "ram_objects": [[n, s] for n, s in ram_symbols(run_elf)[:6]]},
        "stack": stack_numbers(st, ["SysTick (the 1 kHz ISR)"]),
        "marker_overhead": overhead, "tick_limits": {"rx": rx, "acks": acks},
        "clock_mhz": MCU_CLOCKS_MHZ[0][1],
        "failures": check_failures(heap, st["total"], stack_reserved, check)}


# ------------------------------------------------ budget: the tables (pure)


def write_files(outputs: list) -> None:
    """Writes [(path, text)] all or none (hdtools.safeio.Outputs: temporary
    files beside the targets, renamed together; a target that is not a
    regular file, /dev/null or a FIFO, is written directly)."""
    try:
        with Outputs() as out:
            for path, text in outputs:
                out.write_text(path, text)
            out.commit()
    except OutputError as exc:
        raise TargetError(str(exc)) from None


def write_json(dest: Path, numbers: dict) -> None:
    """--json: the measured numbers (not the failures), atomically."""
    write_files([(dest, json.dumps({k: v for k, v in numbers.items() if k != "failures"},
                                   indent=1))])
