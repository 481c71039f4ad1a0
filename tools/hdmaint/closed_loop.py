"""tools/target closed-loop: the Cortex-M4F image closing the control loop
against the host's dynamic plant, tick by tick, and the host build of the
same firmware against the same plant: bit for bit (issue 23).

The image (firmware/board/mps2_an386/main_ctrl.c, hd_ctrl_image) and the
plant (tests/target/target_plant.c, host build) talk through two FIFOs,
one record each way per tick (firmware/board/common/hd_lockstep.h): the
plant writes tick k's sensors and setpoint, the image runs hd_fw_isr and
answers with its drive command, the plant's simulated drive takes it and
the joint is integrated.  The step test: TORQUE 0 N m, then 10 N m from
tick 300, against a spring.  The host reference (`target_plant host`) runs
the same records through the host build in one process; the two command
files (mode, drive enable, current, torque reference, filtered torque,
faults, limits per tick) must be equal byte for byte.
"""
from __future__ import annotations

import os
import struct
import subprocess
import tempfile
from pathlib import Path

from .board import HOST_BUILD, Board, TargetError, build_images, host_tools, run_qemu, sh
from .qemu_run import f32

CTRL_IMAGE = "hd_ctrl_image"
# u32 tick, u32 mode | enabled << 8, f32 current, f32 torque ref, f32 filtered, u32 faults,
# u32 limits
CTRL_RECORD = struct.Struct("<IIIIIII")
STEP_TICK, STEP_NM = 300, 10.0     # tests/target/target_plant.c
PLANT_TIMEOUT_S = 30


def plant_tool(host_build: Path | None) -> Path:
    bdir = host_build or HOST_BUILD
    if host_build is None:
        host_tools(None)              # configures build/target-host if needed
        sh(["cmake", "--build", bdir, "-j2", "--target", "target_plant"],
             stdout=subprocess.DEVNULL)
    path = bdir / "tests" / "target" / "target_plant"
    if not path.exists():
        raise TargetError(f"{path} is missing: build the host tree {bdir} first")
    return path


def read_records(path: Path) -> list:
    data = path.read_bytes()
    if len(data) % CTRL_RECORD.size:
        raise TargetError(f"{path}: not a whole number of {CTRL_RECORD.size}-byte records")
    return [CTRL_RECORD.unpack_from(data, i) for i in range(0, len(data), CTRL_RECORD.size)]


def compare_records(host: list, qemu: list) -> list:
    """Exact comparison; returns the problems found."""
    problems = []
    if len(host) != len(qemu) or not host:
        problems.append(f"{len(host)} host ticks, {len(qemu)} QEMU ticks")
    diff = [i for i, (h, q) in enumerate(zip(host, qemu)) if h != q]
    if diff:
        h, q = host[diff[0]], qemu[diff[0]]
        problems.append(f"{len(diff)} of {len(host)} ticks differ; first at tick {h[0]}: "
                        f"current host {f32(h[2])!r} qemu {f32(q[2])!r}, torque reference "
                        f"host {f32(h[3])!r} qemu {f32(q[3])!r}, filtered host "
                        f"{f32(h[4])!r} qemu {f32(q[4])!r}")
    return problems


def run_lockstep(board: Board, plant: Path, work: Path, ticks: int) -> tuple:
    """(QEMU exit status and console, plant exit status and stderr)."""
    samples, commands = work / "samples.fifo", work / "commands.fifo"
    os.mkfifo(samples)
    os.mkfifo(commands)
    proc = subprocess.Popen([str(plant), "lockstep", str(samples), str(commands),
                             str(work / "qemu.bin"), str(ticks)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        rc, text = run_qemu(board, board.image(CTRL_IMAGE), [samples, commands])
        try:
            _, err = proc.communicate(timeout=PLANT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
            err = f"did not finish ({err.strip()})"
        return rc, text, proc.returncode, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def cmd_closed_loop(board: Board, a) -> int:
    build_images(board)
    plant = plant_tool(Path(a.host_build).resolve() if a.host_build else None)
    with tempfile.TemporaryDirectory(prefix="hd-target-loop-") as tmp:
        work = Path(tmp)
        rc, text, prc, perr = run_lockstep(board, plant, work, a.ticks)
        if rc != 0 or prc != 0:
            print(f"FAIL: QEMU exit status {rc}, plant exit status {prc}\n{text}{perr}")
            return 1
        sh([plant, "host", work / "host.bin", str(a.ticks)], stdout=subprocess.DEVNULL)
        host, qemu = read_records(work / "host.bin"), read_records(work / "qemu.bin")
    problems = compare_records(host, qemu)
    for msg in problems:
        print(f"FAIL: {msg}")
    ok = not problems
    last = qemu[-1] if qemu else None
    modes = sorted({r[1] & 0xFF for r in qemu})
    print(f"closed loop: {len(qemu)} ticks in lockstep with the plant, TORQUE 0 -> {STEP_NM:g} "
          f"N m at tick {STEP_TICK}; drive commands, torque reference, filtered torque, faults "
          f"and limits {'bit-identical' if ok else 'DIFFERENT'} to the host build" +
          (f"; last tick: current {f32(last[2]):.4f} A, filtered {f32(last[4]):.3f} N m, "
           f"modes run {modes}" if last else ""))
    return 0 if ok else 1


def add_parser(sub, parents) -> None:
    c = sub.add_parser("closed-loop", parents=parents,
                       help="the image closing its control loop against the host plant, in "
                            "lockstep, vs the host build: bit for bit")
    c.add_argument("--ticks", type=int, default=1000, help="ticks to run (default 1000)")
    c.add_argument("--host-build", help="host build tree with target_plant (default: "
                   "build/target-host, built on demand)")
