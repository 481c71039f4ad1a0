"""docs/results/fleet.md's measured tables and docs/results/fleet.json, written by
the runs that measure them (nothing typed by hand):

    cd tools && ../.venv/bin/python -m hdmaint.fleet_bench --write [--ray-python PY]

1. Detection: simulated fleets of TUNE_SEEDS (the thresholds were looked at
   on these) and REPORT_SEEDS (held out: the numbers to quote), each run
   without the engine, scored against the truth.
2. Throughput: one fleet of long logs run directly (the task called in this
   process: the baseline), then on a LocalCluster of 1 and 2 workers, and,
   with --ray-python (a Python with ray installed: not a project
   dependency), on Ray with 1 and 2 workers (fleet_bench_ray.py); each REPEATS
   times, interleaved, the faster counting.  A benchmark: the numbers of
   one run on this machine, not pass/fail.
3. A paper estimate for 1000 joints x 8 h a day from the measured cost."""
from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from hdtools import docblock
from hdtools.fleet import job, simfleet, trends
from hdtools.safeio import Outputs

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "results" / "fleet.md"
RESULT = ROOT / "docs" / "results" / "fleet.json"
MEASURED, THRESHOLDS = "fleet-measured", "fleet-thresholds"      # hdtools.docblock blocks
TUNE_SEEDS = (1, 2)
REPORT_SEEDS = (3, 4)
DETECT_FLEET = {"n_joints": 12, "days": 14, "logs_per_day": 2, "log_s": 60.0}
SPEED_FLEET = {"n_joints": 16, "days": 3, "logs_per_day": 1, "log_s": 600.0, "seed": 11}
MEMORY_FLEET = {"n_joints": 1, "days": 1, "logs_per_day": 1, "log_s": 7200.0, "seed": 12}
MEMORY_CHUNKS_MB = (16, 4096)     # cut in chunks; whole (one task)
OPTIONS = {"gear_ratio": 100.0, "loop": False}
# Paper estimate: assumptions, said in the doc next to the result.
FLEET_JOINTS, HOURS_PER_DAY = 1000, 8.0
USD_PER_CORE_HOUR = 0.04     # an on-demand cloud vCPU-hour, order of magnitude


def _epoch_day(utc):
    from datetime import datetime, timezone
    from hdtools.fleet import catalog
    t = datetime.strptime(utc, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=timezone.utc)
    return (t - catalog.EPOCH).total_seconds() / 86400.0


def score(truth, doc) -> dict:
    """Per joint: the truth, what was flagged, how late (first flagged day
    minus onset), and for a sudden change the change point's error."""
    rows = {j["joint"]: j for j in doc["joints"]}
    out = []
    for tj in truth["joints"]:
        r = rows[tj["joint"]]
        e = {"joint": tj["joint"], "wear": tj["wear"], "flagged": r["flagged"],
             "alarms": r["alarms"]}
        if tj["wear"] != "none":
            onset = _epoch_day(tj["onset_utc"])
            firsts = [r["indicators"][a]["first_flagged_day"] for a in r["alarms"]]
            e["delay_days"] = min(firsts) - onset if firsts else None
            if tj["wear"] == "tooth":
                ind = r["indicators"]["new line motor 1x"]
                e["change_point_error_days"] = (ind["change_point_day"] - onset
                                                if ind["change_point"] else None)
        out.append(e)
    wear = [e for e in out if e["wear"] != "none"]
    return {"joints": out, "wearing": len(wear), "wearing_flagged": sum(e["flagged"] for e in wear),
            "healthy": len(out) - len(wear),
            "healthy_flagged": sum(e["flagged"] for e in out if e["wear"] == "none"),
            "max_delay_days": max((e["delay_days"] for e in wear if e.get("delay_days") is not None),
                                  default=None),
            "tooth_change_point_error_days": [e.get("change_point_error_days") for e in wear
                                              if e["wear"] == "tooth"]}


