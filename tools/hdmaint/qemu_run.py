"""tools/target run, compare and count: a firmware image on a raw sample
stream under QEMU, the host build against it bit for bit, and the
instruction counts between an image's markers (hd_mark.h).  Standard
library only."""
from __future__ import annotations

import re
import statistics
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

from .board import Board, TargetError, build_images, host_tools, run_qemu, sh

DUMP_RECORD = struct.Struct("<IiIIIII")  # tick, counts, raw, filtered, ripple, faults, kf_status


def cmd_run(board: Board, a) -> int:
    build_images(board)
    out = Path(a.out).resolve() if a.out else "-"
    can = Path(a.can).resolve() if a.can else "-"
    count = Path(a.count).resolve() if a.count else None
    rc, text = run_qemu(board, board.image(board.run_image),
                        [Path(a.stream).resolve(), out, can], count)
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


def compare_stream(board: Board, stream: Path, tools: dict, work: Path) -> bool:
    """Host vs QEMU on one stream: per-tick float bits and the CAN log."""
    h_bin, q_bin = work / "host.bin", work / "qemu.bin"
    h_log, q_log = work / "host.log", work / "qemu.log"
    sh([tools["hostref"], stream, h_bin], stdout=subprocess.DEVNULL)
    sh([tools["runner"], "--sensors", f"replay:{stream}", "--can", f"log:{h_log}", "--quiet"],
       stdout=subprocess.DEVNULL)
    rc, text = run_qemu(board, board.image(board.run_image), [stream, q_bin, q_log])
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


def cmd_compare(board: Board, a) -> int:
    build_images(board)
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
        return 0 if compare_stream(board, stream, tools, work) else 1


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


def labelled_sections(board: Board, elf: Path, args: list) -> list:
    """Runs an image with the plugin; pairs its 'section LABEL N' console lines
    with the plugin's sections."""
    with tempfile.TemporaryDirectory(prefix="hd-count-") as tmp:
        out = Path(tmp) / "count.txt"
        rc, text = run_qemu(board, elf, args, out)
        if rc != 0:
            raise TargetError(f"{elf.name} exited with status {rc}:\n{text}")
        sections, _ = parse_counts(out.read_text())
    labels = [(m.group(1), int(m.group(2)))
              for m in re.finditer(r"(?m)^section (\S+) (\d+)$", text)]
    if len(labels) != len(sections):
        raise TargetError(f"{len(labels)} section labels but {len(sections)} counted sections")
    return [dict(label=lbl, states=n, **s) for (lbl, n), s in zip(labels, sections)]


def cmd_count(board: Board, a) -> int:
    build_images(board)
    elf = Path(a.elf)
    for s in labelled_sections(board, elf, a.args):
        iv = s["intervals"]
        if iv:
            print(f"{s['label']:<16} calls {len(iv):4d}  instructions min {min(iv)} "
                  f"mean {statistics.mean(iv):.1f} max {max(iv)}")
    return 0
