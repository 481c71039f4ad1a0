"""`hdsense bench` (= tools/bench): accuracy and compute benchmarks (issue 7).

Runs the accuracy benchmark on the simulated scenarios (tests/bench/
scenarios) and the real iiwa logs, the host compute benchmark
(tests/bench/bench_compute) and the Cortex-M4 counts if tools/target exists;
prints the tables, writes OUT/results.json, OUT/results.md and
OUT/bench_accuracy.png (OUT = out/bench).  --update-docs also writes the
tables into docs/bench.md (between the generated-results markers) and the
plot to docs/img/bench_accuracy.png.
"""
from __future__ import annotations

import datetime
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BEGIN = "<!-- bench:results:begin -->"
END = "<!-- bench:results:end -->"


def register(subparsers) -> None:
    p = subparsers.add_parser("bench", help="benchmarks: accuracy vs peers, compute cost",
                              description=__doc__.split("\n\n")[1])
    p.add_argument("--out", type=Path, default=ROOT / "out" / "bench",
                   help="output directory (default out/bench)")
    p.add_argument("--skip", action="append", default=[],
                   choices=["accuracy", "slow", "real", "host", "target"], help="skip a part")
    p.add_argument("--quick", action="store_true",
                   help="tiny sizes (smoke test): short runs, 2 real segments, few reps")
    p.add_argument("--update-docs", action="store_true",
                   help="write the tables into docs/bench.md and the plot into docs/img/")
    p.set_defaults(func=run)


def run(args) -> int:
    from .bench import accuracy, compute, real, report
    args.out.mkdir(parents=True, exist_ok=True)
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
        from .bench import slow
        print("slow-torque benchmark (firmware on the simulated joint)...", file=sys.stderr)
        results["slow"] = slow.run(quick=bool(args.quick))
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
    results["compute"] = {}
    if "host" not in args.skip:
        print("host compute benchmark...", file=sys.stderr)
        results["compute"]["host"] = (compute.host(200, 3, 1) if args.quick
                                      else compute.host())
    if "target" not in args.skip:
        results["compute"]["target"] = compute.target()
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
    report.write_json(results, args.out / "results.json")
    md = f"_{header}_\n" + report.markdown(tabs)
    (args.out / "results.md").write_text(md)
    plot = args.out / "bench_accuracy.png"
    if "accuracy" in results:
        report.plot(results, plot)
    print(f"\nwrote {args.out / 'results.json'}, {args.out / 'results.md'}"
          + (f", {plot}" if plot.exists() else ""))
    if args.update_docs:
        update_docs(md, plot if plot.exists() else None)
    return 0


def update_docs(md: str, plot: Path | None) -> None:
    doc = ROOT / "docs" / "bench.md"
    text = doc.read_text() if doc.exists() else f"# Benchmarks\n\n{BEGIN}\n{END}\n"
    if BEGIN not in text or END not in text:
        raise SystemExit(f"{doc}: results markers missing")
    pre, rest = text.split(BEGIN, 1)
    post = rest.split(END, 1)[1]
    doc.write_text(f"{pre}{BEGIN}\n{md}\n{END}{post}")
    if plot is not None:
        (ROOT / "docs" / "img").mkdir(exist_ok=True)
        shutil.copy(plot, ROOT / "docs" / "img" / "bench_accuracy.png")
    print(f"updated {doc}")