def detection(seed, tmp, hdsim) -> dict:
    root, store = Path(tmp) / f"fleet{seed}", Path(tmp) / f"store{seed}"
    truth = simfleet.generate(root, hdsim, seed=seed, **DETECT_FLEET)
    job.run([str(root)], store, OPTIONS, trends.load_thresholds(), direct=True, quiet=True)
    return {"seed": seed, **score(truth, json.loads((store / "report.json").read_text()))}


def _timed(root, store, options=OPTIONS, **kw):
    t0 = time.perf_counter()
    s = job.run([str(root)], store, options, trends.load_thresholds(), quiet=True, **kw)
    s["wall_s"] = time.perf_counter() - t0
    return s


def _row(name, workers, s, base_s):
    per_min = s["joint_hours"] / (s["engine_s"] / 60.0)
    return {"engine": name, "workers": workers, "logs": s["analysed"], "joint_hours": s["joint_hours"],
            "engine_s": s["engine_s"], "wall_s": s["wall_s"], "task_s": s["task_s"],
            "joint_hours_per_min": per_min, "joint_hours_per_min_per_worker": per_min / workers,
            "vs_direct": base_s / s["engine_s"],
            "peak_rss_mb_per_worker": max(s["max_rss_mb_per_worker"], default=None)}


REPEATS = 3     # each configuration twice, interleaved; the faster run counts (a shared machine)


def _dask(root, store, n):
    from hdtools.fleet import engine
    t0 = time.perf_counter()
    client = engine.connect(None, n, "2GiB")
    client.wait_for_workers(n)
    start_s = time.perf_counter() - t0
    try:
        s = _timed(root, store, client=client)
    finally:
        engine.close(client)
    s["startup_s"] = start_s
    return s


def _ray(root, n, ray_python):
    p = subprocess.run([ray_python, "-m", "hdmaint.fleet_bench_ray", str(root), str(n)],
                       cwd=ROOT / "tools", capture_output=True, text=True, check=True,
                       env=dict(os.environ, PYTHONPATH=str(ROOT / "tools")))
    s = json.loads(p.stdout.strip().splitlines()[-1])
    return dict(s, analysed=s["logs"], max_rss_mb_per_worker=[])


# What a robot's own 200 Hz log holds: the analysis' columns, no simulation truth
# (hdsim's CSV adds 9 columns of truth and counts the analysis never reads).
ROBOT_COLUMNS = ("t_s", "motor_angle_rad", "output_angle_rad", "torque_nm",
                 "torque_feedforward_nm")


def robot_logs(src: Path, dst: Path) -> None:
    """The fleet's logs again with ROBOT_COLUMNS only, the values' text
    unchanged (the same numbers, fewer bytes to parse)."""
    for f in sorted(src.rglob("*.csv")):
        out = dst / f.relative_to(src)
        out.parent.mkdir(parents=True, exist_ok=True)
        with open(f) as fh, open(out, "w") as oh:
            head = fh.readline().rstrip("\n").split(",")
            idx = [head.index(c) for c in ROBOT_COLUMNS]
            oh.write(",".join(ROBOT_COLUMNS) + "\n")
            oh.writelines(",".join(r[i] for i in idx) + "\n"
                          for r in (line.rstrip("\n").split(",") for line in fh))


def _best_of(configs) -> dict:
    best = {}
    for i in range(REPEATS):
        for name, n, run in configs:
            s = run(i)
            if (name, n) not in best or s["engine_s"] < best[(name, n)]["engine_s"]:
                best[(name, n)] = s
    return best


