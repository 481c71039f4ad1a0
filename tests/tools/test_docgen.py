"""One doc generator registry and one marker syntax (tools/hdmaint/docgen.py,
tools/hdtools/docblock.py; no build needed): every generated block of
docs/**/*.md and README.md is in the one syntax and written by exactly one
registered generator (hdtools.protocol's tables included), every registered
block is there, docs/reference/testing.md's table is the registry's, and splicing,
migrating and running behave as written out by hand below."""
from __future__ import annotations

import re
import sys

import pytest

from conftest import ROOT
from hdmaint import docgen
from hdtools import docblock
from hdtools.safeio import UsageError

# Hand-written blocks that tests check against the code (not generated).
CHECKED = {"docs/how-to/ros2.md": {"<!-- BEGIN ros2:topics -->", "<!-- END ros2:topics -->",
                            "<!-- BEGIN ros2:contract -->", "<!-- END ros2:contract -->",
                            "<!-- BEGIN ros2_control:interfaces -->",
                            "<!-- END ros2_control:interfaces -->",
                            "<!-- BEGIN ros2_control:urdf -->", "<!-- END ros2_control:urdf -->"}}


def docs() -> dict:
    return {str(p.relative_to(ROOT)): p.read_text() for p in docgen.documents()}


def test_one_marker_syntax():
    other = {rel: set(docblock.foreign_markers(text)) - CHECKED.get(rel, set())
             for rel, text in docs().items()}
    assert {k: v for k, v in other.items() if v} == {}


def test_every_block_has_one_generator_and_every_registered_block_is_there():
    protocol = docgen.protocol_blocks()
    claimed = docgen.claimed()
    found = {(rel, name) for rel, text in docs().items() for name in docblock.names(text)}
    orphans = sorted(f"{rel}: {name}" for rel, name in found if (rel, name) not in claimed
                     and not (rel.startswith("docs/") and name in protocol))
    assert orphans == [], "generated blocks no registered generator writes"
    missing = sorted(f"{rel}: {name}" for rel, name in claimed if (rel, name) not in found)
    assert missing == [], "registered blocks missing from their documents"
    assert all("-" in name for _, name in claimed if name != "headline"), \
        "names without a hyphen are hdtools.protocol's"
    for rel, text in docs().items():
        names = docblock.names(text)
        assert len(names) == len(set(names)), f"{rel}: a block twice"


def test_testing_md_table_is_the_registry():
    text = (ROOT / "docs" / "reference" / "testing.md").read_text()
    assert docblock.body(text, "docgen-generators", "testing.md") == docgen.table(), \
        "run (cd tools && ../.venv/bin/python -m hdmaint.docgen --write-table)"


def test_update_docs_runs_the_registry():
    script = (ROOT / "tools" / "update-docs").read_text()
    assert "-m hdmaint.docgen" in script
    code = "\n".join(ln for ln in script.splitlines() if not ln.lstrip().startswith("#"))
    for g in docgen.GENERATORS:     # no generator run beside the registry
        assert " ".join(g.argv[1:]) not in code, g.name


def test_splice_by_hand():
    doc = "# t\n<!-- BEGIN generated:x-y -->\nold\nlines\n<!-- END generated:x-y -->\ntail\n"
    assert docblock.splice(doc, "x-y", "new", "d.md") == \
        "# t\n<!-- BEGIN generated:x-y -->\nnew\n<!-- END generated:x-y -->\ntail\n"
    assert docblock.body(doc, "x-y", "d.md") == "old\nlines"
    assert docblock.names(doc) == ["x-y"]
    for bad in ("# no block\n", doc + doc,
                "<!-- END generated:x-y -->\n<!-- BEGIN generated:x-y -->\n"):
        with pytest.raises(UsageError, match="d.md: needs one"):
            docblock.splice(bad, "x-y", "new", "d.md")
    with pytest.raises(ValueError):
        docblock.markers("no spaces")


def test_migrate_by_hand():
    old = ("a\n<!-- target:budget:begin -->\nx\n<!-- target:budget:end -->\n"
           "<!-- generated: slow-bands -->\ny\n<!-- end: slow-bands -->\n"
           "<!-- BEGIN ros2:bench -->\nz\n<!-- END ros2:bench -->\n"
           "<!-- BEGIN ros2:topics -->\n<!-- written by x; do not edit -->\n")
    assert docgen.migrate(old) == (
        "a\n<!-- BEGIN generated:target-budget -->\nx\n<!-- END generated:target-budget -->\n"
        "<!-- BEGIN generated:analyze-slow-bands -->\ny\n"
        "<!-- END generated:analyze-slow-bands -->\n"
        "<!-- BEGIN generated:ros2-bench -->\nz\n<!-- END generated:ros2-bench -->\n"
        "<!-- BEGIN ros2:topics -->\n<!-- written by x; do not edit -->\n")
    assert docgen.migrate(docgen.migrate(old)) == docgen.migrate(old)
    assert docblock.foreign_markers(old) == [
        "<!-- target:budget:begin -->", "<!-- target:budget:end -->",
        "<!-- generated: slow-bands -->", "<!-- end: slow-bands -->",
        "<!-- BEGIN ros2:bench -->", "<!-- END ros2:bench -->", "<!-- BEGIN ros2:topics -->"]


