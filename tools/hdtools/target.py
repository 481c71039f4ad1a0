"""tools/target: the Cortex-M4F firmware image under QEMU, and on the board.

  tools/target build              cross-build the images (preset cortex-m4, or
                                  stm32f4 for --board netduinoplus2/stm32f4),
                                  the instruction-count plugin and the host pieces
  tools/target run IN.hdraw [--out OUT.bin] [--can CAN.log] [--count FILE]
                                  run the firmware image on a raw sample stream
  tools/target compare (IN.hdraw | --scenario INI [--duration S])
                                  host build vs QEMU image: bit-identical?
  tools/target budget [--markdown]
                                  flash, RAM, worst-case stack, instruction
                                  counts per filter update / ISR, cycle estimate
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
                       run="hd_image", bench="hd_bench", targets=["hd_image", "hd_bench"]),
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
    lo = hi = 0
    unknown = 0
    for pc, n in hist.items():
        if pc not in insns:
            unknown += n
            lo += n
            hi += n
            continue
        c_lo, c_hi = m4_cycles(*insns[pc])
        lo += n * c_lo
        hi += n * c_hi
    return lo / calls, hi / calls, unknown


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
    ci_files = [p for p in build.rglob("*.ci")
                if "CMakeFiles" in p.parts and
                (not any(".dir" in part and part.split(".dir")[0] in current_board()["targets"]
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
    hal_candidates = [t for t, ci in origin.items()
                      if ("hal_mock.dir" in str(ci) or "hal_semihost.dir" in str(ci))
                      and t.split(":")[-1] in defined
                      and (":" in t or t == "hal_sh_canlog_hook")]
    if hal_funcs is not None:
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


# hd_kf_step's slow paths in the bench image (main_bench.c), worst last.
KF_PATHS = [("kfpartial", "partial gains"), ("kffrozen", "over Nyquist"),
            ("kflost", "phase lost"), ("kfclamp", "clamp"), ("kfreset", "reset"),
            ("kfworst", "all at once")]


def budget_kf_paths(by: dict, models: list, overhead: int, p) -> dict:
    """The filter step's typical and slow paths, per model: a table (through
    p) and {model: {"typical", PATH..., "worst", "worst_path", "dense_ratio"}}
    (max instructions per call; dense_ratio = dense mean / typical mean)."""
    if not all(f"{kind}:{key}" in by for kind, _ in KF_PATHS for key, _ in models):
        return {}

    def mx(label):
        return max(by[label]["intervals"]) - overhead

    def mean(label):
        return statistics.mean(by[label]["intervals"]) - overhead

    result, rows = {}, []
    for key, states in models:
        r = {"typical": mx(f"kf:{key}")}
        for kind, _ in KF_PATHS:
            r[kind] = mx(f"{kind}:{key}")
        worst = max(KF_PATHS, key=lambda k: r[k[0]])
        r["worst"], r["worst_path"] = max(r["typical"], r[worst[0]]), worst[1]
        r["dense_ratio"] = round(mean(f"dense:{key}") / mean(f"kf:{key}"), 2)
        result[key] = r
        rows.append([states, r["typical"]] + [r[k] for k, _ in KF_PATHS] +
                    [f"{r['worst']} ({r['worst_path']})", f"{r['dense_ratio']:.1f}"])
    p("\nhd_kf_step by path, max instructions per call (the bench image forces each path on "
      "every call: every gain fraction below 1, no block frozen (motor blocks below "
      "q_motion_ref_rad, output_learn_scale 0.5); motor blocks over Nyquist; a phase "
      "advance beyond four turns; every covariance block above p_max; a non-finite state; "
      "all of them (but partial gains) with an offset jump):\n")
    p(md_table(["states", "typical"] + [name for _, name in KF_PATHS] +
               ["worst case", "dense / typical (mean)"], rows))
    return result


def budget(p=None) -> dict:
    """Builds the mps2-an386 images, measures them and returns the budget's
    numbers: {flash_bytes, ram_bytes, stack_reserved_bytes, stack_worst_bytes,
    heap_symbols, counter_check, instructions: {LABEL: {states, calls, mean,
    max}}, kf_paths, failures: [...]} (failures: what failed, empty when all
    checks passed).  p, if given, receives the markdown tables line by line.
    Raises TargetError on a setup problem."""
    build_images()
    run_elf, bench_elf = image("hd_image"), image("hd_bench")
    if p is None:
        p = lambda _line: None  # noqa: E731 (quiet)

    # --- memory
    sizes = section_sizes(run_elf)
    flash = sizes.get(".text", 0) + sizes.get(".ARM.exidx", 0) + sizes.get(".data", 0)
    stack_reserved = sizes.get(".stack", 0)
    ram = sizes.get(".data", 0) + sizes.get(".bss", 0) + stack_reserved
    p("### Memory (hd_image.elf, arm-none-eabi-size -A)\n")
    p(md_table(["region", "used", "of", "contents"], [
        ["flash", f"{flash} B", "512 KB", ".text (code, constants, vector table) + .data image"],
        ["RAM", f"{ram} B", "128 KB",
         f".data {sizes.get('.data', 0)} + .bss {sizes.get('.bss', 0)} + "
         f"reserved stack {stack_reserved}"],
    ]))
    fl, rm = map_by_component(run_elf.with_suffix(".map"))
    p("\nBy component (linker map):\n")
    comps = sorted(set(fl) | set(rm), key=lambda c: -(fl.get(c, 0) + rm.get(c, 0)))
    p(md_table(["component", "flash B", "RAM B (static)"],
               [[c, fl.get(c, 0), rm.get(c, 0)] for c in comps]))
    syms = ram_symbols(run_elf)
    p("\nLargest RAM objects: " + ", ".join(f"`{n}` {s} B" for n, s in syms[:6]) +
      ".  The firmware's own state is `g_fw` (hd_fw_t, two pipelines: the running "
      "model and the one a command builds); `g_mock`, `g_stream`, `g_dump`, `g_canlog` "
      "are the QEMU board's I/O (NVM in RAM, semihosting buffers) that a real board "
      "replaces with peripherals.")

    # --- heap
    heap = [s for s in ("malloc", "_malloc_r", "calloc", "realloc", "free", "_free_r", "_sbrk",
                        "_sbrk_r", "sbrk") if s in symbols(run_elf) or s in symbols(bench_elf)]
    p("\n### Heap\n")
    if heap:
        p(f"FAIL: allocator symbols linked: {', '.join(heap)}")
    else:
        p("None.  Images link with `-nostdlib` (no libc; the board supplies memcpy/memset/"
          "memcmp/strlen/strcmp), the linker script `ASSERT`s that malloc/free/_sbrk are "
          "undefined, and a post-build step checks the symbol table (nm): no "
          "malloc/calloc/realloc/free/_sbrk.")

    # --- stack
    st = worst_stack(run_elf)
    p("\n### Worst-case stack (-fstack-usage + -fcallgraph-info call graph)\n")
    p(md_table(["context", "bytes", "deepest path"], [
        ["main loop (Reset_Handler + main)", st["reset"] + st["main"][0],
         " > ".join(st["main"][1])],
        ["exception entry, FP context (26 words + align)", st["frame"], "hardware"],
        ["SysTick (the 1 kHz ISR)", st["tick"][0], " > ".join(st["tick"][1])],
        ["exception entry (fault inside the ISR)", st["frame"], "hardware"],
        ["HardFault handler", st["fault"][0], " > ".join(st["fault"][1])],
        ["**total worst case**", f"**{st['total']}**", f"reserved: {stack_reserved} B"],
    ]))
    p("\nIndirect calls (HAL vtable, CAN transmit hook) are bounded by the deepest HAL "
      "backend function linked into the image; no recursion" +
      (("; notes: " + "; ".join(st["notes"])) if st["notes"] else "") + ".")
    stack_ok = st["total"] <= stack_reserved

    # --- instruction counts
    sections = labelled_sections(bench_elf, [])
    insns = disassembly(bench_elf)
    by = {s["label"]: s for s in sections}
    overhead = min(by["empty:-"]["intervals"])
    loop = by["loop:-"]["intervals"]
    loop_ok = len(loop) == 2 and loop[1] - loop[0] == 2 * 1000
    p("\n### Instructions per call (QEMU TCG plugin, exact) and estimated cycles\n")
    p(f"Counted by tools/qemu-plugin/hdcount.c between the image's markers, "
      f"{len(by['kf:4']['intervals'])} calls each; marker overhead ({overhead} "
      f"instruction) subtracted.  Counter check: hd_bench_loop(1010) - hd_bench_loop(10) = "
      f"{loop[1] - loop[0] if len(loop) == 2 else '?'} instructions (expected 2000).  "
      "These are **instructions, not cycles**: QEMU has no cycle model.  Cycles are "
      "estimated from the per-instruction execution counts with the Cortex-M4 TRM timings "
      "(ALU 1, LDR 1-2, STR 1-2, taken branch 2-4, VADD/VMUL 1, VMLA 3, VLDR/VSTR 2, "
      "VDIV/VSQRT 14, push/pop 1+N), zero wait states; range = best..worst case.\n")
    models = [("4", "4"), ("6", "6"), ("8", "8"), ("default", "7 (firmware default)"),
              ("max", "17 (max)")]
    rx, acks = fw_tick_limits()
    cmd_label = f"ISR + commands ({rx} in, {acks} ACK out)"
    kinds = [("kf", "hd_kf_step"), ("isr", "ISR (hd_fw_isr)"),
             ("isrcmd", cmd_label), ("dense", "dense textbook KF")]
    mhz = MCU_CLOCKS_MHZ[0][1]
    insn_rows, cycle_rows = [], []
    for key, states in models:
        irow, crow = [states], [states]
        for kind, _ in kinds:
            s = by[f"{kind}:{key}"]
            iv = [n - overhead for n in s["intervals"]]
            lo, hi, _ = cycle_estimate(s["hist"], insns, len(iv))
            lo -= overhead * 2  # the marker's bl (1 + P)
            hi -= overhead * 4
            worst_us = max(iv) * (hi / statistics.mean(iv)) / mhz
            irow.append(f"{statistics.mean(iv):.0f} / {max(iv)}")
            crow.append(f"{lo:.0f}-{hi:.0f} ({worst_us:.1f} us)")
        isr_max = max(by[f"isr:{key}"]["intervals"]) - overhead
        cmd_max = max(by[f"isrcmd:{key}"]["intervals"]) - overhead
        irow.append(f"{cmd_max / isr_max:.2f}")
        insn_rows.append(irow)
        cycle_rows.append(crow)
    p("Instructions per call, mean / max:\n")
    p(md_table(["states"] + [k[1] for k in kinds] + ["with commands / ISR (max)"],
               insn_rows))
    p("\nEstimated Cortex-M4 cycles per call, mean best-worst (worst-case time):\n")
    p(md_table(["states"] + [k[1] for k in kinds], cycle_rows))
    p(f"\nus = worst-case time at {mhz} MHz ({MCU_CLOCKS_MHZ[0][0]}; "
      f"{MCU_CLOCKS_MHZ[1][0]} at {MCU_CLOCKS_MHZ[1][1]} MHz is within 2 %): max "
      "instructions x worst-case cycles per instruction of that section.  The ISR budget "
      "is 1000 us per tick.  ISR = the whole 1 kHz tick body: ADC and encoder reads "
      "(hal_mock), calibration, encoder deltas, tracker, expected torque, filter, faults, "
      f"telemetry (2 frames at 1 kHz) and the heartbeat (tick 0); '{cmd_label}' adds "
      f"command frames on every tick: the tick takes at most HD_FW_RX_PER_TICK = {rx} "
      "frames (a BLOCK_ENABLE toggle of block 0, applied by the tick to the running "
      "filter, and a SET_PARAM r_nm2, whose model rebuild the background does between "
      f"ticks, outside the count), applies the change the background prepared and sends "
      f"at most HD_FW_ACKS_PER_TICK = {acks} ACK.  Other command mixes are not "
      "enumerated: this is a measured load, not a proof of the worst case.")
    kf_paths = budget_kf_paths(by, models, overhead, p)
    counts = {s["label"]: {"states": s["states"], "calls": len(s["intervals"]),
                           "mean": statistics.mean(s["intervals"]) - overhead,
                           "max": max(s["intervals"]) - overhead}
              for s in sections if s["intervals"]}
    failures = [f"allocator symbols linked: {', '.join(heap)}"] if heap else []
    if not stack_ok:
        failures.append(f"worst-case stack {st['total']} B exceeds the reserved "
                        f"{stack_reserved} B")
    if not loop_ok:
        failures.append(f"the instruction counter check failed: {loop}")
    return {"flash_bytes": flash, "ram_bytes": ram, "stack_reserved_bytes": stack_reserved,
            "stack_worst_bytes": st["total"], "heap_symbols": heap,
            "counter_check": loop[1] - loop[0] if len(loop) == 2 else None,
            "instructions": counts, "kf_paths": kf_paths, "failures": failures}


def cmd_budget(a) -> int:
    out = []
    numbers = budget(out.append)
    print("\n".join(out))
    if a.json:
        dest = Path(a.json)
        tmp = dest.with_name(dest.name + ".tmp")
        try:
            tmp.write_text(json.dumps({k: v for k, v in numbers.items() if k != "failures"},
                                      indent=1))
            os.replace(tmp, dest)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise TargetError(f"cannot write {dest}: {exc.strerror or exc}") from exc
    for failure in numbers["failures"]:
        print(f"\nFAIL: {failure}")
    return 1 if numbers["failures"] else 0


# --------------------------------------------------------------------- main

def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="tools/target", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    on = argparse.ArgumentParser(add_help=False)
    on.add_argument("--board", choices=sorted(BOARDS), default="mps2-an386",
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
    b = sub.add_parser("budget", parents=[on], help="print the budget tables (markdown)")
    b.add_argument("--markdown", action="store_true", help="(the default format)")
    b.add_argument("--json", help="also write the numbers to this JSON file")
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
        # hdtools.target_stm32f4 uses this module's helpers and board state:
        # when run as __main__ (the launcher), it is that module.
        sys.modules.setdefault("hdtools.target", sys.modules[__name__])
        from hdtools import target_stm32f4
        if a.cmd == "flash":
            return target_stm32f4.cmd_flash(a)
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
