"""`hdsense canlog`: decode a joint's candump log, or turn a firmware
configuration file into CAN commands.

  hdsense canlog decode out/demo/telemetry.log [--node 1] [--csv telem.csv]
                        [--rate HZ] [--cpr MOTOR[,OUTPUT]]
  hdsense canlog commands model.cfg [--node 1]      # prints cansend lines
  hdsense canlog convert run.log --mcap run.mcap [--rosbag DIR] [--joint NAME]

convert: the decoded telemetry (as decode --csv has it) as ROS 2 messages:
/joint_states (effort = the filtered torque), the firmware's other
signals on /hdjoint/NAME/..., heartbeats and faults on /diagnostics, the
device's answers in the metadata (docs/how-to/ros2.md).  Exit status as decode's;
3 also when a rosbag2 folder exists already.

decode: samples are placed in device time (telemetry sequence x period;
the period from --rate, the log's telemetry_rate_hz answers, or estimated
from the time stamps), host time stamps only find gaps; the CSV carries
motor/output angles from TELEM_C's raw counts (docs/reference/protocol.md, "Time
from the device").  Without --node the node is found in the log (a log with frames of
several nodes needs --node).  Lines that are not candump -l frames (a line
cut by an interrupted logger, bad hex, a wrong length) and frames that do
not decode for their message (wrong DLC) are skipped and counted; the first
few line numbers are named on stderr.  Exit status: 0 decoded (with or
without skipped lines), 2 bad command line or input (no frames of the node),
3 the CSV could not be written (an old one is left as it was).
"""
from __future__ import annotations

import argparse
import csv
import io
import sys

import cantools

from hdtools import canproto, protocol, safeio, telemetry
from hdtools.canshared import node_id as _node

SHOW_LINES = 5


def _rate(text: str) -> float:
    try:
        rate = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (1 <= rate <= 1000 and rate == int(rate)):
        raise argparse.ArgumentTypeError(f"rate {text} must be a whole number of Hz in 1..1000")
    return rate


def _cpr(text: str) -> tuple[float, float | None]:
    parts = text.split(",")
    try:
        vals = [int(p, 10) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: want MOTOR_CPR[,OUTPUT_CPR] as whole "
                                         "numbers") from None
    if len(vals) > 2 or any(not 1 <= v <= 1 << 24 for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r}: want MOTOR_CPR[,OUTPUT_CPR] in 1..16777216")
    return float(vals[0]), float(vals[1]) if len(vals) == 2 else None


def _lines(items: list) -> str:
    shown = ", ".join(f"line {n}: {why}" for n, why in items[:SHOW_LINES])
    more = f", ... ({len(items) - SHOW_LINES} more)" if len(items) > SHOW_LINES else ""
    return shown + more