def _speed_rows(best, root) -> dict:
    csv_bytes = sum(f.stat().st_size for f in root.rglob("*.csv"))
    d = best[("direct (no engine)", 1)]
    rows = []
    for (name, n), s in best.items():
        r = _row(name + (f" {s['version']}" if "version" in s else ""), n, s, d["engine_s"])
        r["startup_s"] = s.get("startup_s")
        rows.append(r)
    one = next(r for r in rows if r["engine"] == "Dask LocalCluster" and r["workers"] == 1)
    two = next(r for r in rows if r["engine"] == "Dask LocalCluster" and r["workers"] == 2)
    return {"csv_bytes": csv_bytes, "rows": rows,
            "dask_overhead_1_worker": one["engine_s"] / d["engine_s"] - 1,
            "dask_speedup_2_workers": one["engine_s"] / two["engine_s"],
            "direct_s_per_joint_hour": d["engine_s"] / d["joint_hours"],
            "csv_bytes_per_joint_hour": csv_bytes / d["joint_hours"]}


def _configs(root, tmp, tag, ray_python=None):
    configs = [("direct (no engine)", 1,
                lambda i: _timed(root, Path(tmp) / f"{tag}d{i}", direct=True))]
    configs += [("Dask LocalCluster", n, lambda i, n=n: _dask(root, Path(tmp) / f"{tag}k{n}_{i}", n))
                for n in (1, 2)]
    if ray_python:
        configs += [("Ray", n, lambda i, n=n: _ray(root, n, ray_python)) for n in (1, 2)]
    return configs


def speed(tmp, hdsim, ray_python=None) -> dict:
    """The simulator's CSVs (with Ray when given), then the same logs as a
    robot writes them (ROBOT_COLUMNS: the "robot" part)."""
    root, robot = Path(tmp) / "speed", Path(tmp) / "speed_robot"
    simfleet.generate(root, hdsim, **SPEED_FLEET)
    robot_logs(root, robot)
    out = {"fleet": SPEED_FLEET, **_speed_rows(_best_of(_configs(root, tmp, "", ray_python)), root)}
    out["robot"] = {"columns": list(ROBOT_COLUMNS),
                    **_speed_rows(_best_of(_configs(robot, tmp, "r")), robot)}
    return out


def memory(tmp, hdsim) -> dict:
    """Peak RSS of one LocalCluster worker on one long log, cut in chunks
    and whole."""
    from hdtools.fleet import engine
    root = Path(tmp) / "memory"
    simfleet.generate(root, hdsim, **MEMORY_FLEET)
    size = sum(f.stat().st_size for f in root.rglob("*.csv"))
    rows = []
    for mb in MEMORY_CHUNKS_MB:
        client = engine.connect(None, 1, "6GiB")
        try:
            s = _timed(root, Path(tmp) / f"m{mb}", dict(OPTIONS, chunk_bytes=mb << 20),
                       client=client)
        finally:
            engine.close(client)
        rows.append({"chunk_mb": mb, "tasks": s["analysed"], "engine_s": s["engine_s"],
                     "peak_rss_mb": max(s["max_rss_mb_per_worker"], default=None)})
        shutil.rmtree(Path(tmp) / f"m{mb}")
    shutil.rmtree(root)
    return {"log_s": MEMORY_FLEET["log_s"], "csv_bytes": size, "rows": rows}


def estimate(sp) -> dict:
    """1000 joints x 8 h a day, from the measured direct cost per joint-hour
    at 200 Hz (the analysis is linear in the samples: x5 at 1 kHz)."""
    jh = FLEET_JOINTS * HOURS_PER_DAY
    out = {"joint_hours_per_day": jh}
    for hz, k in (("200 Hz", 1.0), ("1 kHz", 5.0)):
        core_h = jh * sp["direct_s_per_joint_hour"] * k / 3600.0
        out[hz] = {"core_hours_per_day": core_h, "usd_per_day": core_h * USD_PER_CORE_HOUR,
                   "hours_on_32_cores": core_h / 32 * (1 + max(sp["dask_overhead_1_worker"], 0)),
                   "csv_gb_per_day": jh * sp["csv_bytes_per_joint_hour"] * k / 1e9}
    return out


def _f(x, fmt="{:.3g}"):
    return "-" if x is None else fmt.format(x)


