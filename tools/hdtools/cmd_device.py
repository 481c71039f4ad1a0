"""`hdsense send` and `hdsense device`: put a model into a joint over CAN
and keep it there; ask and set single things.

  hdsense send can0 out/model.cfg              # apply, CONFIG_SAVE, read back
  hdsense send can0 out/model.can --reboot     # ... then REBOOT, read back again
  hdsense device can0 version | info | params | get KEY | set KEY VALUE
  hdsense device can0 save | load | defaults | reboot
  hdsense device can0 profile save | load | clear | put PROFILE.json [--save]

send: FILE is a model.cfg (the configuration text `hdsense analyze`
writes; docs/design/firmware.md) or a model.can (cansend lines ID#DATA, comments
and everything after the first blank line ignored).  The joint's parameter
table must be this tool's (VERSION PARAM_TABLE_CRC).  The commands go one
at a time; each waits for its ACK (matched by opcode and token) within
--timeout.  A refusal is printed as one line and nothing is saved.  Then
CONFIG_SAVE (unless --no-save), then every parameter the file sets is read
back with GET_PARAM and compared as float32 (and the number of filter
blocks with block_count).  --reboot: REBOOT, wait for the BOOT frame, read
back again.

Exit status: 0 applied, saved and every value read back equal; 1 a command
was refused or a value read back differs; 2 bad command line or FILE;
5 the CAN interface cannot be used or the joint did not answer.
"""
from __future__ import annotations

import argparse
import re
import sys
import time

import cantools

from . import canproto, protocol, safeio
from .canshared import add_bus_arguments, boot_report, fmt_item as _fmt_item, node_id as _node
from .joint import BOOT_TIMEOUT_S, Joint, NoAnswer, open_bus
from .protocol import f32, name_of
from .safeio import HdError, UsageError

MODEL_OPCODES = ("FILTER_ENABLE", "ADD_MOTOR", "ADD_OUTPUT", "ADD_FIXED", "BLOCK_ENABLE",
                 "BLOCKS_CLEAR", "SET_PARAM")
BUSY_RETRY_S = 1.0
_CANSEND = re.compile(r"^([0-9A-Fa-f]{3}|[0-9A-Fa-f]{8})#([0-9A-Fa-f]{0,16})$")


class Refused(HdError):
    code = 1


# ------------------------------------------------------------------ file
def _is_can_text(text: str) -> bool:
    lines = [l.strip() for l in text.split("\n\n", 1)[0].splitlines()]
    lines = [l for l in lines if l and not l.startswith("#")]
    return bool(lines) and all(_CANSEND.match(l) for l in lines)


