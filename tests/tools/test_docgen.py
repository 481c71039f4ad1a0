"""One doc generator registry and one marker syntax (tools/hdmaint/docgen.py,
tools/hdtools/docblock.py; no build needed): every generated block of
docs/*.md and README.md is in the one syntax and written by exactly one
registered generator (hdtools.protocol's tables included), every registered
block is there, docs/testing.md's table is the registry's, and splicing,
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
CHECKED = {"docs/ros2.md": {"<!-- BEGIN ros2:topics -->", "<!-- END ros2:topics -->",
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
    text = (ROOT / "docs" / "testing.md").read_text()
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
    found += [f"{p.relative_to(ROOT)}: {m.group(0)}"
              for p in sorted((ROOT / "docs" / "decisions").glob("*.md"))
              for m in re.finditer(r"(?i)\bissues? \d+", p.read_text())]
    assert found == []


def test_relative_links_resolve():
    pages = docgen.documents() + sorted((ROOT / "docs" / "decisions").glob("*.md")) + \
        [ROOT / "CONTRIBUTING.md"]
    broken = []
    for page in pages:
        text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            path = target.split("#", 1)[0]
            if not path or re.match(r"[a-z]+:", path):
                continue
            if not (page.parent / path).exists():
                broken.append(f"{page.relative_to(ROOT)}: {target}")
    assert broken == []


def test_paths_named_in_typed_docs_exist():
    """A `tools/...` or `tests/...` path in prose names a file of the tree (a
    moved module leaves no stale name behind; globs must match something)."""
    missing = []
    for rel, text in docs().items():
        for path in re.findall(r"`((?:tools|tests)/[\w./*-]+)`", prose(text)):
            path = path.rstrip(".")
            if not any(ROOT.glob(path)) and not any(ROOT.glob(path + ".*")):  # or its source
                missing.append(f"{rel}: {path}")
    assert missing == []
