"""tools/target: the Cortex-M4F firmware image under QEMU, and on the board.

  tools/target build              cross-build the images (preset cortex-m4, or
                                  stm32f4 for --board netduinoplus2/stm32f4),
                                  the instruction-count plugin and the host pieces
  tools/target run IN.hdraw [--out OUT.bin] [--can CAN.log] [--count FILE]
                                  run the firmware image on a raw sample stream
  tools/target compare (IN.hdraw | --scenario INI [--duration S])
                                  host build vs QEMU image: bit-identical?
  tools/target closed-loop [--ticks N]
                                  the image closing its control loop against
                                  the host's dynamic plant in lockstep (a step
                                  test) vs the host build: bit-identical?
  tools/target budget [--markdown] [--json FILE]
                                  flash, RAM, worst-case stack, instruction
                                  counts per filter update / ISR, cycle estimate
  tools/target budget --update-docs [--docs DIR]
                                  both ports' budgets into docs/target.md,
                                  docs/stm32f4.md (between <!-- target:budget:begin
                                  --> and <!-- target:budget:end -->) and
                                  docs/results/budget.json, all or none
  tools/target count ELF [ARG...] instruction counts between the markers of
                                  any image that uses them (hd_mark.h)
  tools/target flash --board odrive-v3|mini-cheetah [--tool openocd|dfu]
                     [--image ELF] [--dry-run]
                                  program a board (ST-Link + OpenOCD, or USB DFU)

--board (build, run, compare, budget, count): mps2-an386 (default; QEMU's
MPS2 AN386), netduinoplus2 (QEMU's STM32F405 model running the STM32F4
port's emulator image), stm32f4 (budget of the STM32F4 board images; the
instruction counts run on netduinoplus2).  Environment: HD_TARGET_BUILD
(mps2-an386 build, default build/cortex-m4), HD_TARGET_BUILD_STM32F4 (STM32F4
build, default build/stm32f4), HD_TARGET_HOST_BUILD (default
build/target-host).  Exit status: 0 ok, 1 check failed, 2 setup or usage
error.  Only the Python standard library is used.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
M4_BUILD = Path(os.environ.get("HD_TARGET_BUILD", ROOT / "build" / "cortex-m4"))
HOST_BUILD = Path(os.environ.get("HD_TARGET_HOST_BUILD", ROOT / "build" / "target-host"))
BOARD_REL = Path("firmware/board/mps2_an386")
RUN_IMAGE, BENCH_IMAGE = "hd_image", "hd_bench"
PLUGIN_SRC = ROOT / "tools" / "qemu-plugin" / "hdcount.c"
QEMU = "qemu-system-arm"
QEMU_ARGS = ["-M", "mps2-an386", "-nographic", "-monitor", "none", "-serial", "none",
             "-icount", "shift=0,sleep=off"]
DUMP_RECORD = struct.Struct("<IiIIIII")  # tick, counts, raw, filtered, ripple, faults, kf_status
QEMU_TIMEOUT_S = 120

# Board ports: the cross-build tree (and its preset), the board folder, the
# QEMU machine and the images run and counted there.
BOARDS = {
    "mps2-an386": dict(env="HD_TARGET_BUILD", build="cortex-m4", cmake_board="mps2_an386",
                       rel="firmware/board/mps2_an386", machine="mps2-an386",
                       run="hd_image", bench="hd_bench",
                       targets=["hd_image", "hd_bench", "hd_ctrl_image"]),
    "netduinoplus2": dict(env="HD_TARGET_BUILD_STM32F4", build="stm32f4", cmake_board="stm32f4",
                          rel="firmware/board/stm32f4", machine="netduinoplus2",
                          run="hd_nd2", bench="hd_stm32f4_bench",
                          targets=["hd_nd2", "hd_stm32f4_bench", "hd_odrive_v3",
                                   "hd_mini_cheetah"]),
}
BOARDS["stm32f4"] = BOARDS["netduinoplus2"]
# Boards tools/target flash programs: the image, and where its two loadable
# parts go (sector 0, then sector 3 on: sectors 1-2 hold the records and are
# never written, see firmware/board/stm32f4/stm32f4.ld).
FLASH_BOARDS = {"odrive-v3": "hd_odrive_v3", "mini-cheetah": "hd_mini_cheetah"}
FLASH_BOOT_ADDR, FLASH_MAIN_ADDR = 0x08000000, 0x0800C000
OPENOCD_CFG = ["interface/stlink.cfg", "target/stm32f4x.cfg"]


def select_board(name: str) -> dict:
    """Points the module's build tree, board folder, QEMU machine and image
    names at a board port."""
    global M4_BUILD, BOARD_REL, QEMU_ARGS, RUN_IMAGE, BENCH_IMAGE
    b = BOARDS[name]
    M4_BUILD = Path(os.environ.get(b["env"], ROOT / "build" / b["build"]))
    BOARD_REL = Path(b["rel"])
    QEMU_ARGS = ["-M", b["machine"]] + QEMU_ARGS[2:]
    RUN_IMAGE, BENCH_IMAGE = b["run"], b["bench"]
    return b


# Clock frequencies of the MCU classes the image targets (for microseconds).
MCU_CLOCKS_MHZ = [("STM32F4", 168), ("STM32G4", 170)]


class TargetError(Exception):
    """A setup problem (missing tool, build failure): exit status 2."""


# ------------------------------------------------------------------ helpers

def need(tool: str) -> str:
    path = shutil.which(tool)
    if path is None:
        raise TargetError(f"{tool} not found: run tools/setup (installs gcc-arm-none-eabi "
                          f"and qemu-system-arm)")
    return path


def sh(cmd: list, **kw) -> subprocess.CompletedProcess:
    kw.setdefault("check", True)
    try:
        return subprocess.run([str(c) for c in cmd], **kw)
    except subprocess.CalledProcessError as exc:
        raise TargetError(f"command failed ({exc.returncode}): {' '.join(map(str, cmd))}") from exc


def image(name: str) -> Path:
    return M4_BUILD / BOARD_REL / f"{name}.elf"


def symbols(elf: Path) -> dict:
    out = sh([need("arm-none-eabi-nm"), elf], capture_output=True, text=True).stdout
    syms = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3:
            syms[parts[2]] = int(parts[0], 16)
    return syms


# -------------------------------------------------------------------- build

def current_board() -> dict:
    return next(b for b in BOARDS.values() if Path(b["rel"]) == BOARD_REL)


def build_images() -> None:
    need("arm-none-eabi-gcc")
    need("cmake")
    b = current_board()
    if not (M4_BUILD / "build.ninja").exists():
        if M4_BUILD == ROOT / "build" / b["build"]:
            sh(["cmake", "--preset", b["build"]], cwd=ROOT, stdout=subprocess.DEVNULL)
        else:
            sh(["cmake", "-S", ROOT, "-B", M4_BUILD, "-G", "Ninja",
                f"-DCMAKE_TOOLCHAIN_FILE={ROOT / 'cmake' / 'arm-none-eabi.cmake'}",
                "-DCMAKE_BUILD_TYPE=MinSizeRel", f"-DHD_BOARD={b['cmake_board']}"],
               stdout=subprocess.DEVNULL)
    sh(["cmake", "--build", M4_BUILD, "-j2", "--target", *b["targets"]],
       stdout=subprocess.DEVNULL)


def build_plugin() -> Path:
    cc = shutil.which("cc") or need("gcc")
    out = HOST_BUILD / "hdcount.so"
    header = PLUGIN_SRC.parent / "hd_qemu_plugin_abi.h"
    newest = max(PLUGIN_SRC.stat().st_mtime, header.stat().st_mtime)
    if not out.exists() or out.stat().st_mtime < newest:
        HOST_BUILD.mkdir(parents=True, exist_ok=True)
        sh([cc, "-shared", "-fPIC", "-O2", "-std=c11", "-Wall", "-Wextra", "-Werror",
            "-o", out, PLUGIN_SRC])
    return out


def host_tools(host_build: Path | None) -> dict:
    """target_hostref, hdjoint-host and hdsim from a host build tree."""
    bdir = host_build or HOST_BUILD
    if host_build is None:
        if not (bdir / "build.ninja").exists():
            sh(["cmake", "-S", ROOT, "-B", bdir, "-G", "Ninja",
                "-DCMAKE_BUILD_TYPE=RelWithDebInfo"], stdout=subprocess.DEVNULL)
        sh(["cmake", "--build", bdir, "-j2", "--target", "target_hostref", "hdjoint-host",
            "hdsim_cli"], stdout=subprocess.DEVNULL)
    tools = {
        "hostref": bdir / "tests" / "target" / "target_hostref",
        "runner": bdir / "firmware" / "host" / "hdjoint-host",
        "hdsim": bdir / "sim" / "hdsim",
    }
    for name, path in tools.items():
        if not path.exists():
            raise TargetError(f"{path} is missing: build the host tree {bdir} first")
    return tools


# ---------------------------------------------------------------------- run

def run_qemu(elf: Path, args: list, count_out: Path | None = None,
             timeout: float = QEMU_TIMEOUT_S) -> tuple:
    """Runs an image; returns (exit status, console text)."""
    need(QEMU)
    for a in args:
        if " " in str(a) or "," in str(a):
            raise TargetError(f"semihosting arguments cannot contain spaces or commas: {a}")
    semi = ",".join(["enable=on", "target=native", f"arg={elf.stem}"] +
                    [f"arg={a}" for a in args])
    cmd = [QEMU] + QEMU_ARGS + ["-kernel", elf, "-semihosting-config", semi]
    if count_out is not None:
        syms = symbols(elf)
        plugin = build_plugin()
        cmd += ["-plugin", f"{plugin},begin={syms['hd_mark_begin']:#x},"
                f"end={syms['hd_mark_end']:#x},section={syms['hd_mark_section']:#x},"
                f"out={count_out}"]
    try:
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        raise TargetError(f"QEMU did not finish within {timeout} s: {elf.name}") from exc
    return proc.returncode, proc.stdout + proc.stderr


def cmd_run(a) -> int:
    build_images()
    out = Path(a.out).resolve() if a.out else "-"
    can = Path(a.can).resolve() if a.can else "-"
    count = Path(a.count).resolve() if a.count else None
    rc, text = run_qemu(image(RUN_IMAGE), [Path(a.stream).resolve(), out, can], count)
    sys.stdout.write(text)
    if count is not None:
        isr = [n for s in parse_counts(count.read_text())[0] for n in s["intervals"]]
        if isr:
            print(f"isr instructions per tick: mean {statistics.mean(isr):.0f}, "
                  f"max {max(isr)} over {len(isr)} ticks (QEMU board: includes the candump "
                  f"text formatting of the CAN hook)")
    print(f"exit status {rc}")
    return 0 if rc == 0 else 1


# ------------------------------------------------------------------ compare

def read_dump(path: Path) -> list:
    data = path.read_bytes()
    if len(data) % DUMP_RECORD.size:
        raise TargetError(f"{path}: not a whole number of {DUMP_RECORD.size}-byte records")
    return [DUMP_RECORD.unpack_from(data, i) for i in range(0, len(data), DUMP_RECORD.size)]


def f32(bits: int) -> float:
    return struct.unpack("<f", struct.pack("<I", bits))[0]


def compare_dumps(host: list, qemu: list) -> list:
    """Exact comparison of two per-tick dumps; returns the problems found."""
    problems = []
    if len(host) != len(qemu) or not host:
        problems.append(f"{len(host)} host ticks, {len(qemu)} QEMU ticks")
    diff = [i for i, (h, q) in enumerate(zip(host, qemu)) if h != q]
    if diff:
        i = diff[0]
        h, q = host[i], qemu[i]
        problems.append(f"{len(diff)} of {len(host)} ticks differ; first at tick {h[0]}: "
                        f"filtered host {f32(h[3])!r} qemu {f32(q[3])!r}, raw host "
                        f"{f32(h[2])!r} qemu {f32(q[2])!r}, faults {h[5]:#x}/{q[5]:#x}")
    return problems


def compare_stream(stream: Path, tools: dict, work: Path) -> bool:
    """Host vs QEMU on one stream: per-tick float bits and the CAN log."""
    h_bin, q_bin = work / "host.bin", work / "qemu.bin"
    h_log, q_log = work / "host.log", work / "qemu.log"
    sh([tools["hostref"], stream, h_bin], stdout=subprocess.DEVNULL)
    sh([tools["runner"], "--sensors", f"replay:{stream}", "--can", f"log:{h_log}", "--quiet"],
       stdout=subprocess.DEVNULL)
    rc, text = run_qemu(image(RUN_IMAGE), [stream, q_bin, q_log])
    if rc != 0:
        print(f"FAIL: the QEMU image exited with status {rc}\n{text}")
        return False
    host, qemu = read_dump(h_bin), read_dump(q_bin)
    problems = compare_dumps(host, qemu)
    for msg in problems:
        print(f"FAIL: {msg}")
    ok = not problems
    h_text, q_text = h_log.read_bytes(), q_log.read_bytes()
    if h_text != q_text:
        hl, ql = h_text.splitlines(), q_text.splitlines()
        first = next((i for i, (x, y) in enumerate(zip(hl, ql)) if x != y), min(len(hl), len(ql)))
        print(f"FAIL: CAN logs differ ({len(hl)} vs {len(ql)} frames), first at line {first + 1}")
        ok = False
    n_frames = h_text.count(b"\n")
    status = "bit-identical" if ok else "DIFFERENT"
    print(f"{stream.name}: {len(qemu)} ticks, filtered/raw torque and ripple float bits "
          f"{status}; CAN log {n_frames} frames {'identical' if h_text == q_text else 'DIFFERENT'}")
    return ok


def cmd_compare(a) -> int:
    build_images()
    tools = host_tools(Path(a.host_build).resolve() if a.host_build else None)
    with tempfile.TemporaryDirectory(prefix="hd-target-") as tmp:
        work = Path(tmp)
        if a.scenario:
            stream = work / "stream.hdraw"
            cmd = [tools["hdsim"], Path(a.scenario).resolve(), "--csv", work / "sim.csv",
                   "--raw", stream]
            if a.duration:
                cmd += ["--duration", str(a.duration)]
            sh(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        else:
            stream = Path(a.stream).resolve()
        return 0 if compare_stream(stream, tools, work) else 1


# -------------------------------------------------------------------- count

def parse_counts(text: str) -> list:
    """Plugin output -> sections [{intervals: [...], hist: {pc: n}}], total."""
    sections = [{"intervals": [], "hist": {}}]
    total = None
    for line in text.splitlines():
        kind, *rest = line.split()
        if kind == "I":
            sections[-1]["intervals"].append(int(rest[0]))
        elif kind == "P":
            sections[-1]["hist"][int(rest[0], 16)] = int(rest[1])
        elif kind == "S":
            sections.append({"intervals": [], "hist": {}})
        elif kind == "T":
            total = int(rest[0])
    if not sections[-1]["intervals"] and not sections[-1]["hist"]:
        sections.pop()
    return sections, total


def labelled_sections(elf: Path, args: list) -> list:
    """Runs an image with the plugin; pairs its 'section LABEL N' console lines
    with the plugin's sections."""
    with tempfile.TemporaryDirectory(prefix="hd-count-") as tmp:
        out = Path(tmp) / "count.txt"
        rc, text = run_qemu(elf, args, out)
        if rc != 0:
            raise TargetError(f"{elf.name} exited with status {rc}:\n{text}")
        sections, _ = parse_counts(out.read_text())
    labels = [(m.group(1), int(m.group(2)))
              for m in re.finditer(r"(?m)^section (\S+) (\d+)$", text)]
    if len(labels) != len(sections):
        raise TargetError(f"{len(labels)} section labels but {len(sections)} counted sections")
    return [dict(label=lbl, states=n, **s) for (lbl, n), s in zip(labels, sections)]


