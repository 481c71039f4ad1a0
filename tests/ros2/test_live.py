"""`hdsense monitor --mcap` and `--foxglove` against the emulated joint
(the real firmware on python-can's virtual bus, tools/hdtools/emu.py):
what reaches the MCAP file and a real WebSocket client is checked against
the CAN frames sent, recorded by the same run's --log and decoded by
python-can's candump reader and cantools on the DBC; CDR is decoded by
mcap-ros2-support (not the rosbags library that encodes it)."""
from __future__ import annotations

import asyncio
import json
import math
import socket
import struct
import threading
import uuid
from pathlib import Path

import numpy as np
import pytest
import websockets
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory

HERE = Path(__file__).resolve().parent
from test_bags import can_frames, mcap_messages

from hdtools import cli, emu

GEAR, CPR = 100.0, 4096.0          # what the emulated joint answers (hd_fw_config defaults)
SUBPROTOCOL = "foxglove.sdk.v1"    # what foxglove-sdk 0.30 serves


def monitor(channel, *args):
    rc = cli.main(["monitor", "-i", "virtual", channel, "-q", *[str(a) for a in args]])
    assert rc == 0


def test_monitor_mcap_holds_the_frames_sent(tmp_path):
    channel = f"hd-{uuid.uuid4().hex[:10]}"
    with emu.Emulator() as j, j.attach("virtual", channel):
        monitor(channel, "--duration", "2", "--log", tmp_path / "run.log",
                "--mcap", tmp_path / "run.mcap", "--joint", "elbow")
    frames = can_frames(tmp_path / "run.log")
    msgs, meta = mcap_messages(tmp_path / "run.mcap")
    a, b = [d for _, d in frames["TELEM_A"]], [d for _, d in frames["TELEM_B"]]
    js = [m for _, m in msgs["/joint_states"]]
    # every pair sent (the log may end on a TELEM_A whose TELEM_B came too late)
    assert len(js) == len(b) > 1500 and len(a) - len(js) in (0, 1)
    a = a[:len(js)]
    assert [m.effort[0] for m in js] == [d["TorqueFiltered"] for d in a]
    assert np.allclose([m.velocity[0] for m in js], [d["MotorVelocity"] / GEAR for d in b],
                       rtol=1e-12, atol=0)
    # device time: the sequence x 1 ms, whatever the virtual bus's delivery
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in js])
    assert np.array_equal(np.diff(stamps), np.full(len(js) - 1, 1_000_000))
    # the motor angle at each TELEM_C sample: its counts / motor_cpr, unwrapped
    angle = {t: m.data for t, m in msgs["/hdjoint/elbow/motor_angle_rad"]}
    t_a = [t for t, _ in frames["TELEM_A"][:len(js)]]
    anchors = []
    for t, d in frames["TELEM_C"]:                # the pair sent just before it
        k = int(np.searchsorted(t_a, t, side="right")) - 1
        if 0 <= k < len(js) and a[k]["SeqA"] == d["SeqC"]:
            anchors.append((k, d["MotorCounts"]))
    anchors = [(k, c) for k, c in anchors if stamps[k] in angle]   # after motor_cpr came
    assert len(anchors) > 150
    counts = np.unwrap(np.array([c for _, c in anchors], float), period=2**32)
    got = [angle[stamps[k]] for k, _ in anchors]
    assert np.allclose(got, (counts - counts[0]) * 2 * math.pi / CPR + got[0], rtol=0, atol=1e-9)
    text = meta["rosbag2"]["serialized_metadata"]
    assert "hdjoint.param.gear_ratio: '100'" in text
    assert "hdjoint.version.firmware_version:" in text


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def _client(port: int, want: int, got: dict) -> None:
    """Connects, waits for /joint_states to be advertised, subscribes,
    keeps `want` messages as (log time, decoded)."""
    for _ in range(100):
        try:
            ws = await websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL])
            break
        except OSError:
            await asyncio.sleep(0.05)
    else:
        raise AssertionError("no server")
    decoder = None
    subscribe, waited_s = None, 0.0
    async with ws:
        while len(got["messages"]) < want:
            try:
                m = await asyncio.wait_for(ws.recv(), timeout=0.5)
            except asyncio.TimeoutError:
                # foxglove-sdk can drop a subscription sent right after the channel's
                # advertisement ("subscribe to unknown channel"): say it again until
                # data comes (the same subscription id; a duplicate is only logged)
                waited_s += 0.5
                if waited_s >= 10:
                    raise
                if subscribe is not None and not got["messages"]:
                    await ws.send(subscribe)
                continue
            if isinstance(m, str):
                op = json.loads(m)
                got.setdefault("ops", []).append(op["op"])
                for ch in op.get("channels", []):
                    got.setdefault("topics", []).append(ch["topic"])
                    if ch["topic"] == "/joint_states" and decoder is None:
                        schema = Schema(id=ch["id"], name=ch["schemaName"],
                                        encoding=ch["schemaEncoding"],
                                        data=ch["schema"].encode())
                        decoder = DecoderFactory().decoder_for(ch["encoding"], schema)
                        subscribe = json.dumps({"op": "subscribe", "subscriptions": [
                            {"id": 7, "channelId": ch["id"]}]})
                        await ws.send(subscribe)
                continue
            opcode, sub, log_time = struct.unpack_from("<BIQ", m)
            assert opcode == 1 and sub == 7                 # message data, our subscription
            got["messages"].append((log_time, decoder(m[13:])))


def test_foxglove_client_decodes_joint_states_of_the_frames_sent(tmp_path):
    channel, port = f"hd-{uuid.uuid4().hex[:10]}", _free_port()
    got: dict = {"messages": []}
    errors = []

    def run_client():
        try:
            asyncio.run(_client(port, 300, got))
        except BaseException as exc:  # noqa: BLE001 - reported by the test below
            errors.append(exc)
    client = threading.Thread(target=run_client, daemon=True)
    client.start()
    with emu.Emulator() as j, j.attach("virtual", channel):
        # 300 samples take 0.3 s at the joint's rate; the rest of the duration is for a
        # loaded machine, where the client connects and subscribes late (it stops at 300)
        monitor(channel, "--duration", "8", "--log", tmp_path / "run.log", "--foxglove",
                "--foxglove-port", port, "--joint", "elbow")
    client.join(timeout=10)
    assert not errors, errors
    assert got["ops"][0] == "serverInfo" and "/hdjoint/elbow/torque_raw_nm" in got["topics"]
    msgs = got["messages"]
    assert len(msgs) == 300 and all(list(m.name) == ["elbow"] for _, m in msgs)
    # the client's 300 consecutive samples are 300 consecutive TELEM_A/B pairs sent
    frames = can_frames(tmp_path / "run.log")
    filt = [d["TorqueFiltered"] for _, d in frames["TELEM_A"]]
    vel = [d["MotorVelocity"] / GEAR for _, d in frames["TELEM_B"]]
    effort = [m.effort[0] for _, m in msgs]
    starts = [k for k in range(len(filt) - len(effort) + 1)
              if filt[k:k + len(effort)] == effort]
    # the filtered torque can repeat (a still joint), so the run is the start whose
    # velocities (one motor increment per tick, hd_fw_filter.c) match as well
    got_vel = [m.velocity[0] for _, m in msgs]
    assert any(np.allclose(got_vel, vel[k:k + len(msgs)], rtol=1e-12) for k in starts)
    times = np.array([t for t, _ in msgs])
    assert np.array_equal(np.diff(times), np.full(len(msgs) - 1, 1_000_000))
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in msgs]
    assert stamps == list(times)
