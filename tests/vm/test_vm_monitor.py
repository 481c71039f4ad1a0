"""Host side of the VM test of `hdsense monitor` and `hdsense device` on a
real kernel's vcan0 (tests/vm/guest_monitor.py, docs/how-to/socketcan.md).

The CTest fixture vm_monitor booted the VM; inside it the monitor watched
hdjoint-host through python-can's socketcan interface while a raw socket
captured every frame (CAN FD and error frames too, kernel time stamps),
frames of other devices and bad frames were injected, and `hdsense device`
set and saved a parameter.  Here the monitor's log and summary are
compared with that independent capture, its log decoded through the DBC
with the runner's CSV, and the saved configuration booted on the host.
"""
from __future__ import annotations

import collections
import io
import json
import os
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
from hdtools import canproto, protocol, summary

import vm_checks

SCENARIO = ROOT / "sim" / "scenarios" / "paper_156.ini"


def build_dir() -> Path:
    return Path(os.environ.get("HD_BUILD_DIR", ROOT / "build" / "host-debug")).resolve()


@pytest.fixture(scope="module")
def run():
    out = build_dir() / "tests" / "vm" / "vm-monitor"
    log = out / "serial.log"
    if not log.is_file():
        pytest.fail(f"no serial log at {log}: the vm_monitor test (QEMU) did not run or could "
                    "not start the VM -- run ctest -R vm_monitor")
    if "HDVM: VERDICT PASS" not in log.read_text(errors="replace"):
        pytest.fail(f"the VM run has no PASS verdict; see {log} and the vm_monitor output")
    share = out / "share"
    result = json.loads((share / "result.json").read_text())
    text = lambda name: (share / name).read_text()  # noqa: E731
    return {"share": share, "result": result, "text": text,
            "summary": summary.parse(text("monitor.out")),
            "runner": summary.parse(text("runner.out")),
            "runner_device": summary.parse(text("runner-device.out")),
            "capture": canproto.read_log(share / "capture.log"),
            "monitor": canproto.read_log(share / "monitor.log")}


def key(msg) -> tuple:
    return (msg.arbitration_id, msg.is_extended_id, msg.is_remote_frame, msg.is_error_frame,
            msg.is_fd, bytes(msg.data) if not msg.is_remote_frame else msg.dlc)


def classify(msg, db) -> str:
    """error | foreign | malformed | node: the frame's kind for node 1, from
    the DBC alone (docs/reference/protocol.md: 29-bit ids, one DLC per message)."""
    if msg.is_error_frame:
        return "error"
    if not msg.is_extended_id:
        return "foreign"
    try:
        spec = db.get_message_by_frame_id(msg.arbitration_id)
    except KeyError:
        return "foreign"
    if msg.is_remote_frame or msg.is_fd or len(msg.data) != spec.length:
        return "malformed"
    return "node"


def joint_ids(node: int) -> dict[int, str]:
    return {canproto.BASE_IDS[name] + node: name for name in canproto.BASE_IDS}


# ------------------------------------------------------------------ tests
def test_every_process_ended_as_expected(run):
    r = run["result"]["exit"]
    assert r == {"device-set": 0, "device-save": 0, "runner-device": 143, "runner": 0,
                 "monitor": 0}
    assert run["text"]("monitor.err") == ""
    assert "monitor: stopped" in run["text"]("monitor.out")      # SIGTERM, then the summary
    assert run["runner_device"]["interrupted"] == "SIGTERM"


