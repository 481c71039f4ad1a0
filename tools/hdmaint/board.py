"""The board ports tools/target builds and runs, as objects passed to the
build, QEMU and budget code (never module state), and the helpers they all
use: tools on PATH, subprocesses, the host pieces, running an image under
QEMU.  Standard library only."""
from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HOST_BUILD = Path(os.environ.get("HD_TARGET_HOST_BUILD", ROOT / "build" / "target-host"))
PLUGIN_SRC = ROOT / "tools" / "qemu-plugin" / "hdcount.c"
QEMU = "qemu-system-arm"
QEMU_COMMON_ARGS = ["-nographic", "-monitor", "none", "-serial", "none",
                    "-icount", "shift=0,sleep=off"]
QEMU_TIMEOUT_S = 120


class TargetError(Exception):
    """A setup problem (missing tool, build failure): exit status 2."""


@dataclass(frozen=True)
class Board:
    """A board port: its cross-build tree (and preset), the toolchain of a
    tree made outside the preset, the board folder, the QEMU machine and
    the images run and counted there."""
    name: str
    build_env: str          # environment variable that overrides the build tree
    preset: str             # CMake preset; its tree is build/<preset>
    cmake_board: str        # HD_BOARD
    rel: str                # the board folder, inside the build tree too
    machine: str            # qemu-system-arm -M
    run_image: str
    bench_image: str
    targets: tuple          # the CMake targets of its images
    toolchain: str = "cmake/arm-none-eabi.cmake"
    build_type: str = "MinSizeRel"

    @property
    def build_dir(self) -> Path:
        return Path(os.environ.get(self.build_env, ROOT / "build" / self.preset))

    def image(self, name: str) -> Path:
        return self.build_dir / self.rel / f"{name}.elf"

    def qemu_args(self) -> list:
        return ["-M", self.machine, *QEMU_COMMON_ARGS]


MPS2_AN386 = Board("mps2-an386", "HD_TARGET_BUILD", "cortex-m4", "mps2_an386",
                   "firmware/board/mps2_an386", "mps2-an386", "hd_image", "hd_bench",
                   ("hd_image", "hd_bench", "hd_ctrl_image"))
NETDUINOPLUS2 = Board("netduinoplus2", "HD_TARGET_BUILD_STM32F4", "stm32f4", "stm32f4",
                      "firmware/board/stm32f4", "netduinoplus2", "hd_nd2", "hd_stm32f4_bench",
                      ("hd_nd2", "hd_stm32f4_bench", "hd_odrive_v3", "hd_mini_cheetah"))
# stm32f4: the board images' budget; their instruction counts run on netduinoplus2.
BOARDS = {"mps2-an386": MPS2_AN386, "netduinoplus2": NETDUINOPLUS2, "stm32f4": NETDUINOPLUS2}


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


def symbols(elf: Path) -> dict:
    out = sh([need("arm-none-eabi-nm"), elf], capture_output=True, text=True).stdout
    syms = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3:
            syms[parts[2]] = int(parts[0], 16)
    return syms


# -------------------------------------------------------------------- build

def build_images(board: Board) -> None:
    need("arm-none-eabi-gcc")
    need("cmake")
    build = board.build_dir
    if not (build / "build.ninja").exists():
        if build == ROOT / "build" / board.preset:
            sh(["cmake", "--preset", board.preset], cwd=ROOT, stdout=subprocess.DEVNULL)
        else:
            sh(["cmake", "-S", ROOT, "-B", build, "-G", "Ninja",
                f"-DCMAKE_TOOLCHAIN_FILE={ROOT / board.toolchain}",
                f"-DCMAKE_BUILD_TYPE={board.build_type}", f"-DHD_BOARD={board.cmake_board}"],
               stdout=subprocess.DEVNULL)
    sh(["cmake", "--build", build, "-j2", "--target", *board.targets],
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

def run_qemu(board: Board, elf: Path, args: list, count_out: Path | None = None,
             timeout: float = QEMU_TIMEOUT_S) -> tuple:
    """Runs an image on the board's QEMU machine; returns (exit status,
    console text)."""
    need(QEMU)
    for a in args:
        if " " in str(a) or "," in str(a):
            raise TargetError(f"semihosting arguments cannot contain spaces or commas: {a}")
    semi = ",".join(["enable=on", "target=native", f"arg={elf.stem}"] +
                    [f"arg={a}" for a in args])
    cmd = [QEMU] + board.qemu_args() + ["-kernel", elf, "-semihosting-config", semi]
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