def thresholds_table(th=None) -> str:
    th = th or trends.THRESHOLDS
    rows = ["| indicator | record column | rule |", "|---|---|---|"]
    for name, (col, rule, limit) in th["indicators"].items():
        rows.append(f"| {name} | `{col}` | {trends.RULE_TEXT[rule].format(limit)} |")
    rows.append("")
    rows.append(", ".join(f"`{k}` = {v:g}" for k, v in th.items() if k != "indicators"))
    return "\n".join(rows)


def markdown(res) -> str:
    L = [f"Measured {res['date']} on {res['machine']} (a benchmark: one run, shared machine).", ""]
    L += ["**Detection** (fleets of {n_joints} joints x {days} days x {logs_per_day} logs of "
          "{log_s:g} s at 200 Hz; thresholds above, looked at on the tuning seeds only):"
          .format(**DETECT_FLEET), "",
          "| seeds | fleet seed | wearing flagged | healthy flagged | latest first alarm after onset "
          "[days] | tooth change point after onset [days] |", "|---|---|---|---|---|---|"]
    for kind, key in (("tuning", "tune"), ("held out", "report")):
        for d in res["detection"][key]:
            L.append(f"| {kind} | {d['seed']} | {d['wearing_flagged']} / {d['wearing']} | "
                     f"{d['healthy_flagged']} / {d['healthy']} | {_f(d['max_delay_days'])} | "
                     + ", ".join(_f(x) for x in d["tooth_change_point_error_days"]) + " |")
    sp = res["speed"]
    f = sp["fleet"]
    L += ["", f"**Throughput** ({f['n_joints']} joints x {f['days']} logs of {f['log_s']:g} s at "
          f"200 Hz = {sp['rows'][0]['joint_hours']:.3g} joint-hours, "
          f"{sp['csv_bytes'] / 1e6:.0f} MB of CSV; `engine s` excludes the cluster's start):", "",
          ]
    L += _speed_table(sp["rows"])
    rb = sp.get("robot")
    if rb:
        L += ["", f"The same logs as a robot writes them ({len(rb['columns'])} columns: "
              f"{', '.join('`%s`' % c for c in rb['columns'])}; {rb['csv_bytes'] / 1e6:.0f} MB, "
              f"{rb['csv_bytes_per_joint_hour'] / 1e6:.1f} MB per joint-hour):", ""]
        L += _speed_table(rb["rows"])
    L += ["", f"Each row the fastest of {REPEATS} interleaved runs. Load average "
          f"{res['load_average'][0]:.1f} at the start and {res['load_average'][1]:.1f} at the end "
          f"on {os.cpu_count()} cores: other work shares the machine, so rows of the same work "
          "differ by more than the engines do (a row faster than the direct baseline is load, "
          "not speed).", "",
          f"Dask's overhead with 1 worker against the direct call: "
          f"**{100 * sp['dask_overhead_1_worker']:+.1f} %**; 2 workers against 1: "
          f"**{sp['dask_speedup_2_workers']:.2f}x** (this machine has 2 cores, shared)"
          + (f"; on the robot's logs {100 * rb['dask_overhead_1_worker']:+.1f} % and "
             f"**{rb['dask_speedup_2_workers']:.2f}x**." if rb else "."), ""]
    m = res["memory"]
    L += [f"**Memory per worker** on one {m['log_s'] / 3600:g} h log at 200 Hz "
          f"({m['csv_bytes'] / 1e6:.0f} MB of CSV), one LocalCluster worker:", "",
          "| chunk limit [MB] | tasks | engine s | peak RSS of the worker [MB] |", "|---|---|---|---|"]
    for r in m["rows"]:
        L.append(f"| {r['chunk_mb']} | {r['tasks']} | {r['engine_s']:.2f} | "
                 f"{_f(r['peak_rss_mb'], '{:.0f}')} |")
    L.append("")
    e = res["estimate"]
    L += [f"**Paper estimate** for {FLEET_JOINTS} joints x {HOURS_PER_DAY:g} h a day = "
          f"{e['joint_hours_per_day']:.0f} joint-hours a day, from the measured "
          f"{sp['direct_s_per_joint_hour']:.2f} s per joint-hour (one core, 200 Hz) and "
          f"{sp['csv_bytes_per_joint_hour'] / 1e6:.1f} MB of CSV per joint-hour; "
          f"${USD_PER_CORE_HOUR:g} per core-hour assumed:", "",
          "| rate | core-hours / day | cost / day | hours on 32 cores | CSV / day |", "|---|---|---|---|---|"]
    for hz in ("200 Hz", "1 kHz"):
        x = e[hz]
        L.append(f"| {hz} | {x['core_hours_per_day']:.1f} | ${x['usd_per_day']:.2f} | "
                 f"{x['hours_on_32_cores']:.2f} | {x['csv_gb_per_day']:.0f} GB |")
    return "\n".join(L)


