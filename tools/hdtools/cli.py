"""`hdsense` command line: one entry point, one module per subcommand.

Each subcommand lives in hdtools/cmd_<name>.py and defines
`register(subparsers)`, which adds its parser and sets `func` on it.

Every subcommand ends with exit 0 and whole outputs, or one line on stderr
and a non-zero status (docs/results/reliability.md, "Exit status"):
  0 ok   1 negative result (calib: rejected)   2 bad command line or input
  3 an output could not be written   4 internal error (a bug: the line says
  where to look; HDSENSE_TRACEBACK=1 prints the traceback)   130 interrupted
No traceback reaches the user from any subcommand.
"""
from __future__ import annotations

import argparse
import errno
import importlib
import os
import sys
from pathlib import Path

from hdtools.safeio import HdError

SUBCOMMANDS = ["analyze", "calib", "sim", "canlog", "monitor", "device", "profile",
               "current", "fleet", "control", "tune"]
EXIT_INTERNAL = 4


class OneLineParser(argparse.ArgumentParser):
    """argparse with a one-line error (its default prints the usage too)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def version() -> str:
    """The CMake project version (the one place it is written) and the git
    commit of the source tree, if there is one."""
    from hdtools import paths
    if not paths.in_source_tree():      # installed: what the build step recorded
        info = paths.build_info()
        ver = info.get("version", "unknown")
        return ver + (f" (git {info['git']})" if info.get("git") else "")
    root = Path(__file__).resolve().parents[2]
    try:
        ver = paths.project_version(root) or "unknown"
    except OSError:
        ver = "unknown"
        try:
            from importlib.metadata import version as dist_version
            ver = dist_version("hdtools")
        except Exception:  # noqa: BLE001 - not installed either
            pass
    rev = paths.git_revision(root)
    return ver + (f" (git {rev})" if rev else "")


def _parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="hdsense",
        description="Host tools for the harmonic-drive torque sensor firmware.")
    parser.add_argument("--version", action="version", version=f"hdsense {version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"hdtools.cmd_{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"hdtools.cmd_{name}":
                continue  # subcommand not present in this tree
            raise
        module.register(sub)
    return parser


def _say(prog: str, msg: str) -> None:
    msg = " | ".join(part for part in str(msg).splitlines() if part.strip()) or "error"
    try:
        print(f"{prog}: {msg}", file=sys.stderr, flush=True)
    except OSError:
        pass


def main(argv: list[str] | None = None) -> int:
    return run(_parser, argv, "hdsense")


def run(make_parser, argv: list[str] | None, name: str) -> int:
    """Parses argv with make_parser() and runs the chosen `func` with the
    exit statuses above (also for tools that are not hdsense subcommands:
    tools/bench)."""
    prog = name
    try:
        args = make_parser().parse_args(argv)
        prog = " ".join([name] + ([args.command] if getattr(args, "command", None) else []) +
                        [v for k, v in vars(args).items() if k.endswith("_command") and v])
        rc = int(args.func(args) or 0)
        try:
            sys.stdout.flush()  # a failed write to stdout is an error too
        except OSError as exc:
            _devnull_stdout()
            _say(prog, f"stdout: write failed: {exc.strerror or exc}")
            return 3
        return rc
    except SystemExit:
        raise
    except HdError as exc:
        _say(prog, str(exc))
        return exc.code
    except KeyboardInterrupt:
        _say(prog, "interrupted")
        return 130
    except BrokenPipeError:
        # stdout closed early (e.g. `| head`): nothing more can be shown there
        _devnull_stdout()
        _say(prog, "stdout closed before the output was complete")
        return 3
    except OSError as exc:
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        what = ("write failed" if exc.errno in (errno.ENOSPC, errno.EFBIG, errno.EDQUOT,
                                                errno.EIO, errno.EPIPE) else "I/O error")
        _devnull_stdout()
        _say(prog, f"{where}{what}: {exc.strerror or exc}")
        return 3
    except Exception as exc:  # noqa: BLE001 - the last line of defence
        if os.environ.get("HDSENSE_TRACEBACK"):
            raise
        tb = exc.__traceback__
        while tb is not None and tb.tb_next is not None:
            tb = tb.tb_next
        at = f" at {Path(tb.tb_frame.f_code.co_filename).name}:{tb.tb_lineno}" if tb else ""
        _say(prog, f"internal error: {type(exc).__name__}: {exc}{at} "
                   "(a bug; HDSENSE_TRACEBACK=1 shows the traceback)")
        return EXIT_INTERNAL


def _devnull_stdout() -> None:
    """Python flushes stdout at exit; after a failed write that would print a
    second error, so point it at /dev/null."""
    try:
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, sys.stdout.fileno())
        os.close(fd)
    except OSError:
        pass


if __name__ == "__main__":
    sys.exit(main())
