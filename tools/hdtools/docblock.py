"""Generated blocks in the documents: one marker syntax for every generator.

    <!-- BEGIN generated:NAME -->
    ...what the generator wrote...
    <!-- END generated:NAME -->

NAME is [A-Za-z0-9_-]+.  hdtools.protocol owns the names without a hyphen
in docs/**/*.md (its tables) and README's `headline`; every other generator's
names have one (`target-budget`, `reliability-faults`).  The registry of
generators, the commands that write each block, is tools/hdmaint/docgen.py.
Writing goes through hdtools.safeio (all files of a generator or none).
Standard library only (tools/target uses it before .venv exists).
"""
from __future__ import annotations

import re
from pathlib import Path

from .safeio import Outputs, UsageError

NAME = r"[A-Za-z0-9_-]+"
BEGIN_RE = re.compile(rf"^<!-- BEGIN generated:({NAME}) -->$", re.M)
# Any HTML comment that looks like a block marker, in this syntax or another
# (`<!-- x:y:begin -->`, `<!-- generated: x -->`, `<!-- END x -->`).
MARKER_LIKE_RE = re.compile(r"^<!-- ?(?:BEGIN|END|begin|end|generated)\b[^>]*-->$|"
                            r"^<!-- [\w-]+(?::[\w-]+)+:(?:begin|end) -->$", re.M)


def markers(name: str) -> tuple[str, str]:
    if not re.fullmatch(NAME, name):
        raise ValueError(f"block name {name!r} is not {NAME}")
    return f"<!-- BEGIN generated:{name} -->", f"<!-- END generated:{name} -->"


def splice(text: str, name: str, body: str, where: str) -> str:
    """text with block `name`'s body replaced by body (kept as given: the
    block is BEGIN, newline, body, newline, END).  UsageError naming `where`
    unless the block occurs exactly once with its END after its BEGIN."""
    begin, end = markers(name)
    if text.count(begin + "\n") != 1 or text.count(end) != 1 or \
            text.index(begin) > text.index(end):
        raise UsageError(f"{where}: needs one {begin} line and one {end} line after it")
    pre, rest = text.split(begin + "\n", 1)
    post = rest.split(end, 1)[1]
    return f"{pre}{begin}\n{body}\n{end}{post}"


def body(text: str, name: str, where: str) -> str:
    """The body of block `name` (UsageError if it is not there once)."""
    begin, end = markers(name)
    if text.count(begin + "\n") != 1 or text.count(end) != 1:
        raise UsageError(f"{where}: needs one {begin} line and one {end} line after it")
    inner = text.split(begin + "\n", 1)[1].split(end, 1)[0]
    return inner[:-1] if inner.endswith("\n") else inner


def names(text: str) -> list[str]:
    """The block names of a document, in order."""
    return BEGIN_RE.findall(text)


def foreign_markers(text: str) -> list[str]:
    """Marker-like comment lines that are not this syntax's BEGIN / END."""
    ours = re.compile(rf"^<!-- (?:BEGIN|END) generated:{NAME} -->$")
    return [m.group(0) for m in MARKER_LIKE_RE.finditer(text) if not ours.match(m.group(0))]


def write(outputs: list[tuple[Path, str]]) -> None:
    """Writes [(path, text)] all or none (OutputError)."""
    with Outputs() as out:
        for path, text in outputs:
            out.write_text(path, text)
        out.commit()


def update(path: Path, blocks: dict[str, str]) -> tuple[str, str]:
    """(old text, new text) of a document with its blocks replaced; nothing
    written (the caller checks or writes, with others, through write)."""
    from .safeio import read_text
    old = read_text(path)
    new = old
    for name, text in blocks.items():
        new = splice(new, name, text, str(path))
    return old, new