def _decode(args) -> int:
    res = canproto.decode_log(args.log, args.node, args.rate)
    node = res["node"]
    others = {n: c for n, c in res["nodes"].items() if n != node}
    if res["nodes"].get(node, 0) == 0:
        found = ", ".join(f"{n} ({c} frames)" for n, c in sorted(others.items()))
        raise safeio.UsageError(f"{args.log}: no frames of node {node}" +
                                (f"; the log has nodes {found}" if found else
                                 f" ({res['frames']} frames, {len(res['malformed'])} "
                                 "malformed lines)"))
    telem = res["telemetry"]
    out = [f"log = {args.log}",
           f"node = {node}{'' if args.node is not None else ' (found in the log)'}",
           f"frames = {res['frames']}",
           f"malformed_lines = {len(res['malformed'])}",
           f"undecodable_frames = {len(res['bad_frames'])}"]
    if others:
        out.append("other_nodes = " + ", ".join(f"{n} ({c} frames)"
                                                for n, c in sorted(others.items())))
    out += [f"telemetry_frames = {len(telem)}", f"lost_telemetry = {res['lost_telemetry']}"]
    if telem:
        period = res["period_s"]
        out.append(f"telemetry_period_s = {period:g}" if period else
                   "telemetry_period_s = varies in this log")
        out.append(f"period_source = {res['period_source']}")
    if telem:
        valid = [r for r in telem if r["valid"]]
        out.append(f"invalid_samples = {len(telem) - len(valid)}")
        faults = 0
        for r in telem:
            faults |= int(r["Faults"])
        out.append(f"faults_seen = {canproto.faults_str(faults)}")
        span = telem[-1]["t_s"] - telem[0]["t_s"]
        if span > 0:
            out.append(f"telemetry_rate_hz = {(len(telem) - 1) / span:.1f}")
    out.append(f"heartbeats = {len(res['heartbeats'])}")
    for hb in res["heartbeats"][-1:]:
        out.append(f"last_heartbeat = state {hb['State']}, faults "
                   f"{canproto.faults_str(int(hb['HbFaults']))}, calib {hb['CalibStatus']}, "
                   f"deadline misses {hb['DeadlineMisses']}")
    for ack in res["acks"]:
        out.append(f"ack: {ack['AckOpcode']} token {ack['AckToken']} -> {ack['AckResult']} "
                   f"(aux {ack['AckAux']}, value {ack['AckValue']:g})")
    if args.csv:
        cols, notes = telemetry.columns(res, *(args.cpr or (None, None)))
        out += [f"angles = {note}" for note in notes]
        buf = io.StringIO(newline="")
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(list(cols))
        fmt = {"t_s": "{:.6f}", "t_host_s": "{:.6f}"}
        for i in range(len(telem)):
            w.writerow([fmt.get(k, "{:.9g}").format(v[i]) if v.dtype.kind == "f" else str(v[i])
                        for k, v in cols.items()])
        with safeio.Outputs() as outputs:
            outputs.write_text(args.csv, buf.getvalue())
            outputs.commit()
        out.append(f"csv = {args.csv}")
    sys.stdout.write("\n".join(out) + "\n")
    skipped = []
    if res["malformed"]:
        skipped.append(f"skipped {len(res['malformed'])} malformed line(s) "
                       f"({_lines(res['malformed'])})")
    if res["bad_frames"]:
        skipped.append(f"{len(res['bad_frames'])} frame(s) did not decode "
                       f"({_lines(res['bad_frames'])})")
    if skipped:
        print(f"hdsense canlog decode: {args.log}: warning: " + "; ".join(skipped),
              file=sys.stderr)
    return 0


def _convert(args) -> int:
    from .rosio import cli as rosio_cli
    return rosio_cli.convert(args)


def _commands(args) -> int:
    text = safeio.read_text(args.config)
    try:
        frames = canproto.config_to_commands(text, canproto.load_db(args.node))
    except (ValueError, IndexError, KeyError, cantools.database.errors.Error) as exc:
        raise safeio.UsageError(f"{args.config}: {exc}") from None
    sys.stdout.write("".join(canproto.cansend_str(frame) + "\n" for frame in frames))
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("canlog", help="decode joint CAN logs; config -> CAN commands",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="canlog_command", required=True)
    d = sub.add_parser("decode", help="decode a candump -l log with firmware/hdjoint.dbc")
    d.add_argument("log")
    d.add_argument("--node", type=_node, default=None,
                   help=f"node id {protocol.NODE_MIN}..{protocol.NODE_MAX} "
                        "(default: the one node found in the log)")
    d.add_argument("--csv", help="write the decoded telemetry here (the columns "
                   "hdsense analyze reads: t_s in device time, torque_nm, motor_angle_rad, ...)")
    d.add_argument("--rate", type=_rate, default=None, metavar="HZ",
                   help="telemetry_rate_hz of the log (default: the log's GET_PARAM answers, "
                        "else estimated from the time stamps)")
    d.add_argument("--cpr", type=_cpr, default=None, metavar="MOTOR[,OUTPUT]",
                   help="encoder counts per revolution (default: the log's GET_PARAM answers)")
    d.set_defaults(func=_decode)
    v = sub.add_parser("convert", help="a candump -l log -> MCAP / rosbag2 (ROS 2 messages)")
    v.add_argument("log")
    v.add_argument("--node", type=_node, default=None,
                   help="node id (default: the one node found in the log)")
    v.add_argument("--rate", type=_rate, default=None, metavar="HZ",
                   help="telemetry_rate_hz of the log (as for decode)")
    v.add_argument("--cpr", type=_cpr, default=None, metavar="MOTOR[,OUTPUT]",
                   help="encoder counts per revolution (as for decode)")
    from .rosio import cli as rosio_cli
    rosio_cli.add_output_arguments(v)
    v.set_defaults(func=_convert)
    c = sub.add_parser("commands", help="print the CAN commands (cansend ID#DATA) for a config file")
    c.add_argument("config")
    c.add_argument("--node", type=_node, default=1)
    c.set_defaults(func=_commands)
