"""`hdsense send` / `hdsense device` against the emulated joint: the issue's
round trip (analyze a log, apply the model over CAN, save, reboot, read
back, compare), refusals, no answer, bad files."""
from __future__ import annotations

import re
import struct
import time

import can
import pytest

from conftest import run_cli, summary
from hdtools import canproto, protocol
from hdtools.cmd_monitor import candump_line
from hdtools.joint import Joint


def f32(v):
    return struct.unpack("<f", struct.pack("<f", float(v)))[0]


def config_values(text):
    """key -> float of a model.cfg, read here independently of canproto:
    `key = value` lines, on/off as 1/0; block lines counted."""
    values, blocks = {}, 0
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        key, value = (s.strip() for s in line.split("=", 1))
        if key == "block":
            blocks += 1
        else:
            values[key] = {"on": 1.0, "off": 0.0}.get(value, None)
            if values[key] is None:
                values[key] = float(value)
    return values, blocks


def read_device(channel, node, keys):
    bus = can.Bus(interface="virtual", channel=channel)
    try:
        j = Joint(bus, node)
        return {k: j.get(protocol.param_by_key(k)).value for k in keys}
    finally:
        bus.shutdown()


@pytest.fixture(scope="module")
def analyzed(tmp_path_factory, paper_scenario):
    """model.cfg and model.can that `hdsense analyze` wrote for a log of the
    emulated joint (decoded by `hdsense canlog decode --csv`)."""
    from hdtools import cli, emu
    tmp = tmp_path_factory.mktemp("analyzed")
    with emu.Emulator(scenario=paper_scenario, config="angle_telemetry_every = 1\n") as j:
        frames = j.run_frames(6000)
    log = tmp / "joint.log"
    log.write_text("".join(candump_line(m, "vcan0") for m in frames))
    assert cli.main(["canlog", "decode", str(log), "--csv", str(tmp / "joint.csv"),
                     "--cpr", "4096"]) == 0
    assert cli.main(["analyze", str(tmp / "joint.csv"), "--json", str(tmp / "r.json"),
                     "--out", str(tmp / "out"), "--quiet"]) == 0
    return tmp / "out"


def test_analyze_model_reaches_the_joint_and_survives_reboot(analyzed, joint, channel, capsys):
    cfg_text = (analyzed / "model.cfg").read_text()
    want, n_blocks = config_values(cfg_text)
    j = joint()
    with j.attach("virtual", channel):
        before = read_device(channel, 1, ["r_nm2"])
        rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel,
                               analyzed / "model.cfg", "--reboot")
        assert rc == 0, err
        s = summary(out)
        assert s["saved"].startswith("yes")
        assert "configuration from the saved record (OK)" in s["boot"]
        # read back here, independently of the tool: every key of the file
        got = read_device(channel, 1, list(want) + ["block_count"])
    assert f32(before["r_nm2"]) != f32(want["r_nm2"])   # the model did change something
    for key, value in want.items():
        assert got[key] == f32(value), key
    assert got["block_count"] == n_blocks
    assert j.boots == 2                                   # the REBOOT restarted the firmware
    # a power cycle (not a REBOOT): still the model
    j.power_cycle()
    with j.attach("virtual", channel):
        again = read_device(channel, 1, list(want))
    assert again == {k: got[k] for k in want}


def test_model_can_lines_apply_too(analyzed, joint, channel, capsys):
    can_text = (analyzed / "model.can").read_text()
    frames = [l for l in can_text.split("\n\n", 1)[0].splitlines() if l.strip()]
    assert frames and all("#" in f and not f.startswith("#") for f in frames)
    with joint().attach("virtual", channel):
        rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel, analyzed / "model.can")
        assert rc == 0, err
        n = int(summary(out)["applied"].split()[0])
    assert n == len(frames)


def test_not_saved_does_not_survive_a_reboot(analyzed, joint, channel, capsys):
    with joint().attach("virtual", channel):
        rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel,
                               analyzed / "model.cfg", "--no-save", "--reboot")
    assert rc == 1
    assert "configuration defaults (MISSING)" in out
    after_boot = out.split("boot = ", 1)[1]
    assert re.search(r"read back r_nm2 = \S+  DIFFERS from the file's", after_boot)
    assert re.search(r"read back block_count = \d+  DIFFERS from the file's 2 blocks", after_boot)
    assert "DIFFERS" not in out.split("boot = ", 1)[0]       # before the reboot all equal
    assert len(err.strip().splitlines()) == 1 and "differ" in err


