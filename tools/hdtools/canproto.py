"""The joint's CAN protocol on the host side, from firmware/hdjoint.dbc.

The DBC (generated from firmware/hd_protocol.def by hdtools.protocol)
describes node 1; load_db(node_id) moves every identifier to another node
(identifier = 0x01D00000 | type << 8 | node_id, 29-bit).  Helpers build
command frames (as (frame_id, bytes) pairs or `cansend` strings) and turn a
firmware configuration text file (docs/design/firmware.md, parsed by the firmware's
own parser: hdtools.cfgtext) into the equivalent commands: every key of the
parameter table (firmware/hd_params.def) has one.
"""
from __future__ import annotations

import io
import re
import warnings
from pathlib import Path

import cantools

from . import cfgtext, protocol

ROOT = protocol.ROOT
DBC_PATH = protocol.DBC_PATH

# Identifier of each frame for node 0; add the node id.
BASE_IDS = {f.name: f.can_id(0) for f in protocol.frames()}

FAULT_BITS = [f.name for f in sorted(protocol.faults(), key=lambda f: f.code)]


def load_db(node_id: int = 1, strict: bool = True) -> cantools.database.can.Database:
    """Loads the DBC (raising on any warning) with identifiers for node_id."""
    if not protocol.NODE_MIN <= node_id <= protocol.NODE_MAX:
        raise ValueError(f"node_id must be {protocol.NODE_MIN}..{protocol.NODE_MAX}, got {node_id}")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        db = cantools.database.load_file(str(DBC_PATH), strict=strict)
    if node_id != 1:
        for msg in db.messages:
            msg.frame_id = BASE_IDS[msg.name] + node_id
        db.refresh()
    return db


# TELEM_A's torques at their integer minimum (-327.68 N m) mean "not
# available" (hd_protocol.def, type I); anything above half a count of it is a value.
_TORQUE = next(s for s in protocol.frame_signals("TELEM_A") if s.name == "TorqueRaw")
_TORQUE_NOT_AVAILABLE_ABOVE = (-(1 << (_TORQUE.bits - 1)) + 0.5) * float(_TORQUE.scale)


def torque_valid(telem_a: dict) -> bool:
    """Whether a decoded TELEM_A carries torques (an invalid sample sends
    both as "not available")."""
    return (telem_a["TorqueRaw"] > _TORQUE_NOT_AVAILABLE_ABOVE and
            telem_a["TorqueFiltered"] > _TORQUE_NOT_AVAILABLE_ABOVE)


def faults_str(bits: int) -> str:
    return "|".join(protocol.fault_names(bits)) or "-"


def command(db, opcode: str, token: int = 0, **signals) -> tuple[int, bytes]:
    """One CMD frame: command(db, "SET_PARAM", SetParamId="R_NM2", SetParamValue=0.5)."""
    msg = db.get_message_by_name("CMD")
    data = msg.encode({"Opcode": opcode, "Token": token, **signals}, strict=True)
    return msg.frame_id, bytes(data)


def cansend_str(frame: tuple[int, bytes]) -> str:
    """`cansend` notation: 8 hex digits for a 29-bit identifier."""
    frame_id, data = frame
    width = 8 if frame_id > 0x7FF else 3
    return f"{frame_id:0{width}X}#{data.hex().upper()}"


# ADD_MOTOR / ADD_OUTPUT / ADD_FIXED carry the order (or frequency) as a
# uint16 of hundredths (hd_protocol.def: HD_ARG MotorOrder, UQ 16 bits, 0.01).
ORDER_MIN, ORDER_MAX = 0.01, 0xFFFF / 100.0


def order_representable(order: float) -> bool:
    return 0 < round(order * 100) <= 0xFFFF


def param_value(param: protocol.Param, text: str) -> float:
    """A configuration-text value as the firmware's parser reads it
    (ValueError naming the key, not the line): hdtools.cfgtext."""
    return cfgtext.param_value(param, text)


