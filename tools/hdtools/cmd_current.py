"""`hdsense current`: fit the firmware's current-to-torque parameters from a
log with torque_nm and motor_current_a (docs/design/slow-torque.md, "Motor current").

  hdsense current LOG.csv [--gear-ratio N] [--config OUT.cfg] [--json OUT.json]

Prints each parameter with its standard error; OUT.cfg holds the firmware
configuration lines (current_nm_per_a, current_inertia_kgm2, current_viscous_
nm_s_rad, current_coulomb_nm, current_backdrive_nm_per_a) for hdjoint-host
--config or `hdsense canlog commands`.  A log that cannot support the fit (no current column, too short,
no reversals, a current that does not follow the load) is refused in one
line.  Exit status: 0 fitted, 2 bad command line or a log that cannot
support the fit, 3 an output could not be written.
"""
from __future__ import annotations

import json
import math

from .safeio import Outputs, UsageError


def register(sub) -> None:
    p = sub.add_parser("current", help="fit the motor-current torque model from a log",
                       description=__doc__.split("\n\n")[0])
    p.add_argument("log", help="CSV with t_s, torque_nm, motor_current_a and an output angle "
                   "or velocity")
    p.add_argument("--gear-ratio", type=float, help="N: reports eta kt at the motor, and turns "
                   "a motor angle into the output velocity when there is no output column")
    p.add_argument("--profile", metavar="PROFILE.json", help="the joint's profile (hdsense "
                   "analyze, commissioning): its lines are subtracted instead of fitted (needed "
                   "on an arm, where gravity is an output-order-1 torque)")
    p.add_argument("--config", metavar="OUT.cfg", help="write the firmware configuration lines")
    p.add_argument("--json", metavar="OUT.json", help="write the fit as JSON")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=main)


def main(args) -> int:
    from . import current_fit      # scipy: loaded only when this subcommand runs
    from .analysis import loading
    if args.gear_ratio is not None and not (math.isfinite(args.gear_ratio) and
                                            args.gear_ratio >= 1):
        raise UsageError(f"--gear-ratio must be a finite number >= 1 (got {args.gear_ratio:g})")
    lines = None
    if args.profile:
        from .cmd_profile import load_profile
        lines = [{"lock": ln.lock, "order": ln.order, "a_nm": ln.a_nm, "b_nm": ln.b_nm}
                 for ln in load_profile(args.profile)[0]]
    data = loading.load(args.log)
    f = current_fit.fit(data, args.gear_ratio, args.log, lines)
    if not args.quiet:
        print(f"{args.log}: {f.samples} fit samples ({f.seconds:.0f} s at "
              f"{current_fit.DECIMATE_HZ:g} Hz after a {current_fit.CUTOFF_HZ:g} Hz low-pass), "
              f"residual {f.residual_rms_nm:.4g} N m RMS")
        for k, unit in zip(current_fit.NAMES, current_fit.UNITS):
            w = f.written.get(k)
            tag = "" if w is None else f"   -> {w:.6g}"
            print(f"  {k:26s} {f.value[k]:12.6g} +- {f.sigma[k]:.2g} {unit}{tag}")
        for n in f.notes:
            print(f"  note: {n}")
    with Outputs() as out:
        if args.config:
            out.write_text(args.config, current_fit.config_text(f, args.log))
        if args.json:
            out.write_text(args.json, json.dumps(
                {"value": f.value, "sigma": f.sigma, "written": f.written, "notes": f.notes,
                 "residual_rms_nm": f.residual_rms_nm, "samples": f.samples,
                 "seconds": f.seconds, "source": args.log}, indent=1) + "\n")
        out.commit()
    return 0
