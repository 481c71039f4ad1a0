"""tools/target for the STM32F4 board port: the budget of the board images
(tools/target budget --board stm32f4) and programming a board
(tools/target flash).  Standard library only, like the rest of tools/target,
whose build, QEMU and analysis helpers this uses.
"""
from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from .board import BOARDS, ROOT, Board, TargetError, build_images, need, run_qemu, sh, symbols
from .budget import (ALLOCATORS, MCU_CLOCKS_MHZ, TICK_PERIOD_US, check_failures,
                     section_counts, section_sizes, stack_numbers, worst_us)
from .budget_render import md_table, stack_table, timing
from .m4_cycles import disassembly
from .qemu_run import labelled_sections
from .stack import worst_stack

BOARD_SRC = ROOT / "firmware" / "board" / "stm32f4"
BOARD_IMAGES = [("hd_odrive_v3", "ODrive v3.x class, STM32F405RG"),
                ("hd_mini_cheetah", "Mini Cheetah class, STM32F446RE")]
# The interrupts of a board image, lowest priority first (each may preempt
# the ones before it: stm32f4_board.c, stm32_board_start).
ISRS = ("CAN1_TX_IRQHandler", "TIM1_UP_TIM10_IRQHandler")
FAULT_ENTRY = "stm32_fault_entry"  # HardFault_Handler is two instructions and a branch here
FLASH_PART_KB = 512                 # the smaller part (F446RE); the F405RG has 1024
RAM_PART_KB = 128
BOOT_SECTOR = 16 * 1024
TICK_RATE_WINDOW_MS = 20
# Boards tools/target flash programs: the image, and where its two loadable
# parts go (sector 0, then sector 3 on: sectors 1-2 hold the records and are
# never written, see firmware/board/stm32f4/stm32f4.ld).
FLASH_BOARDS = {"odrive-v3": "hd_odrive_v3", "mini-cheetah": "hd_mini_cheetah"}
FLASH_BOOT_ADDR, FLASH_MAIN_ADDR = 0x08000000, 0x0800C000
OPENOCD_CFG = ["interface/stlink.cfg", "target/stm32f4x.cfg"]


def hal_functions() -> tuple:
    """The functions the board puts in its hal_t, read from the code that
    binds them (stm32_board_bind, stm32_flash_bind): the candidates of the
    firmware's indirect calls."""
    names = set()
    for src, func in ((BOARD_SRC / "stm32f4_board.c", "stm32_board_bind"),
                      (BOARD_SRC / "stm32f4_flash.c", "stm32_flash_bind")):
        text = src.read_text()
        body = re.search(rf"\n\w[^\n]*\b{func}\([^)]*\)\n\{{(.*?)\n\}}", text, re.S)
        if body is None:
            raise TargetError(f"{src.name}: {func} not found")
        names.update(re.findall(r"->\w+(?:\.\w+)? = (\w+);", body.group(1)))
    return tuple(sorted(n for n in names if "_" in n))  # not the contexts (b, drv)


def memory_rows(elf: Path) -> dict:
    s = section_sizes(elf)
    boot = s.get(".boot", 0)
    flash = boot + s.get(".text", 0) + s.get(".ARM.exidx", 0) + s.get(".data", 0)
    ram = s.get(".noinit", 0) + s.get(".data", 0) + s.get(".bss", 0) + s.get(".stack", 0)
    return {"flash": flash, "boot": boot, "ram": ram, "bss": s.get(".bss", 0),
            "data": s.get(".data", 0), "noinit": s.get(".noinit", 0),
            "stack": s.get(".stack", 0), "nvm": s.get(".nvm", 0)}


def tick_rate(board: Board, bench: Path) -> int:
    """TIM2 update events in TICK_RATE_WINDOW_MS of SysTick time (both
    counted by the bench image on netduinoplus2)."""
    rc, text = run_qemu(board, bench, ["tickrate"])
    m = re.search(r"tickrate: (\d+)\s+per ms: (\d+)", text)
    if rc != 0 or m is None or int(m.group(2)) != TICK_RATE_WINDOW_MS:
        raise TargetError(f"{bench.name} tickrate: exit {rc}:\n{text}")
    return int(m.group(1))


def interrupt_counts(board: Board, bench: Path) -> tuple:
    """({label: {states, calls, mean, max, cycles_best, cycles_worst}} of the
    bench image's interrupt bodies (label without ':states'), counter
    check)."""
    counts, check, _ = section_counts(labelled_sections(board, bench, []), disassembly(bench))
    return {label.split(":")[0]: c for label, c in counts.items()
            if label not in ("empty:-", "loop:-")}, check


