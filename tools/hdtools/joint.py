"""Talking to one joint over a python-can bus: commands one at a time, each
answered by an ACK matched by opcode and token (docs/reference/protocol.md,
"Commands"), parameters by key, VERSION / INFO items, reboot and the BOOT
frame.  Used by `hdsense send`, `hdsense device` and `hdsense monitor`.

Errors are one-line HdErrors with their exit status (hdtools.cli):
  BusError  5  the CAN interface cannot be opened or used
  NoAnswer  5  the joint did not answer in time (wrong node, not powered...)
A refused command is not an exception: Ack.ok is False and Ack.result
names the reason.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import can

from . import canproto, protocol
from .safeio import HdError, UsageError

DEFAULT_TIMEOUT_S = 0.5
BOOT_TIMEOUT_S = 3.0


class BusError(HdError):
    code = 5


class NoAnswer(HdError):
    code = 5


def open_bus(interface: str, channel: str, bitrate: int | None = None, **kwargs) -> can.BusABC:
    """A python-can bus, or BusError with one line saying why not."""
    if bitrate and interface not in ("socketcan", "virtual"):
        kwargs["bitrate"] = bitrate     # SocketCAN's bitrate is the kernel's (ip link)
    try:
        return can.Bus(interface=interface, channel=channel, **kwargs)
    except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as exc:
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise BusError(f"{interface} {channel}: cannot open the CAN interface: {why}") from None


@dataclass
class Ack:
    opcode: str
    token: int
    result: str
    aux: int
    value: float | int
    t_s: float

    @property
    def ok(self) -> bool:
        return self.result == "OK"


class Joint:
    """One node on a bus.  BOOT frames received while waiting for answers
    are kept in boots (wait_boot takes them first); on_frame, if set, sees
    every frame sent or received."""

    def __init__(self, bus: can.BusABC, node: int, timeout_s: float = DEFAULT_TIMEOUT_S):
        if not protocol.NODE_MIN <= node <= protocol.NODE_MAX:
            raise UsageError(f"node id {node} outside {protocol.NODE_MIN}..{protocol.NODE_MAX}")
        self.bus, self.timeout_s = bus, timeout_s
        self._token = 0
        self.boots: list[dict] = []
        self.on_frame = None        # called with every frame sent or received
        self._set_node(node)

    def _set_node(self, node: int) -> None:
        self.node = node
        self.db = canproto.load_db(node)
        self.cmd_msg = self.db.get_message_by_name("CMD")
        self.ack_msg = self.db.get_message_by_name("ACK")
        self.boot_msg = self.db.get_message_by_name("BOOT")

    # ----------------------------------------------------------- commands
    def next_token(self) -> int:
        self._token = (self._token + 1) % 256
        return self._token

    def send_raw(self, data: bytes) -> Ack:
        """Sends one CMD payload (its token byte replaced by a fresh one) and
        waits for the ACK of that opcode and token."""
        if len(data) != 8:
            raise UsageError(f"a command is 8 bytes, got {len(data)}")
        token = self.next_token()
        data = bytes([data[0], token]) + bytes(data[2:])
        msg = can.Message(arbitration_id=self.cmd_msg.frame_id, is_extended_id=True, data=data,
                          timestamp=time.time())
        try:
            self.bus.send(msg, timeout=self.timeout_s)
        except can.CanError as exc:
            raise BusError(f"node {self.node}: send failed: {' '.join(str(exc).split())}") from None
        if self.on_frame is not None:
            self.on_frame(msg)
        ack = self._wait_ack(data[0], token)
        if ack is None:
            op = protocol.name_of(protocol.opcodes(), data[0])
            raise NoAnswer(f"node {self.node}: no answer to {op} within {self.timeout_s:g} s "
                           "(is the joint on this bus, powered, with this node id?)")
        return ack

    def command(self, opcode: str, **signals) -> Ack:
        return self.send_raw(canproto.command(self.db, opcode, 0, **signals)[1])

    def _wait_ack(self, opcode: int, token: int) -> Ack | None:
        deadline = time.monotonic() + self.timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            msg = self._recv(left)
            if msg is None:
                return None
            if (not msg.is_extended_id or msg.is_error_frame or msg.is_remote_frame
                    or msg.is_fd or len(msg.data) != 8):
                continue
            if msg.arbitration_id == self.boot_msg.frame_id:
                self.boots.append({"t_s": msg.timestamp, **self.boot_msg.decode(bytes(msg.data))})
                continue
            if msg.arbitration_id != self.ack_msg.frame_id:
                continue
            d = self.ack_msg.decode(bytes(msg.data), decode_choices=False)
            if d["AckOpcode"] != opcode or d["AckToken"] != token:
                continue    # an answer to someone else's command
            value = d.get("AckValue", d.get("AckValueU32", 0))
            return Ack(protocol.name_of(protocol.opcodes(), opcode), token,
                       protocol.name_of(protocol.results(), d["AckResult"]), d["AckAux"], value,
                       msg.timestamp)

    # --------------------------------------------------------- parameters
    def get(self, param: protocol.Param) -> Ack:
        return self.command("GET_PARAM", GetParamId=param.name)

    def block_field(self, index: int, field: int) -> float | None:
        """One field of a configured filter block (BLOCK_GET; protocol.BLOCK_FIELDS),
        or None if refused."""
        ack = self.command("BLOCK_GET", BlockGetIndex=index, BlockGetField=field)
        return ack.value if ack.ok else None

    def set(self, param: protocol.Param, value: float) -> Ack:
        ack = self.command("SET_PARAM", SetParamId=param.name, SetParamValue=float(value))
        if ack.ok and param.key == "node_id":
            self._set_node(int(value))
        return ack

    def item(self, name: str) -> Ack:
        entry = protocol.by_name(protocol.info_items(), name)
        op = "VERSION" if entry.code < 16 else "INFO"
        field = "VersionItem" if op == "VERSION" else "InfoItem"
        return self.command(op, **{field: entry.code})

    def wait_boot(self, timeout_s: float = BOOT_TIMEOUT_S) -> dict | None:
        """The next BOOT frame of this node (after a REBOOT), or None."""
        if self.boots:
            return self.boots.pop(0)
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            msg = self._recv(left)
            if msg is None:
                break
            if (msg.is_extended_id and msg.arbitration_id == self.boot_msg.frame_id
                    and len(msg.data) == 8 and not msg.is_remote_frame):
                return {"t_s": msg.timestamp, **self.boot_msg.decode(bytes(msg.data))}
        return None

    def drain(self) -> None:
        """Forgets frames already received (before a command whose answer
        or BOOT frame must be new)."""
        while self._recv(0) is not None:
            pass
        self.boots.clear()

    def _recv(self, timeout_s: float) -> can.Message | None:
        """One frame from the bus (shown to on_frame), None after timeout_s;
        a failing bus is a BusError, not a traceback."""
        try:
            msg = self.bus.recv(timeout=timeout_s)
        except can.CanError as exc:
            raise BusError(f"receive failed: {' '.join(str(exc).split())}") from None
        if msg is not None and self.on_frame is not None:
            self.on_frame(msg)
        return msg
