"""`hdsense analyze`: close the loop with measured data.

Replays a torque log through the firmware's own filter (C, via ctypes),
finds structure the model lacks in one part of the log, traces it to an
effect, adds the effect, re-runs, keeps it only if it helps in the part of
the log it was not found in, and reports the error before and after, in and
out of sample.  See docs/design/analyze.md."""
from __future__ import annotations

import math
import sys

from . import canproto, protocol
from .safeio import UsageError


def register(sub):
    p = sub.add_parser("analyze", help="find and add un-modelled effects in a torque log",
                       description=__doc__)
    p.add_argument("input", nargs="?", help="CSV (t_s, torque_nm, motor_angle_rad or "
                   "output_angle_rad, ...), candump -l log of the firmware telemetry, "
                   ".mcap file or rosbag2 folder (sensor_msgs/msg/JointState)")
    p.add_argument("--json", metavar="REPORT.json", help="write the report here")
    p.add_argument("--out", metavar="DIR", help="also write report.md, PNG plots, model.cfg, "
                   "model.can and profile.json")
    p.add_argument("--gear-ratio", type=float, help="gear ratio N (inferred when absent)")
    p.add_argument("--motor-orders", default="2,4", help="starting motor orders (default 2,4)")
    p.add_argument("--output-orders", default="1", help="starting output orders (default 1; '' for none)")
    p.add_argument("--inertia", type=float, default=0.0, metavar="J_kgm2",
                   help="load inertia for the expected torque [kg m^2] (default 0)")
    p.add_argument("--config", metavar="JOINT.cfg",
                   help="the joint's configuration text (e.g. from `hdsense current --config`): "
                        "its motor-current keys are replayed with the log's motor_current_a "
                        "and written to model.cfg")
    p.add_argument("--fs", type=float, metavar="HZ", help="sample rate when there is no t_s column")
    p.add_argument("--time-unit", choices=("s", "ms", "us"),
                   help="unit of the t_s column (detected from its step when absent)")
    p.add_argument("--angle-unit", choices=("rad", "deg"),
                   help="unit of the angle columns (detected from the speeds when absent)")
    p.add_argument("--joint", metavar="NAME", help="which joint of a bag's JointState "
                   "(MCAP, rosbag2 folder; default: its only joint; docs/how-to/ros2.md)")
    p.add_argument("--node-id", type=int, default=1, help="CAN node id for model.can (default 1)")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--bench-hour", action="store_true",
                   help="speed benchmark: simulate one hour at 1 kHz and time the analysis")
    p.add_argument("--results-doc", metavar="FILE.md",
                   help="run the simulated cases and the iiwa logs and write the results "
                        "tables (docs/results/analyze-results.md); with --bench-hour, the "
                        "benchmark too")
    p.set_defaults(func=main)


def _orders(text, name):
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UsageError(f"--{name}: expected comma-separated numbers, got {text!r}") from None
    lo, hi = canproto.ORDER_MIN, canproto.ORDER_MAX
    for v in vals:
        if not lo <= v <= hi:
            raise UsageError(f"--{name}: order {v:g} outside {lo:g}..{hi:g} (not representable "
                             "on CAN)")
    return vals


def _check_args(args):
    if not args.input:
        raise UsageError("INPUT is required")
    if not args.json and not args.out:
        raise UsageError("give --json REPORT.json and/or --out DIR")
    if not protocol.NODE_MIN <= args.node_id <= protocol.NODE_MAX:
        raise UsageError(f"--node-id must be {protocol.NODE_MIN}..{protocol.NODE_MAX} "
                         f"(got {args.node_id})")
    for name in ("gear_ratio", "fs", "inertia"):
        v = getattr(args, name)
        if v is not None and not math.isfinite(v):
            raise UsageError(f"--{name.replace('_', '-')} must be a finite number")
    if args.gear_ratio is not None and not args.gear_ratio >= 1:
        raise UsageError(f"--gear-ratio must be >= 1 (got {args.gear_ratio:g})")
    if args.inertia < 0:
        raise UsageError(f"--inertia must be >= 0 (got {args.inertia:g})")
    if args.fs is not None and not args.fs > 0:
        raise UsageError(f"--fs must be > 0 (got {args.fs:g})")


def _config_text(path) -> str:
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"--config {path}: cannot read ({getattr(exc, 'strerror', None) or exc})"
                         ) from None


def main(args) -> int:
    """Errors are raised as hdtools.safeio errors (one line and the exit
    status from hdtools.cli: 2 bad input, 3 an output could not be written,
    4 internal error)."""
    if args.results_doc:
        from .analysis import results
        return results.main(args.results_doc, with_bench=args.bench_hour)
    if args.bench_hour:
        from .analysis import bench_speed
        return bench_speed.main()
    _check_args(args)
    motor = _orders(args.motor_orders, "motor-orders")
    output = _orders(args.output_orders, "output-orders")
    config_text = _config_text(args.config) if args.config else None
    from .analysis import pipeline
    from .analysis.cfilter import FilterError
    log = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    try:
        report = pipeline.analyze(
            args.input, gear_ratio=args.gear_ratio, motor_orders=motor, output_orders=output,
            inertia_kgm2=args.inertia, fs_hz=args.fs, out_dir=args.out, json_path=args.json,
            node_id=args.node_id, log=log, time_unit=args.time_unit, angle_unit=args.angle_unit,
            joint=args.joint, config_text=config_text)
    except FilterError as exc:
        raise UsageError(f"the filter refuses this log's model: {exc}") from None
    print(report["summary"])
    return 0