def config_to_commands(text: str, db=None, token: int = 0) -> list[tuple[int, bytes]]:
    """The CAN commands equivalent to a configuration text file.

    The firmware's own parser reads the text (hdtools.cfgtext: on top of the
    defaults, so its errors, with their line, are the joint's).  Blocks
    become BLOCKS_CLEAR + ADD_* (+ BLOCK_ENABLE 0 for `off` blocks); every
    other key is a row of the parameter table and becomes SET_PARAM with the
    value the firmware parsed.  node_id, if present, is sent last so the
    other commands reach the old id.
    """
    db = db or load_db()
    parsed = cfgtext.parse(text)
    cmds: list[tuple[int, bytes]] = []
    node_cmd = None
    for _line, param, value in parsed.values:
        frame = command(db, "SET_PARAM", token, SetParamId=param.name, SetParamValue=value)
        if param.key == "node_id":
            node_cmd = frame
        else:
            cmds.append(frame)
    if parsed.blocks is not None:
        block_cmds = [command(db, "BLOCKS_CLEAR", token)]
        for index, b in enumerate(parsed.blocks):
            if not order_representable(b.order):
                raise ValueError(f"block {b.kind} {b.order:g}: order not representable on CAN "
                                 f"({ORDER_MIN:g} .. {ORDER_MAX:g})")
            if b.kind == "motor":
                block_cmds.append(command(db, "ADD_MOTOR", token, MotorOrder=b.order, MotorQ=b.q_nm2))
            elif b.kind == "output":
                block_cmds.append(command(db, "ADD_OUTPUT", token, OutputOrder=b.order,
                                          OutputQ=b.q_nm2))
            else:
                block_cmds.append(command(db, "ADD_FIXED", token, FixedFrequency=b.order,
                                          FixedQ=b.q_nm2))
            if not b.enabled:
                block_cmds.append(command(db, "BLOCK_ENABLE", token, BlockIndex=index,
                                          BlockEnable=0))
        cmds = block_cmds + cmds
    if node_cmd is not None:
        cmds.append(node_cmd)
    return cmds


LOG_MAX_BYTES = 1 << 30       # a candump log larger than 1 GiB is refused
_FD_LENGTHS = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64}
_CAN_ERR_FLAG = 0x20000000


_HEX = re.compile(r"[0-9A-Fa-f]*")
# The common good line (a classic data or remote frame, no error flag), matched at once;
# anything else takes candump_line_fault's checks one by one.
_PLAIN_LINE = re.compile(r"\(\d+\.\d+\)\s+\S+\s+(?:[0-7][0-9A-Fa-f]{2}|[01][0-9A-Fa-f]{7})#"
                         r"(?:(?:[0-9A-Fa-f]{2}){0,8}|[Rr][0-8]?)(?:\s+[RTrt])?")


def candump_line_fault(line: str) -> str | None:
    """Why python-can's can.io.CanutilsLogReader would misread one `candump -l` line
    (it raises on some and silently mangles others), or None for a good line.
    Forms: (ts) IF 123#0011 [R|T], 12345678#.. (extended), 123#R / 123#R3
    (remote), 123##1<data> (CAN FD with its flags nibble), an 8-digit id with
    the error flag (error frame), classic 8 bytes with a _D raw DLC suffix.
    Parsing the good lines is can.io's job (read_log_lines)."""
    if _PLAIN_LINE.fullmatch(line):
        return None
    parts = line.split()
    if len(parts) == 4 and parts[3] in ("R", "T", "r", "t"):
        parts = parts[:3]                    # python-can's writer adds the direction
    if len(parts) != 3:
        return f"{len(parts)} fields, expected 3 ((time) interface frame)"
    ts, _iface, frame = parts
    if not (ts.startswith("(") and ts.endswith(")")):
        return "no (time stamp)"
    try:
        t = float(ts[1:-1])
    except ValueError:
        return f"time stamp {ts} is not a number"
    if t != t or t in (float("inf"), float("-inf")):
        return "time stamp not finite"
    can_id, sep, data = frame.partition("#")
    if not sep:
        return "no '#' in the frame"
    if len(can_id) not in (3, 8) or not _HEX.fullmatch(can_id):
        return f"identifier {can_id!r} is not 3 or 8 hex digits"
    ident = int(can_id, 16)
    if len(can_id) == 8 and ident & _CAN_ERR_FLAG:
        ok = not len(data) % 2 and len(data) <= 16 and _HEX.fullmatch(data)
        return None if ok else "error frame data is not 0-8 hex bytes"
    if (len(can_id) == 3 and ident > 0x7FF) or ident > 0x1FFFFFFF:
        return f"identifier {can_id} out of range"
    is_fd = data.startswith("#")
    if is_fd:
        if len(data) < 2 or data[1] not in "0123456789":   # can.io reads it as decimal
            return "CAN FD frame without its flags digit"
        data = data[2:]
    elif data[:1] in ("R", "r"):
        rest = data[1:]
        if rest and not (len(rest) == 1 and rest.isdigit() and int(rest) <= 8):
            return f"remote frame length {rest!r}"
        return None
    elif "_" in data:
        data, _, raw_dlc = data.partition("_")
        if len(data) != 16 or len(raw_dlc) != 1 or raw_dlc not in "9ABCDEFabcdef":
            return "bad raw DLC suffix"
    if len(data) % 2:
        return f"odd number of hex digits in the data ({len(data)}): cut short?"
    if not _HEX.fullmatch(data):
        return "data is not hex"
    n = len(data) // 2
    if (is_fd and n not in _FD_LENGTHS) or (not is_fd and n > 8):
        return f"{n} data bytes is not a valid {'CAN FD' if is_fd else 'CAN'} length"
    return None


