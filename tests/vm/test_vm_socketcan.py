"""Host side of the real-SocketCAN VM test (tests/vm, docs/how-to/socketcan.md).

The CTest fixture vm_socketcan boots the VM; inside it, hdjoint-host ran the
simulated joint with its CAN on vcan0 through the SocketCAN backend, and the
guest test program captured every frame on a second socket (candump -l
format) and printed the capture, the runner's per-sample CSV and its summary
on the serial console.  Here the captured frames are decoded through
firmware/hdjoint.dbc (python-can reader + cantools) and compared with the
values the simulated joint and the firmware produced (the CSV), and the
command ACKs with what the commands asked for.
"""
from __future__ import annotations

import io
import os
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
from hdtools import canproto, summary as key_values

import vm_checks

DURATION_S = 2.0  # hd_vm_can_test runs the runner for 2 s at 1 kHz


def serial_log() -> Path:
    build = Path(os.environ.get("HD_BUILD_DIR", ROOT / "build" / "host-debug"))
    log = build / "tests" / "vm" / "vm" / "serial.log"
    if not log.is_file():
        pytest.fail(f"no serial log at {log}: the vm_socketcan test (QEMU) did not run "
                    "or could not start the VM -- run ctest -R vm_socketcan")
    return log


def sections(text: str) -> dict[str, str]:
    """The HDVM-BEGIN/HDVM-END blocks of the serial log."""
    out, name, buf = {}, None, []
    for line in text.replace("\r", "").splitlines():
        if line.startswith("HDVM-BEGIN "):
            name, buf = line.split(" ", 1)[1], []
        elif line.startswith("HDVM-END ") and name is not None:
            out[name] = "\n".join(buf) + "\n"
            name = None
        elif name is not None:
            buf.append(line)
    return out


@pytest.fixture(scope="module")
def vm(tmp_path_factory):
    text = serial_log().read_text(errors="replace")
    if "HDVM: VERDICT PASS" not in text:
        pytest.fail("the VM run has no PASS verdict; see the vm_socketcan test output")
    sec = sections(text)
    for name in ("capture", "csv", "host-summary"):
        assert name in sec, f"serial log lacks the {name} section (truncated console output?)"
    tmp = tmp_path_factory.mktemp("vm")
    capture = tmp / "capture.log"
    capture.write_text(sec["capture"])
    csv = np.genfromtxt(io.StringIO(sec["csv"]), delimiter=",", names=True)
    summary = key_values.parse(sec["host-summary"])
    return {"decoded": canproto.decode_log(capture), "csv": csv, "summary": summary,
            "capture": capture}


def test_every_telemetry_frame_decodes_to_the_runner_values(vm):
    telem, csv = vm["decoded"]["telemetry"], vm["csv"]
    n = int(round(DURATION_S * 1000))
    assert len(csv) == n and int(vm["summary"]["samples"]) == n
    assert len(telem) == n, "telemetry pairs captured over vcan0"
    assert vm["decoded"]["lost_telemetry"] == 0
    vm_checks.assert_telemetry_matches_csv(telem, csv)


def test_telemetry_matches_the_simulated_joint(vm):
    """Against the simulation's ground truth: the paper's drive at 156 rad/s,
    and the filtered torque closer to the true torque than the raw one."""
    telem, csv = vm["decoded"]["telemetry"], vm["csv"]
    settled = csv["t_s"] >= 1.0
    vel = np.array([float(r["MotorVelocity"]) for r in telem])
    assert abs(np.mean(vel[settled]) - 156.0) < 1.0
    truth = csv["torque_true_nm"]
    raw = np.array([float(r["TorqueRaw"]) for r in telem])
    filt = np.array([float(r["TorqueFiltered"]) for r in telem])
    rms_raw = np.sqrt(np.mean((raw - truth)[settled] ** 2))
    rms_filt = np.sqrt(np.mean((filt - truth)[settled] ** 2))
    assert rms_filt < rms_raw, (rms_raw, rms_filt)


