"""docs/results/analyze-results.md: the analysis tables, written from the tool's own
JSON reports (nothing typed by hand).

    tools/hdsense analyze --results-doc docs/results/analyze-results.md

runs the simulated cases below (hdsim from the build tree) and the KUKA iiwa
logs (../shared/data/real, if present) through pipeline.analyze and writes
the Markdown.  The tests render the same sections from the reports they
compute and compare them with the file (tests/tools: the suite and the
iiwa joints), so a stale table fails a test.

Each case is a scenario of tests/tools/scenarios with --set overrides and an
optional transform of the simulated CSV (what the simulator cannot do: a
position-dependent gravity torque, the controller's feed-forward, time
stamps that jitter, logger pauses)."""
from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import docblock

ROOT = Path(__file__).resolve().parents[3]
SCENARIOS = ROOT / "tests" / "tools" / "scenarios"
REAL = (ROOT / ".." / "shared" / "data" / "real").resolve()
IIWA_JOINTS = (2, 4, 5)
DOC = ROOT / "docs" / "results" / "analyze-results.md"
SUMMARY = ROOT / "docs" / "results" / "analyze.json"
# Cases whose plots go to docs/img/analyze_<prefix>_<plot>.png.
PLOTTED = {"mains": "sim_mains", "slowload-out2": "sim_slowload_out2",
           "swing-gravity": "sim_swing_gravity"}
IIWA_PLOT_PREFIX = "iiwa_j{}"


# --- CSV helpers (plain numpy, independent of the loader) ---------------------

def read_csv(path):
    with open(path) as fh:
        header = fh.readline().strip().split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1)