class _CheckedLines:
    """The good lines of a candump log for can.io.CanutilsLogReader (a file-like
    object to it); the others go to `malformed`.  `numbers` and `error_frames`
    keep, per line handed on, its line number and, for an error frame, its
    identifier and data: python-can keeps neither the class bits nor the data."""

    def __init__(self, fh, malformed: list | None):
        self.fh, self.malformed = fh, malformed
        self.numbers: list[int] = []
        self.error_frames: dict[int, tuple[int, bytes]] = {}

    def _bad(self, lineno: int, reason: str) -> None:
        if self.malformed is not None:
            self.malformed.append((lineno, reason))

    def __iter__(self):
        for lineno, raw in enumerate(self.fh, start=1):
            try:
                line = raw.decode("ascii").strip()
            except UnicodeDecodeError:
                self._bad(lineno, "not ASCII text")
                continue
            if not line or line.startswith("#"):
                continue
            reason = candump_line_fault(line)
            if reason is not None:
                self._bad(lineno, reason)
                continue
            parts = line.split()
            ident, _, data = parts[2].partition("#")
            if "_" in data:           # classic 8 bytes with a raw DLC: can.io reads the bytes
                parts[2] = parts[2].partition("_")[0]
                line = " ".join(parts)
            if len(ident) == 8 and int(ident, 16) & _CAN_ERR_FLAG:
                self.error_frames[len(self.numbers)] = (int(ident, 16) & 0x1FFFFFFF,
                                                        bytes.fromhex(data))
            self.numbers.append(lineno)
            yield line

    def read(self, *_):   # can.io takes an object with read and write as a file
        raise io.UnsupportedOperation("iterate instead")

    write = read

    def close(self) -> None:
        pass


