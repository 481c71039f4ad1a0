"""tools/bench (python -m hdmaint.bench): accuracy and compute benchmarks (issue 7).

Runs the accuracy benchmark on the simulated scenarios (tests/bench/
scenarios) and the real iiwa logs, the host compute benchmark
(tests/bench/bench_compute) and the Cortex-M4 counts if tools/target exists;
checks issue 12's goals against the numbers (bench/goals.py); prints the
tables, writes OUT/results.json, OUT/results.md and OUT/bench_accuracy.png
(OUT = out/bench; the control part, --only control: OUT/control.json; the
random-joint control part, --only control_random: OUT/control-random.json).
--update-docs also writes the tables into docs/results/bench.md
(between the generated-results markers), results.json to
docs/results/bench.json (the README headline reads it) and the plot to
docs/img/bench_accuracy.png; the control part's (issue 23) go into
docs/results/control.md and docs/results/control.json, the random-joint control
part's into docs/results/control-random.md and docs/results/control-random.json,
and bench.md is left alone when only the random and control parts ran.  Every
file is written under a temporary name and all are renamed together once all
are complete.
"""
from __future__ import annotations

import argparse
import datetime
import json
import sys
import tempfile
from pathlib import Path

from hdtools import docblock
from hdtools.safeio import OutputError, Outputs, UsageError

ROOT = Path(__file__).resolve().parents[3]
DOC = ROOT / "docs" / "results" / "bench.md"
DOC_JSON = ROOT / "docs" / "results" / "bench.json"
DOC_PLOT = ROOT / "docs" / "img" / "bench_accuracy.png"
RANDOM_DOC = ROOT / "docs" / "results" / "random-joints.md"
RANDOM_JSON = ROOT / "docs" / "results" / "random.json"
CONTROL_DOC = ROOT / "docs" / "results" / "control.md"
CONTROL_JSON = ROOT / "docs" / "results" / "control.json"
CONTROL_RANDOM_DOC = ROOT / "docs" / "results" / "control-random.md"
CONTROL_RANDOM_JSON = ROOT / "docs" / "results" / "control-random.json"
BLOCK = "bench-results"           # in bench.md and random-joints.md
BEGIN, END = docblock.markers(BLOCK)


PARTS = ["accuracy", "slow", "random", "real", "host", "target", "control", "control_random"]
OWN_DOCS = {"random", "control", "control_random"}   # parts with docs of their own
QUICK_CONTROL_JOINTS = 2


