"""`hdsense sim`: run the simulated joint (the C `hdsim` executable).

The exit status is hdsim's (docs/reference/sim.md: 0 ok, 2 bad usage or scenario,
3 an output could not be written, 130/143 interrupted); 1 if hdsim is not
built (the message names the command that builds it).
"""
from __future__ import annotations

import argparse
import subprocess

from . import native


def register(sub) -> None:
    p = sub.add_parser("sim", help="run the simulated joint (hdsim) on a scenario file",
                       description="Thin front end over the hdsim executable; "
                                   "all arguments after the scenario are passed through.")
    p.add_argument("scenario", help="scenario .ini (see docs/reference/sim.md)")
    p.add_argument("hdsim_args", nargs=argparse.REMAINDER,
                   help="passed to hdsim, e.g. --csv out.csv --raw out.hdraw --duration 5")
    p.set_defaults(func=_run)


def _run(args) -> int:
    exe = native.executable("hdsim")  # NativeMissing: one line with the build command
    return subprocess.run([str(exe), args.scenario, *args.hdsim_args]).returncode
