"""`hdsense analyze`: close the loop with measured data.

Replays a torque log through the firmware's own filter (C, via ctypes),
finds structure the model lacks in the residual, traces it to an effect,
adds the effect, re-runs, keeps it only if it helps, and reports the error
before and after.  See docs/analyze.md."""
from __future__ import annotations

import sys


def register(sub):
    p = sub.add_parser("analyze", help="find and add un-modelled effects in a torque log",
                       description=__doc__)
    p.add_argument("input", nargs="?", help="CSV (t_s, torque_nm, motor_angle_rad or "
                   "output_angle_rad, ...) or candump -l log of the firmware telemetry")
    p.add_argument("--json", metavar="REPORT.json", help="write the report here")
    p.add_argument("--out", metavar="DIR", help="also write report.md, PNG plots, model.cfg, model.can")
    p.add_argument("--gear-ratio", type=float, help="gear ratio N (inferred when absent)")
    p.add_argument("--motor-orders", default="2,4", help="starting motor orders (default 2,4)")
    p.add_argument("--output-orders", default="1", help="starting output orders (default 1; '' for none)")
    p.add_argument("--inertia", type=float, default=0.0, metavar="J_kgm2",
                   help="load inertia for the expected torque [kg m^2] (default 0)")
    p.add_argument("--fs", type=float, metavar="HZ", help="sample rate when there is no t_s column")
    p.add_argument("--node-id", type=int, default=1, help="CAN node id for model.can (default 1)")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--bench-hour", action="store_true",
                   help="speed benchmark: simulate one hour at 1 kHz and time the analysis")
    p.set_defaults(func=main)


def _orders(text, name):
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise SystemExit(f"hdsense analyze: --{name}: expected comma-separated numbers, got {text!r}")
    if any(not v > 0 for v in vals):
        raise SystemExit(f"hdsense analyze: --{name}: orders must be > 0")
    return vals


def main(args) -> int:
    if args.bench_hour:
        from .analysis import bench_speed
        return bench_speed.main()
    if not args.input:
        print("hdsense analyze: INPUT is required", file=sys.stderr)
        return 2
    if not args.json and not args.out:
        print("hdsense analyze: give --json REPORT.json and/or --out DIR", file=sys.stderr)
        return 2
    from .analysis import pipeline
    from .analysis.loading import InputError
    from .analysis.cfilter import FilterError
    log = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    try:
        report = pipeline.analyze(
            args.input, gear_ratio=args.gear_ratio,
            motor_orders=_orders(args.motor_orders, "motor-orders"),
            output_orders=_orders(args.output_orders, "output-orders"),
            inertia_kgm2=args.inertia, fs_hz=args.fs, out_dir=args.out,
            json_path=args.json, node_id=args.node_id, log=log)
    except (InputError, FilterError) as exc:
        print(f"hdsense analyze: {exc}", file=sys.stderr)
        return 2
    s = report["summary"]
    print(s)
    return 0
