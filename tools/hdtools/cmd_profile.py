"""`hdsense profile`: the artifact profile between profile.json (from
`hdsense analyze`), the firmware's record file and CAN commands.

  hdsense profile record PROFILE.json -o JOINT.hdprofile
                         (--config FW.cfg | --gear-ratio N --motor-cpr C --output-cpr C)
  hdsense profile commands PROFILE.json [--node-id 1] [--save] [--gear-ratio N]
  hdsense profile json JOINT.hdprofile [-o PROFILE.json]

record: the record file hdjoint-host --profile stores in NVM (the same
payload the firmware saves with PROFILE_SAVE); it names the joint (gear
ratio, encoder resolutions) and the firmware refuses it on another one.
commands: PROFILE_PUT for every line, PROFILE_LOAD of the uploaded lines
(the running filter takes them at the next tick) and, with --save,
PROFILE_SAVE, as `cansend` lines (hdjoint-host --cmd takes them too).
json: a record file back to profile.json.  A profile.json made for another
gear ratio (more than 0.5 % off) is refused.  docs/design/slow-torque.md.
Exit status: 0 done, 2 bad command line or input, 3 an output could not be
written (an old one is left as it was).
"""
from __future__ import annotations

import json
import math
import sys

from . import canproto, protocol
from . import profile_record as pr
from .safeio import Outputs, UsageError, read_bytes, read_text


def register(sub) -> None:
    p = sub.add_parser("profile", help="profile.json <-> the firmware's profile record and "
                       "CAN commands", description=__doc__.split("\n\n")[0])
    s = p.add_subparsers(dest="profile_command", required=True)
    r = s.add_parser("record", help="profile.json -> record file for hdjoint-host --profile")
    r.add_argument("profile", help="profile.json")
    r.add_argument("-o", "--out", required=True, help="record file to write")
    _joint_args(r)
    r.set_defaults(func=_record)
    c = s.add_parser("commands", help="profile.json -> CAN commands (cansend lines)")
    c.add_argument("profile", help="profile.json")
    c.add_argument("--node-id", type=int, default=1, help="CAN node id (default 1)")
    c.add_argument("--save", action="store_true", help="end with PROFILE_SAVE")
    c.add_argument("--gear-ratio", type=float, help="the joint's, checked against the profile's")
    c.add_argument("-o", "--out", help="write the lines here instead of stdout")
    c.set_defaults(func=_commands)
    j = s.add_parser("json", help="record file -> profile.json")
    j.add_argument("record", help="record file")
    j.add_argument("-o", "--out", help="profile.json to write (default stdout)")
    j.set_defaults(func=_json)


def _joint_args(p) -> None:
    p.add_argument("--config", help="firmware configuration text with gear_ratio, motor_cpr "
                   "and output_cpr")
    p.add_argument("--gear-ratio", type=float)
    p.add_argument("--motor-cpr", type=int)
    p.add_argument("--output-cpr", type=int)


def _joint(args) -> tuple[float, int, int]:
    found = {}
    if args.config:
        found = pr.read_config_joint(read_text(args.config, 1 << 20), args.config)
    given = {"gear_ratio": args.gear_ratio, "motor_cpr": args.motor_cpr,
             "output_cpr": args.output_cpr}
    for key, value in given.items():
        if value is not None:
            found[key] = value
    missing = [k for k in given if k not in found]
    if missing:
        where = f"{args.config} has no " if args.config else "give "
        raise UsageError(where + ", ".join("--" + k.replace("_", "-") for k in missing) +
                         " (the record names the joint it is for)")
    for key in ("motor_cpr", "output_cpr"):
        if found[key] != int(found[key]):
            raise UsageError(f"{key} = {found[key]:g} is not whole")
    pr.check_joint(found["gear_ratio"], int(found["motor_cpr"]), int(found["output_cpr"]))
    return float(found["gear_ratio"]), int(found["motor_cpr"]), int(found["output_cpr"])


def load_profile(path: str) -> tuple[list, float]:
    """(lines, gear ratio) of a profile.json file (UsageError naming the
    file otherwise); hdsense device profile put and hdsense current read it
    here too."""
    text = read_text(path, 1 << 20).removeprefix("\ufeff")     # a BOM is not content
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UsageError(f"{path}:{exc.lineno}: not JSON: {exc.msg}") from None
    return pr.lines_from_json(doc, path)


def _record(args) -> int:
    lines, gear = load_profile(args.profile)
    doc = json.loads(read_text(args.profile, 1 << 20).removeprefix("\ufeff"))
    joint_gear, mcpr, ocpr = _joint(args)
    pr.check_gear(gear, joint_gear, args.profile)
    data = pr.file_bytes(pr.Record(joint_gear, mcpr, ocpr, lines,
                                   pr.load_from_json(doc, args.profile)))
    with Outputs() as out:
        out.write_bytes(args.out, data)
        out.commit()
    print(f"{args.out}: {len(lines)} lines for gear ratio {joint_gear:g}, motor {mcpr} and "
          f"output {ocpr} counts/rev", file=sys.stderr)
    return 0


def _commands(args) -> int:
    if not protocol.NODE_MIN <= args.node_id <= protocol.NODE_MAX:
        raise UsageError(f"--node-id must be {protocol.NODE_MIN}..{protocol.NODE_MAX} "
                         f"(got {args.node_id})")
    lines, gear = load_profile(args.profile)
    if args.gear_ratio is not None:
        if not (math.isfinite(args.gear_ratio) and args.gear_ratio >= 1):
            raise UsageError("--gear-ratio must be a finite number >= 1")
        pr.check_gear(gear, args.gear_ratio, args.profile)
    _emit("".join(canproto.cansend_str(f) + "\n"
                  for f in pr.commands(lines, args.node_id, args.save)), args.out)
    return 0


def _emit(text: str, path: str | None) -> None:
    """text into path (whole, or not at all), or to stdout."""
    if path:
        with Outputs() as out:
            out.write_text(path, text)
            out.commit()
    else:
        sys.stdout.write(text)


def _json(args) -> int:
    rec = pr.parse_file(read_bytes(args.record, 1 << 16), args.record)
    _emit(json.dumps(pr.to_json(rec, args.record), indent=1) + "\n", args.out)
    return 0