def read_model(path: str, node: int | None) -> tuple[int, list[bytes]]:
    """(node, CMD payloads) of a model.cfg or model.can (UsageError naming
    the line otherwise)."""
    text = safeio.read_text(path)
    if not _is_can_text(text):
        node = node or 1
        try:
            frames = canproto.config_to_commands(text, canproto.load_db(node))
        except (ValueError, KeyError, IndexError, cantools.database.errors.Error) as exc:
            raise UsageError(f"{path}: {exc}") from None
        return node, [data for _, data in frames]
    cmd_base = canproto.BASE_IDS["CMD"]
    payloads, file_node = [], None
    opcodes = {e.code: e.name for e in protocol.opcodes()}
    for lineno, raw in enumerate(text.split("\n\n", 1)[0].splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        m = _CANSEND.match(line)
        ident, data = int(m.group(1), 16), bytes.fromhex(m.group(2))
        n = ident - cmd_base
        if len(m.group(1)) != 8 or not protocol.NODE_MIN <= n <= protocol.NODE_MAX:
            raise UsageError(f"{path}:{lineno}: {m.group(1)} is not a joint's CMD identifier")
        if file_node is not None and n != file_node:
            raise UsageError(f"{path}:{lineno}: node {n}, earlier lines address node {file_node}")
        file_node = n
        if len(data) != 8:
            raise UsageError(f"{path}:{lineno}: {len(data)} data bytes, a command has 8")
        if opcodes.get(data[0]) not in MODEL_OPCODES:
            raise UsageError(f"{path}:{lineno}: opcode 0x{data[0]:02X} "
                             f"({opcodes.get(data[0], 'unknown')}) is not part of a model")
        payloads.append(data)
    if node is not None and node != file_node:
        raise UsageError(f"{path}: the file addresses node {file_node}, --node says {node}")
    return file_node, payloads


def describe(db, data: bytes) -> str:
    d = db.get_message_by_name("CMD").decode(data, decode_choices=True)
    op = str(d["Opcode"])
    if op == "SET_PARAM":
        raw = db.get_message_by_name("CMD").decode(data, decode_choices=False)
        p = protocol.param_by_id(raw["SetParamId"])
        return f"SET_PARAM {p.key} = {d['SetParamValue']:.9g}"
    args = ", ".join(f"{k} {v:.9g}" if isinstance(v, float) else f"{k} {v}"
                     for k, v in d.items() if k not in ("Opcode", "Token"))
    return f"{op} {args}".strip()


def expectations(payloads: list[bytes], db=None) -> tuple[dict[int, float], list | None]:
    """What reading back must show: {param id: float32 value} of the
    SET_PARAMs (and FILTER_ENABLE), and, when the model clears the blocks
    first, each block as [lock, order, q_nm2, enabled] in BLOCK_GET's field
    order (None otherwise).  The frames are read through the DBC; an order
    is its raw count divided as the firmware divides it (float32)."""
    msg = (db or canproto.load_db()).get_message_by_name("CMD")
    want: dict[int, float] = {}
    blocks = None
    adds = {"ADD_MOTOR": (0, "MotorOrder", "MotorQ"), "ADD_OUTPUT": (1, "OutputOrder", "OutputQ"),
            "ADD_FIXED": (2, "FixedFrequency", "FixedQ")}
    for data in payloads:
        d = msg.decode(data, decode_choices=False, scaling=False)
        op = name_of(protocol.opcodes(), d["Opcode"])
        if op == "SET_PARAM":
            want[d["SetParamId"]] = f32(d["SetParamValue"])
        elif op == "FILTER_ENABLE":
            want[protocol.param_by_key("filter").id] = float(d["FilterEnable"])
        elif op == "BLOCKS_CLEAR":
            blocks = []
        elif op in adds and blocks is not None:
            lock, order, q = adds[op]
            arg = next(a for a in protocol.command_args(op) if a.name == order)
            divisor = f32(round(1 / float(arg.scale)))
            blocks.append([float(lock), f32(f32(d[order]) / divisor), f32(d[q]), 1.0])
        elif op == "BLOCK_ENABLE" and blocks is not None and d["BlockIndex"] < len(blocks):
            blocks[d["BlockIndex"]][3] = float(d["BlockEnable"])
    return want, blocks


# ---------------------------------------------------------------- joint
def check_table(joint: Joint) -> None:
    ack = joint.item("PARAM_TABLE_CRC")
    if not ack.ok:
        raise Refused(f"node {joint.node}: VERSION PARAM_TABLE_CRC refused ({ack.result})")
    mine = protocol.param_table_crc()
    if int(ack.value) != mine:
        raise Refused(f"node {joint.node}: its parameter table (CRC 0x{int(ack.value):08X}) is "
                      f"not this tool's (0x{mine:08X}): firmware and hdsense versions differ")


def command_retry_busy(joint: Joint, opcode: str, **signals):
    return send_retry_busy(joint, canproto.command(joint.db, opcode, 0, **signals)[1])


def send_retry_busy(joint: Joint, data: bytes):
    """One command, sent again while the joint answers BUSY (its background
    is still writing NVM), for at most BUSY_RETRY_S."""
    deadline = time.monotonic() + BUSY_RETRY_S
    while True:
        ack = joint.send_raw(data)
        if ack.result != "BUSY" or time.monotonic() > deadline:
            return ack
        time.sleep(0.02)


def reboot(joint: Joint) -> str:
    """REBOOT, then the joint's BOOT frame as one line."""
    joint.drain()
    ack = joint.command("REBOOT")
    if not ack.ok:
        raise Refused(f"node {joint.node}: REBOOT refused ({ack.result})")
    boot = joint.wait_boot()
    if boot is None:
        raise NoAnswer(f"node {joint.node}: no BOOT frame within {BOOT_TIMEOUT_S:g} s of REBOOT")
    return boot_report(boot)


def read_back(joint: Joint, want: dict[int, float], blocks: int | None, say) -> int:
    """Compares the joint's values with want; returns the number that differ."""
    bad = 0
    for pid, value in want.items():
        p = protocol.param_by_id(pid)
        ack = joint.get(p)
        if not ack.ok:
            say(f"read back {p.key}: GET_PARAM refused ({ack.result})")
            bad += 1
            continue
        same = f32(ack.value) == f32(value)
        bad += not same
        say(f"read back {p.key} = {ack.value:.9g}" +
            ("" if same else f"  DIFFERS from the file's {value:.9g}"))
    if blocks is not None:
        ack = joint.get(protocol.param_by_key("block_count"))
        same = ack.ok and int(ack.value) == len(blocks)
        bad += not same
        say(f"read back block_count = {ack.value:g}" +
            ("" if same else f"  DIFFERS from the file's {len(blocks)} blocks"))
        for i, fields in enumerate(blocks if same else []):
            got = [joint.block_field(i, k) for k in range(len(protocol.BLOCK_FIELDS))]
            ok = all(g is not None and f32(g) == f32(w) for g, w in zip(got, fields))
            bad += not ok
            shown = ", ".join(f"{n.lower()} {g:.9g}" if g is not None else f"{n.lower()} ?"
                              for n, g in zip(protocol.BLOCK_FIELDS, got))
            say(f"read back block {i}: {shown}" + ("" if ok else "  DIFFERS from the file"))
    return bad


def send(args) -> int:
    node, payloads = read_model(args.file, args.node)
    if not payloads:
        raise UsageError(f"{args.file}: no commands in the file")
    want, blocks = expectations(payloads)

    def say(line: str) -> None:
        print(line, flush=True)

    bus = open_bus(args.interface, args.channel, args.bitrate)
    try:
        joint = Joint(bus, node, timeout_s=args.timeout)
        check_table(joint)
        refused = 0
        db = joint.db
        for data in payloads:
            what = describe(db, data)
            ack = joint.send_raw(data)
            if not ack.ok:
                refused += 1
                say(f"refused: {what}: {ack.result}")
        say(f"applied = {len(payloads) - refused} of {len(payloads)} commands to node "
            f"{joint.node}")
        if refused:
            raise Refused(f"node {joint.node}: {refused} command(s) refused; nothing saved")
        if args.no_save:
            say("saved = no (--no-save)")
        else:
            ack = command_retry_busy(joint, "CONFIG_SAVE")
            if not ack.ok:
                raise Refused(f"node {joint.node}: CONFIG_SAVE refused ({ack.result})")
            say("saved = yes (CONFIG_SAVE)")
        bad = read_back(joint, want, blocks, say)
        if args.reboot:
            say("boot = " + reboot(joint))
            time.sleep(0.05)
            bad += read_back(joint, want, blocks, say)
        total = len(want) + (0 if blocks is None else 1 + len(blocks))
        say(f"verified = {total * (2 if args.reboot else 1) - bad} of "
            f"{total * (2 if args.reboot else 1)} read-backs equal")
        if bad:
            raise Refused(f"node {joint.node}: {bad} value(s) read back differ from {args.file}")
    finally:
        bus.shutdown()
    return 0


# --------------------------------------------------------------- device
def _param_value(p: protocol.Param, text: str) -> float:
    try:
        return canproto.param_value(p, text)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def device(args) -> int:
    if args.action == "profile" and args.profile_action == "put":
        from .cmd_profile import load_profile
        args.profile_lines = load_profile(args.file)
    # a bad key or value is a usage error (exit 2) before any bus is opened
    if args.action in ("get", "set"):
        p = _param(args.key)
        if args.action == "set":
            if p.read_only:
                raise UsageError(f"{p.key} is read only")
            args.set_value = _param_value(p, args.value)
    bus = open_bus(args.interface, args.channel, args.bitrate)
    try:
        joint = Joint(bus, args.node, timeout_s=args.timeout)
        action = args.action
        lines = []
        if action in ("version", "info"):
            for e in protocol.info_items():
                if (e.code < 16) != (action == "version"):
                    continue
                ack = joint.item(e.name)
                lines.append(f"{e.name.lower()} = " +
                             (_fmt_item(e.name, int(ack.value)) if ack.ok else ack.result))
            if action == "version":
                lines.append(f"host_param_table_crc = 0x{protocol.param_table_crc():08X}")
        elif action in ("get", "params"):
            keys = [p.key for p in protocol.params()] if action == "params" else [args.key]
            for key in keys:
                p = _param(key)
                ack = joint.get(p)
                lines.append(f"{p.key} = {ack.value:.9g}" if ack.ok else f"{p.key}: {ack.result}")
        elif action == "set":
            p = _param(args.key)
            ack = joint.set(p, args.set_value)
            lines.append(f"{p.key} = {ack.value:.9g}")
            if not ack.ok:
                print("\n".join(lines))
                raise Refused(f"node {args.node}: SET_PARAM {p.key} refused ({ack.result})")
        elif action in ("save", "load", "defaults"):
            op = {"save": "CONFIG_SAVE", "load": "CONFIG_LOAD", "defaults": "CONFIG_DEFAULTS"}
            ack = command_retry_busy(joint, op[action])
            status = name_of(protocol.record_statuses(), ack.aux)
            if not ack.ok:
                raise Refused(f"node {args.node}: {op[action]} refused ({ack.result}, record "
                              f"{status})")
            lines.append(f"{op[action].lower()} = OK" + (f" (record {status})"
                                                         if action != "defaults" else ""))
        elif action == "reboot":
            lines.append("boot = " + reboot(joint))
        elif action == "profile":
            lines += profile_action(joint, args)
        print("\n".join(lines))
    finally:
        bus.shutdown()
    return 0


PROFILE_ACTIONS = {"save": ("PROFILE_SAVE", {"ProfileSaveSource": 0}),
                   "load": ("PROFILE_LOAD", {"ProfileLoadSource": 0}),
                   "clear": ("PROFILE_CLEAR", {})}


def profile_action(joint: Joint, args) -> list[str]:
    """save: the running filter's profile to NVM (at the next tick); load:
    the stored one into the filter; clear: remove the stored one; put
    FILE.json: upload a profile.json (gear ratio checked against the
    joint's), load it into the filter and, with --save, store it."""
    if args.profile_action == "put":
        from . import profile_record as pr
        lines, gear = args.profile_lines      # read before the bus was opened
        ack = joint.get(protocol.param_by_key("gear_ratio"))
        if not ack.ok:
            raise Refused(f"node {joint.node}: GET_PARAM gear_ratio refused ({ack.result})")
        pr.check_gear(gear, ack.value, args.file)
        frames = [data for _, data in pr.commands(lines, joint.node, args.save)]
    else:
        op, signals = PROFILE_ACTIONS[args.profile_action]
        frames = [canproto.command(joint.db, op, 0, **signals)[1]]
    out = []
    for data in frames:
        op = name_of(protocol.opcodes(), data[0])
        ack = send_retry_busy(joint, data)
        if not ack.ok:
            raise Refused(f"node {joint.node}: {op} refused ({ack.result}, record "
                          f"{name_of(protocol.record_statuses(), ack.aux)})")
        if op != "PROFILE_PUT":
            out.append(f"{op.lower()} = OK (record "
                       f"{name_of(protocol.record_statuses(), ack.aux)}, {int(ack.value)} lines)")
    return out


def _param(key: str) -> protocol.Param:
    try:
        return protocol.param_by_key(key)
    except KeyError:
        raise UsageError(f"unknown parameter {key!r} (hdsense device IFACE params lists them)") \
            from None


def _timeout(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.01 <= v <= 60:
        raise argparse.ArgumentTypeError("--timeout must be 0.01..60 s")
    return v


def register(subparsers) -> None:
    from .cli import version
    s = subparsers.add_parser("send", help="apply a model.cfg / model.can, save, read back",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("--version", action="version", version=f"hdsense send {version()}")
    add_bus_arguments(s)
    s.add_argument("file", metavar="FILE", help="model.cfg or model.can")
    s.add_argument("--node", type=_node, default=None,
                   help="node id (default: model.can's, or 1 for model.cfg)")
    s.add_argument("--no-save", action="store_true", help="apply and read back, no CONFIG_SAVE")
    s.add_argument("--reboot", action="store_true",
                   help="then REBOOT, wait for the BOOT frame and read back again")
    s.add_argument("--timeout", type=_timeout, default=0.5, metavar="S",
                   help="wait this long for each answer (default 0.5 s)")
    s.set_defaults(func=send)

    d = subparsers.add_parser("device", help="ask or set one thing on a joint over CAN",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    d.add_argument("--version", action="version", version=f"hdsense device {version()}")
    add_bus_arguments(d)
    d.add_argument("--node", type=_node, default=1, help="node id (default 1)")
    d.add_argument("--timeout", type=_timeout, default=0.5, metavar="S",
                   help="wait this long for each answer (default 0.5 s)")
    acts = d.add_subparsers(dest="action", required=True, metavar="ACTION")
    for name, help_ in (("version", "firmware, protocol, record versions, board"),
                        ("info", "boot record and counters"),
                        ("params", "every parameter's value"),
                        ("save", "CONFIG_SAVE: the running configuration to NVM"),
                        ("load", "CONFIG_LOAD: the saved configuration into RAM"),
                        ("defaults", "CONFIG_DEFAULTS: the defaults into RAM (not saved)"),
                        ("reboot", "REBOOT and show the BOOT frame")):
        acts.add_parser(name, help=help_)
    pf = acts.add_parser("profile", help="the artifact profile: save, load, clear, put FILE")
    pa = pf.add_subparsers(dest="profile_action", required=True, metavar="PROFILE_ACTION")
    for name, help_ in (("save", "PROFILE_SAVE: the running filter's profile to NVM"),
                        ("load", "PROFILE_LOAD: the stored profile into the filter"),
                        ("clear", "PROFILE_CLEAR: remove the stored profile")):
        pa.add_parser(name, help=help_)
    pp = pa.add_parser("put", help="upload a profile.json (hdsense analyze) and load it")
    pp.add_argument("file", metavar="PROFILE.json")
    pp.add_argument("--save", action="store_true", help="also store it (PROFILE_SAVE)")
    g = acts.add_parser("get", help="one parameter")
    g.add_argument("key")
    st = acts.add_parser("set", help="one parameter (not saved: use save)")
    st.add_argument("key")
    st.add_argument("value")
    d.set_defaults(func=device)
