#!/usr/bin/env python3
"""Writes the corpus inputs that are bytes rather than text one types: CAN
logs and raw streams made by the project's own programs and then damaged,
files with NUL, control or non-UTF-8 bytes, calibration CSVs from the
campaign simulator.  Run it again when a format changes (e.g. the CAN ids):

  tests/corpus/make_inputs.py BUILD_DIR

Every file is small (the largest is a calibration CSV of ~6 KB)."""
from __future__ import annotations

import os
import re
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def run(*argv: str) -> None:
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)


def put(rel: str, data: bytes | str) -> None:
    path = HERE / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data.encode() if isinstance(data, str) else data)


def canlogs(build: Path, tmp: Path) -> None:
    log = tmp / "good.log"
    run(str(build / "firmware/host/hdjoint-host"), "--sensors", "mock", "--duration", "0.01",
        "--can", f"log:{log}", "--cmd", "01D01001#2100010000000000", "-q")
    lines = log.read_text().splitlines(keepends=True)
    good = "".join(lines)
    put("canlog/good.log", good)
    put("canlog/cut_last_line.log", good[:-10])     # an interrupted logger: 7 hex digits left
    put("canlog/cut_last_frame.log", good[:-9])     # ... cut between two bytes: 4 bytes left
    put("canlog/comment_blank.log", "# captured on the bench\n\n" + good + "\n   \n")
    telem_a = next(i for i, ln in enumerate(lines) if " 01D00201#" in ln)   # TELEM_A, node 1
    bad_hex = lines.copy()
    bad_hex[telem_a] = bad_hex[telem_a].replace("01D00201#", "01D00201#ZZ")
    put("canlog/bad_hex.log", "".join(bad_hex))
    short = lines.copy()                                          # DLC 4 for an 8-byte message
    head, _, data = short[telem_a].rstrip("\n").partition("01D00201#")
    short[telem_a] = f"{head}01D00201#{data[:8]}\n"
    put("canlog/wrong_dlc.log", "".join(short))
    node5 = "".join(re.sub(r" (01D0[0-9A-F]{2})01#", r" \g<1>05#", ln) for ln in lines)
    put("canlog/node5.log", node5)
    put("canlog/two_nodes.log", good + node5)
    put("canlog/binary.log", bytes(range(256)) * 4)
    put("canlog/empty.log", b"")
    foreign = ("(0.000100) vcan0 12345678#0011\n(0.000200) vcan0 01D00201#R\n"
               "(0.000250) vcan0 101#0F000F0000000000\n"
               "(0.000300) vcan0 124##100112233445566778899AABB\n(0.000400) vcan0 20000080#0000000000000000\n"
               "(0.000500) vcan0 7E5#00\n")
    put("canlog/foreign_frames.log", foreign + good)
    put("canlog/nul_line.log", good.replace("\n", "\n\0junk\n", 1))


def replays(build: Path, tmp: Path) -> None:
    raw = tmp / "g.hdraw"
    run(str(build / "sim/hdsim"), str(ROOT / "sim/scenarios/paper_156.ini"), "--duration", "0.05",
        "--csv", str(tmp / "g.csv"), "--raw", str(raw))
    good = raw.read_bytes()
    put("host-input/good.hdraw", good)
    put("host-input/short_header.hdraw", good[:5])
    put("host-input/bad_magic.hdraw", b"XXXX" + good[4:])
    put("host-input/period_2ms.hdraw", good[:8] + struct.pack("<I", 2000) + good[12:])
    put("host-input/trailing.hdraw", good + b"\x01" * 7)
    put("host-input/empty.hdraw", b"")
    put("host-input/nvm_zero.bin", b"")
    nvm = tmp / "nvm.bin"
    run(str(build / "firmware/host/hdjoint-host"), "--sensors", "mock", "--duration", "0.001",
        "--nvm", str(nvm), "--calib", "6.6,0", "-q")
    put("host-output/nvm_good.bin", nvm.read_bytes())
    put("host-input/nvm_short.bin", b"\xff" * 100)


def text_bytes() -> None:
    """Configuration and scenario files with bytes no editor shows."""
    put("host-input/cfg_nul.cfg", b"gear_ratio = 100\0\nnode_id = 999\n")
    put("host-input/cfg_ctrl.cfg", b"gear_ratio = 100\x01\n")
    put("host-input/cfg_bad_utf8.cfg", b"# \xe9t\xe9\ngear_ratio = 100\n")
    put("scenario/nul_byte.ini", b"duration_s = 1\nnoise_nm = 0.1\0encoder_cpr = 1\n")
    put("scenario/ctrl_char.ini", b"duration_s = 1\x1b[0m\n")
    put("scenario/bad_utf8.ini", b"# caf\xe9\nduration_s = 1\n")
    put("scenario/cut_utf8.ini", b"duration_s = 1\n# \xc3")
    put("scenario/utf8_comment.ini", "# café, 5 N·m ±1 %\nduration_s = 0.01\n")
    put("scenario/crlf.ini", b"duration_s = 0.01\r\nnoise_nm = 0.01\r\n")
    put("scenario/binary.ini", bytes(range(1, 256)))
    put("scenario/long_line.ini", "duration_s = 1" + " " * 5000 + "\n")
    put("calib/nul.csv", b"experiment,direction,position_deg,torque_nm,bridge_v\n"
                         b"1,load,0,0,0.0\n1,lo\0ad,0,30,4.5\n")
    put("calib/non_utf8.csv", b"experiment,direction,position_deg,torque_nm,bridge_v\n"
                              b"# r\xe9sultats\n1,load,0,0,0.0\n")
    put("canlog/cfg_nul.cfg", b"r_nm2 = 0.0004\0\ntelemetry_rate_hz = 100\n")
    put("canlog/cfg_non_utf8.cfg", b"# \xff\nr_nm2 = 0.0004\n")