def test_commands_and_acks_through_the_dbc(vm):
    dec = vm["decoded"]
    # The capture socket saw the commands as any node on the bus would: the
    # node-1 ones decode (the 2-byte one as an error), node 2's is on the bus.
    cmds = dec["commands"]
    assert [int(c["Token"]) for c in cmds if "Token" in c] == [1, 2, 3, 4, 5, 8]
    assert [c["data"] for c in cmds if "error" in c] == ["2107"]
    node2 = [m for m in canproto.read_log(vm["capture"])
             if m.arbitration_id == canproto.BASE_IDS["CMD"] + 2]
    assert len(node2) == 1 and bytes(node2[0].data)[:2] == bytes([0x21, 6])
    acks = {int(a["AckToken"]): a for a in dec["acks"]}
    assert sorted(acks) == [1, 2, 3, 4, 5, 7, 8], "one ACK per node-1 command, none for node 2"
    expect = {  # token: (opcode, result, value or None)
        1: ("GET_PARAM", "OK", 100.0),      # gear_ratio = 100 in the scenario file
        2: ("SET_PARAM", "OK", 0.5),
        3: ("GET_PARAM", "OK", 0.5),        # the value just set
        4: ("SET_PARAM", "OUT_OF_RANGE", None),
        5: ("GET_PARAM", "UNKNOWN_PARAM", None),
        7: ("GET_PARAM", "BAD_LENGTH", None),
        8: ("GET_PARAM", "OK", 1000.0),     # default telemetry rate, 1 kHz
    }
    for token, (opcode, result, value) in expect.items():
        a = acks[token]
        assert (str(a["AckOpcode"]), str(a["AckResult"])) == (opcode, result), token
        if value is not None:
            assert float(a["AckValue"]) == pytest.approx(value, rel=1e-7), token
    assert int(vm["summary"]["command_errors"]) == 3
    assert int(vm["summary"]["commands"]) == 7


def test_heartbeats_and_runner_counters(vm):
    dec, summary = vm["decoded"], vm["summary"]
    hb = dec["heartbeats"]
    assert len(hb) == 2  # at 0 s and 1 s of a 2 s run
    assert all(str(h["CalibStatus"]) == "OK" for h in hb)
    # every frame the runner's backend accepted reached the capture socket
    # every frame the joint sent: telemetry pairs, TELEM_C with every 10th
    # pair (angle_telemetry_every), heartbeats, the boot report, ACKs
    frames = canproto.read_log(vm["capture"])
    ours = {canproto.BASE_IDS[n] + 1 for n in ("TELEM_A", "TELEM_B", "TELEM_C", "HEARTBEAT",
                                               "BOOT", "ACK")}
    n_tx = sum(1 for m in frames if m.arbitration_id in ours)
    n_c = sum(1 for m in frames if m.arbitration_id == canproto.BASE_IDS["TELEM_C"] + 1)
    assert n_c == (len(dec["telemetry"]) + 9) // 10
    assert int(summary["can_tx_ok"]) == n_tx
    assert int(summary["can_tx_dropped"]) == 0


def test_cantools_cli_decodes_the_capture(vm):
    """The stock cantools command line reads the same capture."""
    import subprocess
    out = subprocess.run([sys.executable, "-m", "cantools", "decode", "--single-line",
                          str(canproto.DBC_PATH)], input=vm["capture"].read_text(),
                         capture_output=True, text=True, check=True, timeout=60)
    lines = out.stdout.splitlines()
    assert sum("TELEM_A(" in line for line in lines) == int(DURATION_S * 1000)
    assert sum("ACK(" in line for line in lines) == 7


def test_vm_doc_reads_the_run_as_the_dbc_decoder_does(vm):
    """tests/vm/vm_doc.py (which writes the measured table of
    docs/how-to/socketcan.md) counts the captured frames as python-can + cantools
    decode them, the runner's own transmit count, and every in-guest check."""
    import vm_doc
    text = serial_log().read_text(errors="replace")
    r = vm_doc.parse_log(text)
    dec, frames = vm["decoded"], r["frames"]
    assert frames["TELEM_A"] == frames["TELEM_B"] == len(dec["telemetry"])
    assert frames["HEARTBEAT"] == len(dec["heartbeats"])
    assert frames["ACK"] == len(dec["acks"])
    assert frames["BOOT"] == len(dec["boots"])
    sent = sum(frames.get(n, 0) for n in ("TELEM_A", "TELEM_B", "TELEM_C", "HEARTBEAT", "BOOT",
                                           "ACK"))
    assert sent == int(vm["summary"]["can_tx_ok"])
    assert r["checks_self"] > 0 and r["checks_e2e"] > 0
    assert r["checks_self"] + r["checks_e2e"] == text.count("HDVM: ok  ")
    assert 0 < r["boot_s"] and 0 < r["runner_s"] and 0 <= r["dump_s"]