def _speed_table(rows) -> list[str]:
    return ["| engine | workers | engine s | start s | joint-hours / min | per worker | vs direct | "
            "peak RSS / worker [MB] |", "|---|---|---|---|---|---|---|---|"] + [
            f"| {r['engine']} | {r['workers']} | {r['engine_s']:.2f} | {_f(r.get('startup_s'))} | "
            f"{r['joint_hours_per_min']:.0f} | {r['joint_hours_per_min_per_worker']:.0f} | "
            f"{r['vs_direct']:.2f}x | {_f(r['peak_rss_mb_per_worker'], '{:.0f}')} |" for r in rows]


PARTS = ("detection", "speed", "memory")


def main(argv=None) -> int:
    import argparse
    from hdtools import native
    p = argparse.ArgumentParser(prog="python -m hdmaint.fleet_bench", description=__doc__)
    p.add_argument("--write", action="store_true",
                   help="write docs/results/fleet.md and fleet.json")
    p.add_argument("--ray-python", help="a Python with ray installed (comparison only)")
    p.add_argument("--parts", default=",".join(PARTS),
                   help="which parts to measure (the others are kept from fleet.json): "
                        + ", ".join(PARTS))
    a = p.parse_args(argv)
    parts = [x for x in a.parts.split(",") if x]
    if not parts or set(parts) - set(PARTS):
        p.error(f"--parts: a comma-separated list of {', '.join(PARTS)}")
    kept = {}
    if set(PARTS) - set(parts):
        try:
            kept = json.loads(RESULT.read_text())
        except (OSError, ValueError) as exc:
            p.error(f"--parts without all of them needs {RESULT.name}: {exc}")
    hdsim = native.executable("hdsim")
    load_start = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hdfleet-bench-") as tmp:
        res = {"date": time.strftime("%Y-%m-%d"), "machine": f"{platform.processor() or platform.machine()}"
               f", {os.cpu_count()} cores", **{k: kept[k] for k in PARTS if k not in parts}}
        if "detection" in parts:
            res["detection"] = {"tune": [detection(s, tmp, hdsim) for s in TUNE_SEEDS],
                                "report": [detection(s, tmp, hdsim) for s in REPORT_SEEDS]}
        if "speed" in parts:
            res["speed"] = speed(tmp, hdsim, a.ray_python)
        if "memory" in parts:
            res["memory"] = memory(tmp, hdsim)
    res["estimate"] = estimate(res["speed"])
    res["load_average"] = [load_start, os.getloadavg()[0]]
    md = markdown(res)
    print(md)
    if a.write:
        text = docblock.splice(DOC.read_text(), MEASURED, md, str(DOC))
        text = docblock.splice(text, THRESHOLDS, thresholds_table(), str(DOC))
        with Outputs() as out:
            out.write_text(DOC, text)
            out.write_text(RESULT, json.dumps(res, indent=1) + "\n")
            out.commit()
    return 0


if __name__ == "__main__":
    sys.exit(main())
