"""`hdsense monitor` against the emulated joint on a virtual bus: live
decode, recording, foreign and malformed frames, Ctrl-C, bad records,
errors."""
from __future__ import annotations

import _thread
import struct
import threading
import time
import zlib

import can
import pytest

from conftest import run_cli, summary
from hdtools import canproto, protocol
from hdtools.joint import Joint

PNG_WIDTH_MIN = 1000


def png_size(path):
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", head[16:24])


def test_monitor_decodes_records_and_plots(joint, channel, capsys, tmp_path):
    log, png = tmp_path / "run.log", tmp_path / "run.png"
    with joint().attach("virtual", channel):
        rc, out, err = run_cli(capsys, "monitor", "-i", "virtual", channel, "--duration", "2",
                               "--log", log, "--plot-png", png)
    assert rc == 0, err
    s = summary(out)
    assert s["node"] == "1" and s["foreign_frames"] == "0" and s["malformed_frames"] == "0"
    assert s["lost_telemetry"] == "0"
    pairs = int(s["telemetry_pairs"])
    assert 1500 <= pairs <= 2100          # 1 kHz for ~2 s (a loaded machine may slip)
    assert int(s["angle_frames"]) in range(pairs // 10 - 2, pairs // 10 + 3)
    assert s["param motor_cpr"] == "4096" and s["param telemetry_rate_hz"] == "1000"
    assert "| RUN |" in out and "calib OK config MISSING" in out
    # the recording: whole lines, every frame, decodable with its own answers
    lines = log.read_text().splitlines()
    assert len(lines) == int(s["frames"])
    res = canproto.decode_log(log)
    assert not res["malformed"] and res["params"]["motor_cpr"] == 4096
    assert "estimated" not in res["period_source"] and res["period_s"] == 0.001
    assert len(res["telemetry"]) == pairs and res["lost_telemetry"] == 0
    assert not list(tmp_path.glob(".run.log.*"))          # no temporary left
    assert png_size(png)[0] >= PNG_WIDTH_MIN


def test_only_this_node_counted_foreign_and_malformed(joint, channel, capsys):
    """Another joint (node 2), a CANopen-style 11-bit frame, a 29-bit frame
    of another protocol, and frames on node 1's identifiers that are
    malformed: counted exactly, never fatal, node 1 still decoded."""
    node1 = canproto.BASE_IDS["TELEM_A"] + 1
    sent = {"foreign": 0, "malformed": 0, "error": 0}

    def inject():
        bus = can.Bus(interface="virtual", channel=channel)
        time.sleep(0.3)
        frames = [("foreign", can.Message(arbitration_id=0x701, is_extended_id=False, data=[5])),
                  ("foreign", can.Message(arbitration_id=0x18FF0001, data=bytes(8))),
                  ("malformed", can.Message(arbitration_id=node1, data=bytes(4))),
                  ("malformed", can.Message(arbitration_id=node1, is_remote_frame=True, dlc=8)),
                  ("malformed", can.Message(arbitration_id=node1, is_fd=True, data=bytes(12))),
                  ("error", can.Message(arbitration_id=0, is_error_frame=True))]
        for _ in range(5):
            for kind, msg in frames:
                bus.send(msg)
                sent[kind] += 1
            time.sleep(0.1)
        bus.shutdown()

    a = joint()
    b = joint(config="node_id = 2\ntelemetry_rate_hz = 100\n")
    with a.attach("virtual", channel), b.attach("virtual", channel):
        t = threading.Thread(target=inject)
        t.start()
        rc, out, err = run_cli(capsys, "monitor", "-i", "virtual", channel, "--node", "1",
                               "--duration", "1.5", "--passive", "--quiet")
        t.join()
    assert rc == 0, err
    s = summary(out)
    n2 = int(s["other_joint_nodes"].split()[1].strip("("))
    assert s["other_joint_nodes"].startswith("2 (") and n2 > 100
    assert int(s["foreign_frames"]) == sent["foreign"] + n2
    assert int(s["malformed_frames"]) == sent["malformed"] == 15
    assert int(s["error_frames"]) == sent["error"]
    assert s["malformed: TELEM_A: 4 data bytes, TELEM_A has 8"] == "5"
    assert s["malformed: TELEM_A: remote frame"] == "5"
    assert s["malformed: TELEM_A: CAN FD frame"] == "5"
    assert int(s["telemetry_pairs"]) > 1000 and s["lost_telemetry"] == "0"


def test_ctrl_c_ends_cleanly_with_whole_log(joint, channel, capsys, tmp_path):
    log = tmp_path / "cut.log"
    timer = threading.Timer(1.0, _thread.interrupt_main)
    with joint().attach("virtual", channel):
        timer.start()
        rc, out, err = run_cli(capsys, "monitor", "-i", "virtual", channel, "--log", log,
                               "--quiet")
    assert rc == 0, err
    assert "monitor: stopped" in out
    s = summary(out)
    text = log.read_text()
    assert text.endswith("\n") and len(text.splitlines()) == int(s["frames"]) > 500
    bad = []
    canproto.read_log(log, bad)
    assert bad == []


def _config_entry(nvm):
    """(offset of the newest copy, offset of the CONFIG directory entry,
    payload offset, payload length) from the store layout documented in
    calib/hd_record_store.h, read here independently."""
    half = len(nvm) // 2
    best = None
    for base in (0, half):
        magic, fmt, length, seq, count = struct.unpack_from("<IHHIB", nvm, base)
        if magic == 0x54534448 and (best is None or seq > best[1]):
            best = (base, seq, count)
    base, _, count = best
    for i in range(count):
        e = base + 16 + 12 * i
        kind, _, version, offset, length, crc = struct.unpack_from("<BBHHHI", nvm, e)
        if kind == 2:
            return base, e, base + offset, length, count
    raise AssertionError("no configuration record")


@pytest.mark.parametrize("damage,status", [("payload", "CORRUPT"), ("version", "BAD_VERSION")])
def test_bad_configuration_record_boots_defaults_with_a_flag(joint, channel, capsys, damage,
                                                             status):
    j = joint()
    with j.attach("virtual", channel):
        bus = can.Bus(interface="virtual", channel=channel)
        jt = Joint(bus, 1)
        r = protocol.param_by_key("r_nm2")
        default_r = jt.get(r).value
        assert jt.set(r, 0.5).ok and jt.command("CONFIG_SAVE").ok
        bus.shutdown()
    nvm = j.nvm()
    base, entry, payload, length, count = _config_entry(bytes(nvm))
    if damage == "payload":
        nvm[payload + length // 2] ^= 0x01
    else:
        nvm[entry + 2] ^= 0x01                          # the record's format version
        hdr = bytes(nvm[base + 4: base + 16 + 12 * count])
        crc = struct.pack("<I", zlib.crc32(hdr))
        for i in range(4):                              # the header CRC still holds
            nvm[base + 16 + 12 * count + i] = crc[i]
    j.power_cycle()
    with j.attach("virtual", channel):
        rc, out, err = run_cli(capsys, "monitor", "-i", "virtual", channel, "--duration", "1.3",
                               "--quiet")
        bus = can.Bus(interface="virtual", channel=channel)
        now_r = Joint(bus, 1).get(r).value
        bus.shutdown()
    assert rc == 0, err
    assert f"configuration {status}" in out             # heartbeat
    assert "CONFIG_DEFAULTS" in summary(out)["faults_seen"]
    assert now_r == default_r != 0.5


def test_monitor_errors_are_one_line(capsys, tmp_path, channel):
    rc, out, err = run_cli(capsys, "monitor", "-i", "socketcan", "hdnone0", "--duration", "1")
    assert rc == 5 and "cannot open the CAN interface" in err and len(err.splitlines()) == 1
    rc, out, err = run_cli(capsys, "monitor", "-i", "virtual", channel, "--duration", "0.2",
                           "--log", tmp_path / "no" / "such" / "dir.log")
    assert rc == 3 and len(err.splitlines()) == 1
    rc, out, err = run_cli(capsys, "monitor", "-i", "virtual", channel, "--duration", "-1")
    assert rc == 2 and len(err.splitlines()) == 1
    rc, out, err = run_cli(capsys, "monitor", "--version")
    assert rc == 0 and out.startswith("hdsense monitor ")


def ctrl_state_bytes(asked, run, limits, torque_ref_nm, current_a, seq, flags):
    """CTRL_STATE as docs/reference/protocol.md lays it out: mode asked (bits 0..3) and
    run (4..7), the limits, int16 torque reference (0.01 N m), int16 current
    command (1 mA), the setpoint's sequence, flags."""
    return struct.pack("<BBhhBB", asked | run << 4, limits, round(torque_ref_nm * 100),
                       round(current_a * 1000), seq, flags)


def test_monitor_shows_and_records_the_control_state(joint, channel, capsys, tmp_path):
    """CTRL_STATE frames (a board with a drive; the emulated joint has none,
    so they are sent beside it): the mode run and asked, torque reference,
    current command, limits and flags by the names of docs/reference/protocol.md
    (modes 1 DAMP, 2 TORQUE, 3 IMPEDANCE; limits 1 torque, 8 current,
    32 fallback; flags 1 enabled, 2 watchdog), and the frames in the log."""
    ident = canproto.BASE_IDS["CTRL_STATE"] + 1
    sent = [ctrl_state_bytes(3, 1, 0x20, -1.25, 0.5, 7, 2)] * 3 + \
           [ctrl_state_bytes(2, 2, 0x09, 12.34, -2.5, 8, 1)] * 3
    log = tmp_path / "run.log"

    def inject():
        bus = can.Bus(interface="virtual", channel=channel)
        time.sleep(0.4)
        for data in sent:
            bus.send(can.Message(arbitration_id=ident, data=data))
            time.sleep(0.05)
        bus.shutdown()

    with joint().attach("virtual", channel):
        t = threading.Thread(target=inject)
        t.start()
        rc, out, err = run_cli(capsys, "monitor", "-i", "virtual", channel, "--duration", "1.5",
                               "--passive", "--quiet", "--log", log)
        t.join()
    assert rc == 0, err
    s = summary(out)
    assert s["malformed_frames"] == "0" and s["ctrl_state_frames"] == "6"
    assert s["last_ctrl_state"] == ("TORQUE (asked TORQUE), torque ref +12.34 Nm, current "
                                    "-2.500 A, limits TORQUE|CURRENT, flags ENABLED, "
                                    "setpoint seq 8")
    assert s["ctrl_limits_seen"] == "TORQUE|CURRENT|FALLBACK"
    events = [line for line in out.splitlines() if line.startswith("control: ")]
    assert events == ["control: mode DAMP (asked IMPEDANCE)", "control: flags WATCHDOG",
                      "control: limited by FALLBACK", "control: mode TORQUE (asked TORQUE)",
                      "control: flags ENABLED", "control: limited by TORQUE|CURRENT"]
    recorded = [line.split()[2].split("#")[1] for line in log.read_text().splitlines()
                if line.split()[2].startswith(f"{ident:08X}#")]
    assert recorded == [d.hex().upper() for d in sent]
