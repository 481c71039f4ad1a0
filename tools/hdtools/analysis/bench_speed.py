"""Speed benchmark: one hour of 1 kHz data through the whole analysis.

    tools/hdsense analyze --bench-hour

Simulates one hour with hdsim (the motor6 test scenario, speed cycling,
extra motor order 6), writes the CSV to a temporary directory, then times
loading + the full analysis (every C filter re-run included).  Prints
numbers; it is a benchmark, not a pass/fail test."""
from __future__ import annotations

import subprocess
import tempfile
import time
from pathlib import Path

from .. import native
from . import pipeline

SCENARIO = Path(__file__).resolve().parents[3] / "tests" / "tools" / "scenarios" / "motor6.ini"
HOUR_S = 3600.0


def main(duration_s: float = HOUR_S) -> int:
    sim = native.find_file("hdsim", target="hdsim_cli")
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "hour.csv"
        t0 = time.perf_counter()
        subprocess.run([str(sim), str(SCENARIO), "--duration", str(duration_s), "--csv", str(csv)],
                       check=True, capture_output=True)
        t_sim = time.perf_counter() - t0
        size_mb = csv.stat().st_size / 1e6
        t1 = time.perf_counter()
        rep = pipeline.analyze(csv, log=lambda *a: None)
        t_an = time.perf_counter() - t1
    n = rep["data"]["samples"]
    rounds = len(rep["history"]) - 1 + sum(1 for e in rep["effects"] if not e["added"])
    print(f"analyze-speed: {n} samples ({n * rep['data']['ts_s'] / 3600:.2f} h at "
          f"{1 / rep['data']['ts_s']:.0f} Hz), CSV {size_mb:.0f} MB")
    print(f"  simulate + write CSV : {t_sim:7.2f} s (not part of the analysis)")
    print(f"  load + analyse       : {t_an:7.2f} s  ({n / t_an / 1e6:.2f} M samples/s, "
          f"~{rounds + 1} filter replays)")
    print(f"  result               : {rep['summary']}")
    return 0
