"""Smoke test of `tools/bench`: runs every part on tiny sizes and checks only
that the output is well formed (the benchmarks print numbers; they are not
pass/fail tests of accuracy or speed)."""
import json
import math
import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_quick_output_is_well_formed(tmp_path):
    env = dict(os.environ)
    proc = subprocess.run([str(ROOT / "tools" / "bench"), "--quick", "--skip", "target",
                           "--out", str(tmp_path)], capture_output=True, text=True, env=env,
                          timeout=110)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "RMS error against the ripple-free truth" in proc.stdout
    assert "Host updates per second" in proc.stdout

    res = json.loads((tmp_path / "results.json").read_text())
    assert res["machine"]["cpu"]
    scen = res["accuracy"]["scenarios"]
    assert set(scen) >= {"const156", "torque_step", "standstill"}
    for sc in scen.values():
        assert set(sc["methods"]) >= {"kf_recommended", "fw_commissioned", "kf_paper4",
                                      "kf_paper6", "butter_20db", "order_notch",
                                      "fourier_table", "ideal"}
        for m in sc["methods"].values():
            assert math.isfinite(m["rms_nm"]) and m["rms_nm"] >= 0.0
    assert res["goals"] and all(g["goal"] and g["rows"] for g in res["goals"])
    assert "The slow-torque goals" in proc.stdout
    for f in res["real"]["files"].values():
        assert f["segments"] and "kf_recommended" in f["median"]

    host = res["compute"]["host"]
    impls = {c["impl"] for c in host["compute"]}
    assert impls == {"hd_kf_step", "hd_pipeline_step", "dense_f32", "dense_f64_ref",
                     "hd_kf_step_v0"}
    assert {c["states"] for c in host["compute"]} >= {4, 6, 8}
    assert all(c["updates_per_s"] > 0 for c in host["compute"])
    assert all(m["hd_kf_bytes"] > 0 for m in host["memory"])

    assert (tmp_path / "results.md").read_text().count("|") > 100
    assert (tmp_path / "bench_accuracy.png").stat().st_size > 1000


def test_bench_compute_rejects_bad_arguments():
    from hdtools import native
    exe = native.executable("bench_compute")
    proc = subprocess.run([str(exe), "--steps", "0"], capture_output=True, text=True)
    assert proc.returncode == 2 and "usage" in proc.stderr