def test_refusals_are_reported_and_nothing_is_saved(joint, channel, capsys, tmp_path):
    # nine blocks: the firmware has room for eight.  Its parser (which the
    # tools run) refuses such a text; sent as frames, the joint answers NO_SPACE
    nine = "r_nm2 = 0.001\n" + "".join(f"block = motor {k} 1e-7\n" for k in range(1, 10))
    text_cfg = tmp_path / "nine.cfg"
    text_cfg.write_text(nine)
    db = canproto.load_db()
    cfg = tmp_path / "nine.can"
    cfg.write_text("".join(canproto.cansend_str(f) + "\n" for f in canproto.config_to_commands(
        nine.replace("block = motor 9 1e-7\n", "")) + [canproto.command(
            db, "ADD_MOTOR", MotorOrder=9, MotorQ=1e-7)]))
    cmd_id = canproto.BASE_IDS["CMD"] + 1
    bad_can = tmp_path / "bad.can"      # SET_PARAM r_nm2 = -1, past the host-side checks
    bad_can.write_text(f"{cmd_id:08X}#20000100" + struct.pack("<f", -1.0).hex().upper() + "\n")
    with joint().attach("virtual", channel):
        rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel, text_cfg)
        assert rc == 2 and "line 10: too many blocks" in err
        rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel, cfg)
        assert rc == 1
        refused = [l for l in out.splitlines() if l.startswith("refused:")]
        assert refused == ["refused: ADD_MOTOR MotorOrder 9, MotorQ 1.00000001e-07: NO_SPACE"]
        assert "saved" not in summary(out)
        assert len(err.strip().splitlines()) == 1
        rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel, bad_can)
        assert rc == 1 and "refused: SET_PARAM r_nm2 = -1: OUT_OF_RANGE" in out
        # nothing was saved: the record is still missing
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "load")
        assert rc == 1 and "NO_DATA" in err


def test_no_answer_and_bad_files(joint, channel, capsys, tmp_path):
    cfg = tmp_path / "m.cfg"
    cfg.write_text("r_nm2 = 0.001\n")
    with joint().attach("virtual", channel):
        t0 = time.monotonic()
        rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel, cfg, "--node", "5",
                               "--timeout", "0.2")
        assert rc == 5 and "no answer" in err and len(err.strip().splitlines()) == 1
        assert time.monotonic() - t0 < 3
        for text, why in (("r_nm2 = banana\n", "not a number"), ("bogus = 1\n", "unknown key"),
                          ("01D01001#2000\n", "2 data bytes"),
                          ("01D01001#6200000000000000\n", "not part of a model")):
            cfg.write_text(text)
            rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel, cfg)
            assert rc == 2 and why in err, (text, err)
        rc, out, err = run_cli(capsys, "send", "-i", "virtual", channel, tmp_path / "none.cfg")
        assert rc == 2 and "cannot read" in err


def test_device_helper(joint, channel, capsys):
    with joint().attach("virtual", channel):
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "version")
        s = summary(out)
        assert rc == 0 and s["board_id"] == "'EMU0'"
        assert s["param_table_crc"] == s["host_param_table_crc"]
        header = (protocol.FIRMWARE / "hd_can_proto.h").read_text()
        assert f"#define HD_CAN_PROTOCOL_VERSION {s['protocol_version']}u" in header
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "set",
                               "telemetry_rate_hz", "250")
        assert rc == 0 and summary(out)["telemetry_rate_hz"] == "250"
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "get",
                               "telemetry_rate_hz")
        assert summary(out)["telemetry_rate_hz"] == "250"
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "set",
                               "telemetry_rate_hz", "2000")
        assert rc == 2 and "outside" in err
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "save")
        assert rc == 0
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "reboot")
        assert rc == 0 and "from the saved record (OK)" in out
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "params")
        assert summary(out)["telemetry_rate_hz"] == "250"
        assert set(summary(out)) == {p.key for p in protocol.params()}
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "info")
        assert int(summary(out)["reset_cause"], 16) == 0x04     # HAL_RESET_SOFTWARE


def test_device_profile_actions(joint, channel, capsys, tmp_path):
    """`hdsense device IFACE profile ...`: an uploaded profile is stored
    (its float32 values are in the NVM image), survives a reboot, is
    cleared; refusals name the record status; a profile for another gear
    ratio never reaches the joint."""
    import json
    lines = [{"lock": "motor", "order": 2, "a_nm": 0.8125, "b_nm": -0.3359375},
             {"lock": "output", "order": 1, "a_nm": 0.4140625, "b_nm": 0.1796875}]
    good = tmp_path / "profile.json"
    good.write_text(json.dumps({"schema": "hdjoint-profile/1", "gear_ratio": 100,
                                "lines": lines}))
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"schema": "hdjoint-profile/1", "gear_ratio": 50,
                                 "lines": lines}))
    j = joint()
    dev = ("device", "-i", "virtual", channel, "profile")
    with j.attach("virtual", channel):
        rc, out, err = run_cli(capsys, *dev, "load")
        assert rc == 1 and "PROFILE_LOAD refused" in err and "record" in err
        rc, out, err = run_cli(capsys, *dev, "put", other, "--save")
        assert rc == 2 and "gear ratio 50" in err
        rc, out, err = run_cli(capsys, *dev, "put", good, "--save")
        assert rc == 0, err
        assert summary(out)["profile_save"].startswith("OK") and "2 lines" in out
        rc, out, err = run_cli(capsys, "device", "-i", "virtual", channel, "reboot")
        assert rc == 0
        rc, out, err = run_cli(capsys, *dev, "load")
        assert rc == 0 and "2 lines" in summary(out)["profile_load"]
    image = bytes(j.nvm())
    for ln in lines:
        for key in ("a_nm", "b_nm"):
            assert struct.pack("<f", ln[key]) in image, (ln, key)
    with j.attach("virtual", channel):
        rc, out, err = run_cli(capsys, *dev, "clear")
        assert rc == 0 and "profile_clear = OK" in out
        rc, out, err = run_cli(capsys, *dev, "load")
        assert rc == 1 and "PROFILE_LOAD refused" in err
        rc, out, err = run_cli(capsys, *dev, "save")       # the running filter's blocks
        assert rc == 0 and summary(out)["profile_save"].startswith("OK"), err
