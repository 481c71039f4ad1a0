"""The joint's CAN protocol on the host side, from firmware/hdjoint.dbc.

The DBC describes node 1; load_db(node_id) shifts every identifier to
another node (identifier = base + node_id).  Helpers build command frames
(as (frame_id, bytes) pairs or `cansend` strings) and turn a firmware
configuration text file (docs/firmware.md) into the equivalent commands.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import cantools

ROOT = Path(__file__).resolve().parents[2]
DBC_PATH = ROOT / "firmware" / "hdjoint.dbc"

BASE_IDS = {"TELEM_A": 0x100, "TELEM_B": 0x180, "ACK": 0x580, "CMD": 0x600, "HEARTBEAT": 0x700}

FAULT_BITS = ["ADC_ERROR", "ADC_SATURATED", "OPEN_BRIDGE", "TORQUE_RANGE", "ENC_GLITCH",
              "ENC_FAULT", "KF_FROZEN", "KF_RESET", "CAN_TX_FULL", "CAN_BUS_OFF",
              "CALIB_MISSING", "CALIB_CORRUPT", "DEADLINE_MISS", "CMD_ERROR", "CALIB_ONE_COPY"]

# SET_PARAM ids of the configuration keys that have one (docs/firmware.md).
PARAM_OF_KEY = {"r_nm2": "R_NM2", "gear_ratio": "GEAR_RATIO", "inertia_kgm2": "INERTIA_KGM2",
                "viscous_nm_s_rad": "VISCOUS_NM_S_RAD", "coulomb_nm": "COULOMB_NM",
                "offset": "OFFSET_ENABLED", "offset_q_nm2": "OFFSET_Q_NM2", "p0_nm2": "P0_NM2",
                "track_bandwidth_hz": "TRACK_BANDWIDTH_HZ",
                "telemetry_rate_hz": "TELEMETRY_RATE_HZ", "node_id": "NODE_ID"}
NOT_ON_CAN = {"p_max_nm2", "nyquist_fraction", "offset_is_sensor_error", "coulomb_vel_eps_rad_s",
              "motor_cpr", "output_cpr", "adc_volts_per_count", "torque_limit_nm",
              "max_motor_speed_rad_s"}


def load_db(node_id: int = 1, strict: bool = True) -> cantools.database.can.Database:
    """Loads the DBC (raising on any warning) with identifiers for node_id."""
    if not 1 <= node_id <= 127:
        raise ValueError(f"node_id must be 1..127, got {node_id}")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        db = cantools.database.load_file(str(DBC_PATH), strict=strict)
    if node_id != 1:
        for msg in db.messages:
            msg.frame_id = BASE_IDS[msg.name] + node_id
        db.refresh()
    return db


def faults_str(bits: int) -> str:
    names = [name for i, name in enumerate(FAULT_BITS) if bits & (1 << i)]
    return "|".join(names) if names else "-"


def command(db, opcode: str, token: int = 0, **signals) -> tuple[int, bytes]:
    """One CMD frame: command(db, "SET_PARAM", SetParamId="R_NM2", SetParamValue=0.5)."""
    msg = db.get_message_by_name("CMD")
    data = msg.encode({"Opcode": opcode, "Token": token, **signals}, strict=True)
    return msg.frame_id, bytes(data)


def cansend_str(frame: tuple[int, bytes]) -> str:
    frame_id, data = frame
    return f"{frame_id:03X}#{data.hex().upper()}"


def _on_off(value: str, line: int) -> int:
    if value in ("on", "1", "yes"):
        return 1
    if value in ("off", "0", "no"):
        return 0
    raise ValueError(f"line {line}: expected on or off, got {value!r}")


def config_to_commands(text: str, db=None, token: int = 0) -> list[tuple[int, bytes]]:
    """The CAN commands equivalent to a configuration text file.

    Blocks become BLOCKS_CLEAR + ADD_* (+ BLOCK_ENABLE 0 for `off` blocks);
    keys with a parameter become SET_PARAM; `filter` becomes FILTER_ENABLE.
    Keys that have no CAN equivalent raise ValueError (the firmware's own
    parser is the reference for validation; this only translates).
    node_id, if present, is sent last so the other commands reach the old id.
    """
    db = db or load_db()
    cmds: list[tuple[int, bytes]] = []
    blocks: list[tuple[str, float, float, int]] = []
    node_cmd = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        key, _, rest = line.partition("=") if "=" in line else line.partition(" ")
        key = key.strip()
        values = rest.split()
        if not values:
            raise ValueError(f"line {lineno}: missing value")
        if key == "block":
            kind, order, q = values[0], float(values[1]), float(values[2])
            enabled = _on_off(values[3], lineno) if len(values) > 3 else 1
            blocks.append((kind, order, q, enabled))
        elif key == "filter":
            cmds.append(command(db, "FILTER_ENABLE", token, FilterEnable=_on_off(values[0], lineno)))
        elif key in PARAM_OF_KEY:
            value = float(_on_off(values[0], lineno)) if key == "offset" else float(values[0])
            frame = command(db, "SET_PARAM", token, SetParamId=PARAM_OF_KEY[key], SetParamValue=value)
            if key == "node_id":
                node_cmd = frame
            else:
                cmds.append(frame)
        elif key in NOT_ON_CAN:
            raise ValueError(f"line {lineno}: {key} cannot be set over CAN")
        else:
            raise ValueError(f"line {lineno}: unknown key {key!r}")
    if blocks:
        block_cmds = [command(db, "BLOCKS_CLEAR", token)]
        for index, (kind, order, q, enabled) in enumerate(blocks):
            if kind == "motor":
                block_cmds.append(command(db, "ADD_MOTOR", token, MotorOrder=order, MotorQ=q))
            elif kind == "output":
                block_cmds.append(command(db, "ADD_OUTPUT", token, OutputOrder=order, OutputQ=q))
            elif kind == "fixed":
                block_cmds.append(command(db, "ADD_FIXED", token, FixedFrequency=order, FixedQ=q))
            else:
                raise ValueError(f"unknown block kind {kind!r}")
            if not enabled:
                block_cmds.append(command(db, "BLOCK_ENABLE", token, BlockIndex=index, BlockEnable=0))
        cmds = block_cmds + cmds
    if node_cmd is not None:
        cmds.append(node_cmd)
    return cmds


def read_log(path: str | Path):
    """Frames of a candump -l log, through python-can's reader."""
    import can
    return list(can.CanutilsLogReader(str(path)))