def test_the_log_is_whole_and_holds_what_the_kernel_delivered(run):
    """Every classic frame the capture socket saw, and nothing else, is in
    the monitor's log; those the monitor received carry the same kernel time
    stamp (to the microsecond); the CAN FD frame never reached its classic
    socket."""
    share = run["share"]
    assert not list(share.glob(".monitor.log*")), "a temporary log was left behind"
    for name in ("monitor.log", "capture.log"):
        text = (share / name).read_text()
        assert text.endswith("\n")
        bad = []
        canproto.read_log(share / name, bad)
        assert bad == [], (name, bad[:3])
    cap, mon = run["capture"], run["monitor"]
    fd = [m for m in cap if m.is_fd]
    assert len(fd) == 1
    classic = [m for m in cap if not m.is_fd]
    assert collections.Counter(map(key, mon)) == collections.Counter(map(key, classic))
    # In kernel order with the kernel's stamps, except the commands: the
    # monitor logs its own GET_PARAMs when it sends them, at host time.
    cmd = canproto.BASE_IDS["CMD"] + 1
    mon_rx = [m for m in mon if m.arbitration_id != cmd]
    cap_rx = [m for m in classic if m.arbitration_id != cmd]
    assert [key(m) for m in mon_rx] == [key(m) for m in cap_rx]
    dt = np.array([m.timestamp - c.timestamp for m, c in zip(mon_rx, cap_rx)])
    assert np.max(np.abs(dt)) <= 1.5e-6


def test_summary_counts_equal_the_frames_captured(run):
    s, db = run["summary"], canproto.load_db(1)
    classic = [m for m in run["capture"] if not m.is_fd]
    kind = [classify(m, db) for m in classic]
    kinds = collections.Counter(kind)
    ours, node2 = joint_ids(1), joint_ids(2)
    names = collections.Counter(ours[m.arbitration_id] for m, k in zip(classic, kind)
                                if k == "node")
    others = collections.Counter(m.arbitration_id - canproto.BASE_IDS["TELEM_A"]
                                 for m, k in zip(classic, kind) if k == "foreign"
                                 and m.is_extended_id and m.arbitration_id in node2)
    # the injected frames are all there (so none of these counts is trivially 0)
    injected = {(i["can_id"] & 0x1FFFFFFF, i["len"]) for i in run["result"]["injected"]}
    assert len(injected) == 7
    assert kinds["error"] == 1 and kinds["malformed"] == 2 and kinds["foreign"] == 4
    assert others == {2: 1}
    assert s["node"] == "1"
    assert int(s["frames"]) == len(classic) == len(run["monitor"])
    assert int(s["node_frames"]) == kinds["node"]
    assert int(s["foreign_frames"]) == kinds["foreign"]
    assert int(s["malformed_frames"]) == kinds["malformed"]
    assert int(s["error_frames"]) == kinds["error"]
    assert s["other_joint_nodes"] == "2 (1 frames)"
    assert s["malformed: TELEM_A: remote frame"] == "1"
    assert s["malformed: TELEM_A: 4 data bytes, TELEM_A has 8"] == "1"
    assert int(s["telemetry_pairs"]) == names["TELEM_A"] == names["TELEM_B"]
    assert int(s["angle_frames"]) == names["TELEM_C"]
    assert int(s["heartbeats"]) == names["HEARTBEAT"]
    assert int(s["boots"]) == names["BOOT"] == 2          # the two runs of the joint
    assert s["lost_telemetry"] == "0"
    # kernel receive buffer: what the monitor asked for (root in the guest)
    assert int(s["rx_buffer_bytes"]) >= 8 << 20


