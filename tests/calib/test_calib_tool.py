"""End to end: hdsim-campaign -> calibration CSV -> `hdsense calib` (C library
through ctypes).  References: the simulator's injected ground truth, numpy
double-precision least squares, zlib's CRC-32 and the documented byte layout."""
from __future__ import annotations

import json
import math
import os
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]

from hdtools import native
from hdtools.calibtool import lib as L


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


def experiments(d: dict) -> list[dict]:
    """The report's per-experiment fits: hdsim-campaign's default campaign
    has 8 (a shorter list would let a loop over it pass on nothing)."""
    assert len(d["experiments"]) == 8, len(d["experiments"])
    return d["experiments"]


def full_range(d: dict) -> list[dict]:
    """The full-scale half of the campaign (4 positions at full range, 4 at
    --low-range)."""
    fs = max(f["full_scale_nm"] for f in experiments(d))
    full = [f for f in d["experiments"] if f["full_scale_nm"] == fs]
    assert len(full) == 4, [f["full_scale_nm"] for f in d["experiments"]]
    return full


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

# The simulated campaign draws each experiment's gain as 6.60 (1 + 0.02 z),
# z standard normal, used as drawn.  The estimator's figures are then random
# too: for n experiments (n-1) s^2 / sigma^2 is chi-square(n-1), s the
# sample std of the fitted gains and sigma^2 = (0.02 x 6.60)^2 plus the fit
# noise (mean se^2 of the per-experiment gains); the mean gain's t statistic
# has n-1 degrees of freedom.  Checked over many independent campaigns
# against those distributions (scipy), not against "2.0 %".  The same
# figures are written into docs/how-to/calibration.md by calib_doc.py.
import calib_doc
from calib_doc import N_CAMPAIGNS, N_EXP, TRUE_GAIN, TRUE_SPREAD, spread_interval  # noqa: F401


def campaign_figures(tmp_path: Path, seed: int) -> dict:
    return calib_doc.campaign_figures(tmp_path, seed)


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("campaigns")
    return [campaign_figures(tmp, seed) for seed in range(1, N_CAMPAIGNS + 1)]


def test_consistency_follows_its_chi_distribution(campaigns):
    from scipy import stats
    sigma2 = np.array([(TRUE_SPREAD * TRUE_GAIN) ** 2 + c["se2"] for c in campaigns])
    q = np.array([(N_EXP - 1) * c["std"] ** 2 for c in campaigns]) / sigma2
    ks = stats.kstest(q, stats.chi2(N_EXP - 1).cdf)
    # rescaled draws (the old round trip) give q = 7 every time: p ~ 0
    assert ks.pvalue > 0.01, ks
    assert 0.5 < np.std(q) / math.sqrt(2 * (N_EXP - 1)) < 1.5


def test_spread_intervals_cover_the_true_spread(campaigns):
    covered = [lo <= TRUE_SPREAD <= hi
               for lo, hi in (spread_interval(c["consistency"]) for c in campaigns)]
    rate = np.mean(covered)
    # binomial(300, 0.95): sd 1.26 %; 3.5 sd either side
    assert 0.906 <= rate <= 0.994, rate


def test_mean_gain_intervals_cover_the_true_gain(campaigns):
    from scipy import stats
    tq = stats.t.ppf(0.975, N_EXP - 1)
    covered = [abs(c["mean"] - TRUE_GAIN) <= tq * c["std"] / math.sqrt(N_EXP) for c in campaigns]
    assert 0.906 <= np.mean(covered) <= 0.994, np.mean(covered)


def test_docs_hold_the_measured_numbers(campaigns):
    """docs/how-to/calibration.md's measured table and Table I paragraph are what
    calib_doc.py computes now (re-run it after a change)."""
    assert calib_doc.update(check=True, figs=campaigns) == 0, "run tests/calib/calib_doc.py"


def test_table1_shaped_report(tmp_path):
    """One campaign in the shape of Table I: the report's figures are the
    estimator's and its 95 % interval for the spread contains the truth."""
    csv = sim(tmp_path, "t1", "--gain", "6.60", "--spread", "0.02", "--seed", "1")
    d, p = report(tmp_path, csv)
    assert p.returncode == 0 and "ACCEPTED" in p.stdout
    assert f"{d['gain_nm_per_v']:.2f} Nm/Volts" in p.stdout
    assert f"{100 * d['consistency']:.1f}%" in p.stdout
    lo, hi = spread_interval(d["consistency"])
    assert lo <= TRUE_SPREAD <= hi, (lo, hi)
    assert not d["nonlinearity_detected"] and not d["hysteresis_detected"]
    assert d["position"]["testable"] and not d["position"]["detected"]


