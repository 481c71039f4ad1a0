"""What the CAN commands (monitor, device, send, canlog) and rosio share:
the bus arguments, node ids, and the text of a BOOT frame and of a device
INFO item.  A module of its own so that no command module imports another
(that made an import cycle of cmd_monitor, cmd_device, cmd_canlog and
rosio)."""
from __future__ import annotations

import argparse

from . import protocol


def node_id(text: str) -> int:
    """argparse type: a decimal node id in NODE_MIN..NODE_MAX."""
    try:
        node = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a decimal node id") from None
    if not protocol.NODE_MIN <= node <= protocol.NODE_MAX:
        raise argparse.ArgumentTypeError(f"node id {node} outside "
                                         f"{protocol.NODE_MIN}..{protocol.NODE_MAX}")
    return node


def positive(text: str) -> float:
    """argparse type: a positive number below 1e9."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (v > 0 and v < 1e9):
        raise argparse.ArgumentTypeError(f"{text} must be a positive number")
    return v


def add_bus_arguments(p, channel_optional: bool = False) -> None:
    if channel_optional:
        p.add_argument("channel", nargs="?", metavar="IFACE",
                       help="CAN channel, e.g. can0 (or --channel)")
        p.add_argument("--channel", dest="channel_opt", metavar="CHANNEL",
                       help="CAN channel (instead of IFACE)")
    else:
        p.add_argument("channel", metavar="IFACE", help="CAN channel, e.g. can0")
    p.add_argument("-i", "--interface", default="socketcan",
                   help="python-can interface (socketcan, pcan, kvaser, slcan, virtual, ...; "
                        "default socketcan)")
    p.add_argument("--bitrate", type=int, default=1000000,
                   help="bit rate in bit/s (opens non-SocketCAN adapters at it; bus load "
                        "is computed against it; default 1000000)")


RESET_CAUSES = ("POWER_ON", "PIN", "SOFTWARE", "WATCHDOG", "BROWNOUT", "LOCKUP", "CLOCK")


def boot_report(d: dict) -> str:
    """The BOOT frame as one line."""
    cause = int(d["ResetCause"])
    names = [n for i, n in enumerate(RESET_CAUSES) if cause & (1 << i)] or [f"0x{cause:02X}"]
    status = protocol.name_of(protocol.record_statuses(), d["BootConfigStatus"])
    fault = f"HardFault at PC 0x{int(d['FaultPc']):08X}" if d["FaultRecord"] else "no fault record"
    return (f"reset {'|'.join(names)}, configuration "
            f"{'from the saved record' if d['ConfigFromRecord'] else 'defaults'} ({status}), "
            f"{fault}, protocol {d['ProtocolVersion']}")


def fmt_item(name: str, value: int) -> str:
    """An INFO item's value as `hdsense device info` prints it."""
    if name == "FIRMWARE_VERSION":
        return f"{value >> 16}.{(value >> 8) & 0xFF}.{value & 0xFF}"
    if name in ("GIT_HASH", "PARAM_TABLE_CRC", "FAULT_PC", "FAULT_LR", "FAULT_CFSR",
                "FAULT_HFSR", "FAULT_ADDR", "RESET_CAUSE"):
        return f"0x{value:08X}"
    if name == "BOARD_ID":
        text = value.to_bytes(4, "little").decode("ascii", "replace")
        return f"{text!r}"
    return str(value)