SECTION_TEXT = {
    "tick": "tick interrupt: CAN service + hd_fw_isr (ADC, encoders, filter, telemetry)",
    "tickrx": "tick interrupt with a command frame received",
    "tickadc": "tick interrupt, conversion missing: ADC wait to its bound",
    "cantx": "CAN transmit interrupt: 3 queued frames into the mailboxes",
}


def measure(board: Board) -> dict:
    """Builds the STM32F4 images and measures them: {images: {NAME: memory},
    heap_symbols, stack_worst_bytes, stack_reserved_bytes, counter_check,
    tick_rate_per_20ms, interrupts: {LABEL: counts}, stack, clock_mhz,
    failures}.  Raises TargetError on a setup problem."""
    build_images(board)
    images = {name: memory_rows(board.image(name)) for name, _ in BOARD_IMAGES}
    elf = board.image("hd_odrive_v3")
    linked = symbols(elf)
    heap = [s for s in ALLOCATORS if s in linked]
    st = worst_stack(board, elf, isrs=ISRS, fault_entry=FAULT_ENTRY, hal_funcs=hal_functions())
    stack_reserved = images["hd_odrive_v3"]["stack"]
    bench = board.image(board.bench_image)
    rate = tick_rate(board, bench)
    interrupts, check = interrupt_counts(board, bench)
    mhz = MCU_CLOCKS_MHZ[0][1]
    for c in interrupts.values():
        c["worst_us"] = worst_us(c, mhz)
    failures = check_failures(heap, st["total"], stack_reserved, check)
    if rate != TICK_RATE_WINDOW_MS:
        failures.append(f"{rate} ticks in {TICK_RATE_WINDOW_MS} ms of emulator time")
    return {"images": images, "heap_symbols": heap, "stack_worst_bytes": st["total"],
            "stack_reserved_bytes": stack_reserved, "counter_check": check,
            "tick_rate_per_20ms": rate, "interrupts": interrupts,
            "stack": stack_numbers(st, list(ISRS)),
            "clock_mhz": mhz, "failures": failures}


def render(n: dict) -> str:
    """The STM32F4 budget tables (markdown) from measure()'s numbers."""
    rows = []
    what = dict(BOARD_IMAGES)
    for name, m in n["images"].items():
        rows.append([f"`{name}.elf` ({what[name]})", f"{m['flash']} B",
                     f"{m['boot']} B of {BOOT_SECTOR}", f"{m['ram']} B",
                     f".data {m['data']} + .bss {m['bss']} + .noinit {m['noinit']} + stack "
                     f"{m['stack']}"])
    mhz = n["clock_mhz"]
    nvm = next(iter(n["images"].values()))["nvm"]
    out = ["#### Memory (arm-none-eabi-size -A of the board images)\n",
           md_table(["image", f"flash (of {FLASH_PART_KB} KB - {nvm // 1024} KB NVM)",
                       "sector 0", f"RAM (of {RAM_PART_KB} KB)", "RAM contents"], rows),
           f"\nNVM: flash sectors 1 and 2 ({nvm} B) reserved by the linker script for the A/B "
           "record store; nothing is linked there.",
           "\n#### Heap\n",
           ("FAIL: allocator symbols linked: " + ", ".join(n["heap_symbols"])
            if n["heap_symbols"] else
            "None (no libc; the linker script ASSERTs it and the build checks the symbol "
            "table)."),
           "\n#### Worst-case stack, hd_odrive_v3.elf (-fstack-usage + -fcallgraph-info call "
           "graph)\n",
           stack_table(n["stack"], n["stack_worst_bytes"], n["stack_reserved_bytes"],
                         "fault handler", "fault inside the tick"),
           "\nThe CAN transmit interrupt (priority 2) can be preempted by the tick (priority 1); "
           "indirect calls are bounded by the deepest function the board puts in its hal_t" +
           ("; notes: " + "; ".join(n["stack"]["notes"]) if n["stack"]["notes"] else "") + ".",
           "\n#### Instructions per interrupt (hd_stm32f4_bench.elf on QEMU netduinoplus2)\n",
           "The board code and drivers of the ODrive image, compiled the same way, with their "
           "registers in RAM set to what the hardware shows (update flag, conversion done, "
           "mailboxes empty); counted by tools/qemu-plugin between the markers, marker overhead "
           f"subtracted; counter check: hd_bench_loop(1010) - hd_bench_loop(10) = "
           f"{n['counter_check']} instructions (expected 2000).  Cycles: the Cortex-M4 TRM "
           "timings per executed instruction, zero wait states (best-worst); us = max "
           f"instructions x worst cycles per instruction at {mhz} MHz; share = us of the "
           f"{TICK_PERIOD_US} us tick.\n",
           md_table(["interrupt body", "filter states", "instructions mean / max",
                       "cycles mean (best-worst)", "worst-case us", "share of the tick"],
                      [[SECTION_TEXT.get(k, k), c["states"], f"{c['mean']:.0f} / {c['max']}",
                        f"{c['cycles_best']:.0f}-{c['cycles_worst']:.0f}",
                        f"{worst_us(c, mhz):.1f}",
                        f"{100 * worst_us(c, mhz) / TICK_PERIOD_US:.1f} %"]
                       for k, c in n["interrupts"].items()]),
           f"\nTick rate in the emulator: {n['tick_rate_per_20ms']} TIM2 update events in "
           f"{TICK_RATE_WINDOW_MS} ms of SysTick time (stm32_tick_init for QEMU's 1 GHz timer "
           f"clock; expected {TICK_RATE_WINDOW_MS})."]
    return "\n".join(out)


