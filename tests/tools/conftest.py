"""Shared helpers for the analyze tests: the simulated joint (hdsim) and the
analysis entry point, both from the CMake build tree (HD_BUILD_DIR)."""
from __future__ import annotations

import difflib
import re
import subprocess
from pathlib import Path

import pytest

from hdtools import native

ROOT = Path(__file__).resolve().parents[2]
# (header, array) of a CSV and back: plain numpy, independent of the tool's
# loader (hdtools.analysis.loading); the results tables' cases use them too.
from hdtools.analysis.results import read_csv, write_csv  # noqa: F401

SCENARIOS = Path(__file__).resolve().parent / "scenarios"


@pytest.fixture(scope="session")
def hdsim(build_dir):
    # not built: skipped by hand, a failure under CTest (tests/conftest.py)
    return native.find_file("hdsim", target="hdsim_cli")


@pytest.fixture(scope="session")
def simulate(hdsim, tmp_path_factory):
    """simulate(name, *--set overrides) -> path of the CSV (cached)."""
    from hdtools.analysis import results
    return results.simulator(hdsim, tmp_path_factory.mktemp("sim"))


def analyze(path, **kw):
    from hdtools.analysis import pipeline
    kw.setdefault("log", lambda *a: None)
    return pipeline.analyze(str(path), **kw)


@pytest.fixture(scope="session")
def analyzed(case_report):
    """analyzed(name) -> the report of the suite case of that scenario."""
    return case_report


def never_worse_out_of_sample(history):
    """Every kept change lowered (or kept) the held-out innovation, by the
    measure it was judged on (its likelihood for R, else its RMS)."""
    for h0, h1 in zip(history, history[1:]):
        key = "out_of_sample_" + h1.get("judged_by", "innovation_rms_nm")
        assert h1[key] <= h0[key] + 1e-6 * abs(h0[key]), (h1["change"], key, h0[key], h1[key])


def added(report):
    return [e for e in report["effects"] if e["added"]]


@pytest.fixture(scope="session")
def case_report(simulate, tmp_path_factory):
    """case_report(name) -> the report of a case of hdtools.analysis.results
    (SUITE or SLOW: scenario, --set overrides, the CSV transform), analysed
    once per session: the tests and docs/results/analyze-results.md see the same
    runs."""
    from hdtools.analysis import results
    cases = {c.name: c for c in results.SUITE + results.SLOW}
    tmp = tmp_path_factory.mktemp("cases")
    cache = {}

    def run(name):
        if name not in cache:
            c = cases[name]
            cache[name] = analyze(results.prepare(c, simulate, tmp), **c.kwargs)
        return cache[name]
    return run


def doc_section(name, lines):
    """The generated section of docs/results/analyze-results.md and the one these
    reports give (equal unless the file is stale)."""
    from hdtools.analysis import results
    text = results.DOC.read_text() if results.DOC.is_file() else ""
    return results.extract(text, name), results.section(name, lines)


def assert_summary_current(part, entries):
    """docs/results/analyze.json (the README's headline source, written in
    the same run as docs/results/analyze-results.md) holds these entries of `part`
    ("cases" or "iiwa"): numbers to the tables' tolerance (DOC_NUMBER_REL,
    DOC_NUMBER_ABS: the processor's rounding)."""
    import json
    from hdtools.analysis import results
    stale = ("docs/results/analyze.json is stale: run "
             "tools/hdsense analyze --results-doc docs/results/analyze-results.md")
    assert results.SUMMARY.is_file(), stale
    stored = json.loads(results.SUMMARY.read_text())[part]
    for name, now in entries.items():
        now = results._finite(now)
        assert set(stored.get(name, {})) == set(now), f"{stale} ({name})"
        for key, value in now.items():
            if isinstance(value, float):
                assert stored[name][key] == pytest.approx(
                    value, rel=DOC_NUMBER_REL, abs=DOC_NUMBER_ABS), f"{stale} ({name} {key})"
            else:
                assert stored[name][key] == value, f"{stale} ({name} {key})"


# Numbers in a generated table may differ in their last printed digit from
# one processor to another (numpy's BLAS kernels round differently); a table
# is stale when its words differ or a number moves by more than this.
DOC_NUMBER_REL = 5e-3
# ... or by less than this in absolute value: a residual of a millinewton-metre
# (a twentieth of the sensor noise) is where the kernels' rounding reaches
# the analysis' choices (output3's slow error after the loop read 1.47 mN m
# on one processor and 1.14 on another).
DOC_NUMBER_ABS = 5e-4
_NUMBER = re.compile(r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")


def same_text_but_rounding(a, b, rel=DOC_NUMBER_REL, abs_tol=DOC_NUMBER_ABS):
    """a and b are the same text, each number within rel of the other's or
    within abs_tol of it."""
    pa, pb = _NUMBER.split(a), _NUMBER.split(b)
    if len(pa) != len(pb):
        return False
    for i, (x, y) in enumerate(zip(pa, pb)):
        if i % 2 == 0:
            if x != y:
                return False
        elif x != y and abs(float(x) - float(y)) > max(
                abs_tol, rel * max(abs(float(x)), abs(float(y)))):
            return False
    return True


def assert_doc_current(sections):
    """Each (name, lines) section of docs/results/analyze-results.md is what these
    reports give (numbers to DOC_NUMBER_REL)."""
    for name, lines in sections:
        in_doc, now = doc_section(name, lines)
        assert same_text_but_rounding(in_doc, now), (
            f"docs/results/analyze-results.md section {name!r} is stale: run "
            "tools/hdsense analyze --results-doc docs/results/analyze-results.md\n"
            + "\n".join(l for l in difflib.unified_diff(in_doc.splitlines(), now.splitlines(),
                                                        lineterm="", n=0)))
