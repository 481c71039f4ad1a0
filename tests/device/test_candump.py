"""candump -l I/O through python-can's can.io: what `hdsense monitor --log`
writes reads back frame for frame, lines in can-utils' own form (typed here
from can-utils' lib.c log format, not produced by the project) read as
can-utils means them, and lines can.io alone would misread are refused with
their line number instead of ending the read or changing a frame."""
from __future__ import annotations

import can

from hdtools import canproto
from hdtools.monitor_log import CandumpWriter

FRAMES = [
    can.Message(timestamp=1.000001, arbitration_id=0x123, is_extended_id=False, data=b"\x01\x02"),
    can.Message(timestamp=1.5, arbitration_id=0x1FFFFFFF, data=bytes(range(8))),
    can.Message(timestamp=2.0, arbitration_id=0x7FF, is_extended_id=False),
    can.Message(timestamp=2.25, arbitration_id=0x18FF0001, is_remote_frame=True, dlc=8),
    can.Message(timestamp=3.0, arbitration_id=0x100, is_fd=True, bitrate_switch=True,
                error_state_indicator=True, data=bytes(range(12))),
    # an error frame: controller problem (class 0x04) with its status bytes
    can.Message(timestamp=4.0, arbitration_id=0x04, is_error_frame=True,
                data=b"\x00\x04\x00\x00\x00\x00\x00\x00"),
    can.Message(timestamp=5.0, arbitration_id=0x80, is_error_frame=True, data=bytes(8)),
]


def _key(msg: can.Message) -> tuple:
    return (round(msg.timestamp, 6), msg.arbitration_id, msg.is_extended_id,
            msg.is_remote_frame, msg.is_error_frame, msg.is_fd, msg.bitrate_switch,
            msg.error_state_indicator, bytes(msg.data) if not msg.is_remote_frame else msg.dlc)


def test_written_frames_read_back_equal(tmp_path):
    writer = CandumpWriter("vcan0")
    for msg in FRAMES:
        writer.on_message_received(msg)
    log = tmp_path / "w.log"
    log.write_text(writer.text())
    bad: list = []
    back = canproto.read_log_lines(log, bad)
    assert bad == []
    assert [n for n, _ in back] == list(range(1, len(FRAMES) + 1))
    assert [_key(m) for _, m in back] == [_key(m) for m in FRAMES]


def test_can_utils_lines_and_misreads(tmp_path):
    log = tmp_path / "c.log"
    log.write_text("\n".join([
        "(1700000000.000123) can0 12345678#DEADBEEF",        # 1 extended, no direction
        "(1700000000.000200) can0 123##5AABB",               # 2 FD, flags BRS|FDF
        "(1700000000.000300) can0 20000004#0004000000000000",  # 3 error: controller
        "(1700000000.000400) can0 123#0011223344556677_9",   # 4 8 bytes, raw DLC 9
        "",
        "# a comment",
        "(1700000000.000500) can0 123#00112",                # 7 cut short
        "(1700000000.000600) can0 123##A00",                 # 8 flags can.io reads as decimal
        "(1700000000.000700) can0 800#00",                   # 9 11-bit id out of range
        "(1700000000.000800) can0 123##1" + "00" * 9,        # 10 9 bytes is no FD length
        "(1700000000.000900) can0 321#01 T",                 # 11 python-can's direction
        "(1700000000.001000) can0 20000004#000",             # 12 error frame cut short
    ]) + "\n")
    bad: list = []
    frames = dict(canproto.read_log_lines(log, bad))
    assert [n for n, _ in bad] == [7, 8, 9, 10, 12]
    assert sorted(frames) == [1, 2, 3, 4, 11]
    assert frames[1].arbitration_id == 0x12345678 and frames[1].is_extended_id
    assert bytes(frames[1].data) == bytes.fromhex("DEADBEEF")
    assert frames[2].is_fd and frames[2].bitrate_switch and not frames[2].error_state_indicator
    assert frames[3].is_error_frame and frames[3].arbitration_id == 0x04
    assert bytes(frames[3].data)[1] == 0x04
    assert bytes(frames[4].data) == bytes.fromhex("0011223344556677")
    assert frames[11].arbitration_id == 0x321 and not frames[11].is_extended_id