def read_log_lines(path: str | Path, malformed: list | None = None) -> list:
    """(line number, can.Message) for every frame of a candump -l log.

    Blank lines and '#' comments are ignored; a malformed line (cut short,
    bad hex, wrong length, not text) is skipped and, if `malformed` is a
    list, appended to it as (line number, reason).  A file that is not a
    regular file or is over LOG_MAX_BYTES raises safeio.UsageError."""
    from hdtools import safeio
    import os
    import stat
    try:
        st = os.stat(path)
    except OSError as exc:
        raise safeio.UsageError(f"{path}: cannot read: {exc.strerror}") from None
    if stat.S_ISDIR(st.st_mode):
        raise safeio.UsageError(f"{path}: is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise safeio.UsageError(f"{path}: not a regular file (FIFO, device or socket)")
    if st.st_size > LOG_MAX_BYTES:
        raise safeio.UsageError(f"{path}: {st.st_size} bytes, more than the limit of "
                                f"{LOG_MAX_BYTES}")
    import can
    out = []
    try:
        with open(path, "rb") as f:
            lines = _CheckedLines(f, malformed)
            for i, msg in enumerate(can.io.CanutilsLogReader(lines)):
                if i in lines.error_frames:
                    ident, data = lines.error_frames[i]
                    msg = can.Message(timestamp=msg.timestamp, is_error_frame=True,
                                      arbitration_id=ident, is_extended_id=True, data=data,
                                      channel=msg.channel)
                out.append((lines.numbers[i], msg))
    except OSError as exc:
        raise safeio.UsageError(f"{path}: cannot read: {exc.strerror}") from None
    return out


def read_log(path: str | Path, malformed: list | None = None):
    """Frames of a candump -l log (can.Message), malformed lines skipped
    (and listed in `malformed` if given): see read_log_lines."""
    return [msg for _, msg in read_log_lines(path, malformed)]


def nodes_in(frames) -> dict[int, int]:
    """Frames per node id (protocol.NODE_MIN..NODE_MAX) among the joint's identifiers (29-bit
    data frames only: remote, FD, 11-bit and error frames are not ours)."""
    counts: dict[int, int] = {}
    for _, msg in frames:
        if not msg.is_extended_id or msg.is_error_frame or msg.is_remote_frame or msg.is_fd:
            continue
        for base in BASE_IDS.values():
            node = msg.arbitration_id - base
            if protocol.NODE_MIN <= node <= protocol.NODE_MAX:
                counts[node] = counts.get(node, 0) + 1
                break
    return counts


def decode_log(path: str | Path, node_id: int | None = 1, rate_hz: float | None = None) -> dict:
    """Decodes a candump log: telemetry rows (paired A/B by sequence, with
    the TELEM_C counts of the same sequence when sent), acks, heartbeats,
    boots, commands and sequence gaps.

    Telemetry rows are placed in device time (hdtools.telemetry.place):
    "t_s" is seconds from the first row, sequence x period; "t_host_s" is
    the candump time stamp, "segment" counts BOOT frames before the row.
    The period comes from rate_hz, else the log's telemetry_rate_hz answers,
    else the host stamps ("period_s", "period_source").  Other frames' "t_s"
    is the host's.  "params" holds the last value answered (GET_PARAM or
    SET_PARAM, OK) for each parameter key.

    node_id None: the node is found in the log (exactly one node must be
    present, else safeio.UsageError names those found).  Malformed lines and
    frames that do not decode (wrong length for their message...) are
    skipped and listed: "malformed" and "bad_frames" as (line, reason)."""
    from hdtools import safeio, telemetry
    malformed: list = []
    frames = read_log_lines(path, malformed)
    nodes = nodes_in(frames)
    if node_id is None:
        if len(nodes) != 1:
            found = ", ".join(f"{n} ({c} frames)" for n, c in sorted(nodes.items()))
            raise safeio.UsageError(
                f"{path}: frames of nodes {found}: choose one with --node" if nodes else
                f"{path}: no frames of any joint node ({len(frames)} frames, "
                f"{len(malformed)} malformed lines)")
        node_id = next(iter(nodes))
    db = load_db(node_id)
    ids = {name: BASE_IDS[name] + node_id for name in BASE_IDS}
    telem, acks, heartbeats, commands, bad_frames, boots = [], [], [], [], [], []
    feedforward: list = []
    params: dict[str, float] = {}
    rate, rate_kind = None, None
    pending_a = None
    for lineno, msg in frames:
        if msg.is_error_frame or msg.is_remote_frame or not msg.is_extended_id or msg.is_fd:
            continue
        data = bytes(msg.data)
        ident = msg.arbitration_id
        if ident not in ids.values():
            continue
        try:
            decoded = db.decode_message(ident, data, decode_choices=(ident != ids["TELEM_A"] and
                                                                     ident != ids["TELEM_B"]))
        except Exception as exc:  # noqa: BLE001 - cantools raises several kinds
            bad_frames.append((lineno, f"{ident:08X}: {str(exc).splitlines()[0]}"))
            if ident == ids["CMD"]:  # malformed command: keep it visible
                commands.append({"t_s": msg.timestamp, "error": str(exc), "data": data.hex()})
            continue
        if ident == ids["TELEM_A"]:
            pending_a = (msg.timestamp, decoded)
        elif ident == ids["TELEM_B"]:
            if pending_a is not None and pending_a[1]["SeqA"] == decoded["SeqB"]:
                row = {"t_host_s": pending_a[0], **pending_a[1], **decoded,
                       "segment": len(boots), "rate_hz": rate, "rate_kind": rate_kind}
                row["valid"] = torque_valid(row)
                telem.append(row)
            pending_a = None
        elif ident == ids["TELEM_C"]:
            if telem and telem[-1]["SeqA"] == decoded["SeqC"] and "MotorCounts" not in telem[-1]:
                telem[-1].update(decoded)
        elif ident == ids["BOOT"]:
            boots.append({"t_s": msg.timestamp, **decoded})
        elif ident == ids["ACK"]:
            acks.append({"t_s": msg.timestamp, **decoded})
            op, res = str(decoded["AckOpcode"]), str(decoded["AckResult"])
            if op in ("GET_PARAM", "SET_PARAM") and res == "OK":
                try:
                    key = protocol.param_by_id(int(decoded["AckAux"])).key
                except KeyError:
                    continue
                params[key] = float(decoded["AckValue"])
                if key == "telemetry_rate_hz" and decoded["AckValue"] > 0:
                    rate, rate_kind = float(decoded["AckValue"]), op[:3]
        elif ident == ids["HEARTBEAT"]:
            heartbeats.append({"t_s": msg.timestamp, **decoded})
        elif ident == ids["CMD"]:
            commands.append({"t_s": msg.timestamp, **decoded})
        elif ident == ids["FEEDFORWARD"]:
            feedforward.append({"t_s": msg.timestamp, **decoded})
    try:
        timing = telemetry.place(telem, rate_hz)
    except ValueError as exc:
        raise safeio.UsageError(f"{path}: {exc}") from None
    return {"telemetry": telem, "acks": acks, "heartbeats": heartbeats, "boots": boots,
            "commands": commands, "feedforward": feedforward,
            "lost_telemetry": timing["lost"], "node": node_id,
            "nodes": nodes, "frames": len(frames), "malformed": malformed,
            "bad_frames": bad_frames, "params": params, "period_s": timing["period_s"],
            "period_source": timing["period_source"]}