def test_fits_agree_with_numpy_reference(tmp_path):
    """Per-experiment gain, offset and standard error against numpy (double)."""
    csv = sim(tmp_path, "np", "--spread", "0.01", "--noise", "0.003", "--seed", "11")
    d, _ = report(tmp_path, csv)
    rows = [ln.split(",") for ln in csv.read_text().splitlines()
            if ln and not ln.startswith("#")][1:]
    for f in experiments(d):
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
    for f in experiments(d):
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


def _rows(exp: str, pos: float, pts) -> str:
    return "".join(f"{exp},{d},{pos},{t},{t / 6.6 + 0.001 * ((i * 7) % 3 - 1):.6f}\n"
                   for i, (d, t) in enumerate(pts))


FULL = [("load", 0), ("load", 20), ("load", 40), ("load", 60), ("unload", 40), ("unload", 20),
        ("unload", 0), ("load", -20), ("load", -40), ("load", -60), ("unload", -40),
        ("unload", -20), ("unload", 0)]


def test_what_the_data_cannot_show_is_not_measurable(tmp_path):
    """2 points per experiment: no nonlinearity, no hysteresis; loading only:
    no hysteresis; 2 positions: no position dependence.  Reported as not
    measurable (null in JSON, never 0.000), rejected, no record."""
    two = HEADER + "".join(_rows(str(e), 45.0 * (e % 4), [("load", 0), ("load", 60)])
                           for e in range(8))
    f = tmp_path / "two.csv"
    f.write_text(two)
    rec = tmp_path / "r.bin"
    d, p = report(tmp_path, f, "--record", str(rec))
    assert p.returncode == 1 and not rec.exists()
    assert "NOT MEASURABLE in any experiment" in p.stdout
    effects = [ln for ln in p.stdout.splitlines() if ln.startswith(("  nonlinearity", "  hysteresis"))]
    assert len(effects) == 2 and not any(ch.isdigit() for ln in effects for ch in ln.split("(")[0])
    assert d["nonlinearity_pct_fs"] is None and d["hysteresis_pct_fs"] is None
    assert not d["nonlinearity_measurable"] and not d["hysteresis_measurable"]
    assert any("not measurable" in r for r in d["reject_reasons"])
    # loading only, full cycle of levels: nonlinearity yes, hysteresis no
    one_dir = HEADER + "".join(_rows(str(e), 45.0 * (e % 4), [x for x in FULL if x[0] == "load"])
                               for e in range(8))
    f.write_text(one_dir)
    d, p = report(tmp_path, f)
    assert d["nonlinearity_measurable"] and not d["hysteresis_measurable"]
    assert d["nonlinearity_pct_fs"] is not None and d["hysteresis_pct_fs"] is None
    assert p.returncode == 1
    # the whole cycle but two positions only: position not measurable
    two_pos = HEADER + "".join(_rows(str(e), 90.0 * (e % 2), FULL) for e in range(8))
    f.write_text(two_pos)
    d, p = report(tmp_path, f)
    assert d["nonlinearity_measurable"] and d["hysteresis_measurable"]
    assert not d["position"]["testable"] and p.returncode == 1
    assert "position dependence NOT MEASURABLE" in p.stdout
    # the user may accept what is there
    d, p = report(tmp_path, f, "--allow-unmeasurable", "--record", str(rec))
    assert p.returncode == 0 and d["accepted"] and rec.stat().st_size == 64


def test_single_experiment_has_no_consistency(tmp_path):
    f = tmp_path / "one.csv"
    f.write_text(HEADER + GOOD.split("2,")[0])
    p = tool(str(f))
    assert p.returncode == 2
    assert "single experiment" in p.stderr and "n/a" in p.stdout


def test_missing_file(tmp_path):
    p = tool(str(tmp_path / "nope.csv"))
    assert p.returncode == 2 and "cannot read" in p.stderr
