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
                                  both ports' budgets into docs/results/target.md,
                                  docs/how-to/stm32f4.md (block target-budget,
                                  hdtools.docblock) and
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
error.  Only the Python standard library is used.  The parts: board.py
(the ports as Board objects, build, QEMU), qemu_run.py, m4_cycles.py,
stack.py, budget.py, budget_render.py, budget_docs.py, stm32f4.py,
closed_loop.py.
"""
from __future__ import annotations

import argparse
import sys

from . import closed_loop, qemu_run, stm32f4
from .board import BOARDS, HOST_BUILD, ROOT, TargetError, build_images, build_plugin
from .budget_docs import cmd_budget, cmd_update_docs


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
    closed_loop.add_parser(sub, [on])
    b = sub.add_parser("budget", parents=[on], help="print the budget tables (markdown)")
    b.add_argument("--markdown", action="store_true", help="(the default format)")
    b.add_argument("--json", help="also write the numbers to this JSON file")
    b.add_argument("--update-docs", action="store_true",
                   help="measure both ports (mps2-an386 and stm32f4) and rewrite their tables "
                        "in docs/results/target.md and docs/how-to/stm32f4.md and "
                        "docs/results/budget.json")
    b.add_argument("--docs", default=str(ROOT / "docs"),
                   help="the docs folder --update-docs writes (default: the tree's docs/)")
    k = sub.add_parser("count", parents=[on], help="instruction counts between markers of an image")
    k.add_argument("elf")
    k.add_argument("args", nargs="*")
    f = sub.add_parser("flash", help="program a board over ST-Link (OpenOCD) or USB DFU")
    f.add_argument("--board", choices=sorted(stm32f4.FLASH_BOARDS), required=True)
    f.add_argument("--tool", choices=["openocd", "dfu"], default="openocd")
    f.add_argument("--image", help="the ELF to program (default: build it)")
    f.add_argument("--dry-run", action="store_true", help="print the commands, run nothing")
    a = ap.parse_args(argv)
    try:
        if a.cmd == "flash":
            return stm32f4.cmd_flash(a)
        if a.cmd == "budget" and a.update_docs:
            if a.board or a.json:
                raise TargetError("budget --update-docs measures both boards: drop --board "
                                  "and --json")
            return cmd_update_docs(a)
        board = BOARDS[a.board or "mps2-an386"]
        if a.cmd == "build":
            build_images(board)
            build_plugin()
            print(f"built {board.image(board.run_image)}, {board.image(board.bench_image)}, "
                  f"{HOST_BUILD / 'hdcount.so'}")
            return 0
        if a.cmd == "run":
            return qemu_run.cmd_run(board, a)
        if a.cmd == "compare":
            if bool(a.stream) == bool(a.scenario):
                ap.error("compare needs a stream or --scenario")
            return qemu_run.cmd_compare(board, a)
        if a.cmd == "closed-loop":
            if board.name != "mps2-an386":
                raise TargetError("closed-loop runs on mps2-an386 only")
            return closed_loop.cmd_closed_loop(board, a)
        if a.cmd == "budget":
            return cmd_budget(board, a)
        return qemu_run.cmd_count(board, a)
    except TargetError as exc:
        print(f"tools/target: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
