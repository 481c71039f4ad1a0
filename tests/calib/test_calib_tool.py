"""End to end: hdsim-campaign -> calibration CSV -> `hdsense calib` (C library
through ctypes).  References: the simulator's injected ground truth, numpy
double-precision least squares, zlib's CRC-32 and the documented byte layout."""
from __future__ import annotations

import json
import math
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

from hdtools import native  # noqa: E402
from hdtools.calibtool import lib as L  # noqa: E402


def sim(tmp_path: Path, name: str, *args: str) -> Path:
    out = tmp_path / f"{name}.csv"
    subprocess.run([str(native.executable("hdsim-campaign")), *args, "-o", str(out)],
                   check=True)
    return out


def tool(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    return subprocess.run([str(ROOT / "tools" / "hdsense"), "calib", *args],
                          capture_output=True, text=True, env=env)


def report(tmp_path: Path, csv: Path, *args: str) -> tuple[dict, subprocess.CompletedProcess]:
    js = tmp_path / (csv.stem + ".json")
    p = tool(str(csv), "--json", str(js), *args)
    assert p.returncode in (0, 1), p.stderr
    return json.loads(js.read_text()), p


def full_range(d: dict) -> list[dict]:
    fs = max(f["full_scale_nm"] for f in d["experiments"])
    return [f for f in d["experiments"] if f["full_scale_nm"] == fs]


# ---------------------------------------------------------------- CRC and record

def test_crc32_matches_zlib():
    rng = np.random.default_rng(7)
    assert L.crc32(b"123456789") == 0xCBF43926
    for n in (0, 1, 3, 60, 64, 1000):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert L.crc32(data) == zlib.crc32(data)


def test_record_layout_matches_documentation():
    data = L.encode_record(6.61, -0.0125, 1700000000, "HD-0042", 0.021, sequence=5)
    assert len(data) == 64
    magic, ver, length, seq, gain, off, date = struct.unpack_from("<4sHHIffI", data, 0)
    serial = data[24:40]
    cons, = struct.unpack_from("<f", data, 40)
    crc, = struct.unpack_from("<I", data, 60)
    assert (magic, ver, length, seq, date) == (b"HDCR", 1, 64, 5, 1700000000)
    assert gain == pytest.approx(6.61, rel=1e-7) and off == pytest.approx(-0.0125, rel=1e-7)
    assert serial == b"HD-0042".ljust(16, b"\0")
    assert cons == pytest.approx(0.021, rel=1e-6)
    assert data[44:60] == bytes(16)
    assert crc == zlib.crc32(data[:60])
    rc, rec, s = L.decode_record(data)
    assert rc == 0 and s == 5 and rec.serial == b"HD-0042"


# ---------------------------------------------------------------- Table I

@pytest.mark.parametrize("seed", ["1", "2", "3"])
def test_table1_campaign_reports_660_and_2_percent(tmp_path, seed):
    csv = sim(tmp_path, f"t1_{seed}", "--gain", "6.60", "--spread", "0.02", "--seed", seed)
    d, p = report(tmp_path, csv)
    assert p.returncode == 0 and "ACCEPTED" in p.stdout
    assert "6.60 Nm/Volts" in p.stdout and "2.0%" in p.stdout
    assert d["gain_nm_per_v"] == pytest.approx(6.60, abs=0.01)
    assert d["consistency"] == pytest.approx(0.020, abs=0.001)
    assert not d["nonlinearity_detected"] and not d["hysteresis_detected"]
    assert d["position"]["testable"] and not d["position"]["detected"]


def test_fits_agree_with_numpy_reference(tmp_path):
    """Per-experiment gain, offset and standard error against numpy (double)."""
    csv = sim(tmp_path, "np", "--spread", "0.01", "--noise", "0.003", "--seed", "11")
    d, _ = report(tmp_path, csv)
    rows = [ln.split(",") for ln in csv.read_text().splitlines()
            if ln and not ln.startswith("#")][1:]
    for f in d["experiments"]:
        sel = [r for r in rows if r[0] == f["experiment"]]
        t = np.array([float(r[3]) for r in sel])
        v = np.array([float(r[4]) for r in sel])
        A = np.column_stack([np.ones_like(t), t])
        coef, rss, *_ = np.linalg.lstsq(A, v, rcond=None)
        cov = rss[0] / (len(t) - 2) * np.linalg.inv(A.T @ A)
        slope = coef[1]
        assert f["gain_nm_per_v"] == pytest.approx(1 / slope, rel=2e-5)
        assert f["offset_v"] == pytest.approx(coef[0], abs=2e-6)
        assert f["gain_se_nm_per_v"] == pytest.approx(math.sqrt(cov[1, 1]) / slope**2, rel=1e-3)


def test_known_gain_and_offset_within_standard_errors(tmp_path):
    csv = sim(tmp_path, "se", "--gain", "6.2", "--offset", "0.04", "--placement-error", "0",
              "--noise", "0.004", "--seed", "5")
    d, _ = report(tmp_path, csv)
    for f in d["experiments"]:
        assert abs(f["gain_nm_per_v"] - 6.2) < 3.5 * f["gain_se_nm_per_v"]
        assert abs(f["offset_v"] - 0.04) < 3.5 * f["offset_se_v"]


# ---------------------------------------------------------------- injected effects

def test_clean_campaign_reports_none(tmp_path):
    csv = sim(tmp_path, "clean", "--seed", "4")
    d, p = report(tmp_path, csv)
    assert p.returncode == 0
    assert not d["nonlinearity_detected"] and not d["hysteresis_detected"]
    assert not d["position"]["detected"]
    assert "none detected" in p.stdout and d["reject_reasons"] == []


def test_nonlinearity_detected_with_right_size(tmp_path):
    csv = sim(tmp_path, "nl", "--nonlinearity", "0.5", "--noise", "0.0005", "--seed", "6")
    d, p = report(tmp_path, csv)
    assert d["nonlinearity_detected"] and not d["hysteresis_detected"]
    # 0.5 mV noise = 0.0055 % of 60 N m per point.
    for f in full_range(d):
        assert f["nonlinearity_detected"]
        assert f["nonlinearity_pct_fs"] == pytest.approx(0.5, abs=0.03)
    assert p.returncode == 0  # below the 1 % limit: reported, accepted
    csv = sim(tmp_path, "nl2", "--nonlinearity", "1.5", "--noise", "0.0005", "--seed", "6")
    d, p = report(tmp_path, csv)
    assert p.returncode == 1 and "nonlinearity above limit" in p.stdout
    assert d["nonlinearity_pct_fs"] == pytest.approx(1.5, abs=0.05)


def test_hysteresis_detected_with_right_size(tmp_path):
    csv = sim(tmp_path, "hy", "--hysteresis", "0.6", "--noise", "0.0005", "--seed", "8")
    d, _ = report(tmp_path, csv)
    assert d["hysteresis_detected"] and not d["nonlinearity_detected"]
    for f in full_range(d):
        assert f["hysteresis_detected"]
        assert f["hysteresis_pct_fs"] == pytest.approx(0.6, abs=0.03)


def test_position_dependence_detected_with_right_size(tmp_path):
    csv = sim(tmp_path, "pos", "--position-dep", "3", "--position-phase", "60", "--seed", "9")
    d, p = report(tmp_path, csv)
    pos = d["position"]
    assert pos["detected"]
    assert pos["amplitude_pct"] == pytest.approx(3.0, abs=0.15)
    assert pos["phase_deg"] == pytest.approx(60.0, abs=3.0)
    assert p.returncode == 1 and "gain depends on flexspline position" in p.stdout


# ---------------------------------------------------------------- outputs

def test_record_and_png_written(tmp_path):
    csv = sim(tmp_path, "out", "--spread", "0.01", "--seed", "2")
    rec, png = tmp_path / "r.bin", tmp_path / "p.png"
    d, p = report(tmp_path, csv, "--record", str(rec), "--png", str(png), "--serial", "SN7",
                  "--date", "1712345678")
    assert p.returncode == 0
    data = rec.read_bytes()
    assert len(data) == 64 and zlib.crc32(data[:60]) == struct.unpack_from("<I", data, 60)[0]
    gain, off, date = struct.unpack_from("<ffI", data, 12)
    assert gain == pytest.approx(d["gain_nm_per_v"], rel=1e-6)
    assert off == pytest.approx(d["offset_v"], abs=1e-7)
    assert date == 1712345678 and data[24:28] == b"SN7\0"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10000


def test_rejected_calibration_writes_no_record(tmp_path):
    csv = sim(tmp_path, "bad", "--spread", "0.05", "--seed", "2")
    rec = tmp_path / "r.bin"
    _, p = report(tmp_path, csv, "--record", str(rec))
    assert p.returncode == 1 and "not consistent" in p.stdout and not rec.exists()


def test_adc_counts_give_the_same_gain(tmp_path):
    v = sim(tmp_path, "v", "--seed", "3", "--noise", "0.001")
    c = sim(tmp_path, "c", "--seed", "3", "--noise", "0.001", "--counts-per-volt", "100000")
    dv, _ = report(tmp_path, v)
    dc, _ = report(tmp_path, c, "--counts-per-volt", "100000")
    assert dc["gain_nm_per_v"] == pytest.approx(dv["gain_nm_per_v"], rel=1e-5)
    p = tool(str(c))
    assert p.returncode == 2 and "--counts-per-volt" in p.stderr


# ---------------------------------------------------------------- bad input

HEADER = "experiment,direction,position_deg,torque_nm,bridge_v\n"
GOOD = ("1,load,0,0,0.0\n1,load,0,30,4.55\n1,load,0,60,9.09\n"
        "2,load,90,0,0.001\n2,load,90,30,4.54\n2,load,90,60,9.10\n")


@pytest.mark.parametrize("text,msg", [
    (HEADER.replace("bridge_v", "bridge_v,temperature") + "1,load,0,0,0,20\n",
     "unknown column(s) temperature"),
    ("experiment,direction,torque_nm,bridge_v\n1,load,0,0\n", "missing column(s) position_deg"),
    (HEADER + GOOD + "3,load,0,10,1.5\n", "experiment 3: fewer than two load points"),
    (HEADER + GOOD + "3,load,0,10,1.5\n3,unload,0,10,1.6\n", "all applied torques"),
    (HEADER + GOOD.replace("4.54", "nan"), "non-finite"),
    (HEADER + GOOD.replace("2,load,90,60", "2,load,90,inf"), "non-finite"),
    (HEADER + GOOD.replace("1,load,0,30", "1,sideways,0,30"), "not load or unload"),
    (HEADER + GOOD.replace("4.55", "4.5x"), "not a number"),
    (HEADER + GOOD.replace("1,load,0,60", "1,load,45,60"), "changes flexspline position"),
    (HEADER, "no data rows"),
    ("", "empty input"),
])
def test_bad_input_gets_clear_error(tmp_path, text, msg):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    p = tool(str(f))
    assert p.returncode == 2, p.stdout + p.stderr
    assert msg in p.stderr
    assert "Traceback" not in p.stderr


def test_single_experiment_has_no_consistency(tmp_path):
    f = tmp_path / "one.csv"
    f.write_text(HEADER + GOOD.split("2,")[0])
    p = tool(str(f))
    assert p.returncode == 2
    assert "single experiment" in p.stderr and "n/a" in p.stdout


def test_missing_file(tmp_path):
    p = tool(str(tmp_path / "nope.csv"))
    assert p.returncode == 2 and "cannot read" in p.stderr
