"""tools/target budget --update-docs: both ports' budgets into
docs/results/target.md, docs/how-to/stm32f4.md (between their markers) and
docs/results/budget.json, all or none; and tools/target budget (print,
--json).  Standard library only."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from hdtools import docblock
from hdtools.safeio import UsageError

from . import stm32f4
from .board import BOARDS, ROOT, Board, TargetError
from .budget import TICK_PERIOD_US, budget, write_files, write_json
from .budget_render import budget_summary, render_budget

BLOCK = "target-budget"
DOC_BEGIN, DOC_END = docblock.markers(BLOCK)
DOC_NOTE = "<!-- written by tools/target budget --update-docs; do not edit -->"


def replace_block(text: str, body: str, name: str) -> str:
    """text with everything between its budget markers replaced by body;
    TargetError (naming the document) unless each marker occurs once, in
    order."""
    try:
        return docblock.splice(text, BLOCK, f"{DOC_NOTE}\n\n{body}\n", name)
    except UsageError as exc:
        raise TargetError(str(exc)) from None


def doc_paths(docs: Path) -> dict:
    return {"mps2-an386": docs / "results" / "target.md",
            "stm32f4": docs / "how-to" / "stm32f4.md",
            "json": docs / "results" / "budget.json"}


def read_docs(docs: Path) -> dict:
    """The two budget documents' text, checked for markers (TargetError)."""
    texts = {}
    for board in ("mps2-an386", "stm32f4"):
        path = doc_paths(docs)[board]
        try:
            texts[board] = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise TargetError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") \
                from None
        replace_block(texts[board], "", str(path))
    return texts


def source_state() -> dict:
    """The commit the numbers were measured on, and whether the tree had
    uncommitted changes then outside docs/ (git; 'unknown' outside a
    checkout)."""
    try:
        head = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short=12", "HEAD"],
                              capture_output=True, text=True, timeout=30)
        dirty = subprocess.run(["git", "-C", ROOT, "status", "--porcelain",
                                "--untracked-files=no", "--", ".", ":(exclude)docs",
                                ":(exclude)README.md"],
                               capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return {"commit": "unknown", "uncommitted_changes": None}
    if head.returncode != 0:
        return {"commit": "unknown", "uncommitted_changes": None}
    return {"commit": head.stdout.strip(), "uncommitted_changes": bool(dirty.stdout.strip())}


def write_budget_docs(docs: Path, m4: dict, f4: dict, source: dict) -> list:
    """Renders both boards' budgets into target.md, stm32f4.md (between the
    markers) and results/budget.json under docs, all or none.  Returns the
    paths written."""
    paths, texts = doc_paths(docs), read_docs(docs)
    # Both pages sit one folder below docs/, so one relative link serves both.
    where = (f"Measured at commit {source['commit']}"
             + (" with uncommitted changes" if source["uncommitted_changes"] else "")
             + "; the numbers: [results/budget.json](../results/budget.json).")
    summary = {"generated_by": "tools/target budget --update-docs", "source": source,
               "tick_period_us": TICK_PERIOD_US, "clock_mhz": m4["clock_mhz"],
               "mps2-an386": budget_summary(m4), "stm32f4": stm32f4.summary(f4)}
    outputs = [(paths["mps2-an386"], replace_block(
                    texts["mps2-an386"], f"{where}\n\n{render_budget(m4)}",
                    str(paths["mps2-an386"]))),
               (paths["stm32f4"], replace_block(
                    texts["stm32f4"], f"{where}\n\n{stm32f4.render(f4)}",
                    str(paths["stm32f4"]))),
               (paths["json"], json.dumps(summary, indent=1) + "\n")]
    write_files(outputs)
    return [p for p, _ in outputs]


def cmd_update_docs(a) -> int:
    """Measures both ports and rewrites their budget documents and
    docs/results/budget.json; nothing is written when a check fails."""
    docs = Path(a.docs)
    read_docs(docs)  # fail on a document without markers before measuring
    m4 = budget(BOARDS["mps2-an386"])
    f4 = stm32f4.measure(BOARDS["stm32f4"])
    failures = m4["failures"] + f4["failures"]
    if failures:
        print(f"tools/target: budget checks failed, nothing written: {'; '.join(failures)}",
              file=sys.stderr)
        return 1
    written = write_budget_docs(docs, m4, f4, source_state())
    print("updated " + ", ".join(str(p) for p in written))
    return 0


def cmd_budget(board: Board, a) -> int:
    """tools/target budget [--json FILE] on one port: its tables, its FAIL lines."""
    if board.name == "mps2-an386":
        numbers, text = budget(board), render_budget
    else:
        numbers, text = stm32f4.measure(board), stm32f4.render
    print(text(numbers))
    if a.json:
        write_json(Path(a.json), numbers)
    for failure in numbers["failures"]:
        print(f"\nFAIL: {failure}")
    return 1 if numbers["failures"] else 0


# --------------------------------------------------------------------- main
