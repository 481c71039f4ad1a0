"""`hdsense canlog`: decode a joint's candump log, or turn a firmware
configuration file into CAN commands.

  hdsense canlog decode out/demo/telemetry.log [--node 1] [--csv telem.csv]
  hdsense canlog commands model.cfg [--node 1]      # prints cansend lines
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

from hdtools import canproto


def _decode(args) -> int:
    if not Path(args.log).exists():
        print(f"hdsense canlog: {args.log}: no such file", file=sys.stderr)
        return 2
    res = canproto.decode_log(args.log, args.node)
    telem = res["telemetry"]
    print(f"log = {args.log}")
    print(f"telemetry_frames = {len(telem)}")
    print(f"lost_telemetry = {res['lost_telemetry']}")
    if telem:
        valid = [r for r in telem if r["valid"]]
        print(f"invalid_samples = {len(telem) - len(valid)}")
        faults = 0
        for r in telem:
            faults |= int(r["Faults"])
        print(f"faults_seen = {canproto.faults_str(faults)}")
        span = telem[-1]["t_s"] - telem[0]["t_s"]
        if span > 0:
            print(f"telemetry_rate_hz = {(len(telem) - 1) / span:.1f}")
    print(f"heartbeats = {len(res['heartbeats'])}")
    for hb in res["heartbeats"][-1:]:
        print(f"last_heartbeat = state {hb['State']}, faults {canproto.faults_str(int(hb['HbFaults']))}, "
              f"calib {hb['CalibStatus']}, deadline misses {hb['DeadlineMisses']}")
    for ack in res["acks"]:
        print(f"ack: {ack['AckOpcode']} token {ack['AckToken']} -> {ack['AckResult']} "
              f"(aux {ack['AckAux']}, value {ack['AckValue']:g})")
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            cols = ["t_s", "SeqA", "TorqueRaw", "TorqueFiltered", "Ripple", "MotorVelocity",
                    "Faults", "KfStatus", "valid"]
            w = csv.DictWriter(f, fieldnames=cols, extrasaction="ignore")
            w.writeheader()
            w.writerows(telem)
        print(f"csv = {args.csv}")
    return 0


def _commands(args) -> int:
    try:
        text = Path(args.config).read_text()
        frames = canproto.config_to_commands(text, canproto.load_db(args.node))
    except (OSError, ValueError) as exc:
        print(f"hdsense canlog commands: {args.config}: {exc}", file=sys.stderr)
        return 2
    for frame in frames:
        print(canproto.cansend_str(frame))
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("canlog", help="decode joint CAN logs; config -> CAN commands")
    sub = p.add_subparsers(dest="canlog_command", required=True)
    d = sub.add_parser("decode", help="decode a candump -l log with firmware/hdjoint.dbc")
    d.add_argument("log")
    d.add_argument("--node", type=int, default=1)
    d.add_argument("--csv", help="write the decoded telemetry here")
    d.set_defaults(func=_decode)
    c = sub.add_parser("commands", help="print the CAN commands (cansend ID#DATA) for a config file")
    c.add_argument("config")
    c.add_argument("--node", type=int, default=1)
    c.set_defaults(func=_commands)