def campaigns(build: Path) -> None:
    exe = str(build / "sim/hdsim-campaign")
    for name, args in (("good", ["--spread", "0.01", "--seed", "3"]),):
        out = HERE / "calib" / f"{name}.csv"
        run(exe, *args, "-o", str(out))
    good = (HERE / "calib/good.csv").read_text().splitlines()
    header = [ln for ln in good if not ln.startswith("#")][0]
    rows = [ln for ln in good if not ln.startswith("#")][1:]
    # two points per experiment: 0 and +FS, loading only
    keep = []
    for e in sorted({r.split(",")[0] for r in rows}, key=int):
        mine = [r for r in rows if r.split(",")[0] == e and r.split(",")[1] == "load"]
        fs = max(float(r.split(",")[3]) for r in mine)
        keep.append(next(r for r in mine if float(r.split(",")[3]) == 0.0))
        keep.append(next(r for r in mine if float(r.split(",")[3]) == fs))
    put("calib/two_points.csv", "\n".join([header] + keep) + "\n")
    put("calib/one_direction.csv", "\n".join([header] + [r for r in rows if ",load," in r]) + "\n")
    put("calib/single.csv", "\n".join([header] + [r for r in rows if r.startswith("1,")]) + "\n")
    many = [header] + [f"{e},{d},{p},{t},{v}" for e in range(1, 34)
                       for _, d, p, t, v in (r.split(",") for r in rows if r.startswith("1,"))]
    put("calib/33_experiments.csv", "\n".join(many) + "\n")
    pts = [header] + [r for r in rows if r.startswith("1,")] * 4
    pts += [r for r in rows if r.startswith("2,")]
    put("calib/84_points.csv", "\n".join(pts) + "\n")
    huge = [header] + rows[:40] + [rows[40].rsplit(",", 1)[0] + ",1e39"] + rows[41:]
    put("calib/huge_value.csv", "\n".join(huge) + "\n")


