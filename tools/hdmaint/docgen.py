"""The registry of document generators: which command writes which block
of which document (hdtools.docblock's one marker syntax) and which result
files, in dependency order.  tools/update-docs runs it; each generator's own
command keeps working alone.

  python -m hdmaint.docgen --list              the generators, in order
  python -m hdmaint.docgen [--no-vm] [--only NAME ...]
                                               run them (tools/update-docs)
  python -m hdmaint.docgen --write-table       docs/reference/testing.md's table of them
  python -m hdmaint.docgen --migrate-markers   rewrite older marker syntaxes
                                               in docs/**/*.md and README.md

Standard library only.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

from hdtools import docblock
from hdtools.safeio import HdError

ROOT = Path(__file__).resolve().parents[2]
PY = ".venv/bin/python"


@dataclass(frozen=True)
class Generator:
    name: str
    argv: tuple                 # run from the top of the tree, tools/ on PYTHONPATH
    what: str                   # docs/reference/testing.md: the document (markdown)
    shown: str                  # docs/reference/testing.md: the command as a user types it
    checked: str                # docs/reference/testing.md: what keeps it from going stale
    blocks: dict = field(default_factory=dict)   # {doc relative to the root: (block, ...)}
    vm: bool = False            # boots VMs (skipped by --no-vm)
    in_all: bool = True         # run by tools/update-docs


# Names without a hyphen are hdtools.protocol's tables (docblock.py).
PROTOCOL = "protocol"
GENERATORS = (
    Generator("protocol", (PY, "-m", "hdtools.protocol", "--write"),
              "parameter, fault, command, frame and record tables in "
              "[firmware.md](../design/firmware.md), "
              "[protocol.md](protocol.md), [records.md](records.md); `firmware/hdjoint.dbc`",
              "`cd tools && ../.venv/bin/python -m hdtools.protocol --write`",
              "`fw_protocol_tables`"),
    Generator("calib", (PY, "tests/calib/calib_doc.py"),
              "[calibration.md](../how-to/calibration.md) (measured section)",
              "`tests/calib/calib_doc.py`",
              "`calib_tool`", {"docs/how-to/calibration.md": ("calib-measured",)}),
    Generator("corpus", (PY, "tests/corpus/run_corpus.py", "--doc", "docs/results/reliability.md"),
              "[reliability.md](../results/reliability.md) (corpus table), "
              "`docs/results/corpus.json`",
              "`tests/corpus/run_corpus.py --doc docs/results/reliability.md`", "`corpus_doc`",
              {"docs/results/reliability.md": ("corpus-classes",)}),
    Generator("filter", (PY, "tests/filter/filter_doc.py", "--build", "build/host-debug"),
              "[filter-tests.md](../results/filter-tests.md) (every measured table)",
              "`tests/filter/filter_doc.py --build build/host-debug` (runs the filter tests)",
              "`filter_doc`",
              {"docs/results/filter-tests.md": ("filter-behaviour", "filter-numerics",
                                                "filter-reference", "filter-shift",
                                                "filter-trig-track")}),
    Generator("rig", (PY, "tests/reliability/rig_identify.py"),
              "`tests/reliability/rig_expected.cfg` (the fault rig's expected-torque model: "
              "regenerate it before the reliability tables, which depend on it)",
              "`.venv/bin/python tests/reliability/rig_identify.py`", "`rel_rig_identified`"),
    Generator("reliability", (PY, "tests/reliability/rel_doc.py", "--build", "build/host-debug"),
              "[reliability.md](../results/reliability.md) (fault-injection, filter-input, "
              "control-reaction and 10^6 soak tables)",
              "`tests/reliability/rel_doc.py --build build/host-debug` (runs `rel_fault_*`, "
              "`fw_control`, `rel_soak_1e6`)", "`rel_doc`",
              {"docs/results/reliability.md": ("reliability-control", "reliability-faults",
                                               "reliability-filter-input", "reliability-soak")}),
    Generator("soak-long", (PY, "tests/reliability/rel_doc.py", "--soak-long",
                            "build/host-release"),
              "[reliability.md](../results/reliability.md) (10^8 soak)",
              "`tests/reliability/rel_doc.py --soak-long build/host-release` (~1 min)",
              "a benchmark: date and machine in the block, not checked",
              {"docs/results/reliability.md": ("reliability-soak-long",)}),
    Generator("vm", (PY, "tests/vm/vm_doc.py", "--build", "build/host-debug"),
              "[socketcan.md](../how-to/socketcan.md) (VM measurements)",
              "`tests/vm/vm_doc.py --build build/host-debug` (boots each VM test, `vm_socketcan` "
              "and `vm_monitor`, 3 times)",
              "wall times under TCG: date and machine in the blocks, not checked; the parsing: "
              "`vm_socketcan_decode`, `vm_monitor_decode`",
              {"docs/how-to/socketcan.md": ("socketcan-vm", "socketcan-vm-monitor")}, vm=True),
    Generator("budget", ("tools/target", "budget", "--update-docs"),
              "budget tables in [target.md](../results/target.md) and "
              "[stm32f4.md](../how-to/stm32f4.md), "
              "`docs/results/budget.json`", "`tools/target budget --update-docs`",
              "numbers of one run, not checked; the rendering: `target_budget_docs`",
              {"docs/results/target.md": ("target-budget",),
               "docs/how-to/stm32f4.md": ("target-budget",)}),
    Generator("demo", ("tools/demo", "--update-docs"),
              "`docs/results/demo.json`, `docs/img/demo.png`, `docs/results/demo_control.json`, "
              "`docs/img/demo_control.png` (the closed-loop part)", "`tools/demo --update-docs`",
              "numbers of one run; the closed-loop part's claims (transparency against the "
              "drive-off baseline, the step's true torque): `device_tools` "
              "(`tests/device/test_demo_control.py`)"),
    Generator("analyze", ("tools/hdsense", "analyze", "--results-doc",
                          "docs/results/analyze-results.md",
                          "--bench-hour"),
              "[analyze-results.md](../results/analyze-results.md), `docs/results/analyze.json`",
              "`tools/hdsense analyze --results-doc docs/results/analyze-results.md`",
              "`analyze_sim`, `analyze_geometry`, `analyze_iiwa`",
              {"docs/results/analyze-results.md": ("analyze-suite", "analyze-bands",
                                                   "analyze-slow", "analyze-slow-bands",
                                                   "analyze-iiwa")}),
    Generator("bench", ("tools/bench", "--update-docs"),
              "[bench.md](../results/bench.md), `docs/results/bench.json`; "
              "[control.md](../results/control.md) (Results), "
              "`docs/results/control.json`; [random-joints.md](../results/random-joints.md), "
              "`docs/results/random.json`; [control-random.md](../results/control-random.md), "
              "`docs/results/control-random.json`",
              "`tools/bench --update-docs` (one part: `--only control`, `--only random`, "
              "`--only control_random`)",
              "benchmarks: numbers of one run, not checked, but `bench_control_docs` checks the "
              "control section and the default gains against the JSON, the random joints' "
              "CI sample is what `analyze_random_joints` holds the firmware to, and "
              "`bench_control_random_docs` checks the random-joint control section against "
              "its JSON and the seeds' joints",
              {"docs/results/bench.md": ("bench-results",),
               "docs/results/control.md": ("control-results",),
               "docs/results/random-joints.md": ("bench-results",),
               "docs/results/control-random.md": ("control-random-results",)}),
    Generator("control-robust", (PY, "-m", "hdmaint.bench.control_robust", "--write"),
              "[control-robust-gains.md](../decisions/control-robust-gains.md) (the table of "
              "gains tuned over the tune joints)",
              "`cd tools && HD_BUILD_DIR=../build/host-release ../.venv/bin/python -m "
              "hdmaint.bench.control_robust --write` (~8 min; not in `tools/update-docs`)",
              "a decision record: numbers of one run, not checked",
              {"docs/decisions/control-robust-gains.md": ("control-robust-table",)},
              in_all=False),
    Generator("fleet", (PY, "-m", "hdmaint.fleet_bench", "--write"),
              "[fleet.md](../results/fleet.md) (measured section), `docs/results/fleet.json`",
              "`cd tools && ../.venv/bin/python -m hdmaint.fleet_bench --write [--ray-python PY]` "
              "(~5 min)", "a benchmark: numbers of one run; the thresholds table: `fleet`",
              {"docs/results/fleet.md": ("fleet-measured", "fleet-thresholds")}),
    Generator("ros2", (PY, "-m", "hdmaint.ros2_bench", "--update-docs", "docs/how-to/ros2.md"),
              "[ros2.md](../how-to/ros2.md) (Benchmarks)",
              "`HD_BUILD_DIR=build/host-release PYTHONPATH=tools .venv/bin/python -m "
              "hdmaint.ros2_bench --update-docs docs/how-to/ros2.md` (~10 min; not in "
              "`tools/update-docs`)", "a benchmark: date and machine in the block, not checked",
              {"docs/how-to/ros2.md": ("ros2-bench",)}, in_all=False),
    Generator("docgen", (PY, "-m", "hdmaint.docgen", "--write-table"),
              "this table", "`cd tools && ../.venv/bin/python -m hdmaint.docgen --write-table`",
              "`tools_docgen`", {"docs/reference/testing.md": ("docgen-generators",)}),
    Generator("headline", (PY, "-m", "hdmaint.headline", "--write"),
              "the README's headline table (from the results above: last)",
              "`cd tools && ../.venv/bin/python -m hdmaint.headline --write`", "`headline`",
              {"README.md": ("headline",)}),
)
BY_NAME = {g.name: g for g in GENERATORS}

# Older marker syntaxes -> the block name they become (--migrate-markers).
LEGACY = [
    (re.compile(r"^<!-- ([a-z0-9_]+):([a-z0-9_]+):(begin|end) -->$", re.M),
     lambda m: (m.group(3), f"{m.group(1)}-{m.group(2)}")),
    (re.compile(r"^<!-- (generated|end): ([a-z0-9-]+) -->$", re.M),
     lambda m: ("begin" if m.group(1) == "generated" else "end", f"analyze-{m.group(2)}")),
    (re.compile(r"^<!-- (BEGIN|END) ros2:bench -->$", re.M),
     lambda m: (m.group(1).lower(), "ros2-bench")),
]


def migrate(text: str) -> str:
    """text with every older generated-block marker in docblock's syntax."""
    for pattern, name_of in LEGACY:
        def sub(m):
            kind, name = name_of(m)
            return docblock.markers(name)[0 if kind == "begin" else 1]
        text = pattern.sub(sub, text)
    return text


