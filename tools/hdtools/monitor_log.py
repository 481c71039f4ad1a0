"""The candump -l log `hdsense monitor --log` records: one line per frame,
in whole lines, flushed every FLUSH_S, written under a temporary name next
to the target and renamed over it at the end (hdtools.safeio.StreamOutput).

The lines are python-can's can.io.CanutilsLogWriter's, which can-utils'
canplayer and log2asc read (they ignore its " R" / " T" direction), and so
does the project's reader (hdtools.canproto.read_log_lines).  Error and
remote frames are written here: python-can writes every error frame with the
bus-error class and no data (the class bits and the controller's status
bytes are what an error frame says), and a remote frame without its DLC."""
from __future__ import annotations

import copy
import io
import time

import can

from .safeio import StreamOutput

FLUSH_S = 0.5
_CAN_ERR_FLAG = 0x20000000


class CandumpWriter(can.io.CanutilsLogWriter):
    """can.io's candump -l writer into a text buffer (`text()` takes what was
    written), error frames with their class and data, remote frames with their DLC."""

    def __init__(self, iface: str):
        super().__init__(io.StringIO(), channel=iface)

    def on_message_received(self, msg: can.Message) -> None:
        if msg.channel is not None and msg.channel != self.channel:
            msg = copy.copy(msg)      # one interface name per log, a token without spaces
            msg.channel = None
        if not (msg.is_error_frame or msg.is_remote_frame):
            super().on_message_received(msg)
            return
        ts = max(self.last_timestamp or 0.0, float(msg.timestamp or 0.0))
        self.last_timestamp = ts
        if msg.is_error_frame:
            frame = f"{_CAN_ERR_FLAG | (msg.arbitration_id & 0x1FFFFFFF):08X}#"
            frame += bytes(msg.data).hex().upper()
        else:
            width = 8 if msg.is_extended_id else 3
            frame = f"{msg.arbitration_id:0{width}X}#R" + (str(msg.dlc) if msg.dlc else "")
        self.file.write(f"({ts:f}) {self.channel} {frame}\n")

    def text(self) -> str:
        out = self.file.getvalue()
        self.file.seek(0)
        self.file.truncate()
        return out


def candump_line(msg: can.Message, iface: str) -> str:
    """One `candump -l` line of one frame (tests and one-off writers)."""
    writer = CandumpWriter(iface)
    writer.on_message_received(msg)
    return writer.text()


class LogRecorder:
    """candump -l lines to a temporary file next to the target; whole lines,
    flushed every FLUSH_S; renamed over the target by close()."""

    def __init__(self, path: str, iface: str):
        self.path, self.iface = path, "".join(c if c.isalnum() or c in "-_." else "_"
                                              for c in iface) or "can0"
        self.out = StreamOutput(path, encoding="ascii")
        self.writer = CandumpWriter(self.iface)
        self.pending = 0
        self.last_flush = time.monotonic()

    def write(self, msg: can.Message) -> None:
        self.writer.on_message_received(msg)
        self.pending += 1
        if time.monotonic() - self.last_flush >= FLUSH_S:
            self.flush()

    def flush(self) -> None:
        self.last_flush = time.monotonic()
        if not self.pending:
            return
        text, self.pending = self.writer.text(), 0
        self.out.write(text)          # OutputError: the temporary is removed

    def close(self) -> None:
        self.flush()
        self.out.commit()

    def abort(self) -> None:
        self.out.discard()
