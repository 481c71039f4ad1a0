"""Sharing a bus with CANopen (docs/reference/protocol.md, "Sharing a bus"): a
CANopen master (the `canopen` package: NMT, SDO, node scan, heartbeat
consumer) and a CANopen slave on one virtual bus with the emulated joint.
The master reads nothing from the joint (no 11-bit frame, no node seen,
no heartbeat of node 1) and the joint counts every CANopen frame as
foreign (INFO FOREIGN_FRAMES) and keeps running."""
from __future__ import annotations

import threading
import time

import can
import pytest

from hdtools import canproto, protocol
from hdtools.joint import Joint

canopen = pytest.importorskip("canopen")

SLAVE = 5
DEVICE_TYPE = 0x00020192


def dictionary():
    od = canopen.ObjectDictionary()
    var = canopen.objectdictionary.ODVariable("Device type", 0x1000, 0)
    var.data_type = canopen.objectdictionary.UNSIGNED32
    var.access_type = "ro"
    var.default = DEVICE_TYPE
    od.add_object(var)
    return od


class Tally(can.Listener):
    """Every frame on the bus, as a third party sees it."""

    def __init__(self):
        self.frames = []
        self.lock = threading.Lock()

    def on_message_received(self, msg):
        with self.lock:
            self.frames.append(msg)


def is_joint_frame(msg, node):
    return (msg.is_extended_id and not msg.is_error_frame and
            msg.arbitration_id - node in canproto.BASE_IDS.values())


def test_canopen_master_and_joint_share_a_bus(joint, channel):
    tally_bus = can.Bus(interface="virtual", channel=channel)
    tally = Tally()
    notifier = can.Notifier(tally_bus, [tally])
    j = joint()
    with j.attach("virtual", channel):
        slave_net = canopen.Network()
        slave_net.connect(interface="virtual", channel=channel)
        slave = canopen.LocalNode(SLAVE, dictionary())
        slave_net.add_node(slave)
        slave.nmt.start_heartbeat(50)

        master = canopen.Network()
        master.connect(interface="virtual", channel=channel)
        seen_ids = []
        notify = master.notify

        def spy(can_id, data, timestamp):
            seen_ids.append(can_id)
            notify(can_id, data, timestamp)
        master.notify = spy
        node5 = master.add_node(canopen.RemoteNode(SLAVE, dictionary()))
        node1 = master.add_node(canopen.RemoteNode(1, dictionary()))   # the joint's number

        master.nmt.state = "OPERATIONAL"                  # NMT broadcast (0x000)
        node5.nmt.wait_for_heartbeat(2.0)                 # heartbeat consumer
        assert node5.sdo.upload(0x1000, 0) == DEVICE_TYPE.to_bytes(4, "little")   # SDO
        master.scanner.search(limit=127)                  # SDO requests to every node id
        master.send_message(0x80, b"")                    # SYNC
        with pytest.raises(canopen.nmt.NmtError):
            node1.nmt.wait_for_heartbeat(0.3)             # nothing from "node 1" in CANopen terms
        time.sleep(0.3)
        assert master.scanner.nodes == [SLAVE]
        slave.nmt.stop_heartbeat()
        slave_net.disconnect()
        master.disconnect()
        time.sleep(0.1)                                  # the last frames reach the joint

        bus = can.Bus(interface="virtual", channel=channel)
        jt = Joint(bus, 1)
        foreign = jt.item("FOREIGN_FRAMES").value
        telemetry_before = jt.item("TELEMETRY_FRAMES").value
        time.sleep(0.2)
        telemetry_after = jt.item("TELEMETRY_FRAMES").value
        bus.shutdown()
    notifier.stop()
    tally_bus.shutdown()

    frames = tally.frames
    standard = [m for m in frames if not m.is_extended_id]
    joint_frames = [m for m in frames if is_joint_frame(m, 1)]
    assert joint_frames, "the joint sent nothing"
    assert all(m.is_extended_id for m in joint_frames)
    # every 11-bit frame is CANopen's: NMT, SYNC, SDO requests/answers, heartbeat
    services = {m.arbitration_id & 0x780 for m in standard}
    assert services <= {0x000, 0x080, 0x580, 0x600, 0x700}, sorted(map(hex, services))
    assert len(standard) > 127
    # the master's stack was handed the joint's frames and dispatched them to no one
    assert any(i > 0x7FF for i in seen_ids)
    # the joint counted exactly the frames that were not its own nor commands to it
    others = [m for m in frames if not is_joint_frame(m, 1)]
    assert int(foreign) == len(others) == len(standard)
    assert telemetry_after > telemetry_before          # still running
