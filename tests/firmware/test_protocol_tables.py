"""One table, three readers: the C firmware (hd_params.def, hd_protocol.def
compiled in), the Python tools (hdtools.protocol parses the same files) and
the DBC (generated).  Fails on any drift: a DBC not regenerated after a row
changed, a Python reader that misreads a row, a C encoder whose bytes the DBC
decodes differently."""
from __future__ import annotations

import json
import struct
import subprocess

import pytest

from hdtools import canproto, native, protocol

TYPES = ["F32", "U32", "U16", "U8", "BOOL"]
FLAGS = {"LIVE": 0x01, "REBUILD": 0x02, "RO": 0x04, "CONFIG": 0x08, "CALIB": 0x10, "LO_OPEN": 0x20}


@pytest.fixture(scope="module")
def dump():
    exe = native.executable("fw_table_dump")
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    return [json.loads(line) for line in out.splitlines()]


def f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def test_committed_dbc_c_codec_and_doc_tables_are_the_generated_ones():
    assert canproto.DBC_PATH.read_text() == protocol.generate_dbc(), \
        "run: (cd tools && ../.venv/bin/python -m hdtools.protocol --write)"
    assert protocol.stale_files() == [], \
        "run: (cd tools && ../.venv/bin/python -m hdtools.protocol --write)"


def test_every_command_argument_and_frame_signal_fits_its_frame():
    """No two signals of a frame (or of one command with the header) share a
    bit, every one is inside the 8 bytes, and every opcode a host may send
    that the DBC multiplexes has its arguments in the C union."""
    def bits(sigs):
        used = set()
        for s in sigs:
            span = set(range(s.start, s.start + s.bits))
            assert not used & span, f"{s.owner}.{s.name} overlaps"
            assert max(span) < 64, f"{s.owner}.{s.name} beyond 8 bytes"
            used |= span
    for fr in protocol.frames():
        sigs = [s for s in protocol.frame_signals(fr.name) if s.mux not in ("U32_REPLY",)]
        bits(sigs)
    header = [s for s in protocol.frame_signals("CMD")]
    for e in protocol.commands():
        bits(header + list(protocol.command_args(e.name)))
    h = protocol.generate_c()[protocol.paths.firmware_file("hd_can_gen.h")]
    for e in protocol.commands():
        if protocol.command_args(e.name):
            assert f"hd_can_cmd_{e.name.lower()}_t {e.name.lower()};" in h


def test_c_and_python_read_the_same_parameter_table(dump):
    c_rows = [d for d in dump if "param" in d]
    py = protocol.params()
    assert len(c_rows) == len(py) >= 29
    for c, p in zip(c_rows, py):
        assert (c["param"], c["name"], c["key"]) == (p.id, p.name, p.key)
        assert TYPES[c["type"]] == p.type
        assert c["flags"] == sum(FLAGS[f] for f in p.flags), p.key
        assert (c["lo"], c["hi"]) == (f32(p.lo), f32(p.hi)), p.key
        # the default column is what hd_fw_config_default gives (LIB: the library's)
        assert c["default"] == (None if p.default is None else f32(p.default)), p.key
        if p.default is not None:
            assert c["value"] == f32(p.default), p.key
    crc = next(d["param_table_crc"] for d in dump if "param_table_crc" in d)
    assert crc == protocol.param_table_crc()
    # ids and keys unique, every writable row in the DBC's value table
    assert len({p.id for p in py}) == len(py) and len({p.key for p in py}) == len(py)
    db = canproto.load_db()
    choices = db.get_message_by_name("CMD").get_signal_by_name("SetParamId").choices
    assert {int(k): str(v) for k, v in choices.items()} == {p.id: p.name for p in py}


def test_control_ranges_in_the_schema_are_control_s_limits(dump):
    """The SETPOINT mode and GAINS ranges (hd_protocol.def) document limits
    that control/hd_ctrl.h owns: a change there must show here."""
    lim = next(d for d in dump if "ctrl_kp_max" in d)
    sig = {s.name: s for s in protocol.signals()}
    assert float(sig["GainKp"].hi) == lim["ctrl_kp_max"]
    assert float(sig["GainKd"].hi) == lim["ctrl_kd_max"]
    assert int(sig["SpMode"].hi) == lim["ctrl_modes"] - 1


def test_c_and_python_read_the_same_vocabulary(dump):
    for kind, entries in (("opcode", protocol.opcodes()), ("result", protocol.results()),
                          ("fault", protocol.faults())):
        c = {d[kind]: d["name"] for d in dump if kind in d}
        assert c == {e.code: e.name for e in entries}, kind
    assert canproto.FAULT_BITS == [d["name"] for d in dump if "fault" in d]