def write_csv(path, header, arr, fmt="%.9g"):
    np.savetxt(path, arr, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    return path


# --- transforms ----------------------------------------------------------------

def add_feedforward(h, a, rng):
    """The controller knows the slow torque: its expected torque is the
    simulation's true transmitted torque."""
    return h + ["torque_feedforward_nm"], np.column_stack([a, a[:, h.index("torque_true_nm")]])


def add_gravity(h, a, rng, with_ff=False):
    """12 N m of gravity, 12 sin(theta + 0.3), part of the transmitted
    torque; with_ff: the controller's model of it, 3 % and 0.02 rad off."""
    th = a[:, h.index("output_angle_rad")]
    g = 12.0 * np.sin(th + 0.3)
    a = a.copy()
    a[:, h.index("torque_nm")] += g
    a[:, h.index("torque_true_nm")] += g
    if with_ff:
        return h + ["torque_feedforward_nm"], np.column_stack([a, 11.64 * np.sin(th + 0.32)])
    return h, a


def jitter_and_pauses(h, a, rng):
    """Time stamps +-1 ms (20 % at 200 Hz), logger pauses at 40-41.5 s and
    85-85.2 s."""
    a = a.copy()
    a[1:, 0] += rng.uniform(-1e-3, 1e-3, len(a) - 1)
    t = a[:, 0]
    keep = ~(((t > 40) & (t < 41.5)) | ((t > 85) & (t < 85.2)))
    return h, a[keep]


def logger_pause(h, a, rng):
    t = a[:, h.index("t_s")]
    return h, a[(t < 40) | (t >= 100)]


SLOW_200HZ = (
    "ts_s=0.005", "duration_s=120",
    "motor_speed_profile=0:80, 8:140, 14:70, 17:-70, 24:-130, 30:-60, 33:90, 40:135, 48:70, "
    "51:-110, 60:-80, 68:-140, 74:-70, 77:70, 84:130, 90:60, 93:-90, 100:-135, 108:-70, "
    "111:110, 120:80",
    "load_torque_profile=0:1, 5:2.5, 12:0.5, 20:3, 27:1.5, 35:-0.5, 45:2, 52:1, 60:2.2, "
    "68:1, 75:3, 84:0.5, 95:2, 104:-0.5, 112:1.5, 120:2")


@dataclass
class Case:
    name: str
    scenario: str
    what: str
    sets: tuple = ()
    transform: object = None
    kwargs: dict = field(default_factory=dict)


SUITE = [
    Case("clean", "clean", "nothing hidden"),
    Case("motor6", "motor6", "motor order 6, 0.3 N m"),
    Case("motor1", "motor1", "motor order 1, 0.3 N m"),
    Case("output3", "output3", "output order 3, 0.4 N m"),
    Case("mains", "mains", "50 Hz, 0.2 N m, varying speed"),
    Case("friction", "friction", "b 1.0, Fc 2.0, reversals; load inertia 0.1"),
    Case("drift", "drift", "sensor drift 0.05 N m/s"),
    Case("loadripple", "loadripple", "ripple x (1 + 0.3 abs T), load ramps at the output period"),
    Case("loadsteps", "loadsteps", "ripple x (1 + 0.3 abs T), load steps held 3-4 s"),
]

SLOW = [
    Case("slowload-out2", "slowload", "output order 2, 0.8 N m",
         ("ripple=output:2:0.8:0.4",)),
    Case("slowload-out3", "slowload", "output order 3, 0.4 N m",
         ("ripple=output:3:0.4:1.0",)),
    Case("slowload-out1+2-undeclared", "slowload", "output orders 1 and 2, none declared",
         ("ripple=output:2:0.8:0.4",), kwargs={"output_orders": ()}),
    Case("slowload-out2-ff", "slowload", "output order 2, slow torque known (feed-forward)",
         ("ripple=output:2:0.8:0.4",), add_feedforward),
    Case("slowload-200hz", "slowload", "output order 2, 200 Hz, 120 s, jitter, 2 pauses",
         ("ripple=output:2:0.8:0.4",) + SLOW_200HZ, jitter_and_pauses),
    Case("swing-gravity", "swing", "+-120 deg swing, 12 N m gravity, no feed-forward", (),
         add_gravity),
    Case("swing-gravity-ff", "swing", "+-120 deg swing, 12 N m gravity, controller's model",
         (), lambda h, a, rng: add_gravity(h, a, rng, True)),
    Case("pause", "pause", "5 N m load, 60 s logger pause", (), logger_pause),
]


def simulator(hdsim, out_dir: Path):
    """simulate(scenario, *--set overrides) -> the CSV hdsim writes for it
    (each run once)."""
    cache = {}

    def simulate(name, *sets):
        key = (name,) + sets
        if key not in cache:
            out = Path(out_dir) / f"{name}_{len(cache)}.csv"
            cmd = [str(hdsim), str(SCENARIOS / f"{name}.ini"), "--csv", str(out)]
            for s in sets:
                cmd += ["--set", s]
            subprocess.run(cmd, check=True, capture_output=True)
            cache[key] = out
        return cache[key]
    return simulate


def prepare(case: Case, simulate, tmp: Path) -> Path:
    """The case's CSV: simulate(scenario, *sets) -> CSV path, then the
    transform (seeded)."""
    path = simulate(case.scenario, *case.sets)
    if case.transform is None:
        return path
    h, a = read_csv(path)
    h, a = case.transform(h, a, np.random.default_rng(5))
    return write_csv(Path(tmp) / f"{case.name}.csv", h, a)


# --- tables ----------------------------------------------------------------------

def _f(x, spec=".4g"):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return format(x, spec)


def kept(r) -> str:
    out = []
    for e in r["effects"]:
        if not e["added"]:
            continue
        if e["kind"] == "motor_order":
            out.append(f"motor order {_f(e['order_per_motor_rev'], 'g')}"
                       + (f" (load coefficient {_f(e['parameters']['ripple_load_coeff_per_nm'], '.3g')}"
                          " /N m)" if e["action"] == "load_scale" else
                          " (retune)" if e["action"] == "retune_block" else ""))
        elif e["kind"] == "output_order":
            out.append(f"output order {_f(e['order_per_output_rev'], 'g')} "
                       f"({_f(e['amplitude_nm'], '.3g')} N m)")
        elif e["kind"] == "fixed_frequency":
            out.append(f"{_f(e['frequency_hz'], '.4g')} Hz")
        elif e["kind"] == "offset_drift":
            out.append(f"drift {_f(e['parameters']['drift_nm_per_s'], '.3g')} N m/s")
        else:
            out.append(e["kind"] + " " + ", ".join(
                f"{k.split('_')[0]} {_f(v, '.3g')}" for k, v in e.get("parameters", {}).items()))
    return ", ".join(out) or "nothing"


def not_kept(r) -> str:
    """Findings not kept, with the reason; report-only low fixed lines
    counted in one item."""
    low = [e for e in r["effects"] if not e["added"] and e["action"] == "report_only"
           and e["kind"] == "fixed_frequency"]
    out = [f"{e['kind']} {_f(e.get('order_per_motor_rev', e.get('frequency_hz')), '.4g')}: "
           f"{e['evidence'].get('rejected_because') or e['evidence'].get('not_added_because') or ''}"
           for e in r["effects"] if not e["added"] and e not in low]
    if low:
        out.append(f"{len(low)} fixed-frequency lines below 20 Hz "
                   f"({', '.join(_f(e['frequency_hz'], '.3g') for e in low)} Hz): reported only, "
                   "may be real periodic torque")
    return "; ".join(out) or "none"


def profile_cell(r) -> str:
    p = r["model_before"]["profile"]
    return ", ".join(f"{_f(x['order'], 'g')}: {_f(math.hypot(x['a_nm'], x['b_nm']), '.3g')}"
                     for x in p) or "none"


def suite_table(reports: dict, cases) -> list[str]:
    """Rows: in- and out-of-sample innovation and error, starting -> final,
    the paper model's error."""
    L = ["| case | hidden | kept (fold B judged) | starting profile [N m] | innovation A / B, "
         "start -> final [N m] | error vs truth A / B, start -> final [N m] | paper model "
         "error [N m] | raw error [N m] |", "|---|---|---|---|---|---|---|---|"]
    for c in cases:
        r = reports[c.name]
        ref = r["metrics_reference"]
        L.append(
            f"| {c.name} | {c.what} | {kept(r)} | {profile_cell(r)} | "
            f"{_f(r['in_sample_residual_rms_before_nm'])} / {_f(r['out_of_sample_residual_rms_before_nm'])}"
            f" -> {_f(r['in_sample_residual_rms_after_nm'])} / {_f(r['out_of_sample_residual_rms_after_nm'])} | "
            f"{_f(r.get('in_sample_error_rms_before_nm'))} / {_f(r.get('out_of_sample_error_rms_before_nm'))}"
            f" -> {_f(r.get('in_sample_error_rms_after_nm'))} / {_f(r.get('out_of_sample_error_rms_after_nm'))} | "
            f"{_f(ref.get('error_rms_nm'))} | {_f(r.get('raw_error_rms_nm'))} |")
    return L


def bands_table(reports: dict, cases) -> list[str]:
    L = ["| case | error above 2 Hz, start -> final [N m] | error below 2 Hz, start -> final [N m] | "
         "final model without feed-forward: error [N m] | paper model without feed-forward [N m] |",
         "|---|---|---|---|---|"]
    for c in cases:
        r = reports[c.name]
        nf = r.get("metrics_without_feedforward") or {}
        L.append(f"| {c.name} | {_f(r.get('error_fast_rms_before_nm'))} -> "
                 f"{_f(r.get('error_fast_rms_after_nm'))} | {_f(r.get('error_slow_rms_before_nm'))} -> "
                 f"{_f(r.get('error_slow_rms_after_nm'))} | "
                 f"{_f((nf.get('after') or {}).get('error_rms_nm'))} | "
                 f"{_f((nf.get('reference') or {}).get('error_rms_nm'))} |")
    return L


def line_removal(r, lock, order):
    """(raw, final) averaged-spectrum amplitude of a model line and the
    percentage removed."""
    for ln in r["lines"]:
        if ln["kind"] == f"{lock}_order" and abs(ln["order"] - order) < 1e-6:
            raw, fin = ln["spectral_raw_amplitude_nm"], ln["spectral_filtered_after_nm"]
            return raw, fin, (100.0 * (1 - fin / raw) if raw else None)
    return None, None, None


def iiwa_table(reports: dict) -> list[str]:
    js = [j for j in IIWA_JOINTS if j in reports]
    L = ["| | " + " | ".join(f"joint {j}" for j in js) + " |", "|---" * (len(js) + 1) + "|"]

    def row(name, fn):
        L.append(f"| {name} | " + " | ".join(fn(reports[j]) for j in js) + " |")

    def gear(r):
        g = r["gear_ratio"]
        p = g.get("peak_ratio_at_multiples", {})
        return (f"{_f(g['value'], 'g')} +- {_f(g.get('uncertainty'), 'g')}, {g.get('confidence')} "
                f"(peaks over floor k=1..4: {', '.join(_f(p.get(f'k={k}'), 'g') for k in (1, 2, 3, 4))};"
                f" runner-up {_f(g.get('runner_up'), 'g')})")

    def lines(r, order):
        raw, fin, pct = line_removal(r, "motor", order)
        return f"{_f(raw, '.3g')} -> {_f(fin, '.3g')} N m ({_f(pct, '.0f')} %)"
    row("samples / stretches", lambda r: f"{r['data']['samples']} / {r['data']['pieces']}")
    row("gear ratio (inferred)", gear)
    row("gravity stand-in feed-forward, held-out variance explained", lambda r: (
        f"{_f(100 * r['position_feedforward']['out_of_sample_explained_fraction'], '.1f')} %"
        if r.get("position_feedforward") else "none"))
    row("output profile", lambda r: (r["starting_profile_fit"].get("why") or "verified").split(":")[0])
    row("R (noise), nyquist_fraction", lambda r: (
        f"{_f(math.sqrt(r['model_after']['r_nm2']), '.3g')} N m "
        f"({_f(math.sqrt(r['model_after']['r_nm2']) / max(r['data']['noise_estimate_nm'], 1e-12), '.3g')}"
        f" x estimate), {_f(r['model_after']['nyquist_fraction'], '.2g')}"))
    row("motor order 2, raw -> filtered (spectrum)", lambda r: lines(r, 2))
    row("motor order 4, raw -> filtered", lambda r: lines(r, 4))
    row("innovation A / B, start -> final [N m]", lambda r: (
        f"{_f(r['in_sample_residual_rms_before_nm'])} / {_f(r['out_of_sample_residual_rms_before_nm'])}"
        f" -> {_f(r['in_sample_residual_rms_after_nm'])} / {_f(r['out_of_sample_residual_rms_after_nm'])}"))
    row("kept", kept)
    row("found, not kept (reason)", not_kept)
    return L


def section(name, lines) -> str:
    begin, end = docblock.markers(f"analyze-{name}")
    return "\n".join([begin] + lines + [end])


def render(suite: dict, slow: dict, iiwa: dict, bench: str | None = None,
           images=()) -> str:
    parts = ["# `hdsense analyze`: measured results",
             "",
             "Generated by `tools/hdsense analyze --results-doc docs/results/analyze-results.md` "
             "from the tool's own JSON reports; the tests render the same tables from the reports "
             "they compute and fail when this file is stale.  What the columns mean: "
             "[analyze.md](../design/analyze.md).  Fold A (in-sample) detects and fits, fold B "
             "(out-of-sample) judges every change; A / B below are the two folds' numbers.",
             "",
             "## Simulated suite (tests/tools/scenarios, hdsim, 20 s at 1 kHz, speed 80..200 rad/s)",
             "", "Starting model: motor orders 2 and 4, output order 1 as a verified angle profile.",
             "", section("suite", suite_table(suite, SUITE)),
             "", "Error split at 2 Hz:", "", section("bands", bands_table(suite, SUITE)),
             "",
             "## Slow unknown loads, gravity, logger pauses",
             "", "`slowload.ini`: output speed 0.8-3 rad/s with reversals, unknown load 0.5-3 N m "
             "varying over 5-10 s, 60 s at 1 kHz (noise 0.02 N m); `swing.ini` with gravity added "
             "in Python; `pause.ini` with 60 s removed.",
             "", section("slow", suite_table(slow, SLOW)),
             "", section("slow-bands", bands_table(slow, SLOW))]
    if iiwa:
        parts += ["", "## KUKA iiwa joints 2, 4, 5 (../shared/data/real, 200 Hz, output angle only)",
                  "", section("iiwa", iiwa_table(iiwa))]
    if bench:
        parts += ["", "## One hour at 1 kHz (`tools/hdsense analyze --bench-hour`)", "", "```",
                  bench.rstrip(), "```"]
    if images:
        parts += ["", "## Plots", ""] + [f"![{n}](../img/{n})" for n in images]
    return "\n".join(parts) + "\n"


def case_summary(r, what: str) -> dict:
    """The numbers of one case the README's headline reads (the same
    report fields as the tables)."""
    return {"what": what, "kept": kept(r),
            "innovation_out_of_sample_before_nm": r["out_of_sample_residual_rms_before_nm"],
            "innovation_out_of_sample_after_nm": r["out_of_sample_residual_rms_after_nm"],
            "error_out_of_sample_before_nm": r.get("out_of_sample_error_rms_before_nm"),
            "error_out_of_sample_after_nm": r.get("out_of_sample_error_rms_after_nm"),
            "error_after_nm": r.get("error_rms_after_nm"),
            "noise_estimate_nm": r["data"]["noise_estimate_nm"]}


def joint_summary(r) -> dict:
    """An iiwa joint: the inferred gear ratio and the motor lines removed."""
    g = r["gear_ratio"]
    return {"gear_ratio": g["value"], "gear_ratio_uncertainty": g.get("uncertainty"),
            "confidence": g.get("confidence"), "kept": kept(r),
            "motor_order_2_removed_pct": line_removal(r, "motor", 2)[2],
            "motor_order_4_removed_pct": line_removal(r, "motor", 4)[2]}


def hour_summary(bench: str | None) -> dict | None:
    """Seconds and peak memory of the one-hour benchmark, read from its
    printed block (the block is the record; it is rerun only with
    --bench-hour)."""
    if not bench:
        return None
    import re
    m = re.search(r"load \+ full analysis\s*:\s*([\d.]+) s .*?peak (\d+) MB", bench)
    h = re.search(r"\(([\d.]+) h at (\d+) Hz\)", bench)
    if not m or not h:
        return None
    return {"hours": float(h.group(1)), "rate_hz": int(h.group(2)),
            "analysis_s": float(m.group(1)), "peak_mb": int(m.group(2))}


def summary(suite: dict, slow: dict, iiwa: dict, bench: str | None) -> dict:
    """docs/results/analyze.json: per case, fold B (out-of-sample) numbers;
    per iiwa joint, the inferred gear ratio and the lines removed."""
    cases = {c.name: case_summary(suite[c.name], c.what) for c in SUITE}
    cases.update({c.name: case_summary(slow[c.name], c.what) for c in SLOW})
    return {"tool": "tools/hdsense analyze --results-doc docs/results/analyze-results.md",
            "cases": cases, "iiwa": {str(j): joint_summary(r) for j, r in iiwa.items()},
            "hour": hour_summary(bench)}


def _finite(o):
    """JSON has no NaN: a number that is not finite becomes null."""
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    return o


def extract(text: str, name: str) -> str | None:
    a, b = docblock.markers(f"analyze-{name}")
    if a not in text or b not in text:
        return None
    return text[text.index(a):text.index(b) + len(b)]


def run_all(log=print, img_dir: Path | None = None):
    """Every case and iiwa joint analysed; with img_dir, the plotted ones'
    PNGs are returned as {file name: bytes} under their docs/img names."""
    from .. import native
    from . import pipeline
    sim = native.find_file("hdsim", target="hdsim_cli")
    images = {}

    def run(path, name, prefix, **kw):
        out = Path(tmp) / f"out_{name}" if (img_dir and prefix) else None
        r = pipeline.analyze(str(path), log=lambda *a: None, out_dir=out, **kw)
        if out is not None:
            for f in sorted(out.glob("*.png")):
                images[f"analyze_{prefix}_{f.name}"] = f.read_bytes()
        return r
    with tempfile.TemporaryDirectory() as tmp:
        simulate = simulator(sim, Path(tmp))
        reports = {}
        for c in SUITE + SLOW:
            log(f"case {c.name}")
            reports[c.name] = run(prepare(c, simulate, Path(tmp)), c.name, PLOTTED.get(c.name),
                                  **c.kwargs)
        iiwa = {}
        if REAL.is_dir():
            for j in IIWA_JOINTS:
                log(f"iiwa joint {j}")
                iiwa[j] = run(REAL / f"iiwa_joint{j}_constvel.csv", f"iiwa{j}",
                              IIWA_PLOT_PREFIX.format(j))
    return reports, iiwa, images


def main(path, with_bench: bool = False) -> int:
    """Writes the results document; with_bench: also runs the one-hour
    benchmark, else the benchmark block of the existing file is kept."""
    from ..safeio import Outputs
    bench = None
    if with_bench:
        from . import bench_speed
        bench = bench_speed.run()
    elif Path(path).is_file():
        old = Path(path).read_text()
        a = old.find("```\nanalyze-speed:")
        if a >= 0:
            bench = old[a + 4:old.index("```", a + 4)]
    # The document sits in docs/results/ beside its JSON; the plots go to docs/img/.
    img_dir = Path(path).resolve().parent.parent / "img"
    reports, iiwa, images = run_all(lambda *a: print(*a, file=sys.stderr), img_dir)
    suite = {c.name: reports[c.name] for c in SUITE}
    slow = {c.name: reports[c.name] for c in SLOW}
    with Outputs() as out:
        out.write_text(path, render(suite, slow, iiwa, bench, sorted(images)))
        results_dir = Path(path).resolve().parent
        results_dir.mkdir(parents=True, exist_ok=True)
        out.write_text(results_dir / "analyze.json",
                       json.dumps(_finite(summary(suite, slow, iiwa, bench)), indent=1,
                                  allow_nan=False) + "\n")
        img_dir.mkdir(parents=True, exist_ok=True)
        for name, data in images.items():
            out.write_bytes(img_dir / name, data)
        out.commit()
    print(f"wrote {path}")
    return 0