def test_run_stops_at_the_first_failing_generator(monkeypatch, tmp_path, capsys):
    mark = tmp_path / "ran"
    fake = (docgen.Generator("ok", (sys.executable, "-c", "pass"), "", "", ""),
            docgen.Generator("fails", (sys.executable, "-c", "raise SystemExit(3)"), "", "", ""),
            docgen.Generator("later", (sys.executable, "-c",
                                       f"open({str(mark)!r}, 'w').close()"), "", "", ""))
    monkeypatch.setattr(docgen, "GENERATORS", fake)
    assert docgen.run([], vm=True) == 1
    assert not mark.exists()
    err = capsys.readouterr().err
    assert re.search(r"fails failed \(exit status 3\)", err)
    assert docgen.run(["later"], vm=True) == 0 and mark.exists()


def prose(text: str) -> str:
    """text without its generated blocks (what people typed)."""
    for name in docblock.names(text):
        begin, end = docblock.markers(name)
        text = text[:text.index(begin)] + text[text.index(end) + len(end):]
    return text


def test_no_issue_numbers_in_typed_docs():
    """History lives in docs/decisions/ and git, not in "issue N" asides."""
    found = [f"{rel}: {m.group(0)}" for rel, text in docs().items()
             for m in re.finditer(r"(?i)\bissues? \d+", prose(text))]
    assert found == []


def slugs(text: str) -> set:
    """The anchors GitHub gives text's headings: lower case, punctuation
    but '-' and '_' dropped, spaces to '-', a repeated one suffixed -1, -2."""
    out, seen = set(), {}
    for title in re.findall(r"^#{1,6} +(.+?) *#*$", text, flags=re.M):
        slug = re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def broken_links(page) -> list:
    """page's relative links (outside code fences) whose file or heading
    anchor does not exist."""
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    name = page.relative_to(ROOT) if page.is_relative_to(ROOT) else page.name
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        path, _, anchor = target.partition("#")
        if re.match(r"[a-z]+:", path):
            continue
        dest = (page.parent / path) if path else page
        if not dest.exists():
            broken.append(f"{name}: {target}")
        elif anchor and dest.suffix == ".md" and anchor not in slugs(
                re.sub(r"```.*?```", "", dest.read_text(), flags=re.S)):
            broken.append(f"{name}: {target} (no such heading)")
    return broken


def test_relative_links_resolve():
    """Every relative link of README.md, CONTRIBUTING.md and docs/**/*.md
    names a file of the tree, and a #heading of a page names one of its
    headings."""
    pages = docgen.documents() + [ROOT / "CONTRIBUTING.md"]
    assert ROOT / "docs" / "README.md" in pages and \
        ROOT / "docs" / "decisions" / "README.md" in pages
    assert [b for page in pages for b in broken_links(page)] == []


def test_index_lists_every_page_once_under_its_kind():
    """docs/README.md names each docs/**/*.md once, under the heading of its
    folder (decisions/ is design history), by the page's own title."""
    text = (ROOT / "docs" / "README.md").read_text()
    kind = {"how-to": "How-to", "reference": "Reference", "design": "Design",
            "decisions": "Design", "results": "Results"}
    listed, heading = {}, None
    for line in text.splitlines():
        if line.startswith("## "):
            heading = line[3:]
        m = re.match(r"- \[([^]]+)\]\(([^)]+)\): (.+)$", line)
        if m:
            assert m.group(1) == m.group(2) and m.group(2) not in listed, line
            listed[m.group(2)] = (heading, m.group(3))
    pages = {str(p.relative_to(ROOT / "docs")): p for p in docgen.documents()
             if p.parent != ROOT and p != ROOT / "docs" / "README.md"}
    assert sorted(listed) == sorted(pages)
    for rel, (heading, title) in listed.items():
        h1 = re.search(r"^# (.+)$", pages[rel].read_text(), flags=re.M).group(1)
        assert (heading, title) == (kind[rel.split("/")[0]], h1), rel


