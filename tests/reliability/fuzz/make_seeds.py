#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz harnesses (tests/reliability/fuzz/corpus/).

Run from the repository root after a build (the replay seed comes from the
hdsim executable):  python3 tests/reliability/fuzz/make_seeds.py [BUILD_DIR]
Layouts follow docs/design/firmware.md, docs/reference/raw-stream.md and calib/hd_calib_record.h.
Crash reproducers found later are added next to the seeds as crash-<name>.
"""
import pathlib
import shutil
import struct
import subprocess
import sys
import zlib

root = pathlib.Path(__file__).resolve().parents[3]
corpus = root / "tests/reliability/fuzz/corpus"
build = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else root / "build/host-debug"


def put(harness, name, data):
    d = corpus / harness
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data if isinstance(data, bytes) else data.encode())


# --- CAN command records: [sel, id_hi, flags, len, data[8]]
def rec(data8, tick=False, sel=0x80, flags=0, length=8):
    return bytes([sel | (0x40 if tick else 0), 0, flags, length]) + bytes(data8)


def cmd(op, token=1, a2=0, a3=0, tail=b"\0\0\0\0"):
    return bytes([op, token, a2, a3]) + tail


f32 = lambda v: struct.pack("<f", v)
put("can_cmd", "set_param_r", rec(cmd(0x20, 1, 1, 0, f32(0.5)), tick=True))
put("can_cmd", "add_blocks", rec(cmd(0x14)) + rec(cmd(0x10, 2, 200 & 255, 0, f32(1e-4)), True)
    + rec(cmd(0x11, 3, 100, 0, f32(1e-5)), True) + rec(cmd(0x12, 4, 0x88, 0x13, f32(1e-4)), True))
put("can_cmd", "tare_save_load", rec(struct.pack("<iI", 3000, 5), tick=True, sel=0x00 | 0x7F)
    + rec(cmd(0x30), True) + rec(cmd(0x31, 5, 0, 0, struct.pack("<I", 1700000000)), True)
    + rec(cmd(0x32, 6), True))
put("can_cmd", "get_node_reset", rec(cmd(0x21, 7, 11)) + rec(cmd(0x20, 8, 11, 0, f32(5.0)))
    + rec(cmd(0x40, 9), True) + rec(cmd(0x13, 10, 0, 0), True) + rec(cmd(0x01, 11, 0), True))
put("can_cmd", "malformed", rec(cmd(0x20), length=3) + rec(cmd(0x20), flags=0x08)
    + rec(cmd(0x77)) + rec(cmd(0x20, 1, 1, 0, f32(float("nan")))))

# --- firmware configuration text (docs/design/firmware.md)
put("config_text", "paper", "gear_ratio = 100\nr_nm2 = 1\np0_nm2 = 1000\noffset = off\n"
    "block = motor 2 1000\nblock = motor 4 1000\nblock = output 1 1000\ntelemetry_rate_hz = 1000\n")
put("config_text", "all_keys", "# every key\ngear_ratio 50\nr_nm2 = 4e-4\np0_nm2 = 0.3\np_max_nm2 = 1e6\n"
    "nyquist_fraction = 0.9\noffset = on\noffset_q_nm2 = 1.6e-5\noffset_is_sensor_error = off\n"
    "block = motor 2 1e-4\nblock = fixed 50 1e-4 off\ninertia_kgm2 = 0.1\nviscous_nm_s_rad = 1\n"
    "coulomb_nm = 0.8\ncoulomb_vel_eps_rad_s = 0.01\ntrack_bandwidth_hz = 20\nnode_id = 5\n"
    "filter = on\nmotor_cpr = 4096\noutput_cpr = 65536\nadc_volts_per_count = 3.0517578e-4\n"
    "torque_limit_nm = 150\nmax_motor_speed_rad_s = 800\n")
put("config_text", "bad_line", "gear_ratio = 100\nblock = sideways 2 1\n")

# --- scenarios: the example files
for p in sorted((root / "sim/scenarios").glob("*.ini")):
    shutil.copy(p, corpus.joinpath("scenario").mkdir(parents=True, exist_ok=True) or corpus / "scenario" / p.name)
put("scenario", "faults", "duration_s = 1\nencoder_fault = 0.1:0.2\nencoder_fault = 0.5:0.6\n"
    "output_encoder_cpr = 65536\nripple = fixed : 50 : 0.1 : 0\nadc_bits = 12\n")

# --- replay: a 50-record stream from hdsim, and a header-only one
hdsim = build / "sim/hdsim"
if hdsim.exists():
    out = corpus / "replay"
    out.mkdir(parents=True, exist_ok=True)
    subprocess.run([str(hdsim), str(root / "sim/scenarios/paper_156.ini"), "--duration", "0.05",
                    "--csv", "/dev/null", "--raw", str(out / "paper_50")], check=True)
    put("replay", "header_only", (out / "paper_50").read_bytes()[:16])
else:
    print(f"make_seeds: {hdsim} not built, replay seeds not written", file=sys.stderr)


# --- calibration NVM images (256 bytes, copy B at 128; calib/hd_calib_record.h)
def record(seq, gain, offset, version=1):
    body = struct.pack("<IHHIffI16sf16s", 0x52434448, version, 64, seq, gain, offset, 1700000000,
                       b"SN-0001", 0.02, bytes(16))
    return body + struct.pack("<I", zlib.crc32(body))


blank = b"\xff" * 64


def image(a, b):
    return a + b"\xff" * 64 + b + b"\xff" * 64


put("calib_record", "two_good", image(record(1, 6.6, 0.01), record(2, 6.5, 0.02)))
put("calib_record", "one_good", image(record(3, 6.6, 0.0), blank))
put("calib_record", "blank", b"\xff" * 256)
put("calib_record", "version2", image(record(1, 6.6, 0.0, 2), record(2, 6.6, 0.0, 2)))
put("calib_record", "neg_gain_fixup", bytes([1]) + image(record(1, -1.0, 0.0), blank)[1:])
print("seeds written to", corpus)
