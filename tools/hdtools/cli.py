"""`hdsense` command line: one entry point, one module per subcommand.

Each subcommand lives in hdtools/cmd_<name>.py and defines
`register(subparsers)`, which adds its parser and sets `func` on it.
"""
from __future__ import annotations

import argparse
import importlib
import sys

SUBCOMMANDS = ["analyze", "calib", "sim", "canlog", "bench"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="hdsense",
        description="Host tools for the harmonic-drive torque sensor firmware.")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"hdtools.cmd_{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"hdtools.cmd_{name}":
                continue  # subcommand not present in this tree
            raise
        module.register(sub)
    args = parser.parse_args(argv)
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