def test_slugs_and_broken_links_by_hand(tmp_path):
    assert slugs("# A `b` c (d/e)\n## A `b` c (d/e)\n### x_y-z.\n") == \
        {"a-b-c-de", "a-b-c-de-1", "x_y-z"}
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "t.md").write_text("# Top\n## Two words\n")
    page = tmp_path / "p.md"
    page.write_text("[a](sub/t.md) [b](sub/t.md#two-words) [c](#here) [d](https://x/y)\n"
                    "# Here\n```\n[e](nowhere.md)\n```\n")
    assert broken_links(page) == []
    page.write_text("[a](sub/gone.md) [b](sub/t.md#three) [c](#there)\n")
    found = [b.split(": ", 1)[1] for b in broken_links(page)]
    assert found == ["sub/gone.md", "sub/t.md#three (no such heading)",
                      "#there (no such heading)"]


def test_paths_named_in_typed_docs_exist():
    """A `tools/...`, `tests/...` or `docs/...` path in prose names a file of
    the tree (a moved module or page leaves no stale name behind; globs must
    match something)."""
    missing = []
    for rel, text in docs().items():
        for path in re.findall(r"`((?:tools|tests|docs)/[\w./*-]+)`", prose(text)):
            path = path.rstrip(".")
            if not any(ROOT.glob(path)) and not any(ROOT.glob(path + ".*")):  # or its source
                missing.append(f"{rel}: {path}")
    assert missing == []


# A measured-looking number: a decimal with a result unit (x the floor, dB, %,
# a time, an RMS torque), or any count of instructions / ns / joint-hours /
# mN m (errors; inputs are in N m).  Integers with x / % / dB are left out:
# in typed prose they are orders (2x line), thresholds and design inputs.
MEASURED_RE = re.compile(
    r"(?<![\w.])\d+\.\d+ ?(?:x|×|dB|%|us|µs|ns|N m RMS)(?![\w/])"
    r"|(?<![\w.])\d[\d ]*(?:\.\d+)? ?(?:instructions|ns|joint-hours|mN m)(?![\w/])")
# A number right after one of these is a limit or an input, not a result.
LIMIT_RE = re.compile(r"(?:<=|>=|<|(?<!-)>|\+|within|default|by|goal|=|at most|at least) ?$")
# (document, number as matched): constants the pattern cannot tell apart.
CONSTANTS = {
    ("docs/design/analyze.md", "57.3x"): "180/pi, the radian-to-degree factor",
    ("docs/design/analyze.md", "0.75 mN m"): "worked example of a resolution",
    ("docs/reference/sim.md", "1.25 mN m"): "the bridge's gain per mrad, derived",
    ("docs/reference/sim.md", "2.6 mN m"): "the closed-form bridge residual a test checks",
    ("docs/reference/sim.md", "0.1 %"): "a test's tolerance",
    ("docs/how-to/stm32f4.md", "3.2 us"): "ADC conversion time from the clock set-up",
    ("docs/how-to/stm32f4.md", "85.7 %"): "CAN sample point from the bit timing",
    ("docs/results/fleet.md", "0.1 %"): "the simulated fleet's scatter (an input)",
    ("docs/design/filter.md", "1.5 x"): "the envelope rule's factor",
}



def measured_numbers(rel: str, text: str, constants=CONSTANTS) -> list:
    """rel's measured-looking numbers outside generated blocks and code fences."""
    typed = re.sub(r"```.*?```", "", prose(text), flags=re.S)
    return [f"{rel}: {m.group(0)}" for m in MEASURED_RE.finditer(typed)
            if not LIMIT_RE.search(typed[max(0, m.start() - 12):m.start()])
            and (rel, m.group(0)) not in constants]


def test_no_measured_numbers_in_typed_docs():
    """A result typed in prose drifts from the table its tool writes: it is
    generated, pointed to, or kept dated in docs/decisions/."""
    found = [hit for rel, text in docs().items() if not rel.startswith("docs/decisions/")
             for hit in measured_numbers(rel, text)]
    assert found == []
    texts = docs()      # an allowed constant that left its page leaves the list too
    stale = [key for key in CONSTANTS
             if f"{key[0]}: {key[1]}" not in measured_numbers(key[0], texts[key[0]], {})]
    assert stale == []


def test_measured_numbers_by_hand():
    doc = ("worst 1.22x raw, 645 instructions, 47 ns, 0.36 N m RMS, 32.4 dB, 86 mN m\n"
           "goal <= 1.5x, within 5.5 %, default 0.02 %, a 2x line, 30 %, 3 N m, RMS + 10 mN m\n"
           "```\n1.9x\n```\n<!-- BEGIN generated:a-b -->\n2.6x\n<!-- END generated:a-b -->\n")
    assert measured_numbers("d.md", doc) == [
        "d.md: 1.22x", "d.md: 645 instructions", "d.md: 47 ns", "d.md: 0.36 N m RMS",
        "d.md: 32.4 dB", "d.md: 86 mN m"]