def decode_log(path: str | Path, node_id: int = 1) -> dict:
    """Decodes a candump log: telemetry rows (paired A/B by sequence), acks,
    heartbeats, and sequence gaps."""
    db = load_db(node_id)
    ids = {name: BASE_IDS[name] + node_id for name in BASE_IDS}
    telem, acks, heartbeats, commands = [], [], [], []
    pending_a = None
    for msg in read_log(path):
        if msg.is_error_frame or msg.is_remote_frame:
            continue
        data = bytes(msg.data)
        if msg.arbitration_id == ids["TELEM_A"]:
            pending_a = (msg.timestamp, db.decode_message(msg.arbitration_id, data, decode_choices=False))
        elif msg.arbitration_id == ids["TELEM_B"]:
            b = db.decode_message(msg.arbitration_id, data, decode_choices=False)
            if pending_a is not None and pending_a[1]["SeqA"] == b["SeqB"]:
                row = {"t_s": pending_a[0], **pending_a[1], **b}
                row["valid"] = row["TorqueRaw"] > -327.675 and row["TorqueFiltered"] > -327.675
                telem.append(row)
            pending_a = None
        elif msg.arbitration_id == ids["ACK"]:
            acks.append({"t_s": msg.timestamp, **db.decode_message(msg.arbitration_id, data)})
        elif msg.arbitration_id == ids["HEARTBEAT"]:
            heartbeats.append({"t_s": msg.timestamp, **db.decode_message(msg.arbitration_id, data)})
        elif msg.arbitration_id == ids["CMD"]:
            try:
                commands.append({"t_s": msg.timestamp, **db.decode_message(msg.arbitration_id, data)})
            except Exception as exc:  # malformed command: keep it visible
                commands.append({"t_s": msg.timestamp, "error": str(exc), "data": data.hex()})
    lost = 0
    for prev, cur in zip(telem, telem[1:]):
        lost += (cur["SeqA"] - prev["SeqA"] - 1) % 256
    return {"telemetry": telem, "acks": acks, "heartbeats": heartbeats,
            "commands": commands, "lost_telemetry": lost}
