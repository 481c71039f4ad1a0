"""`hdsense sim`: run the simulated joint (the C `hdsim` executable).

The exit status is hdsim's (docs/sim.md: 0 ok, 2 bad usage or scenario,
3 an output could not be written, 130/143 interrupted); 1 if hdsim cannot
be found or built.
"""
from __future__ import annotations

import argparse
import subprocess

from . import native
from .safeio import HdError


def register(sub) -> None:
    p = sub.add_parser("sim", help="run the simulated joint (hdsim) on a scenario file",
                       description="Thin front end over the hdsim executable; "
                                   "all arguments after the scenario are passed through.")
    p.add_argument("scenario", help="scenario .ini (see docs/sim.md)")
    p.add_argument("hdsim_args", nargs=argparse.REMAINDER,
                   help="passed to hdsim, e.g. --csv out.csv --raw out.hdraw --duration 5")
    p.set_defaults(func=_run)


def _run(args) -> int:
    try:
        exe = native.executable("hdsim")
    except (OSError, subprocess.CalledProcessError) as exc:
        raise HdError(f"cannot find or build hdsim: {exc}") from None
    return subprocess.run([str(exe), args.scenario, *args.hdsim_args]).returncode