def test_c_encoder_bytes_decode_through_the_dbc(dump):
    frames = {d["frame"]: d for d in dump if "frame" in d}
    db = canproto.load_db(3)

    def decode(key, name):
        f = frames[key]
        assert f["ext"] == 1
        msg = db.get_message_by_frame_id(f["id"])
        assert msg.name == name
        return msg.decode(bytes.fromhex(f["data"]), decode_choices=False)

    a = decode("TELEM_A", "TELEM_A")
    assert a["TorqueFiltered"] == pytest.approx(12.34) and a["TorqueRaw"] == pytest.approx(-1.5)
    assert a["Ripple"] == pytest.approx(0.25) and a["SeqA"] == 0x7F
    b = decode("TELEM_B", "TELEM_B")
    assert b["MotorVelocity"] == pytest.approx(-156.0) and b["Faults"] == 0x018410
    assert b["KfStatus"] == 5 and b["SeqB"] == 0x7F
    c = decode("TELEM_C", "TELEM_C")
    assert (c["MotorCounts"], c["OutputCounts"], c["OutputPresent"], c["SeqC"]) == \
        (0x89ABCDEF, 0x345678, 1, 9)
    h = decode("HEARTBEAT", "HEARTBEAT")
    assert (h["State"], h["HbFaults"], h["DeadlineMisses"]) == (2, 0x020401, 0x1234)
    assert (h["CalibStatus"], h["ConfigStatus"], h["ProfileStatus"]) == (2, 4, 6)
    bt = decode("BOOT", "BOOT")
    assert (bt["ResetCause"], bt["FaultRecord"], bt["FaultPc"], bt["ProtocolVersion"]) == \
        (8, 1, 0x08001234, 2)
    ack = decode("ACK_FLOAT", "ACK")
    assert ack["AckValue"] == 0.5 and ack["AckAux"] == protocol.param_by_key("r_nm2").id
    ver = decode("ACK_U32", "ACK")
    assert ver["AckValueU32"] == 0x00010203 and "AckValue" not in ver
    cmd = decode("CMD", "CMD")
    assert cmd["SetParamId"] == protocol.param_by_key("gear_ratio").id
    assert cmd["SetParamValue"] == 121.0
    add = decode("CMD_ADD_FIXED", "CMD")
    assert (add["Opcode"], add["Token"], add["FixedQ"]) == (protocol.by_name(
        protocol.opcodes(), "ADD_FIXED").code, 8, 2.5)
    assert add["FixedFrequency"] == pytest.approx(123.45)
    get = decode("CMD_BLOCK_GET", "CMD")
    assert (get["BlockGetIndex"], get["BlockGetField"]) == (5, protocol.BLOCK_FIELDS.index("Q_NM2"))
    put = decode("CMD_PROFILE_PUT", "CMD")
    assert (put["ProfilePutLine"], put["ProfilePutOrder"], put["ProfilePutValue"]) == (0x13, 2, -1.5)
    assert decode("CMD_CALIB_SAVE", "CMD")["CalibUnixTime"] == 1700000000
    ff = decode("FEEDFORWARD", "FEEDFORWARD")
    assert ff["FfTorque"] == -2.5 and ff["FfSeq"] == 7
    sp = decode("SETPOINT", "SETPOINT")
    assert (sp["SpMode"], sp["SpSeq"]) == (3, 200)
    assert sp["SpTorque"] == pytest.approx(-12.5) and sp["SpPosition"] == pytest.approx(1.25)
    assert sp["SpVelocity"] == pytest.approx(-0.75)
    g = decode("GAINS", "GAINS")
    assert g["GainKp"] == 150.0 and g["GainKd"] == 2.5
    cs = decode("CTRL_STATE", "CTRL_STATE")
    assert (cs["CtrlModeAsked"], cs["CtrlModeRun"], cs["CtrlLimits"]) == (2, 1, 0x28)
    assert cs["CtrlTorqueRef"] == pytest.approx(-3.5) and cs["CtrlCurrent"] == pytest.approx(1.234)
    assert (cs["CtrlSeq"], cs["CtrlFlags"]) == (17, 3)


def test_python_checks_values_like_the_table():
    gear = protocol.param_by_key("gear_ratio")
    assert gear.check(100.0) is None and gear.check(0.5) is not None
    r = protocol.param_by_key("r_nm2")
    assert r.check(0.0) is not None  # LO_OPEN: 0 excluded
    cpr = protocol.param_by_key("motor_cpr")
    assert cpr.check(4096) is None and cpr.check(4096.5) is not None
    with pytest.raises(ValueError, match="leading zero"):
        canproto.config_to_commands("motor_cpr = 01024\n")
    with pytest.raises(ValueError, match="given twice"):
        canproto.config_to_commands("r_nm2 = 1\nr_nm2 = 2\n")
    with pytest.raises(ValueError, match="read-only"):
        canproto.config_to_commands("block_count = 2\n")


def test_configuration_text_becomes_the_commands_of_its_keys():
    """The firmware's parser (through cfgtext) reads the text; the SET_PARAM
    frames carry the values as Python reads the decimals (float32), in the
    text's order, blocks first, node_id last."""
    keys = [("gear_ratio", "121"), ("node_id", "5"), ("r_nm2", "0.1"), ("offset", "on"),
            ("motor_cpr", "16384"), ("calib_offset_v", "-0.3"), ("telemetry_rate_hz", "500"),
            ("ctrl_torque_kp", "1.7e0"), ("filter", "off")]
    text = "".join(f"{k} = {v}  # c\n" for k, v in keys[:3]) + "block = fixed 50 1e-4 off\n" + \
        "".join(f"{k} {v}\n" for k, v in keys[3:])
    db = canproto.load_db()
    got = [db.decode_message(fid, data) for fid, data in canproto.config_to_commands(text, db)]
    assert [str(g["Opcode"]) for g in got[:3]] == ["BLOCKS_CLEAR", "ADD_FIXED", "BLOCK_ENABLE"]
    assert got[1]["FixedQ"] == f32(1e-4) and got[1]["FixedFrequency"] == 50
    value = {"on": 1.0, "off": 0.0}
    want = [(protocol.param_by_key(k).name, f32(value.get(v) if v in value else float(v)))
            for k, v in keys if k != "node_id"] + [("NODE_ID", 5.0)]
    assert [(str(g["SetParamId"]), g["SetParamValue"]) for g in got[3:]] == want
    nine = "".join(f"block = motor {k} 1\n" for k in range(1, 10))
    with pytest.raises(ValueError, match="line 9: too many blocks"):
        canproto.config_to_commands(nine)
