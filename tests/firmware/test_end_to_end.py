"""End to end: simulated joint -> hdjoint-host (firmware ISR) -> candump log
-> python-can reader + cantools (strict DBC, no warnings) -> compared with
the runner's CSV and with the simulation's ground truth."""
from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import cantools
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
from hdtools import canproto, native, summary as key_values

SCENARIO = ROOT / "sim" / "scenarios" / "paper_156.ini"


def run_host(tmp_path: Path, *extra: str, duration: float = 3.0):
    exe = native.executable("hdjoint-host")
    log, csv = tmp_path / "t.log", tmp_path / "s.csv"
    out = subprocess.run([str(exe), "--sensors", f"sim:{SCENARIO}", "--duration", str(duration),
                          "--can", f"log:{log}", "--csv", str(csv), *extra],
                         check=True, capture_output=True, text=True, timeout=60)
    summary = key_values.parse(out.stdout)
    return log, np.genfromtxt(csv, delimiter=",", names=True), summary


def test_dbc_loads_strict_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        db = cantools.database.load_file(str(canproto.DBC_PATH), strict=True)
    assert {m.name for m in db.messages} == set(canproto.BASE_IDS)
    for m in db.messages:
        assert m.length == 8
        assert m.is_extended_frame  # 29-bit: out of CANopen's 11-bit identifiers
        assert m.frame_id == canproto.BASE_IDS[m.name] + 1


def test_telemetry_decodes_to_the_runner_output_and_beats_raw(tmp_path):
    # No stored profile here: the output-locked (misalignment) block learns
    # online (learning_mode 0), as during commissioning; in the default
    # operating mode it would stay at zero until a profile is saved.
    cfg = tmp_path / "adaptive.cfg"
    cfg.write_text("learning_mode = 0\n")
    log, csv, summary = run_host(tmp_path, "--config", str(cfg), duration=6.0)
    res = canproto.decode_log(log)
    telem = res["telemetry"]
    n = len(csv)
    assert n == 6000 and len(telem) == n
    assert res["lost_telemetry"] == 0
    assert [r["SeqA"] for r in telem] == [i % 256 for i in range(n)]
    filt = np.array([r["TorqueFiltered"] for r in telem])
    raw = np.array([r["TorqueRaw"] for r in telem])
    ripple = np.array([r["Ripple"] for r in telem])
    vel = np.array([r["MotorVelocity"] for r in telem])
    # quantisation only: half an LSB (0.005 Nm torque, 0.0005 Nm ripple)
    assert np.max(np.abs(filt - csv["torque_filtered_nm"])) <= 0.005 + 1e-6
    assert np.max(np.abs(raw - csv["torque_raw_nm"])) <= 0.005 + 1e-6
    assert np.max(np.abs(ripple - csv["ripple_nm"])) <= 0.0005 + 1e-7
    assert np.max(np.abs(vel - csv["motor_velocity_rad_s"])) <= 0.001
    # against the simulation's truth, once the output has turned one
    # revolution (~4 s at 156 rad/s through 100:1): the misalignment line is
    # locked to the output and cannot be learned faster than that
    truth = csv["torque_true_nm"]
    settled = csv["t_s"] >= 4.0
    rms_raw = np.sqrt(np.mean((raw - truth)[settled] ** 2))
    rms_filt = np.sqrt(np.mean((filt - truth)[settled] ** 2))
    assert rms_filt < rms_raw / 5, (rms_raw, rms_filt)
    # the motor speed of the paper's drive: 156 rad/s
    assert abs(np.mean(vel[settled]) - 156.0) < 1.0
    # one heartbeat per second (0 .. 5 s), all healthy with a valid calibration
    hb = res["heartbeats"]
    assert len(hb) == 6
    assert all(str(h["State"]) == "RUN" and str(h["CalibStatus"]) == "OK" for h in hb)
    assert all(int(r["Faults"]) == 0 for r in telem)
    assert int(summary["samples"]) == 6000


def test_cantools_cli_decodes_the_log(tmp_path):
    log, _, _ = run_host(tmp_path, duration=0.01)
    out = subprocess.run([sys.executable, "-m", "cantools", "decode", "--single-line",
                          str(canproto.DBC_PATH)], input=log.read_text(), capture_output=True,
                         text=True, check=True)
    lines = out.stdout.splitlines()
    assert sum("TELEM_A(" in line for line in lines) == 10
    assert sum("HEARTBEAT(" in line for line in lines) == 1


def test_commands_from_a_config_file_take_effect(tmp_path):
    cfg_text = "telemetry_rate_hz = 100\nr_nm2 = 0.0004\nblock = motor 2 1e-7\nblock = motor 4 1e-7\n"
    frames = canproto.config_to_commands(cfg_text)
    cmd_id = canproto.BASE_IDS["CMD"] + 1
    bad = f"{cmd_id:08X}#2000630000000000"   # SET_PARAM of unknown parameter 99
    short = f"{cmd_id:08X}#2000"             # 2 bytes: malformed
    args = []
    for f in frames:
        args += ["--cmd", canproto.cansend_str(f)]
    args += ["--cmd", bad, "--cmd", short]
    log, csv, summary = run_host(tmp_path, *args, duration=2.0)
    res = canproto.decode_log(log)
    results = [(str(a["AckOpcode"]), str(a["AckResult"])) for a in res["acks"]]
    assert results[:len(frames)] == [(str(canproto.load_db().get_message_by_name("CMD")
                                          .decode(f[1])["Opcode"]), "OK") for f in frames]
    assert results[len(frames):] == [("SET_PARAM", "UNKNOWN_PARAM"), ("SET_PARAM", "BAD_LENGTH")]
    assert int(summary["command_errors"]) == 2
    # 100 Hz telemetry once the commands are in (up to 4 commands per tick,
    # executed between ticks, live from the next one)
    times = np.array([r["t_s"] for r in res["telemetry"]])
    assert np.allclose(np.diff(times[5:]), 0.010, atol=1e-6)
    # the rejected commands flagged CMD_ERROR, then the flags clear
    faults = [int(r["Faults"]) for r in res["telemetry"]]
    assert any(f & (1 << 13) for f in faults[:20]) and faults[-1] == 0


def test_runner_refuses_bad_arguments(tmp_path):
    exe = native.executable("hdjoint-host")
    for args in (["--sensors", "bogus"], ["--sensors", "replay:/nonexistent.hdraw"],
                 ["--sensors", "mock", "--duration", "-1"], ["--sensors", "mock", "--cmd", "zz"]):
        r = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=30)
        assert r.returncode != 0 and r.stderr.strip(), args
    bad_cfg = tmp_path / "bad.cfg"
    bad_cfg.write_text("gear_ratio = 100\nr_nm2 = -1\n")
    r = subprocess.run([str(exe), "--sensors", "mock", "--config", str(bad_cfg)],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode != 0 and f"{bad_cfg}:2:" in r.stderr