def cmd_count(a) -> int:
    build_images()
    elf = Path(a.elf)
    for s in labelled_sections(elf, a.args):
        iv = s["intervals"]
        if iv:
            print(f"{s['label']:<16} calls {len(iv):4d}  instructions min {min(iv)} "
                  f"mean {statistics.mean(iv):.1f} max {max(iv)}")
    return 0


# ------------------------------------------------------- Cortex-M4 timings

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


# ---- worst-case stack from -fstack-usage / -fcallgraph-info=su (.ci files)

NODE_RE = re.compile(r'node: \{ title: "([^"]+)" label: "([^"]*)"')
EDGE_RE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')


def load_callgraph(build: Path, image_dirs: list) -> tuple:
    frames, qualifiers, edges, origin = {}, {}, {}, {}
    images = current_board()["targets"]
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


def worst_stack(elf: Path, isrs: tuple = ("SysTick_Handler",), fault_entry: str = "HardFault_Handler",
                hal_funcs: tuple | None = None) -> dict:
    """Deepest stack of main, of each interrupt in isrs (listed from the
    lowest priority up: each may preempt the ones before it) and of the
    fault handler.  hal_funcs: the functions the image puts in its hal_t
    (default: the QEMU backends' functions)."""
    image_dir = f"{elf.stem}.dir"
    frames, qualifiers, edges, origin = load_callgraph(M4_BUILD, [image_dir])
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


