"""Speed and memory benchmark: one hour of 1 kHz data through the whole
analysis.

    tools/hdsense analyze --bench-hour

Simulates one hour with hdsim (the slowload test scenario: varying speed
with reversals, an unknown slow load, an undeclared output order 2),
writes the CSV to a temporary directory, then times loading + the full
analysis (every C filter re-run included) in a child process and reads its
peak resident memory.  The baseline, measured in the same run: loading the
CSV and one plain replay through the C filter, the least any analysis of
the log must do.  Prints numbers and the ratio; it is a benchmark, not a
pass/fail test."""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .. import native

SCENARIO = Path(__file__).resolve().parents[3] / "tests" / "tools" / "scenarios" / "slowload.ini"
HOUR_S = 3600.0

_CHILD = r"""
import json, resource, sys, time
sys.path.insert(0, {tools!r})
t0 = time.perf_counter()
if {baseline!r}:
    from hdtools.analysis import loading, replay
    from hdtools.analysis.model import Model
    d = loading.load({csv!r})
    t1 = time.perf_counter()
    m = Model.starting(100.0, d.ts_s, 0.02, [2, 4], [1])
    replay.metrics(replay.replay(d, m))
    out = {{"load_s": t1 - t0, "samples": d.n}}
else:
    from hdtools.analysis import pipeline
    rep = pipeline.analyze({csv!r}, log=lambda *a: None)
    out = {{"summary": rep["summary"], "samples": rep["data"]["samples"],
           "ts_s": rep["data"]["ts_s"],
           "replays": rep["data"]["replays_full_record_equivalent"]}}
out["elapsed_s"] = time.perf_counter() - t0
out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps(out))
"""


def _child(csv, baseline):
    tools = str(Path(__file__).resolve().parents[2])
    code = _CHILD.format(tools=tools, csv=str(csv), baseline=baseline)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main(duration_s: float = HOUR_S) -> int:
    print(run(duration_s))
    return 0


def run(duration_s: float = HOUR_S) -> str:
    """The benchmark's report (text)."""
    sim = native.find_file("hdsim", target="hdsim_cli")
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "hour.csv"
        t0 = time.perf_counter()
        subprocess.run([str(sim), str(SCENARIO), "--duration", str(duration_s),
                        "--set", "ripple=output:2:0.8:0.4", "--csv", str(csv)],
                       check=True, capture_output=True)
        t_sim = time.perf_counter() - t0
        size_mb = csv.stat().st_size / 1e6
        base = _child(csv, True)
        full = _child(csv, False)
    n = full["samples"]
    lib = native.find_file("libhdfilter.so", target="hdfilter_shared")
    return "\n".join([
        f"analyze-speed: {n} samples ({n * full['ts_s'] / 3600:.2f} h at "
        f"{1 / full['ts_s']:.0f} Hz), CSV {size_mb:.0f} MB, filter library from "
        f"{lib.parent.parent.name}",
        f"  simulate + write CSV      : {t_sim:7.2f} s (not part of the analysis)",
        f"  baseline: load + 1 replay : {base['elapsed_s']:7.2f} s (load {base['load_s']:.2f} s), "
        f"peak {base['peak_rss_mb']:.0f} MB",
        f"  load + full analysis      : {full['elapsed_s']:7.2f} s "
        f"({n / full['elapsed_s'] / 1e6:.2f} M samples/s, {full['replays']:.1f} full-record "
        f"replays), peak {full['peak_rss_mb']:.0f} MB",
        f"  ratio to the baseline     : {full['elapsed_s'] / base['elapsed_s']:.2f} x time, "
        f"{full['peak_rss_mb'] / base['peak_rss_mb']:.2f} x memory",
        f"  result                    : {full['summary']}"])
