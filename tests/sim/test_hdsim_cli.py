"""The hdsim command line: CSV columns, the raw stream of docs/reference/raw-stream.md,
error handling, and the paper's demo scenario (lines at 312 and 624 rad/s)."""
from __future__ import annotations

import os
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCEN = ROOT / "sim" / "scenarios"
COLUMNS = ("t_s,motor_angle_rad,output_angle_rad,motor_velocity_rad_s,output_velocity_rad_s,"
           "torque_nm,torque_true_nm,ripple_true_nm,bridge_counts,motor_counts,output_counts")


def hdsim() -> Path:
    bdir = Path(os.environ.get("HD_BUILD_DIR", ROOT / "build" / "host-release"))
    exe = bdir / "sim" / "hdsim"
    if not exe.exists():
        if os.environ.get("HD_BUILD_DIR"):  # under CTest the build must have made it
            pytest.fail(f"{exe} missing from the build tree")
        pytest.skip(f"{exe} not built")
    return exe


def run(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run([str(hdsim()), *args], capture_output=True, text=True, check=check)


def load_csv(path: Path) -> np.ndarray:
    return np.genfromtxt(path, delimiter=",", names=True)


def nominal(scenario: Path) -> dict[str, float]:
    out = run(str(scenario), "--nominal").stdout
    return {k: float(v) for k, v in (line.split("=") for line in out.split())}


def test_csv_and_raw_agree_and_follow_the_format(tmp_path: Path) -> None:
    csv, raw = tmp_path / "o.csv", tmp_path / "o.hdraw"
    run(str(SCEN / "reversal.ini"), "--duration", "2", "--csv", str(csv), "--raw", str(raw))
    assert csv.read_text().splitlines()[0] == COLUMNS
    d = load_csv(csv)
    assert len(d) == 2000
    blob = raw.read_bytes()
    magic, version, rsize, ts_us, reserved = struct.unpack_from("<4sHHII", blob, 0)
    assert (magic, version, rsize, ts_us, reserved) == (b"HDRW", 1, 16, 1000, 0)
    assert len(blob) == 16 + 16 * 2000
    rec = np.frombuffer(blob[16:], dtype=np.dtype(
        [("counts", "<i4"), ("motor", "<u4"), ("output", "<u4"), ("flags", "<u2"), ("res", "<u2")]))
    assert np.array_equal(rec["counts"], d["bridge_counts"].astype(np.int64))
    assert np.array_equal(rec["motor"], d["motor_counts"].astype(np.uint64))
    assert np.array_equal(rec["output"], d["output_counts"].astype(np.uint64))
    assert np.all(rec["flags"] == 4)  # reversal.ini has an output encoder, nothing saturates
    assert np.all(rec["res"] == 0)
    # torque_nm is the counts through the nominal calibration
    n = nominal(SCEN / "reversal.ini")
    expect = (d["bridge_counts"] * n["adc_v_per_count"] - n["offset_v"]) * n["gain_nm_per_v"]
    assert np.allclose(d["torque_nm"], expect, atol=1e-5)
    # the reversal: motor speed goes from +100 to -100 rad/s, angles in the ratio
    assert np.allclose(d["output_angle_rad"], d["motor_angle_rad"] / 100.0, rtol=1e-8, atol=1e-9)
    # the motor counter (4096/rev) counts back down, wrapping through 0 if needed
    cpr = 4096
    expect_counts = np.floor(d["motor_angle_rad"] * cpr / (2 * np.pi)) % 2**32
    close = np.abs(d["motor_angle_rad"] * cpr / (2 * np.pi) % 1 - 0.5) < 0.499  # not on an edge
    assert np.array_equal(expect_counts[close], d["motor_counts"][close])


def test_paper_demo_has_lines_at_312_and_624_rad_s(tmp_path: Path) -> None:
    csv = tmp_path / "p.csv"
    run(str(SCEN / "paper_156.ini"), "--csv", str(csv))
    d = load_csv(csv)
    hold = d["t_s"] >= 1.0
    assert np.allclose(d["motor_velocity_rad_s"][hold], 156.0)
    x = (d["torque_nm"] - d["torque_true_nm"])[hold]
    t = d["t_s"][hold]
    w = np.arange(100.0, 800.0, 0.5)  # rad/s
    power = np.abs(np.exp(-1j * np.outer(w, t)) @ (x - x.mean())) ** 2
    peaks = w[np.argsort(power)[::-1]]
    top = sorted({round(p / 5) * 5 for p in peaks[:6]})
    assert 310 in top or 315 in top
    assert 625 in top or 620 in top
    # ripple-free truth during the hold: J*0 + b*1.56 + Fc + 3 N m load
    assert np.allclose(d["torque_true_nm"][hold], 1.0 * 1.56 + 0.8 + 3.0, atol=1e-6)


@pytest.mark.parametrize("text,needle", [
    ("duration_s = 1\nbogus = 2\n", ":2: unknown key \"bogus\""),
    ("ripple = motor : two : 1 : 0\n", ":1: ripple: order"),
    ("gear_ratio = 0\n", ":1: gear_ratio: must be > 0"),
])
def test_bad_scenario_exits_2_with_file_and_line(tmp_path: Path, text: str, needle: str) -> None:
    bad = tmp_path / "bad.ini"
    bad.write_text(text)
    r = run(str(bad), "--csv", str(tmp_path / "x.csv"), check=False)
    assert r.returncode == 2
    assert f"{bad}{needle}" in r.stderr


def test_bad_command_lines(tmp_path: Path) -> None:
    s = str(SCEN / "paper_156.ini")
    assert run(check=False).returncode == 2
    assert run(s, check=False).returncode == 2  # no --csv
    assert run(s, "--csv", "-", "--duration", "-1", check=False).returncode == 2
    r = run(s, "--csv", "-", "--set", "nope=1", check=False)
    assert r.returncode == 2 and "unknown key" in r.stderr
    r = run(s, "--csv", str(tmp_path / "missing" / "x.csv"), check=False)
    assert r.returncode == 3 and "cannot write" in r.stderr


def test_all_example_scenarios_run(tmp_path: Path) -> None:
    for ini in sorted(SCEN.glob("*.ini")):
        r = run(str(ini), "--duration", "0.5", "--csv", str(tmp_path / "o.csv"), check=False)
        assert r.returncode == 0, (ini, r.stderr)
