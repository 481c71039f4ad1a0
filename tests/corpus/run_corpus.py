#!/usr/bin/env python3
"""The hostile-input corpus: every CLI of the project against inputs that
must give exit 0 with whole outputs, or one line on stderr and a documented
non-zero status (docs/results/reliability.md, "Exit status").

Each case is a small file tests/corpus/<class>/<name>.case (key = value
lines, '#' comments) next to its input files:

  run = hdjoint-host --sensors mock --duration 0.5 --csv {out:o.csv}
  exit = 3                       expected exit status (a program killed by a
                                 signal never passes: 130 must be exit(130))
  stderr = write failed          substring of stderr (repeatable)
  stdout = samples =             substring of stdout (repeatable)
  not_stdout = ...               must not appear in stdout
  stderr_lines = 1               exact number of non-empty stderr lines
                                 (default: 1 when exit != 0)
  preexist = o.csv               created in the scratch dir before the run
                                 with one known line (repeatable)
  unchanged = o.csv              still exactly that line afterwards
  copy = nvm.bin                 the input file copied into the scratch dir
  same_as_input = nvm.bin        ... and still equal to the input afterwards
  absent = o.csv / exists = o.csv
  lines = o.csv 101              exact number of lines
  whole_lines = o.csv            every line ends with a newline
  contains_hex = nvm.bin 0000d840    the file holds these bytes
  signal = INT 0.7               send SIGINT 0.7 s after the start
  fsize_limit = 20000            RLIMIT_FSIZE in bytes (a disk that fills up)
  stdout_to = /dev/full          the program's stdout
  generate = big.ini 1100000     a scratch file of that many bytes of comments
  pending = why                  known to fail until `why` lands: reported,
                                 not failed; a pending case that passes fails
                                 (remove the mark)
  before = fail | code | wording | pass   how the code before issue 18
                                 (d9ce5d9) did: fail = wrong outcome; code =
                                 one line but another non-zero status;
                                 wording = only the message differs
                                 (written by --mark-before)

Placeholders in `run`: {in:NAME} an input file next to the case, {out:NAME}
and {tmp:NAME} a path in the scratch dir, {dir} the scratch dir, {fifo} a
FIFO in it, {scenario:NAME} sim/scenarios/NAME.

Always checked: no Python traceback, no sanitizer report, no temporary file
(".NAME.*tmp*") left in the scratch dir, no timeout.

Tools: hdjoint-host, hdsim, hdsim-campaign (class "c": also run under the
asan build) and hdsense (class "py": needs the plain build's shared
libraries).  Usage:

  run_corpus.py --build BUILD [--root ROOT] [--only c|py] [-k TEXT] [-v]
  run_corpus.py --doc docs/results/reliability.md [--check]   the class table
  run_corpus.py --build OLD_BUILD --root OLD_ROOT --mark-before
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
C_TOOLS = {"hdjoint-host": "firmware/host/hdjoint-host", "hdsim": "sim/hdsim",
           "hdsim-campaign": "sim/hdsim-campaign"}
OLD_LINE = "OLD CONTENT\n"
DOC_BLOCK = "corpus-classes"    # hdtools.docblock
CLASS_TEXT = {
    "host-output": "hdjoint-host outputs: full disk, /dev/full, unwritable paths, signals, NVM persistence",
    "host-args": "hdjoint-host command line and --cmd frames",
    "host-input": "hdjoint-host inputs: configuration, replay, NVM image, scenario, non-regular files",
    "scenario": "scenario parser (through hdsim): numbers, bytes, sizes, duplicate keys",
    "hdsim-cli": "hdsim command line and outputs",
    "campaign": "hdsim-campaign command line and output",
    "canlog": "hdsense canlog decode / commands",
    "calib": "hdsense calib: data it cannot judge, dates, serials, outputs",
    "hdsense": "hdsense command line in general",
    "joint-tools": "hdsense profile, current, device, send, monitor, control, tune; hdjoint-host --profile, --cmd-at",
    "ros2": "MCAP / rosbag2 in and out: hdsense analyze on bags, canlog convert, monitor --mcap",
    "fleet": "hdsense fleet: corrupt logs, other gear ratios, no identity, empty inputs, scheduler, store, full disk",
}
SANITIZER = re.compile(r"ERROR: AddressSanitizer|runtime error:|LeakSanitizer")


@dataclass
class Case:
    path: Path
    klass: str
    name: str
    run: str = ""
    exit: int = 0
    stderr: list = field(default_factory=list)
    stdout: list = field(default_factory=list)
    not_stdout: list = field(default_factory=list)
    stderr_lines: int | None = None
    preexist: list = field(default_factory=list)
    unchanged: list = field(default_factory=list)
    copy: list = field(default_factory=list)
    same_as_input: list = field(default_factory=list)
    absent: list = field(default_factory=list)
    exists: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    whole_lines: list = field(default_factory=list)
    contains_hex: list = field(default_factory=list)
    generate: list = field(default_factory=list)
    signal: tuple | None = None
    fsize_limit: int | None = None
    stdout_to: str | None = None
    pending: str | None = None
    before: str | None = None
    timeout: float = 60.0

    @property
    def tool(self) -> str:
        return shlex.split(self.run)[0]

    @property
    def lang(self) -> str:
        return "c" if self.tool in C_TOOLS else "py"


LIST_KEYS = {"stderr", "stdout", "not_stdout", "preexist", "unchanged", "copy", "same_as_input",
             "absent", "exists",
             "lines", "whole_lines", "contains_hex", "generate"}


def load_case(path: Path) -> Case:
    case = Case(path=path, klass=path.parent.name, name=path.stem)
    for no, raw in enumerate(path.read_text().splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        key, sep, value = line.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not hasattr(case, key) or key in ("path", "klass", "name"):
            raise SystemExit(f"{path}:{no}: bad line {raw!r}")
        if key in LIST_KEYS:
            getattr(case, key).append(value)
        elif key in ("exit", "stderr_lines", "fsize_limit"):
            setattr(case, key, int(value))
        elif key == "timeout":
            case.timeout = float(value)
        elif key == "signal":
            sig, delay = value.split()
            case.signal = (getattr(signal, "SIG" + sig), float(delay))
        else:
            setattr(case, key, value)
    if not case.run:
        raise SystemExit(f"{path}: no run line")
    return case


def all_cases() -> list[Case]:
    return [load_case(p) for p in sorted(HERE.glob("*/*.case"))]


class Env:
    def __init__(self, build: Path, root: Path, python: str):
        self.build, self.root, self.python = build, root, python

    def argv(self, case: Case, scratch: Path) -> list[str]:
        def sub(m: re.Match) -> str:
            kind, _, arg = m.group(1).partition(":")
            if kind == "in":
                return str(case.path.parent / arg)
            if kind in ("out", "tmp"):
                return str(scratch / arg)
            if kind == "dir":
                return str(scratch)
            if kind == "fifo":
                fifo = scratch / "fifo"
                if not fifo.exists():
                    os.mkfifo(fifo)
                return str(fifo)
            if kind == "scenario":
                return str(self.root / "sim" / "scenarios" / arg)
            raise SystemExit(f"{case.path}: unknown placeholder {{{m.group(1)}}}")
        words = [re.sub(r"\{([a-z]+(?::[^}]*)?)\}", sub, w) for w in shlex.split(case.run)]
        tool = words[0]
        if tool in C_TOOLS:
            return [str(self.build / C_TOOLS[tool])] + words[1:]
        if tool == "hdsense":
            return [self.python, "-m", "hdtools.cli"] + words[1:]
        raise SystemExit(f"{case.path}: unknown tool {tool}")


def _limits(fsize: int | None):
    def pre():
        if fsize is not None:
            # a disk that fills up: writes past the limit fail (EFBIG).  The
            # programs must ignore SIGXFSZ themselves (subprocess resets it to
            # the default, which kills): that is part of what is tested.
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
    return pre


def _other_code(problem: str) -> bool:
    """"exit X, expected Y" with X and Y both failures: another documented
    non-zero status, not a wrong outcome."""
    m = re.match(r"exit (\d+), expected (\d+)$", problem)
    return bool(m) and int(m.group(1)) != 0 and int(m.group(2)) != 0


def verdict(problems: list[str]) -> str:
    """pass | wording (only the message text differs) | code (a non-zero
    status other than today's, one line, nothing else wrong) | fail."""
    if not problems:
        return "pass"
    if all(p.startswith("stderr lacks") for p in problems):
        return "wording"
    if all(p.startswith("stderr lacks") or _other_code(p) for p in problems):
        return "code"
    return "fail"


def run_case(case: Case, env: Env) -> tuple[bool, list[str], dict]:
    """(passed, problems, details)."""
    problems: list[str] = []
    with tempfile.TemporaryDirectory(prefix=f"corpus-{case.name}-") as tmp:
        scratch = Path(tmp)
        for p in case.preexist:
            (scratch / p).write_text(OLD_LINE)
        for p in case.copy:
            shutil.copyfile(case.path.parent / p, scratch / p)
        for g in case.generate:
            name, size = g.split()
            line = b"# " + b"x" * 76 + b"\n"
            data = (line * (int(size) // len(line) + 1))[:int(size)]
            (scratch / name).write_bytes(data)
        argv = env.argv(case, scratch)
        penv = dict(os.environ, PYTHONPATH=str(env.root / "tools"), HD_BUILD_DIR=str(env.build),
                    ASAN_OPTIONS="detect_leaks=1", PYTHONDONTWRITEBYTECODE="1")
        penv.pop("HDSENSE_TRACEBACK", None)
        stdout_file = open(case.stdout_to, "wb") if case.stdout_to else subprocess.PIPE
        t0 = time.monotonic()
        try:
            proc = subprocess.Popen(argv, stdout=stdout_file, stderr=subprocess.PIPE,
                                    stdin=subprocess.DEVNULL, cwd=scratch, env=penv,
                                    preexec_fn=_limits(case.fsize_limit))
            if case.signal:
                sig, delay = case.signal
                try:
                    proc.wait(timeout=delay)
                except subprocess.TimeoutExpired:
                    proc.send_signal(sig)
            out, err = proc.communicate(timeout=case.timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
            problems.append(f"timeout after {case.timeout} s")
        finally:
            if case.stdout_to:
                stdout_file.close()
        elapsed = time.monotonic() - t0
        out = (out or b"").decode("utf-8", "replace")
        err = (err or b"").decode("utf-8", "replace")
        rc = proc.returncode
        if rc != case.exit:
            problems.append(f"exit {rc} (killed by signal {-rc})" if rc < 0 else
                            f"exit {rc}, expected {case.exit}")
        if "Traceback (most recent call last)" in err:
            problems.append("Python traceback on stderr")
        if SANITIZER.search(err):
            problems.append("sanitizer report on stderr")
        err_lines = [ln for ln in err.splitlines() if ln.strip()]
        want_lines = case.stderr_lines if case.stderr_lines is not None else (
            1 if case.exit != 0 else None)
        if want_lines is not None and len(err_lines) != want_lines:
            problems.append(f"{len(err_lines)} stderr lines, expected {want_lines}")
        for s in case.stderr:
            if s not in err:
                problems.append(f"stderr lacks {s!r}")
        for s in case.stdout:
            if s not in out:
                problems.append(f"stdout lacks {s!r}")
        for s in case.not_stdout:
            if s in out:
                problems.append(f"stdout has {s!r}")
        for p in case.unchanged:
            f = scratch / p
            if not f.exists() or f.read_bytes() != OLD_LINE.encode():
                problems.append(f"{p} changed")
        for p in case.same_as_input:
            f = scratch / p
            if not f.exists() or f.read_bytes() != (case.path.parent / p).read_bytes():
                problems.append(f"{p} differs from the input it was copied from")
        for p in case.absent:
            if (scratch / p).exists():
                problems.append(f"{p} exists")
        for p in case.exists:
            if not (scratch / p).exists():
                problems.append(f"{p} missing")
        for spec in case.lines:
            p, n = spec.split()
            f = scratch / p
            got = f.read_bytes().count(b"\n") if f.exists() else None
            if got != int(n):
                problems.append(f"{p}: {got} lines, expected {n}")
        for p in case.whole_lines:
            f = scratch / p
            data = f.read_bytes() if f.exists() else None
            if not data or not data.endswith(b"\n"):
                problems.append(f"{p}: missing or last line cut")
        for spec in case.contains_hex:
            p, hexs = spec.split()
            f = scratch / p
            if not f.exists() or bytes.fromhex(hexs) not in f.read_bytes():
                problems.append(f"{p} does not hold {hexs}")
        left = [q.name for q in scratch.iterdir() if q.name.startswith(".") and "tmp" in q.name]
        if left:
            problems.append(f"temporary files left: {left}")
    details = {"exit": rc, "stderr": err_lines[:3], "seconds": elapsed}
    return not problems, problems, details


def doc_table(cases: list[Case]) -> str:
    classes: dict[str, list[Case]] = {}
    for c in cases:
        classes.setdefault(c.klass, []).append(c)
    rows = ["| class | what | cases | C tools (also under ASan) | pending | "
            "failed before the corpus (d9ce5d9) | before: other status only |",
            "|---|---|---|---|---|---|---|"]
    tot = [0, 0, 0, 0, 0]
    for k in sorted(classes, key=lambda k: list(CLASS_TEXT).index(k) if k in CLASS_TEXT else 99):
        cs = classes[k]
        n, nc = len(cs), sum(c.lang == "c" for c in cs)
        npend = sum(c.pending is not None for c in cs)
        nold = sum(c.before == "fail" for c in cs)
        ncode = sum(c.before == "code" for c in cs)
        tot = [tot[0] + n, tot[1] + nc, tot[2] + npend, tot[3] + nold, tot[4] + ncode]
        rows.append(f"| `{k}` | {CLASS_TEXT.get(k, '')} | {n} | {nc} | {npend} | {nold} | {ncode} |")
    rows.append(f"| **all** | | **{tot[0]}** | {tot[1]} | {tot[2]} | **{tot[3]}** | {tot[4]} |")
    exits: dict[int, int] = {}
    for c in cases:
        exits[c.exit] = exits.get(c.exit, 0) + 1
    rows.append("")
    rows.append("Expected exit status over the corpus: " +
                ", ".join(f"{code}: {n}" for code, n in sorted(exits.items())) + ".")
    return "\n".join(rows)


def write_doc(path: Path, cases: list[Case], check: bool) -> int:
    sys.path.insert(0, str(ROOT / "tools"))     # hdtools.docblock and safeio, this checkout's
    from hdtools import docblock
    from hdtools.safeio import OutputError, Outputs, UsageError
    text = path.read_text()
    try:
        new = docblock.splice(text, DOC_BLOCK, "<!-- written by tests/corpus/run_corpus.py --doc; "
                              f"do not edit -->\n{doc_table(cases)}", str(path))
    except UsageError as exc:
        print(exc, file=sys.stderr)
        return 1
    summary_path = path.resolve().parent / "corpus.json"    # the page sits in docs/results/
    summary = json.dumps(corpus_summary(cases), indent=1) + "\n"
    if check:
        if new != text or not summary_path.is_file() or summary_path.read_text() != summary:
            print(f"{path}: the corpus table or {summary_path.name} is out of date: run "
                  f"tests/corpus/run_corpus.py --doc {path}", file=sys.stderr)
            return 1
        print(f"{path}: corpus table up to date ({len(cases)} cases)")
        return 0
    summary_path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with Outputs() as out:              # both or neither
            out.write_text(path, new)
            out.write_text(summary_path, summary)
            out.commit()
    except OutputError as exc:
        print(exc, file=sys.stderr)
        return 1
    print(f"{path}: corpus table written ({len(cases)} cases), and {summary_path}")
    return 0


def corpus_summary(cases: list[Case]) -> dict:
    """docs/results/corpus.json, the README headline's source: how many
    hostile inputs, in how many classes, and how many the tools failed
    before issue 18 (each case's `before` line)."""
    return {"tool": "tests/corpus/run_corpus.py --doc docs/results/reliability.md",
            "cases": len(cases), "classes": len({c.klass for c in cases}),
            "per_class": {k: sum(c.klass == k for c in cases)
                          for k in sorted({c.klass for c in cases},
                                          key=lambda k: list(CLASS_TEXT).index(k)
                                          if k in CLASS_TEXT else 99)},
            "c_cases": sum(c.lang == "c" for c in cases),
            "pending": sum(c.pending is not None for c in cases),
            "failed_before": sum(c.before == "fail" for c in cases)}


def mark_before(cases: list[Case], results: dict) -> None:
    """before = pass | wording | code | fail (see verdict)."""
    for c in cases:
        if c.name not in results.get(c.klass, {}):
            continue
        v = verdict(results[c.klass][c.name])
        text = c.path.read_text()
        text = re.sub(r"(?m)^before = .*\n", "", text)
        if not text.endswith("\n"):
            text += "\n"
        c.path.write_text(text + f"before = {v}\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", type=Path, help="build tree with the executables")
    ap.add_argument("--root", type=Path, default=ROOT, help="source tree (tools/, sim/scenarios)")
    ap.add_argument("--python", default=sys.executable, help="interpreter for hdsense")
    ap.add_argument("--only", choices=["c", "py"], help="only the C tools or only hdsense")
    ap.add_argument("-k", dest="filter", help="only cases whose class/name contains this")
    ap.add_argument("-v", "--verbose", action="store_true")
    ap.add_argument("--doc", type=Path, help="write (or --check) the class table in this file")
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--mark-before", action="store_true",
                    help="record pass/fail of this (old) build in each case's `before` line")
    args = ap.parse_args(argv)
    cases = all_cases()
    if args.doc:
        return write_doc(args.doc, cases, args.check)
    if args.build is None:
        ap.error("--build is required")
    python = os.path.abspath(args.python) if os.sep in args.python else args.python
    env = Env(args.build.resolve(), args.root.resolve(), python)
    sel = [c for c in cases if (args.only is None or c.lang == args.only) and
           (args.filter is None or args.filter in f"{c.klass}/{c.name}")]
    if not sel:
        print("no cases selected", file=sys.stderr)
        return 1
    failed, pending_ok, results = [], [], {}
    counts: dict[str, list[int]] = {}
    for c in sel:
        ok, problems, det = run_case(c, env)
        results.setdefault(c.klass, {})[c.name] = problems
        cnt = counts.setdefault(c.klass, [0, 0])
        cnt[0] += 1
        cnt[1] += ok
        label = f"{c.klass}/{c.name}"
        if c.pending is not None and not args.mark_before:
            if ok:
                failed.append(label)
                print(f"PASS-PENDING {label}: passes now; remove `pending = {c.pending}`")
            else:
                pending_ok.append(label)
                if args.verbose:
                    print(f"pending      {label}: {'; '.join(problems)} ({c.pending})")
            continue
        if ok:
            if args.verbose:
                print(f"ok           {label} (exit {det['exit']}, {det['seconds']:.2f} s)")
        else:
            failed.append(label)
            print(f"FAIL         {label}: {'; '.join(problems)}")
            for ln in det["stderr"]:
                print(f"             stderr: {ln}")
    if args.mark_before:
        mark_before(sel, results)
        tally: dict[str, int] = {}
        for r in results.values():
            for p in r.values():
                tally[verdict(p)] = tally.get(verdict(p), 0) + 1
        print(f"marked {len(sel)} cases on this build: {tally}")
        return 0
    for k, (n, ok) in counts.items():
        print(f"{k:12s} {ok}/{n} as expected")
    print(f"{len(sel)} cases, {len(failed)} failed, {len(pending_ok)} pending "
          f"({args.build})")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
