"""The README's headline numbers, rendered from the results the measuring
tools write (nothing typed):

  docs/results/demo.json      tools/demo --update-docs
  docs/results/bench.json     tools/bench --update-docs
  docs/results/budget.json    tools/target budget --update-docs
  docs/results/analyze.json   tools/hdsense analyze --results-doc docs/results/analyze-results.md
  docs/results/corpus.json    tests/corpus/run_corpus.py --doc docs/results/reliability.md
  docs/results/fleet.json     cd tools && python -m hdmaint.fleet_bench --write
  docs/results/control.json   tools/bench --only control --update-docs
  docs/results/control-random.json   tools/bench --only control_random --update-docs

  python -m hdmaint.headline --write    rewrite the README block
  python -m hdmaint.headline --check    exit 1 if the README block is stale

The block sits between `<!-- BEGIN generated:headline -->` and
`<!-- END generated:headline -->`; tests/tools/test_headline.py runs --check.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hdtools import docblock
from hdtools.safeio import OutputError, Outputs, UsageError

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "docs" / "results"
README = ROOT / "README.md"
BEGIN, END = docblock.markers("headline")
SOURCES = ("demo", "bench", "random", "budget", "analyze", "corpus", "fleet", "control",
           "control-random")


class HeadlineError(Exception):
    pass


def load(results_dir: Path | None = None) -> dict:
    results_dir = RESULTS if results_dir is None else results_dir
    out = {}
    for name in SOURCES:
        path = results_dir / f"{name}.json"
        try:
            out[name] = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise HeadlineError(f"{path}: {exc}") from None
    return out


def _link(name: str) -> str:
    return f"[{name}.json](docs/results/{name}.json)"


def demo_rows(d: dict) -> list[tuple[str, str, str]]:
    w, wo = d["operate_with_profile"], d["operate_without_profile"]
    noise = float(d["noise_nm"])
    rms = float(w["rms_error_filtered_nm"])
    return [(
        "Demo (`tools/demo`): 10 s up to 156 rad/s with a reversal, an unknown 3 N m load "
        "swinging +-2 N m; the firmware is told its defaults and the profile of its own "
        "commissioning run, never the simulated joint's J, b, Fc",
        f"RMS error **{rms:.4f} N m** = {rms / noise:.2f}x the {noise:g} N m sensor noise "
        f"(raw {float(w['rms_error_raw_nm']):.3f}; first second {float(w['rms_error_filtered_first_1s_nm']):.4f}); "
        f"booted without the profile {float(wo['rms_error_filtered_nm']):.3f}",
        _link("demo") + ", [slow-torque.md](docs/design/slow-torque.md)")]


def _slow(slow: dict, row: str, key: str) -> list[tuple[float, str]]:
    vals = [(s["rows"][row][key], name) for name, s in slow.items() if row in s["rows"]]
    if not vals:
        raise HeadlineError(f"bench.json: no slow-torque row {row!r}")
    return vals


def bench_rows(b: dict) -> list[tuple[str, str, str]]:
    src = _link("bench") + ", [bench.md](docs/results/bench.md)"
    acc = b["accuracy"]["scenarios"]["const156"]["methods"]
    prod = acc["fw_commissioned"]
    ideal = acc["ideal"]["rms_nm"]
    rows = [(
        "Ripple band at a constant 156 rad/s, 3 N m unknown load: the firmware booted from "
        "the profile it saved in its own commissioning run (separate seed), operating mode, "
        "T_exp = 0",
        f"**{prod['rms_nm'] / ideal:.2f}x** the noise floor; lines attenuated "
        + ", ".join(f"{k} {v:.0f} dB" for k, v in prod["attenuation_db"].items()),
        src)]
    slow = b["slow"]["scenarios"]
    n = len(slow)
    x, at = max(_slow(slow, "fw_profile_ff", "x_floor"))
    xc, atc = max(_slow(slow, "fw_profile_current", "x_floor"))
    rows.append((
        f"Slow torque, {n} scenarios (gravity with payload changes, unknown loads of 5-60 s "
        "at 0.3-3 rad/s with reversals, output orders 1-3, controller J/b/Fc 25-30 % off): "
        "commissioned profile + the controller's feed-forward",
        f"worst **{x:.2f}x** the noise floor ({at}); with the motor current instead of the "
        f"feed-forward {xc:.2f}x ({atc})", src))
    kept = _slow(slow, "fw_profile", "load_kept")
    xp, atp = max(_slow(slow, "fw_profile", "x_floor"))
    kept0 = _slow(slow, "fw_default", "load_kept")
    xd, atd = max(_slow(slow, "fw_default", "x_floor"))
    better = sum(s["rows"]["fw_profile"]["rms_nm"]
                 < min(s["rows"][r]["rms_nm"] for r in ("butter_20db", "butter_40db"))
                 for s in slow.values())
    rows.append((
        "Slow torque with no slow-torque information (no feed-forward, no current)",
        f"commissioned: slow load kept {100 * min(kept)[0]:.1f} % or more, worst {xp:.1f}x "
        f"the floor ({atp}), better than the best Butterworth in {better} of {n}; never "
        f"commissioned: kept {100 * min(kept0)[0]:.1f} % or more, worst {xd:.1f}x ({atd})",
        src))
    ratios = [(s["rows"]["fw_default"]["first_s_rms_nm"] / s["rows"]["fw_profile"]["first_s_rms_nm"],
               name) for name, s in slow.items()]
    r, at_r = min(ratios)
    rows.append(("First second after boot: stored profile vs starting from zero",
                 f"error {r:.1f}x lower or better in every scenario (least: {at_r})", src))
    host = [r for r in b.get("compute", {}).get("host", {}).get("compute", [])
            if r["states"] == 7 and r["impl"] in ("hd_kf_step", "hd_kf_step_v0", "dense_f32")]
    by = {r["impl"]: r for r in host}
    if "hd_kf_step" in by:
        kf = by["hd_kf_step"]["ns_median"]
        rows.append((
            f"Filter step on this host, 7 states ({b['machine']['cpu']})",
            f"{kf:.0f} ns ({1e3 / kf:.1f} M updates/s)"
            + "".join(f"; {label} {by[k]['ns_median'] / kf:.1f}x slower"
                      for k, label in (("hd_kf_step_v0", "the step before its rewrite"),
                                       ("dense_f32", "a dense float32 filter")) if k in by),
            src))
    return rows


def random_rows(r: dict) -> list[tuple[str, str, str]]:
    src = _link("random") + ", [random-joints.md](docs/results/random-joints.md)"
    dec, und = r["declared"]["paths"], r["undeclared"]["paths"]

    def within(d):
        return f"{d['within_goal']} of {d['runs']} (median {d['median']:.3g}x, worst {d['worst']:.3g}x)"
    runs = sum(d.get("runs", 0) for part in (dec, und) for d in part.values())
    worse = sum(d.get("worse_than_raw", 0) for part in (dec, und) for d in part.values())
    n = dec["self"]["runs"]
    return [(f"{n} randomly drawn joints ({r['seeds']}; tuned on other seeds): ratio 50-160, "
             "every phase, friction, noise, encoders, speeds and unknown slow loads drawn",
             f"firmware's own commissioning within 1.5x the floor in **{within(dec['self'])}**; "
             f"with one undeclared effect, the loop from another day's log in "
             f"{within(und['analyze_op'])}; filtered worse than raw in **{worse} of {runs}** runs "
             "(every path and mode)", src)]


def _control_tick(p: dict, period_us: float) -> str:
    """The worst tick with the control stage (a board with a drive), if measured."""
    c = [p[k] for k in ("tick_with_control", "tick_with_control_and_commands") if k in p]
    if not c:
        return ""
    w = max(c, key=lambda x: x["worst_us"])
    return (f"; with the control stage and commands **{w['worst_us']:.1f} us = "
            f"{100 * w['worst_us'] / period_us:.1f} %** (goal 5 %)")


def budget_rows(g: dict) -> list[tuple[str, str, str]]:
    src = _link("budget") + (", [target.md](docs/results/target.md), "
                             "[stm32f4.md](docs/how-to/stm32f4.md)")
    m = g["mps2-an386"]
    n = str(m["default_states"])
    p = m["per_states"][n]
    kf, tick, cmd = p["kf_step"], p["tick"], p["tick_with_commands"]
    big = m["per_states"].get("17", {}).get("kf_step")
    rows = [(
        f"Filter step on a Cortex-M4F, {n} states (the firmware default; QEMU, exact "
        "instruction counts, -Os)",
        f"**{kf['typical']['max_instructions']}** instructions typical, "
        f"{kf['worst']['max_instructions']} on the worst path ({kf['worst']['path']})"
        + (f"; 17 states {big['typical']['max_instructions']} / "
           f"{big['worst']['max_instructions']}" if big else "")
        + f"; a correct dense float32 filter takes {kf['dense_over_typical_mean']:.1f}x", src),
        (f"The 1 kHz tick on a Cortex-M4F at {g['clock_mhz']:g} MHz (cycles estimated from "
         "the instruction mix, zero wait states)",
         f"worst {tick['worst_us']:.1f} us = {100 * tick['budget_fraction']:.1f} % of the tick; "
         f"with commands pending ({cmd['frames_in']} frames in, {cmd['acks_out']} ACK out) "
         f"{cmd['worst_us']:.1f} us, {cmd['ratio_to_tick_max']:.2f}x the tick's instructions"
         + _control_tick(p, g["tick_period_us"]), src)]
    f4 = g["stm32f4"]
    imgs = ", ".join(f"`{name}` {v['flash_bytes'] / 1024:.1f} KiB flash, "
                     f"{v['ram_bytes'] / 1024:.1f} KiB RAM" for name, v in f4["images"].items())
    t = f4["interrupts"]["tick"]
    rows.append((
        "STM32F4 images (ODrive v3 / Mini Cheetah class; instruction counts on QEMU's "
        "netduinoplus2, not verified on hardware)",
        f"{imgs}; worst-case stack {f4['stack_worst_bytes']} B; tick interrupt "
        f"{t['max_instructions']} instructions, {t['worst_us']:.1f} us", src))
    return rows


def analyze_rows(a: dict) -> list[tuple[str, str, str]]:
    src = _link("analyze") + ", [analyze-results.md](docs/results/analyze-results.md)"
    cases = a["cases"]
    at_floor = [c for c in cases.values()
                if c["error_out_of_sample_after_nm"] is not None
                and c["error_out_of_sample_after_nm"] <= 1.5 * c["noise_estimate_nm"]]
    worse = [n for n, c in cases.items()
             if c["innovation_out_of_sample_after_nm"] > c["innovation_out_of_sample_before_nm"]]
    rows = [(
        f"Closing the loop (`hdsense analyze`) on {len(cases)} simulated logs, each with an "
        "effect the model lacks (slow loads, 200 Hz, gaps, gravity included)",
        f"held-out error within 1.5x the noise after the loop in {len(at_floor)} of "
        f"{len(cases)}; held-out innovation grew in {len(worse)}", src)]
    j2 = a["iiwa"].get("2")
    if j2:
        rows.append((
            "Real KUKA iiwa joint 2 log (200 Hz, output angle only)",
            f"gear ratio inferred {j2['gear_ratio']:g} +- {j2['gear_ratio_uncertainty']:.2g}; "
            f"wave-generator lines 2x / 4x reduced {j2['motor_order_2_removed_pct']:.0f} % / "
            f"{j2['motor_order_4_removed_pct']:.0f} %", src))
    h = a.get("hour")
    if h:
        rows.append((f"{h['hours']:g} h of {h['rate_hz']} Hz log analysed",
                     f"{h['analysis_s']:.1f} s, peak {h['peak_mb']} MB", src))
    return rows


def corpus_rows(c: dict) -> list[tuple[str, str, str]]:
    classes = ", ".join(f"{k} {n}" for k, n in c["per_class"].items())
    return [(
        f"Hostile inputs to every CLI (`tests/corpus`, run in CI; the C tools' cases also "
        f"under ASan/UBSan): {classes}",
        f"{c['cases']} cases, each a whole output or one line on stderr and a documented exit "
        f"code ({c['failed_before']} failed before the corpus, at d9ce5d9)",
        _link("corpus") + ", [reliability.md](docs/results/reliability.md)")]


def fleet_rows(f: dict) -> list[tuple[str, str, str]]:
    rep = f["detection"]["report"]
    n = {k: sum(d[k] for d in rep) for k in ("wearing", "wearing_flagged", "healthy",
                                              "healthy_flagged")}
    delay = max(d["max_delay_days"] for d in rep)
    sp = f["speed"]
    dask = {r["workers"]: r for r in sp["rows"] if r["engine"] == "Dask LocalCluster"}
    src = _link("fleet") + ", [fleet.md](docs/results/fleet.md)"
    return [
        (f"`hdsense fleet` on held-out simulated fleets (seeds "
         f"{', '.join(str(d['seed']) for d in rep)}; meshing, friction, gauge-gain and "
         "broken-tooth wear; thresholds looked at on other seeds)",
         f"wearing joints flagged **{n['wearing_flagged']} / {n['wearing']}**, healthy "
         f"{n['healthy_flagged']} / {n['healthy']}; first alarm at most {delay:.1f} days after "
         "the onset", src),
        ("`hdsense fleet` throughput on 200 Hz logs, this machine (Dask LocalCluster; 2 cores "
         "shared with other work, so one run's numbers: see fleet.md)",
         f"{dask[1]['joint_hours_per_min']:.0f} joint-hours/min with 1 worker "
         f"({100 * sp['dask_overhead_1_worker']:+.1f} % vs calling the analysis directly), "
         f"{dask[2]['joint_hours_per_min']:.0f} with 2 ({sp['dask_speedup_2_workers']:.2f}x)",
         src)]


def control_rows(c: dict) -> list[tuple[str, str, str]]:
    from .bench.control_report import headline_rows
    return headline_rows(c)


def control_random_rows(d: dict) -> list[tuple[str, str, str]]:
    from .bench.control_random_report import headline_rows
    return headline_rows(d)


def render(results: dict) -> str:
    rows = (demo_rows(results["demo"]) + bench_rows(results["bench"])
            + random_rows(results["random"]) + budget_rows(results["budget"])
            + analyze_rows(results["analyze"]) + corpus_rows(results["corpus"])
            + fleet_rows(results["fleet"]) + control_rows(results["control"])
            + control_random_rows(results["control-random"]))
    lines = ["| what | measured | source |", "|---|---|---|"]
    lines += [f"| {w} | {m} | {s} |" for w, m, s in rows]
    return "\n".join(lines)


def splice(text: str, block: str) -> str:
    try:
        return docblock.splice(text, "headline", block, str(README))
    except UsageError as exc:
        raise HeadlineError(str(exc)) from None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m hdmaint.headline",
                                 description="render the README's headline numbers")
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--write", action="store_true")
    g.add_argument("--check", action="store_true")
    args = ap.parse_args(argv)
    try:
        text = README.read_text()
        new = splice(text, render(load()))
    except (HeadlineError, KeyError, TypeError) as exc:
        print(f"headline: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"headline: {README}: {exc.strerror}", file=sys.stderr)
        return 2
    if args.check:
        if new != text:
            print("README.md headline is stale: run `cd tools && ../.venv/bin/python -m "
                  "hdmaint.headline --write`", file=sys.stderr)
            return 1
        return 0
    try:
        with Outputs() as out:      # a temporary name, renamed; removed on failure
            out.write_text(README, new)
            out.commit()
    except OutputError as exc:
        print(f"headline: {exc}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
