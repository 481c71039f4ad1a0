"""The C tree's layering, read from its #include lines: no header cycle, and
dependencies pointing one way (docs/design/firmware.md):

  filter/ calib/ control/   pure: each other and the C library's pure headers
  hal/hal.h                 the interface: the pure layers only
  firmware/*.[ch]           the core: the pure layers and hal/hal.h, no backend
  hal/<backend>/, firmware/host/, firmware/board/   on top of all of them

so a filter that starts printing, or a core that calls a SocketCAN function
directly, fails here."""
from __future__ import annotations

import re
from pathlib import Path

from conftest import ROOT
from test_structure import cycles

PURE_DIRS = ("filter", "calib", "control")
PURE_SYSTEM = {"math.h", "stdbool.h", "stddef.h", "stdint.h", "string.h", "float.h"}
CORE_SYSTEM = PURE_SYSTEM | {"stdatomic.h"}
INCLUDE = re.compile(r'^\s*#\s*include\s+([<"])([^>"]+)[>"]', re.M)


def sources(root: Path) -> dict[str, Path]:
    """{path relative to root: path} of every C source and header of the layers."""
    out = {}
    for top in PURE_DIRS + ("hal", "firmware"):
        for p in sorted((root / top).rglob("*")):
            if p.suffix in (".c", ".h", ".def"):
                out[p.relative_to(root).as_posix()] = p
    return out


def includes(root: Path) -> dict[str, tuple[set[str], set[str]]]:
    """{file: (project files it includes, system headers it includes)}; a quoted
    include is found by its base name among the layers' files."""
    files = sources(root)
    by_name: dict[str, list[str]] = {}
    for rel in files:
        by_name.setdefault(rel.rsplit("/", 1)[-1], []).append(rel)
    out = {}
    for rel, path in files.items():
        local, system = set(), set()
        for kind, name in INCLUDE.findall(path.read_text(errors="replace")):
            base = name.rsplit("/", 1)[-1]
            if kind == "<":
                system.add(name)
            elif base in by_name:
                same_dir = [c for c in by_name[base] if c.rsplit("/", 1)[0] == rel.rsplit("/", 1)[0]]
                local.add((same_dir or by_name[base])[0])
        out[rel] = (local, system)
    return out


def layer(rel: str) -> str:
    top = rel.split("/")[0]
    if top in PURE_DIRS:
        return "pure"
    if rel == "hal/hal.h":
        return "interface"
    if top == "firmware" and rel.count("/") == 1:
        return "core"
    return "backend"


ALLOWED = {"pure": {"pure"}, "interface": {"pure", "interface"},
           "core": {"pure", "interface", "core"},
           "backend": {"pure", "interface", "core", "backend"}}


def violations(root: Path) -> list[str]:
    found = []
    graph = {}
    for rel, (local, system) in includes(root).items():
        mine = layer(rel)
        for dep in sorted(local):
            if layer(dep) not in ALLOWED[mine]:
                found.append(f"{rel} ({mine}) includes {dep} ({layer(dep)})")
        allowed_sys = PURE_SYSTEM if mine in ("pure", "interface") else (
            CORE_SYSTEM if mine == "core" else None)
        if allowed_sys is not None:
            found += [f"{rel} ({mine}) includes <{s}>" for s in sorted(system - allowed_sys)]
        graph[rel] = {d for d in local if d.endswith((".h", ".def"))}
    found += [f"include cycle: {' -> '.join(sorted(c))}"
              for c in cycles({k: v for k, v in graph.items() if k.endswith((".h", ".def"))})]
    return found


def test_checker_on_a_made_up_tree(tmp_path):
    """A filter that includes <stdio.h> and the HAL, a core file that includes a
    backend, and two headers including each other: four findings, nothing else."""
    for rel, text in {
        "filter/a.h": '#include <stdint.h>\n#include "b.h"\n',
        "filter/b.h": '#include "a.h"\n',
        "filter/a.c": '#include <stdio.h>\n#include "a.h"\n#include "hal.h"\n',
        "hal/hal.h": '#include "a.h"\n',
        "hal/mock/hal_mock.h": '#include "hal.h"\n',
        "firmware/fw.c": '#include "hal_mock.h"\n#include "hal.h"\n',
        "firmware/host/main.c": '#include <stdio.h>\n#include "hal_mock.h"\n',
        "calib/c.c": "",
        "control/d.c": "",
    }.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    assert sorted(violations(tmp_path)) == sorted([
        "filter/a.c (pure) includes hal/hal.h (interface)",
        "filter/a.c (pure) includes <stdio.h>",
        "firmware/fw.c (core) includes hal/mock/hal_mock.h (backend)",
        "include cycle: filter/a.h -> filter/b.h",
    ])


def test_c_tree_layers_and_no_header_cycle():
    assert violations(ROOT) == []
