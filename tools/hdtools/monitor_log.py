"""The candump -l log `hdsense monitor --log` records: one line per frame,
in whole lines, flushed every FLUSH_S, written under a temporary name next
to the target and renamed over it at the end (hdtools.safeio.StreamOutput).

The lines are written here, not by python-can's can.io.CanutilsLogWriter:
python-can 4.4 appends a direction (" R" / " T") to every line and writes
every error frame with one fixed identifier, and the project's reader
(hdtools.canproto.decode_log) takes the three-field `candump -l` form that
can-utils' candump writes and reads."""
from __future__ import annotations

import time

import can

from .safeio import StreamOutput

FLUSH_S = 0.5


def candump_line(msg: can.Message, iface: str) -> str:
    """One `candump -l` line: "(sec.usec) IFACE ID#DATA"."""
    ts = max(0.0, float(msg.timestamp or 0.0))
    sec = int(ts)
    usec = min(999999, int(round((ts - sec) * 1e6)))
    if msg.is_error_frame:
        ident = f"{0x20000000 | (msg.arbitration_id & 0x1FFFFFFF):08X}"
    elif msg.is_extended_id:
        ident = f"{msg.arbitration_id & 0x1FFFFFFF:08X}"
    else:
        ident = f"{msg.arbitration_id & 0x7FF:03X}"
    if msg.is_remote_frame:
        body = "R" + (str(msg.dlc) if msg.dlc else "")
    elif msg.is_fd:
        flags = (1 if msg.bitrate_switch else 0) | (2 if msg.error_state_indicator else 0)
        body = f"#{flags:X}{bytes(msg.data).hex().upper()}"
    else:
        body = bytes(msg.data).hex().upper()
    return f"({sec}.{usec:06d}) {iface} {ident}#{body}\n"


class LogRecorder:
    """candump -l lines to a temporary file next to the target; whole lines,
    flushed every FLUSH_S; renamed over the target by close()."""

    def __init__(self, path: str, iface: str):
        self.path, self.iface = path, "".join(c if c.isalnum() or c in "-_." else "_"
                                              for c in iface) or "can0"
        self.out = StreamOutput(path, encoding="ascii")
        self.pending: list[str] = []
        self.last_flush = time.monotonic()

    def write(self, msg: can.Message) -> None:
        self.pending.append(candump_line(msg, self.iface))
        if time.monotonic() - self.last_flush >= FLUSH_S:
            self.flush()

    def flush(self) -> None:
        self.last_flush = time.monotonic()
        if not self.pending:
            return
        text, self.pending = "".join(self.pending), []
        self.out.write(text)          # OutputError: the temporary is removed

    def close(self) -> None:
        self.flush()
        self.out.commit()

    def abort(self) -> None:
        self.out.discard()