def test_the_monitor_asked_the_joint_over_the_kernel(run):
    """Its GET_PARAMs at the start, answered by the first run (telemetry
    off, IDLE_CONFIG): the scenario's encoders and gear, the rate in force."""
    s = run["summary"]
    scen = dict(re.findall(r"(?m)^(\w+)\s*=\s*([^#\n]+?)\s*$", SCENARIO.read_text()))
    assert float(s["param motor_cpr"]) == float(scen["encoder_cpr"])
    assert float(s["param gear_ratio"]) == float(scen["gear_ratio"])
    assert float(s["param telemetry_rate_hz"]) == 0.0
    every = float(s["param angle_telemetry_every"])
    assert every > 0 and int(s["angle_frames"]) == -(-int(s["telemetry_pairs"]) // int(every))


def test_the_log_decodes_to_the_runner_csv(run):
    """Through the DBC (cantools): every telemetry sample of the 1 kHz run
    equals the runner's CSV within half an LSB, none lost (the runner
    reports none dropped), and every frame the runner's backend sent."""
    share = run["share"]
    dec = canproto.decode_log(share / "monitor.log", rate_hz=1000)
    csv = np.genfromtxt(io.StringIO(run["text"]("samples.csv")), delimiter=",", names=True)
    n = float(run["result"]["duration_s"]) * 1000
    assert len(csv) == int(run["runner"]["samples"]) == n
    assert int(run["runner"]["can_tx_dropped"]) == 0 and dec["lost_telemetry"] == 0
    assert len(dec["boots"]) == 2                       # the two runs of the joint
    assert min(r["t_host_s"] for r in dec["telemetry"]) > dec["boots"][1]["t_s"]
    vm_checks.assert_telemetry_matches_csv(dec["telemetry"], csv)
    # each run's own frames, as its backend counted them (can_tx_ok)
    ours = set(joint_ids(1)) - {canproto.BASE_IDS["CMD"] + 1}
    db = canproto.load_db(1)
    sent = [m for m in run["monitor"] if m.arbitration_id in ours and classify(m, db) == "node"]
    boot = canproto.BASE_IDS["BOOT"] + 1
    second = [i for i, m in enumerate(sent) if m.arbitration_id == boot][1]
    assert int(run["runner_device"]["can_tx_ok"]) == second
    assert int(run["runner"]["can_tx_ok"]) == len(sent) - second


def test_set_and_save_over_the_kernel_then_boot_from_the_saved_record(run, tmp_path):
    """hdsense device set r_nm2 0.5 and save on vcan0; the joint's NVM file
    then boots (here, natively) with r_nm2 = 0.5 and telemetry off -- the
    whole running configuration, the --config setting included."""
    text = run["text"]
    assert text("device-set.out").splitlines() == ["r_nm2 = 0.5"]
    assert re.fullmatch(r"config_save = OK \(record \w+\)\n", text("device-save.out"))
    acks = canproto.decode_log(run["share"] / "monitor.log", rate_hz=1000)["acks"]
    got = [(str(a["AckOpcode"]), str(a["AckResult"])) for a in acks]
    assert ("SET_PARAM", "OK") in got and ("CONFIG_SAVE", "OK") in got
    assert [float(a["AckValue"]) for a in acks if str(a["AckOpcode"]) == "SET_PARAM"] == [0.5]

    nvm = tmp_path / "nvm.bin"
    nvm.write_bytes((run["share"] / "nvm.bin").read_bytes())
    db = canproto.load_db(1)
    cmds = []
    for t, name in ((0.05, "r_nm2"), (0.1, "telemetry_rate_hz")):
        fid, data = canproto.command(db, "GET_PARAM", 0,
                                     GetParamId=protocol.param_by_key(name).name)
        cmds += ["--cmd-at", f"{t}:{fid:08X}#{data.hex().upper()}"]
    log = tmp_path / "boot.log"
    host = build_dir() / "firmware" / "host" / "hdjoint-host"
    r = subprocess.run([str(host), "--sensors", f"sim:{SCENARIO}", "--nvm", str(nvm),
                        "--can", f"log:{log}", "--duration", "0.2", "--quiet"] + cmds,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    dec = canproto.decode_log(log, rate_hz=1000)
    assert len(dec["boots"]) == 1 and dec["boots"][0]["ConfigFromRecord"] == 1
    assert str(dec["boots"][0]["BootConfigStatus"]) == "OK"
    assert dec["params"] == {"r_nm2": 0.5, "telemetry_rate_hz": 0.0}


def test_vm_doc_reads_the_run(run):
    """tests/vm/vm_doc.py (the vm_monitor table of docs/how-to/socketcan.md) reads
    the monitor's summary and the guest's steps of this run."""
    import vm_doc
    r = vm_doc.parse_monitor_run(run["share"].parent)
    assert r["summary"] == run["summary"]
    assert sorted(r["device_s"]) == ["save", "set"]
    t = run["result"]["times_s"]
    assert r["runner_s"] == t["runner_end_s"] - t["runner_start_s"] > 0
    assert 0 < r["boot_s"] and 0 < r["python_start_s"] and 0 < r["imports_s"]
    assert 0 <= r["drain_s"] and 0 < r["monitor_start_s"]
