"""`hdsense calib`: torque sensor calibration report, record and plot.

Reads calibration experiments from CSV (docs/calibration.md), analyses them
with the C library calib/ (ctypes), prints a report in the shape of Table I
of Taghirad 1997 plus nonlinearity, hysteresis and position dependence,
and optionally writes the 64-byte calibration record, a JSON report and a PNG.
Exit status: 0 accepted, 1 rejected (record not written), 2 bad input.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("calib", help="calibration report/record from a calibration CSV",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="calibration CSV ('-' for stdin)")
    p.add_argument("--record", metavar="OUT.bin", help="write the 64-byte calibration record")
    p.add_argument("--force-record", action="store_true",
                   help="write the record even if the calibration is rejected")
    p.add_argument("--png", metavar="OUT.png", help="plot data and fitted lines")
    p.add_argument("--json", metavar="OUT.json", help="write the report as JSON")
    p.add_argument("--serial", default="", help="sensor serial (<= 15 ASCII chars)")
    p.add_argument("--date", type=int, default=None,
                   help="calibration date, unix seconds (default: now)")
    p.add_argument("--counts-per-volt", type=float, default=None,
                   help="ADC counts per volt, when the CSV has bridge_counts")
    p.add_argument("--max-consistency", type=float, help="limit, fraction (default 0.03)")
    p.add_argument("--max-nonlinearity", type=float, help="limit, %% FS (default 1)")
    p.add_argument("--max-hysteresis", type=float, help="limit, %% FS (default 1)")
    p.add_argument("--max-position", type=float, help="limit, %% of gain (default 2)")
    p.add_argument("--alpha", type=float, help="significance level (default 0.001)")
    p.add_argument("--min-experiments", type=int, help="default 2")
    p.set_defaults(func=run)


def _thresholds(args):
    from hdtools.calibtool import lib as L
    t = L.default_thresholds()
    for opt, field in (("max_consistency", "max_consistency"),
                       ("max_nonlinearity", "max_nonlinearity_pct_fs"),
                       ("max_hysteresis", "max_hysteresis_pct_fs"),
                       ("max_position", "max_position_pct"), ("alpha", "alpha"),
                       ("min_experiments", "min_experiments")):
        v = getattr(args, opt)
        if v is not None:
            if isinstance(v, float) and not math.isfinite(v):
                raise L.CalibError(f"--{opt.replace('_', '-')} must be finite")
            setattr(t, field, v)
    if not (0.0 < t.alpha < 1.0):
        raise L.CalibError("--alpha must be in (0, 1)")
    return t


def run(args) -> int:
    from hdtools.calibtool import csvio, report
    from hdtools.calibtool import lib as L
    try:
        text = sys.stdin.read() if args.input == "-" else Path(args.input).read_text()
    except OSError as exc:
        print(f"hdsense calib: cannot read {args.input}: {exc.strerror}", file=sys.stderr)
        return 2
    try:
        thresholds = _thresholds(args)
        exps = csvio.read_csv(text, args.counts_per_volt)
        rep, rc = L.analyze(exps, thresholds)
    except L.CalibError as exc:
        print(f"hdsense calib: error: {exc}", file=sys.stderr)
        return 2
    d = report.to_dict(rep, exps, rc, thresholds)
    sys.stdout.write(report.text(d))
    if args.json:
        Path(args.json).write_text(json.dumps(d, indent=2) + "\n")
    if args.png:
        report.plot(d, exps, args.png)
    if rc == L.ERR_SINGLE_EXPERIMENT:
        print(f"hdsense calib: error: {L.strerror(rc)}", file=sys.stderr)
        return 2
    if args.record:
        if not d["accepted"] and not args.force_record:
            print("hdsense calib: calibration rejected: record not written "
                  "(--force-record to override)", file=sys.stderr)
        else:
            try:
                data = L.encode_record(d["gain_nm_per_v"], d["offset_v"],
                                       int(time.time()) if args.date is None else args.date,
                                       args.serial, d["consistency"] or 0.0)
            except L.CalibError as exc:
                print(f"hdsense calib: error: {exc}", file=sys.stderr)
                return 2
            Path(args.record).write_bytes(data)
            print(f"record: {args.record} ({len(data)} bytes, CRC-32 0x{data[60:64][::-1].hex()})")
    return 0 if d["accepted"] else 1