def parser() -> argparse.ArgumentParser:
    from hdtools.cli import OneLineParser
    p = OneLineParser(prog="tools/bench", description=__doc__.split("\n\n")[1])
    p.add_argument("--out", type=Path, default=ROOT / "out" / "bench",
                   help="output directory (default out/bench)")
    p.add_argument("--skip", action="append", default=[],
                   choices=PARTS, help="skip a part")
    p.add_argument("--only", action="append", default=[], choices=PARTS,
                   help="run only this part (repeatable)")
    p.add_argument("--random-joints", type=int, default=32, metavar="N",
                   help="joints of the random-joint part (default 32; --quick: 4)")
    p.add_argument("--control-joints", type=int, default=None, metavar="N",
                   help="joints of the random-joint control part (default "
                        "control_random.N_REPORT; --quick: 2)")
    p.add_argument("--quick", action="store_true",
                   help="tiny sizes (smoke test): short runs, 2 real segments, few reps; the "
                        "control parts only with --only control / --only control_random")
    p.add_argument("--update-docs", action="store_true",
                   help="write the tables into docs/results/bench.md and the plot into docs/img/")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    from . import accuracy, compute, control_random, control_random_report, control_report
    from . import goals, real, report
    if args.update_docs and args.quick:
        raise UsageError("--update-docs writes the documented numbers: run without --quick")
    only, n_random = args.only, args.random_joints
    if only:
        args.skip = [x for x in PARTS if x not in only]
    elif args.quick:   # --quick: the control parts only with --only
        args.skip = args.skip + [x for x in ("control", "control_random") if x not in args.skip]
    if not 1 <= n_random <= 1000:
        raise UsageError(f"--random-joints must be 1..1000 (got {n_random})")
    n_control = getattr(args, "control_joints", None)
    n_control = (QUICK_CONTROL_JOINTS if args.quick else control_random.N_REPORT) \
        if n_control is None else n_control
    if not 1 <= n_control <= len(control_random.REPORT_SEEDS):
        raise UsageError(f"--control-joints must be 1..{len(control_random.REPORT_SEEDS)} "
                         f"(got {n_control})")
    # bench.md holds every part but the random joints' (docs/results/random-joints.md)
    own_docs = bool(only) and set(only) <= OWN_DOCS
    doc_text = read_doc() if args.update_docs and not own_docs else None
    random_text = read_doc(RANDOM_DOC) if args.update_docs and "random" not in args.skip else None
    control_text = (read_doc(CONTROL_DOC, control_report.BEGIN, control_report.END)
                    if args.update_docs and "control" not in args.skip else None)
    control_random_text = (read_doc(CONTROL_RANDOM_DOC, control_random_report.BEGIN,
                                    control_random_report.END)
                           if args.update_docs and "control_random" not in args.skip else None)
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{args.out}: cannot create: {exc.strerror}") from None
    results = {"date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
               "machine": compute.machine(), "quick": bool(args.quick)}
    residual, note = None, "skipped"
    if "accuracy" not in args.skip or "real" not in args.skip:
        with tempfile.TemporaryDirectory() as tmp:
            residual, note = accuracy.residual_model_from_analyze(Path(tmp))
        results["residual_model"] = {"model": residual, "note": note}
        print(f"residual-tool model: {note}", file=sys.stderr)
    if "accuracy" not in args.skip:
        print("accuracy benchmark (simulated scenarios)...", file=sys.stderr)
        results["accuracy"] = accuracy.run(residual, duration_scale=0.3 if args.quick else 1.0)
    if "slow" not in args.skip:
        from . import slow
        print("slow-torque benchmark (firmware on the simulated joint)...", file=sys.stderr)
        results["slow"] = slow.run(quick=bool(args.quick))
    if "random" not in args.skip:
        from . import random_bench
        print("random-joint benchmark (firmware and analysis on drawn joints)...", file=sys.stderr)
        results["random"] = random_bench.bench(
            1 if args.quick else n_random, log=lambda s: print("  " + s, file=sys.stderr),
            paths=random_bench.QUICK_PATHS if args.quick else random_bench.PATHS,
            ci_sample=not args.quick)
    if "real" not in args.skip:
        print("real iiwa logs...", file=sys.stderr)
        files = sorted(real.DATA_DIR.glob("*.csv"))
        if files:
            results["real"] = real.run(residual is not None,
                                       max_segments=2 if args.quick else None,
                                       files=files[:1] if args.quick else files)
        else:
            results["real"] = None
            print(f"  no logs in {real.DATA_DIR}", file=sys.stderr)
    if "control" not in args.skip:
        from . import control
        print("control benchmark (the torque loop on the dynamic joint)...", file=sys.stderr)
        results["control"] = control.run(quick=bool(args.quick),
                                         log=lambda s: print("  " + s, file=sys.stderr))
    crandom = None   # its own result file, not in results.json
    if "control_random" not in args.skip:
        print(f"random-joint control benchmark (the default torque loop on {n_control} drawn "
              "joints)...", file=sys.stderr)
        crandom = json.loads(control_random.to_json(control_random.run(
            n_control, log=lambda s: print("  " + s, file=sys.stderr))))
    results["compute"] = {}
    if "host" not in args.skip:
        print("host compute benchmark...", file=sys.stderr)
        results["compute"]["host"] = (compute.host(200, 3, 1) if args.quick
                                      else compute.host())
    if "target" not in args.skip:
        results["compute"]["target"] = compute.target()
    results["goals"] = goals.evaluate(results)
    tabs = report.tables(results)
    m = results["machine"]
    header = (f"hdsense bench, {results['date']}, {m['cpu']} ({m['logical_cpus']} logical "
              f"CPUs), {m['compiler']}")
    print(header)
    print(report.text(tabs))
    tgt = results["compute"].get("target")
    if tgt and tgt.get("status") == "ok":
        print("\nCortex-M4F (QEMU, exact instruction counts, max per call)")
        print(f"{'states':>6}  {'hd_kf_step':>10}  {'dense_f32':>10}  {'ratio':>6}  {'whole ISR':>9}")
        for n, r in sorted(tgt["instructions_max"].items()):
            kf, dense = r.get("kf"), r.get("dense")
            ratio = f"{dense / kf:6.2f}" if kf and dense else "     -"
            print(f"{n:>6}  {kf or '-':>10}  {dense or '-':>10}  {ratio}  {r.get('isr', '-'):>9}")
    elif tgt:
        print(f"\nCortex-M4 target: {tgt.get('status')}: {tgt.get('note', '')}")
    control_md = crandom_md = None
    if crandom is not None:
        crandom_md = control_random_report.markdown(crandom)
        print("\n" + crandom_md)
    if "control" in results:
        ctabs = control_report.tables(results["control"])
        print("\n" + control_report.text(ctabs))
        control_md = f"_{header}_\n\n" + control_report.markdown(ctabs)
    js = report.to_json({k: v for k, v in results.items() if k != "control"})
    # bench.json: the parts without a result file of their own (random.json, control.json)
    js_doc = report.to_json({k: v for k, v in results.items() if k not in ("control", "random")})
    md = f"_{header}_\n" + report.markdown(tabs)
    plot = args.out / "bench_accuracy.png"
    written = [args.out / "results.json", args.out / "results.md"]
    with Outputs() as out:
        out.write_text(written[0], js)
        out.write_text(written[1], md)
        if control_md is not None:
            written.append(args.out / "control.json")
            out.write_text(written[-1], control_report.to_json(results["control"]))
        if crandom is not None:
            written.append(args.out / "control-random.json")
            out.write_text(written[-1], control_random.to_json(crandom))
        if control_random_text is not None:
            out.write_text(CONTROL_RANDOM_DOC, control_random_report.splice(
                control_random_text, f"_{header}_\n\n" + crandom_md))
            out.write_text(CONTROL_RANDOM_JSON, control_random.to_json(crandom))
            written += [CONTROL_RANDOM_DOC, CONTROL_RANDOM_JSON]
        if control_text is not None:
            out.write_text(CONTROL_DOC, control_report.splice(control_text, control_md))
            out.write_text(CONTROL_JSON, control_report.to_json(results["control"]))
            written += [CONTROL_DOC, CONTROL_JSON]
        png = None
        if "accuracy" in results:
            with out.path(plot) as tmp:
                report.plot(results, tmp)
                png = Path(tmp).read_bytes()
            written.append(plot)
        if random_text is not None:
            from . import random_report
            out.write_text(RANDOM_DOC, splice(random_text, f"_{header}_\n\n"
                                              + random_report.markdown(results["random"])))
            out.write_text(RANDOM_JSON, json.dumps(results["random"], indent=1) + "\n")
            written += [RANDOM_DOC, RANDOM_JSON]
        if doc_text is not None:
            out.write_text(DOC, splice(doc_text, md))
            out.write_text(DOC_JSON, js_doc)
            written += [DOC, DOC_JSON]
            if png is not None:
                out.write_bytes(DOC_PLOT, png)
                written.append(DOC_PLOT)
        out.commit()
    print("\nwrote " + ", ".join(str(p) for p in written))
    return 0


def read_doc(doc: Path | None = None, begin: str = BEGIN, end: str = END) -> str:
    """A generated doc, docs/results/bench.md by default (checked before the
    benchmark runs: its markers)."""
    doc = DOC if doc is None else doc
    try:
        text = doc.read_text()
    except FileNotFoundError:
        return f"# Benchmarks\n\n{begin}\n{end}\n"
    except OSError as exc:
        raise UsageError(f"{doc}: cannot read: {exc.strerror}") from None
    if begin not in text or end not in text:
        raise UsageError(f"{doc}: the generated-results markers {begin} / {end} are missing")
    return text


def splice(text: str, md: str) -> str:
    """text with the part between the markers replaced by md."""
    return docblock.splice(text, BLOCK, md, "the bench document")