def _team_bag(path: Path, joints, stamps_ns, extra=(), storage="mcap", effort=True) -> None:
    """A bag as another team's logger writes it: JointState of `joints`
    (position, velocity, effort made up), plus (topic, msgtype, msg) extras."""
    import numpy as np
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    bag = path.with_suffix("") if path.suffix else path
    with Writer(bag, version=9, storage_plugin=plugin) as w:
        if joints:
            js = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        conns = {t: w.add_connection(t, ty, typestore=ts) for t, ty, _ in extra}
        # log time: when the logger got it (in order); header.stamp: as given
        for k, (ns, log_ns) in enumerate(zip(stamps_ns, sorted(stamps_ns))):
            sec, nsec = divmod(int(ns), 10**9)
            n = len(joints)
            msg = T["sensor_msgs/msg/JointState"](
                header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                    sec=sec, nanosec=nsec), frame_id=""), name=list(joints),
                position=np.full(n, 0.001 * k), velocity=np.full(n, 1.0),
                effort=np.full(n, 2.0 + 0.01 * k) if effort else np.zeros(0))
            if joints:
                w.write(js, int(log_ns), ts.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
            for t, ty, m in extra:
                w.write(conns[t], int(log_ns), ts.serialize_cdr(m, ty))
    if path.suffix == ".mcap":          # a bare .mcap file, as `ros2 bag` keeps none
        (bag / f"{bag.name}.mcap").rename(path)
        for f in bag.iterdir():
            f.unlink()
        bag.rmdir()


def bags(build: Path, tmp: Path) -> None:
    """MCAP files and rosbag2 folders for `hdsense analyze` (class ros2)."""
    import shutil
    from rosbags.typesys import Stores, get_typestore
    T = get_typestore(Stores.ROS2_HUMBLE).types
    out = HERE / "ros2"
    for old in out.glob("*"):
        if old.suffix != ".case":
            shutil.rmtree(old) if old.is_dir() else old.unlink()
    log = tmp / "short.log"
    run(str(build / "firmware/host/hdjoint-host"), "--sensors", "mock", "--duration", "0.2",
        "--can", f"log:{log}", "-q")
    subprocess.run([sys.executable, "-m", "hdtools.cli", "canlog", "convert", str(log),
                    "--joint", "wrist", "--mcap", str(out / "short.mcap")], check=True,
                   stdout=subprocess.DEVNULL, env=dict(os.environ, PYTHONPATH=str(ROOT / "tools")))
    data = (out / "short.mcap").read_bytes()
    put("ros2/truncated.mcap", data[:len(data) // 2])       # a recording cut off mid-chunk
    put("ros2/not_mcap.mcap", "t_s,torque_nm\n0,1\n")
    put("ros2/empty.mcap", b"")
    stamps = [1_700_000_000_000_000_000 + k * 1_000_000 for k in range(100)]
    _team_bag(out / "two_joints.mcap", ["shoulder", "wrist"], stamps)
    _team_bag(out / "no_jointstate.mcap", [], stamps[:3], extra=[
        ("/hdjoint/wrist/torque_raw_nm", "std_msgs/msg/Float64",
         T["std_msgs/msg/Float64"](data=1.0)),
        ("/chatter", "std_msgs/msg/String", T["std_msgs/msg/String"](data="hello"))])
    _team_bag(out / "wrong_type.mcap", ["wrist"], stamps, extra=[
        ("/hdjoint/wrist/motor_angle_rad", "std_msgs/msg/Float32",
         T["std_msgs/msg/Float32"](data=1.0))])
    shuffled = stamps[::2] + stamps[1::2][::-1]
    _team_bag(out / "shuffled.mcap", ["wrist"], shuffled)
    _team_bag(out / "sqlite_no_effort", ["wrist"], stamps, storage="sqlite3", effort=False)
    _team_bag(out / "version_10", ["wrist"], stamps[:10])
    meta = out / "version_10" / "metadata.yaml"
    meta.write_text(meta.read_text().replace("version: 9", "version: 10"))
    (out / "bad_yaml").mkdir()
    (out / "bad_yaml" / "metadata.yaml").write_text("rosbag2_bagfile_information: [\n")


FLEET_INI = """duration_s = 5
ts_s = 0.005
seed = {seed}
gear_ratio = {ratio}
output_encoder_cpr = 65536
motor_speed_profile = 0:80, 2.5:-110, 5:90
load_sine = 3 : 4 : 0
ripple = motor : 2 : 1.0 : 0.3
noise_nm = 0.02
feedforward = 1
feedforward.load_scale = 1
feedforward.inertia_kgm2 = 0.1
"""
FLEET_COLUMNS = ("t_s", "motor_angle_rad", "output_angle_rad", "torque_nm", "torque_feedforward_nm")


def fleet_log(build: Path, tmp: Path, rel: str, seed: int, ratio: int = 100) -> None:
    """A 5 s, 200 Hz hdsim log with only the columns hdsense fleet reads."""
    ini, csv = tmp / "f.ini", tmp / "f.csv"
    ini.write_text(FLEET_INI.format(seed=seed, ratio=ratio))
    run(str(build / "sim/hdsim"), str(ini), "--csv", str(csv))
    rows = [r.split(",") for r in csv.read_text().splitlines()]
    idx = [rows[0].index(c) for c in FLEET_COLUMNS]
    put(rel, "\n".join(",".join(r[i] for i in idx) for r in rows) + "\n")


def fleets(build: Path, tmp: Path) -> None:
    """hdsense fleet: good logs, one of another gear ratio, a corrupt one,
    one without identity, a sidecar, a bad sidecar."""
    fleet_log(build, tmp, "fleet/fl/j001/2026-01-05T08-00-00.csv", 1)
    fleet_log(build, tmp, "fleet/fl/j001/2026-01-06T08-00-00.csv", 2)
    fleet_log(build, tmp, "fleet/fl/j002/2026-01-05T08-00-00.csv", 3, ratio=160)
    put("fleet/fl/j002/2026-01-06T08-00-00.csv", b"t_s,torque_nm\n\x00\x01\xff garbage\n")
    fleet_log(build, tmp, "fleet/fl/j003/run.csv", 4)
    put("fleet/fl/j003/run.csv.json", '{"joint": "j003", "start_utc": "2026-01-05T09:00:00Z"}\n')
    put("fleet/fl/j003/other.csv", "t_s,torque_nm\n")
    put("fleet/fl/j003/other.csv.json", '{"joint": "j003", "start_utc": \n')
    put("fleet/fl/misc/notes.csv", "t_s,torque_nm\n0,1\n")
    put("fleet/bad/j9/2026-01-05T08-00-00.csv", b"\x00" * 64)


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    build = Path(sys.argv[1]).resolve()
    with tempfile.TemporaryDirectory() as tmp:
        canlogs(build, Path(tmp))
        replays(build, Path(tmp))
        bags(build, Path(tmp))
        fleets(build, Path(tmp))
    text_bytes()
    campaigns(build)
    return 0


if __name__ == "__main__":
    sys.exit(main())
