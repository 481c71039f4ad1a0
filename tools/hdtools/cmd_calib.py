"""`hdsense calib`: torque sensor calibration report, record and plot.

Reads calibration experiments from CSV (docs/how-to/calibration.md), analyses them
with the C library calib/ (ctypes), prints a report in the shape of Table I
of Taghirad 1997 plus nonlinearity, hysteresis and position dependence
(each "NOT MEASURABLE" when the data cannot show it, which rejects the
calibration unless --allow-unmeasurable), and optionally writes the 64-byte
calibration record, a JSON report and a PNG.  The output files are written
together (temporary names, renamed when all are complete).
Exit status: 0 accepted, 1 rejected (record not written), 2 bad input or
command line, 3 an output could not be written (old files left as they were).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time


def _unix_s(text: str) -> int:
    from hdtools.calibtool import lib as L
    try:
        value = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a decimal number of seconds") from None
    if not 0 <= value <= L.UNIX_S_MAX:
        raise argparse.ArgumentTypeError(f"{value} outside 0..{L.UNIX_S_MAX} (unsigned "
                                         "32-bit unix seconds)")
    return value


def _serial(text: str) -> str:
    from hdtools.calibtool import lib as L
    try:
        L.check_serial(text)
    except L.CalibError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not finite")
    return value


def _count(text: str) -> int:
    try:
        value = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 2 <= value <= 32:
        raise argparse.ArgumentTypeError(f"{value} outside 2..32")
    return value


def register(sub) -> None:
    p = sub.add_parser("calib", help="calibration report/record from a calibration CSV",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="calibration CSV ('-' for stdin)")
    p.add_argument("--record", metavar="OUT.bin", help="write the 64-byte calibration record")
    p.add_argument("--force-record", action="store_true",
                   help="write the record even if the calibration is rejected")
    p.add_argument("--png", metavar="OUT.png", help="plot data and fitted lines")
    p.add_argument("--json", metavar="OUT.json", help="write the report as JSON")
    p.add_argument("--serial", default="", type=_serial,
                   help="sensor serial (<= 15 printable ASCII characters)")
    p.add_argument("--date", type=_unix_s, default=None,
                   help="calibration date, unix seconds 0..4294967295 (default: now)")
    p.add_argument("--counts-per-volt", type=_finite, default=None,
                   help="ADC counts per volt, when the CSV has bridge_counts")
    p.add_argument("--max-consistency", type=_finite, help="limit, fraction (default 0.03)")
    p.add_argument("--max-nonlinearity", type=_finite, help="limit, %% FS (default 1)")
    p.add_argument("--max-hysteresis", type=_finite, help="limit, %% FS (default 1)")
    p.add_argument("--max-position", type=_finite, help="limit, %% of gain (default 2)")
    p.add_argument("--alpha", type=_finite, help="significance level (default 0.001)")
    p.add_argument("--min-experiments", type=_count, help="default 2")
    p.add_argument("--allow-unmeasurable", action="store_true",
                   help="accept a campaign whose nonlinearity, hysteresis or position "
                        "dependence cannot be measured (reported as such)")
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
            setattr(t, field, v)
    if not (0.0 < t.alpha < 1.0):
        raise L.CalibError("--alpha must be in (0, 1)")
    t.allow_unmeasurable = 1 if args.allow_unmeasurable else 0
    return t


def run(args) -> int:
    from hdtools import safeio
    from hdtools.calibtool import csvio, report
    from hdtools.calibtool import lib as L
    if args.input == "-":
        text = safeio.read_stdin_text()
    else:
        text = safeio.read_text(args.input)
    try:
        thresholds = _thresholds(args)
        exps = csvio.read_csv(text, args.counts_per_volt)
        rep, rc = L.analyze(exps, thresholds)
    except L.CalibError as exc:
        raise safeio.UsageError(f"error: {exc}") from None
    d = report.to_dict(rep, exps, rc, thresholds)
    if rc == L.ERR_SINGLE_EXPERIMENT:
        sys.stdout.write(report.text(d))
        raise safeio.UsageError(f"error: {L.strerror(rc)}")
    write_record = bool(args.record) and (d["accepted"] or args.force_record)
    record = None
    if write_record:
        try:
            record = L.encode_record(d["gain_nm_per_v"], d["offset_v"],
                                     int(time.time()) if args.date is None else args.date,
                                     args.serial, d["consistency"] or 0.0)
        except L.CalibError as exc:
            raise safeio.UsageError(f"error: {exc}") from None
    # every output staged, then all renamed together
    with safeio.Outputs() as out:
        if args.json:
            out.write_text(args.json, json.dumps(d, indent=2, allow_nan=False) + "\n")
        if args.png:
            with out.path(args.png) as tmp:
                report.plot(d, exps, tmp)
        if record is not None:
            out.write_bytes(args.record, record)
        out.commit()
    sys.stdout.write(report.text(d))
    if record is not None:
        print(f"record: {args.record} ({len(record)} bytes, CRC-32 0x{record[60:64][::-1].hex()})")
    elif args.record:
        print("hdsense calib: calibration rejected: record not written "
              "(--force-record to override)", file=sys.stderr)
    return 0 if d["accepted"] else 1