def summary(n: dict) -> dict:
    """The STM32F4 part of docs/results/budget.json."""
    what = dict(BOARD_IMAGES)
    return {"images": {name: {"board": what[name], "flash_bytes": m["flash"],
                              "sector0_bytes": m["boot"], "ram_bytes": m["ram"]}
                       for name, m in n["images"].items()},
            "stack_worst_bytes": n["stack_worst_bytes"],
            "stack_reserved_bytes": n["stack_reserved_bytes"],
            "instructions_counted_on": "hd_stm32f4_bench.elf, QEMU netduinoplus2",
            "interrupts": {k: dict(timing(c, n["clock_mhz"]), states=c["states"],
                                   what=SECTION_TEXT.get(k, k))
                           for k, c in n["interrupts"].items()}}


# ------------------------------------------------------------------ flash

def split_binaries(elf: Path) -> tuple:
    """The two loadable parts of a board image as raw binaries next to it:
    sector 0 (.boot) and sector 3 on (.text, .ARM.exidx, .data), so the
    record sectors in between are never written.  The build writes them
    for its images; they are made again when missing or older than the
    ELF (an --image rebuilt since its last flash)."""
    boot, main = elf.with_suffix(".boot.bin"), elf.with_suffix(".main.bin")
    built = elf.stat().st_mtime
    if any(not p.exists() or p.stat().st_mtime < built for p in (boot, main)):
        objcopy = need("arm-none-eabi-objcopy")
        sh([objcopy, "-O", "binary", "-j", ".boot", elf, boot])
        sh([objcopy, "-O", "binary", "-j", ".text", "-j", ".ARM.exidx", "-j", ".data",
              elf, main])
    return boot, main


def flash_commands(tool: str, elf: Path) -> list:
    if tool == "openocd":
        cfg = [x for c in OPENOCD_CFG for x in ("-f", c)]
        return [["openocd", *cfg, "-c", f"program {elf} verify reset exit"]]
    boot, main = split_binaries(elf)
    return [["dfu-util", "-a", "0", "-s", f"0x{FLASH_BOOT_ADDR:08X}", "-D", str(boot)],
            ["dfu-util", "-a", "0", "-s", f"0x{FLASH_MAIN_ADDR:08X}:leave", "-D", str(main)]]


def cmd_flash(a) -> int:
    if a.image:
        elf = Path(a.image).resolve()
    else:
        board = BOARDS["stm32f4"]
        elf = board.image(FLASH_BOARDS[a.board])
        if not a.dry_run or not elf.exists():
            build_images(board)
    if not elf.is_file():
        raise TargetError(f"{elf}: no such image (tools/target build --board stm32f4, "
                            "or --image ELF)")
    program = "openocd" if a.tool == "openocd" else "dfu-util"
    if not a.dry_run:
        if shutil.which(program) is None:
            raise TargetError(f"{program} not found: install Debian's {program} "
                                "(tools/setup installs it)")
    cmds = flash_commands(a.tool, elf)
    for cmd in cmds:
        print(shlex.join(str(c) for c in cmd))
    if a.dry_run:
        return 0
    for cmd in cmds:
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
        sys.stdout.write(proc.stdout)
        if proc.returncode != 0:
            lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
            why = next((ln for ln in reversed(lines) if "rror" in ln or "No DFU" in ln),
                       lines[-1] if lines else "no message")
            print(f"tools/target: {program} failed (exit status {proc.returncode}): {why}",
                  file=sys.stderr)
            return 1
    print(f"flashed {elf.name} to {a.board} with {program}")
    return 0