def documents() -> list[Path]:
    return sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]


def protocol_blocks() -> set:
    from hdtools import protocol
    return set(protocol.doc_tables())


def claimed() -> dict:
    """{(document, block): generator name} of every registered block."""
    out = {}
    for g in GENERATORS:
        for doc, names in g.blocks.items():
            for name in names:
                out[(doc, name)] = g.name
    return out


def table() -> str:
    rows = ["| document | written by | checked by |", "|---|---|---|"]
    rows += [f"| {g.what} | {g.shown} | {g.checked} |" for g in GENERATORS]
    return "\n".join(rows)


def write_table() -> Path:
    path = ROOT / "docs" / "reference" / "testing.md"
    old, new = docblock.update(path, {"docgen-generators": table()})
    if new != old:
        docblock.write([(path, new)])
    return path


def run(names: list, vm: bool) -> int:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "tools") + (
        os.pathsep + os.environ["PYTHONPATH"] if os.environ.get("PYTHONPATH") else ""))
    for g in GENERATORS:
        if (names and g.name not in names) or (not names and (not g.in_all or (g.vm and not vm))):
            continue
        print(f"=== {g.name}: {' '.join(g.argv)}", file=sys.stderr, flush=True)
        rc = subprocess.run(list(g.argv), cwd=ROOT, env=env).returncode
        if rc != 0:
            print(f"hdmaint.docgen: {g.name} failed (exit status {rc}); later generators not "
                  "run", file=sys.stderr)
            return 1
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m hdmaint.docgen", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--list", action="store_true", help="list the generators in order")
    ap.add_argument("--only", action="append", default=[], choices=sorted(BY_NAME),
                    help="run only this generator (repeatable)")
    ap.add_argument("--no-vm", action="store_true", help="skip the generators that boot VMs")
    ap.add_argument("--write-table", action="store_true",
                    help="write docs/reference/testing.md's table of the generators")
    ap.add_argument("--migrate-markers", action="store_true",
                    help="rewrite older marker syntaxes in docs/**/*.md and README.md")
    a = ap.parse_args(argv)
    try:
        if a.list:
            for g in GENERATORS:
                flags = (" [vm]" if g.vm else "") + ("" if g.in_all else " [not in all]")
                print(f"{g.name:<12} {' '.join(g.argv)}{flags}")
            return 0
        if a.write_table:
            print(f"wrote {write_table()}")
            return 0
        if a.migrate_markers:
            outputs = [(p, migrate(p.read_text())) for p in documents()]
            changed = [(p, t) for p, t in outputs if t != p.read_text()]
            docblock.write(changed)
            print("migrated " + (", ".join(str(p.relative_to(ROOT)) for p, _ in changed)
                                 or "nothing"))
            return 0
        return run(a.only, vm=not a.no_vm)
    except (HdError, OSError) as exc:
        print(f"hdmaint.docgen: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