def md_table(header: list, rows: list) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


# The filter models of the bench image (main_bench.c): label key, what the
# row adds to its state count.
MODELS = [("4", ""), ("6", ""), ("8", ""), ("default", " (firmware default)"),
          ("max", " (max)")]
# hd_kf_step's slow paths in the bench image (main_bench.c), worst last.
KF_PATHS = [("kfpartial", "partial gains"), ("kffrozen", "over Nyquist"),
            ("kflost", "phase lost"), ("kfclamp", "clamp"), ("kfreset", "reset"),
            ("kfworst", "all at once")]
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


def budget() -> dict:
    """Builds the mps2-an386 images, measures them and returns the budget's
    numbers: {flash_bytes, ram_bytes, stack_reserved_bytes, stack_worst_bytes,
    heap_symbols, counter_check, instructions: {LABEL: {states, calls, mean,
    max, cycles_best, cycles_worst}}, kf_paths, memory, stack, tick_limits,
    clock_mhz, failures: [...]} (failures: what failed, empty when all checks
    passed).  Raises TargetError on a setup problem."""
    build_images()
    run_elf, bench_elf = image("hd_image"), image("hd_bench")
    sizes = section_sizes(run_elf)
    flash = sizes.get(".text", 0) + sizes.get(".ARM.exidx", 0) + sizes.get(".data", 0)
    stack_reserved = sizes.get(".stack", 0)
    ram = sizes.get(".data", 0) + sizes.get(".bss", 0) + stack_reserved
    fl, rm = map_by_component(run_elf.with_suffix(".map"))
    comps = sorted(set(fl) | set(rm), key=lambda c: -(fl.get(c, 0) + rm.get(c, 0)))
    linked = set(symbols(run_elf)) | set(symbols(bench_elf))
    heap = [s for s in ALLOCATORS if s in linked]
    st = worst_stack(run_elf)
    counts, check, overhead = section_counts(labelled_sections(bench_elf, []),
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

def stack_table(st: dict, total: int, reserved: int, fault_name: str,
                fault_context: str) -> str:
    rows = [["main loop (Reset_Handler + main)", st["main"][0], " > ".join(st["main"][1])]]
    for name, nbytes, path in st["isrs"]:
        rows.append(["exception entry, FP context (26 words + align)", st["frame"], "hardware"])
        rows.append([name, nbytes, " > ".join(path)])
    rows += [[f"exception entry ({fault_context})", st["frame"], "hardware"],
             [fault_name, st["fault"][0], " > ".join(st["fault"][1])],
             ["**total worst case**", f"**{total}**", f"reserved: {reserved} B"]]
    return md_table(["context", "bytes", "deepest path"], rows)


def command_label(n: dict) -> str:
    return f"ISR + commands ({n['tick_limits']['rx']} in, {n['tick_limits']['acks']} ACK out)"


def headline_table(n: dict) -> str:
    """The firmware default's filter step, tick and tick with commands in one
    table (what docs and the README quote), from budget_summary."""
    s = budget_summary(n)
    states = s["default_states"]
    row = s["per_states"][str(states)]
    step = row["kf_step"]
    parts = [("hd_kf_step, typical path", step["typical"], "")]
    if "worst" in step:
        parts.append((f"hd_kf_step, worst path ({step['worst']['path']})", step["worst"], ""))
    cmd = row["tick_with_commands"]
    parts += [("the tick (hd_fw_isr)", row["tick"], ""),
              (f"the tick with commands ({cmd['frames_in']} in, {cmd['acks_out']} ACK out)", cmd,
               f" ({cmd['ratio_to_tick_max']:.2f}x the tick)")]
    if "ctrl_step" in s:
        ctl, ctlcmd = row["tick_with_control"], row["tick_with_control_and_commands"]
        parts += [("hd_ctrl_step (the control law, every mode)", s["ctrl_step"], ""),
                  (f"the tick with control (a drive, {ctl['frames_in']} control frames in)", ctl,
                   f" ({ctl['ratio_to_tick_max']:.2f}x the tick)"),
                  (f"the tick with control and commands ({cmd['frames_in']} in)", ctlcmd,
                   f" ({ctlcmd['ratio_to_tick_max']:.2f}x the tick)")]
    return md_table([f"{states} states (firmware default)", "instructions (max)",
                     f"estimated worst-case us at {n['clock_mhz']} MHz",
                     f"share of the {TICK_PERIOD_US} us tick"],
                    [[what, f"{c['max_instructions']}{note}", f"{c['worst_us']:.1f}",
                      f"{100 * c['budget_fraction']:.1f} %"] for what, c, note in parts])


def render_budget(n: dict) -> str:
    """The mps2-an386 budget tables (markdown) from budget()'s numbers."""
    mem, ins, mhz = n["memory"], n["instructions"], n["clock_mhz"]
    out = ["#### Summary\n", headline_table(n),
           "\n#### Memory (hd_image.elf, arm-none-eabi-size -A)\n",
           md_table(["region", "used", "of", "contents"], [
               ["flash", f"{n['flash_bytes']} B", "512 KB",
                ".text (code, constants, vector table) + .data image"],
               ["RAM", f"{n['ram_bytes']} B", "128 KB",
                f".data {mem['data']} + .bss {mem['bss']} + reserved stack "
                f"{n['stack_reserved_bytes']}"]]),
           "\nBy component (linker map):\n",
           md_table(["component", "flash B", "RAM B (static)"], mem["components"]),
           "\nLargest RAM objects: " +
           ", ".join(f"`{name}` {size} B" for name, size in mem["ram_objects"]) +
           ".  The firmware's own state is `g_fw` (hd_fw_t, two pipelines: the running "
           "model and the one a command builds); `g_mock`, `g_stream`, `g_dump`, `g_canlog` "
           "are the QEMU board's I/O (NVM in RAM, semihosting buffers) that a real board "
           "replaces with peripherals.",
           "\n#### Heap\n",
           ("FAIL: allocator symbols linked: " + ", ".join(n["heap_symbols"])
            if n["heap_symbols"] else
            "None.  Images link with `-nostdlib` (no libc; the board supplies memcpy/memset/"
            "memcmp/strlen/strcmp), the linker script `ASSERT`s that malloc/free/_sbrk are "
            "undefined, and a post-build step checks the symbol table (nm): no "
            "malloc/calloc/realloc/free/_sbrk."),
           "\n#### Worst-case stack (-fstack-usage + -fcallgraph-info call graph)\n",
           stack_table(n["stack"], n["stack_worst_bytes"], n["stack_reserved_bytes"],
                       "HardFault handler", "fault inside the ISR"),
           "\nIndirect calls (HAL vtable, CAN transmit hook) are bounded by the deepest HAL "
           "backend function linked into the image; no recursion" +
           ("; notes: " + "; ".join(n["stack"]["notes"]) if n["stack"]["notes"] else "") + "."]
    cmd = command_label(n)
    kinds = [("kf", "hd_kf_step"), ("isr", "ISR (hd_fw_isr)"), ("isrcmd", cmd),
             ("dense", "dense textbook KF")]
    control = f"isrctrl:{MODELS[0][0]}" in ins
    if control:
        kinds[3:3] = [("isrctrl", "ISR + control"), ("isrctrlcmd", "ISR + control + commands")]
    insn_rows, cycle_rows = [], []
    for key, note in MODELS:
        states = f"{ins[f'kf:{key}']['states']}{note}"
        cells = [ins[f"{kind}:{key}"] for kind, _ in kinds]
        insn_rows.append([states] + [f"{c['mean']:.0f} / {c['max']}" for c in cells] +
                         [f"{ins[f'isrcmd:{key}']['max'] / ins[f'isr:{key}']['max']:.2f}"])
        cycle_rows.append([states] + [f"{c['cycles_best']:.0f}-{c['cycles_worst']:.0f} "
                                      f"({worst_us(c, mhz):.1f} us)" for c in cells])
    out += ["\n#### Instructions per call (QEMU TCG plugin, exact) and estimated cycles\n",
            f"Counted by tools/qemu-plugin/hdcount.c between the image's markers, "
            f"{ins['kf:4']['calls']} calls each; marker overhead ({n['marker_overhead']} "
            f"instruction) subtracted.  Counter check: hd_bench_loop(1010) - hd_bench_loop(10) "
            f"= {n['counter_check']} instructions (expected 2000).  These are **instructions, "
            "not cycles**: QEMU has no cycle model.  Cycles are estimated from the "
            "per-instruction execution counts with the Cortex-M4 TRM timings (ALU 1, LDR 1-2, "
            "STR 1-2, taken branch 2-4, VADD/VMUL 1, VMLA 3, VLDR/VSTR 2, VDIV/VSQRT 14, "
            "push/pop 1+N), zero wait states; range = best..worst case.\n",
            "Instructions per call, mean / max:\n",
            md_table(["states"] + [k[1] for k in kinds] + ["with commands / ISR (max)"],
                     insn_rows),
            "\nEstimated Cortex-M4 cycles per call, mean best-worst (worst-case time):\n",
            md_table(["states"] + [k[1] for k in kinds], cycle_rows),
            f"\nus = worst-case time at {mhz} MHz ({MCU_CLOCKS_MHZ[0][0]}; "
            f"{MCU_CLOCKS_MHZ[1][0]} at {MCU_CLOCKS_MHZ[1][1]} MHz is within 2 %): max "
            "instructions x worst-case cycles per instruction of that section.  The ISR budget "
            f"is {TICK_PERIOD_US} us per tick.  ISR = the whole 1 kHz tick body: ADC and "
            "encoder reads (hal_mock), calibration, encoder deltas, tracker, expected torque, "
            "filter, faults, telemetry (2 frames at 1 kHz) and the heartbeat (tick 0); "
            f"'{cmd}' adds command frames on every tick: the tick takes at most "
            f"HD_FW_RX_PER_TICK = {n['tick_limits']['rx']} frames (a BLOCK_ENABLE toggle of "
            "block 0, applied by the tick to the running filter, and a SET_PARAM r_nm2, whose "
            "model rebuild the background does between ticks, outside the count), applies the "
            "change the background prepared and sends at most HD_FW_ACKS_PER_TICK = "
            f"{n['tick_limits']['acks']} ACK.  Other command mixes are not enumerated: this is "
            "a measured load, not a proof of the worst case."]
    if control:
        c = ins["ctrl:default"]
        worst = {key: max(worst_us(ins[f"{k}:{key}"], mhz) for k in ("isrctrl", "isrctrlcmd"))
                 for key in ("default", "max")}
        out += [f"\nControl (issue 23): 'ISR + control' is the tick on a board with a drive: "
                "the control stage (setpoint checks, watchdog and fault reactions, "
                "control/hd_ctrl's law, the drive command) runs every tick, with "
                f"HD_FW_RX_PER_TICK = {n['tick_limits']['rx']} control frames arriving every "
                "tick (a TORQUE SETPOINT and a GAINS frame, decoded and checked by the tick) "
                "and CTRL_STATE sent with the telemetry; 'ISR + control + commands' runs "
                "TORQUE with the command frames above instead.  hd_ctrl_step alone, cycling "
                "its modes over inputs that reach the velocity, position and current limits: "
                f"{c['mean']:.0f} / {c['max']} instructions (mean / max), "
                f"{c['cycles_best']:.0f}-{c['cycles_worst']:.0f} cycles, "
                f"{worst_us(c, mhz):.2f} us at {mhz} MHz.  The worst tick with control: "
                f"{worst['default']:.1f} us = {100 * worst['default'] / TICK_PERIOD_US:.1f} % of "
                f"the {TICK_PERIOD_US} us tick with the firmware's default filter "
                f"({ins['kf:default']['states']} states), {worst['max']:.1f} us = "
                f"{100 * worst['max'] / TICK_PERIOD_US:.1f} % with the largest "
                f"({ins['kf:max']['states']} states); the goal is at most 5 % "
                f"({'met' if worst['default'] <= 0.05 * TICK_PERIOD_US else 'not met'} at the "
                "default)."]
    if n["kf_paths"]:
        rows = []
        for key, note in MODELS:
            r = n["kf_paths"][key]
            rows.append([f"{ins[f'kf:{key}']['states']}{note}", r["typical"]] + [r[k] for k, _ in KF_PATHS] +
                        [f"{r['worst']} ({r['worst_path']})", f"{r['dense_ratio']:.1f}"])
        out += ["\nhd_kf_step by path, max instructions per call (the bench image forces each "
                "path on every call: every gain fraction below 1, no block frozen (motor blocks "
                "below q_motion_ref_rad, output_learn_scale 0.5); motor blocks over Nyquist; a "
                "phase advance beyond four turns; every covariance block above p_max; a "
                "non-finite state; all of them (but partial gains) with an offset jump):\n",
                md_table(["states", "typical"] + [name for _, name in KF_PATHS] +
                         ["worst case", "dense / typical (mean)"], rows)]
    return "\n".join(out)


def timing(c: dict, mhz: float) -> dict:
    """One counted section for docs/results/budget.json."""
    us = worst_us(c, mhz)
    return {"mean_instructions": round(float(c["mean"]), 1), "max_instructions": c["max"],
            "cycles_best": round(c["cycles_best"]), "cycles_worst": round(c["cycles_worst"]),
            "worst_us": round(us, 2), "budget_fraction": round(us / TICK_PERIOD_US, 4)}


def budget_summary(n: dict) -> dict:
    """The mps2-an386 part of docs/results/budget.json: per filter size, the
    filter step (typical and worst path), the tick and the tick with
    commands, as instructions, estimated cycles, us and fraction of the
    tick."""
    ins, mhz = n["instructions"], n["clock_mhz"]
    per_states = {}
    for key, _ in MODELS:
        kf, isr, cmd = (ins[f"{k}:{key}"] for k in ("kf", "isr", "isrcmd"))
        step = {"typical": timing(kf, mhz)}
        if n["kf_paths"]:
            path = n["kf_paths"][key]
            kind = max(KF_PATHS, key=lambda k: path[k[0]])[0]
            step["worst"] = dict(timing(ins[f"{kind}:{key}"], mhz), path=path["worst_path"])
        step["dense"] = timing(ins[f"dense:{key}"], mhz)
        if n["kf_paths"]:
            step["dense_over_typical_mean"] = n["kf_paths"][key]["dense_ratio"]
        per_states[str(kf["states"])] = {
            "kf_step": step, "tick": timing(isr, mhz),
            "tick_with_commands": dict(timing(cmd, mhz),
                                       ratio_to_tick_max=round(cmd["max"] / isr["max"], 2),
                                       frames_in=n["tick_limits"]["rx"],
                                       acks_out=n["tick_limits"]["acks"])}
        if f"isrctrl:{key}" in ins:
            for name, kind in (("tick_with_control", "isrctrl"),
                               ("tick_with_control_and_commands", "isrctrlcmd")):
                c = ins[f"{kind}:{key}"]
                per_states[str(kf["states"])][name] = dict(
                    timing(c, mhz), ratio_to_tick_max=round(c["max"] / isr["max"], 2),
                    frames_in=n["tick_limits"]["rx"])
    control = {"ctrl_step": timing(ins["ctrl:default"], mhz)} if "ctrl:default" in ins else {}
    return {**control,"image": "hd_image.elf (instructions: hd_bench.elf)",
            "flash_bytes": n["flash_bytes"], "ram_bytes": n["ram_bytes"],
            "stack_worst_bytes": n["stack_worst_bytes"],
            "stack_reserved_bytes": n["stack_reserved_bytes"],
            "default_states": ins["kf:default"]["states"], "max_states": ins["kf:max"]["states"],
            "per_states": per_states}


# ------------------------------------------- budget: the documents it writes

DOC_BEGIN, DOC_END = "<!-- target:budget:begin -->", "<!-- target:budget:end -->"
DOC_NOTE = "<!-- written by tools/target budget --update-docs; do not edit -->"


def replace_block(text: str, body: str, name: str) -> str:
    """text with everything between its budget markers replaced by body;
    TargetError (naming the document) unless each marker occurs once, in
    order."""
    if text.count(DOC_BEGIN) != 1 or text.count(DOC_END) != 1 or \
            text.index(DOC_BEGIN) > text.index(DOC_END):
        raise TargetError(f"{name}: needs one {DOC_BEGIN} line and one {DOC_END} line after it")
    pre, rest = text.split(DOC_BEGIN, 1)
    post = rest.split(DOC_END, 1)[1]
    return f"{pre}{DOC_BEGIN}\n{DOC_NOTE}\n\n{body}\n\n{DOC_END}{post}"


def doc_paths(docs: Path) -> dict:
    return {"mps2-an386": docs / "target.md", "stm32f4": docs / "stm32f4.md",
            "json": docs / "results" / "budget.json"}


def read_docs(docs: Path) -> dict:
    """The two budget documents' text, checked for markers (TargetError)."""
    texts = {}
    for board in ("mps2-an386", "stm32f4"):
        path = doc_paths(docs)[board]
        try:
            texts[board] = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise TargetError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") \
                from None
        replace_block(texts[board], "", str(path))
    return texts


def umask() -> int:
    mask = os.umask(0o22)
    os.umask(mask)
    return mask


def write_files(outputs: list) -> None:
    """Writes [(path, text)] all or none: every text to a temporary file
    beside its target, then renames them over the targets.  A target that
    exists and is not a regular file (/dev/null, a FIFO) is written
    directly, never replaced."""
    temps, path = [], None
    try:
        for path, text in outputs:
            if path.exists() and not path.is_file():
                path.write_text(text)
                continue
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
            temps.append((Path(tmp), path))
            with os.fdopen(fd, "w") as f:
                f.write(text)
            os.chmod(tmp, path.stat().st_mode & 0o777 if path.exists() else 0o666 & ~umask())
        for tmp, path in temps:
            os.replace(tmp, path)
    except OSError as exc:
        for tmp, _ in temps:
            tmp.unlink(missing_ok=True)
        raise TargetError(f"cannot write {path}: {exc.strerror or exc}") from None


def source_state() -> dict:
    """The commit the numbers were measured on, and whether the tree had
    uncommitted changes then outside docs/ (git; 'unknown' outside a
    checkout)."""
    try:
        head = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short=12", "HEAD"],
                              capture_output=True, text=True, timeout=30)
        dirty = subprocess.run(["git", "-C", ROOT, "status", "--porcelain",
                                "--untracked-files=no", "--", ".", ":(exclude)docs",
                                ":(exclude)README.md"],
                               capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return {"commit": "unknown", "uncommitted_changes": None}
    if head.returncode != 0:
        return {"commit": "unknown", "uncommitted_changes": None}
    return {"commit": head.stdout.strip(), "uncommitted_changes": bool(dirty.stdout.strip())}


def write_budget_docs(docs: Path, m4: dict, f4: dict, source: dict) -> list:
    """Renders both boards' budgets into target.md, stm32f4.md (between the
    markers) and results/budget.json under docs, all or none.  Returns the
    paths written."""
    from hdtools import target_stm32f4
    paths, texts = doc_paths(docs), read_docs(docs)
    where = (f"Measured at commit {source['commit']}"
             + (" with uncommitted changes" if source["uncommitted_changes"] else "")
             + "; the numbers: [results/budget.json](results/budget.json).")
    summary = {"generated_by": "tools/target budget --update-docs", "source": source,
               "tick_period_us": TICK_PERIOD_US, "clock_mhz": m4["clock_mhz"],
               "mps2-an386": budget_summary(m4), "stm32f4": target_stm32f4.summary(f4)}
    outputs = [(paths["mps2-an386"], replace_block(
                    texts["mps2-an386"], f"{where}\n\n{render_budget(m4)}",
                    str(paths["mps2-an386"]))),
               (paths["stm32f4"], replace_block(
                    texts["stm32f4"], f"{where}\n\n{target_stm32f4.render(f4)}",
                    str(paths["stm32f4"]))),
               (paths["json"], json.dumps(summary, indent=1) + "\n")]
    write_files(outputs)
    return [p for p, _ in outputs]


def write_json(dest: Path, numbers: dict) -> None:
    """--json: the measured numbers (not the failures), atomically."""
    write_files([(dest, json.dumps({k: v for k, v in numbers.items() if k != "failures"},
                                   indent=1))])


def cmd_update_docs(a) -> int:
    """Measures both ports and rewrites their budget documents and
    docs/results/budget.json; nothing is written when a check fails."""
    from hdtools import target_stm32f4
    docs = Path(a.docs)
    read_docs(docs)  # fail on a document without markers before measuring
    select_board("mps2-an386")
    m4 = budget()
    select_board("stm32f4")
    f4 = target_stm32f4.measure()
    failures = m4["failures"] + f4["failures"]
    if failures:
        print(f"tools/target: budget checks failed, nothing written: {'; '.join(failures)}",
              file=sys.stderr)
        return 1
    written = write_budget_docs(docs, m4, f4, source_state())
    print("updated " + ", ".join(str(p) for p in written))
    return 0


def cmd_budget(a) -> int:
    numbers = budget()
    print(render_budget(numbers))
    if a.json:
        write_json(Path(a.json), numbers)
    for failure in numbers["failures"]:
        print(f"\nFAIL: {failure}")
    return 1 if numbers["failures"] else 0


# --------------------------------------------------------------------- main

def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="tools/target", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    on = argparse.ArgumentParser(add_help=False)
    on.add_argument("--board", choices=sorted(BOARDS),
                    help="board port (default mps2-an386)")
    sub.add_parser("build", parents=[on], help="build the images and the plugin")
    r = sub.add_parser("run", parents=[on], help="run the firmware image on a raw stream")
    r.add_argument("stream")
    r.add_argument("--out", help="per-tick float dump (28-byte records)")
    r.add_argument("--can", help="candump -l log of the transmitted frames")
    r.add_argument("--count", help="write the plugin's instruction counts here")
    c = sub.add_parser("compare", parents=[on], help="host build vs QEMU image, bit for bit")
    c.add_argument("stream", nargs="?")
    c.add_argument("--scenario", help="simulate this sim/ scenario (.ini) with hdsim")
    c.add_argument("--duration", type=float, help="override the scenario's duration_s")
    c.add_argument("--host-build", help="host build tree with target_hostref, "
                   "hdjoint-host and hdsim (default: build/target-host, built on demand)")
    # hdtools.target_stm32f4 and hdtools.target_closed_loop use this module's
    # helpers and board state: when run as __main__ (the launcher), it is that module.
    sys.modules.setdefault("hdtools.target", sys.modules[__name__])
    from hdtools import target_closed_loop
    target_closed_loop.add_parser(sub, [on])
    b = sub.add_parser("budget", parents=[on], help="print the budget tables (markdown)")
    b.add_argument("--markdown", action="store_true", help="(the default format)")
    b.add_argument("--json", help="also write the numbers to this JSON file")
    b.add_argument("--update-docs", action="store_true",
                   help="measure both ports (mps2-an386 and stm32f4) and rewrite their tables "
                        "in docs/target.md and docs/stm32f4.md and docs/results/budget.json")
    b.add_argument("--docs", default=str(ROOT / "docs"),
                   help="the docs folder --update-docs writes (default: the tree's docs/)")
    k = sub.add_parser("count", parents=[on], help="instruction counts between markers of an image")
    k.add_argument("elf")
    k.add_argument("args", nargs="*")
    f = sub.add_parser("flash", help="program a board over ST-Link (OpenOCD) or USB DFU")
    f.add_argument("--board", choices=sorted(FLASH_BOARDS), required=True)
    f.add_argument("--tool", choices=["openocd", "dfu"], default="openocd")
    f.add_argument("--image", help="the ELF to program (default: build it)")
    f.add_argument("--dry-run", action="store_true", help="print the commands, run nothing")
    a = ap.parse_args(argv)
    try:
        from hdtools import target_stm32f4
        if a.cmd == "flash":
            return target_stm32f4.cmd_flash(a)
        if a.cmd == "budget" and a.update_docs:
            if a.board or a.json:
                raise TargetError("budget --update-docs measures both boards: drop --board "
                                  "and --json")
            return cmd_update_docs(a)
        a.board = a.board or "mps2-an386"
        select_board(a.board)
        if a.cmd == "build":
            build_images()
            build_plugin()
            print(f"built {image(RUN_IMAGE)}, {image(BENCH_IMAGE)}, {HOST_BUILD / 'hdcount.so'}")
            return 0
        if a.cmd == "run":
            return cmd_run(a)
        if a.cmd == "compare":
            if bool(a.stream) == bool(a.scenario):
                ap.error("compare needs a stream or --scenario")
            return cmd_compare(a)
        if a.cmd == "closed-loop":
            if a.board != "mps2-an386":
                raise TargetError("closed-loop runs on mps2-an386 only")
            return target_closed_loop.cmd_closed_loop(a)
        if a.cmd == "budget":
            if a.board != "mps2-an386":
                return target_stm32f4.cmd_budget(a)
            return cmd_budget(a)
        return cmd_count(a)
    except TargetError as exc:
        print(f"tools/target: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
