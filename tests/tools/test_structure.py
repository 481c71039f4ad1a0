"""The shape of tools/hdtools (the installed package), tools/hdmaint (the
maintainer tools beside it) and of the CTest names (docs/reference/testing.md): no
import cycle among their modules (every import counted, also those inside
functions), hdtools never importing hdmaint (the wheel carries hdtools
only), no module over MAX_LINES lines but the ones listed with the change
that will split them, and every CTest test named <area>_<module> with a
known area."""
from __future__ import annotations

import ast
import re
from pathlib import Path

from conftest import ROOT

PACKAGE = ROOT / "tools" / "hdtools"
MAINT = ROOT / "tools" / "hdmaint"
PACKAGES = (PACKAGE, MAINT)
MAX_LINES = 500
# Over MAX_LINES today, each owned by a change in flight (issue 22): remove an
# entry when that change lands.
LONG_ALLOWED = {
    "hdtools/analysis/detect.py": "the filter/analysis change works on it",
}
AREAS = ("harness", "filter", "calib", "control", "hal", "sim", "fw", "analyze", "tools",
         "fleet", "device", "ros2", "rel", "corpus", "target", "stm32f4", "socketcan", "vm",
         "bench")


def module_name(package: Path, path: Path) -> str:
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(*packages: Path) -> dict[str, set[str]]:
    """{module: modules of the packages it imports}; a package's __init__ is
    not an edge (importing a.b runs a/__init__ first, which is no cycle)."""
    files = {module_name(package, p): p for package in packages for p in package.rglob("*.py")}
    tops = {package.name for package in packages}

    def resolve(name: str) -> str | None:
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for mod, path in files.items():
        base = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        targets = []
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets += [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    parts = base.split(".")
                    parts = parts[:len(parts) - node.level + 1]
                    origin = ".".join(parts + ([node.module] if node.module else []))
                else:
                    origin = node.module or ""
                targets += [f"{origin}.{a.name}" if f"{origin}.{a.name}" in files else origin
                            for a in node.names]
        graph[mod] = {t for t in map(resolve, targets)
                      if t and t != mod and t.split(".")[0] in tops
                      and files[t].name != "__init__.py"}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(comp)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_cycle_finder_on_a_made_up_package(tmp_path):
    """a -> b -> c -> a (one import inside a function, one relative from a
    subpackage) is one cycle; d -> a is none; a package's __init__ is not."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from . import a\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .sub import b\n")
    (pkg / "sub" / "b.py").write_text("def f():\n    from ..c import x\n")
    (pkg / "c.py").write_text("import pkg.a\nx = 1\n")
    (pkg / "d.py").write_text("from pkg import a\n")
    g = import_graph(pkg)
    assert g["pkg.a"] == {"pkg.sub.b"} and g["pkg.d"] == {"pkg.a"}
    assert cycles(g) == [{"pkg.a", "pkg.sub.b", "pkg.c"}]


def test_no_import_cycle_in_the_tools():
    found = cycles(import_graph(*PACKAGES))
    assert found == [], f"import cycles in tools/hdtools, tools/hdmaint: {found}"


def test_the_installed_package_never_imports_the_maintainer_tools():
    graph = import_graph(*PACKAGES)
    found = sorted(f"{m} -> {t}" for m, ts in graph.items() if m.startswith("hdtools")
                   for t in ts if t.startswith("hdmaint"))
    assert found == [], f"hdtools imports hdmaint (not in the wheel): {found}"


def test_no_module_over_the_line_limit():
    sizes = {str(p.relative_to(package.parent)): len(p.read_text().splitlines())
             for package in PACKAGES for p in package.rglob("*.py")}
    over = {name: n for name, n in sizes.items() if n > MAX_LINES and name not in LONG_ALLOWED}
    assert over == {}, f"modules over {MAX_LINES} lines: {over}"
    stale = [name for name in LONG_ALLOWED if sizes.get(name, 0) <= MAX_LINES]
    assert stale == [], f"LONG_ALLOWED lists modules that fit now: {stale}"


def test_ctest_names_are_area_module():
    names = []
    for cmake in sorted((ROOT / "tests").rglob("CMakeLists.txt")):
        text = cmake.read_text()
        names += re.findall(r"(?:hd_add_unity_test|hd_add_python_test|add_test)\(\s*NAME\s+"
                            r"([A-Za-z0-9_${}.]+)", text)
    assert len(names) > 50
    bad = [n for n in names if not re.fullmatch(rf"({'|'.join(AREAS)})_[a-z0-9_${{}}]+", n)]
    assert bad == [], f"CTest names not <area>_<module>: {bad}"


def test_firmware_file_table_names_every_source():
    """docs/design/firmware.md's file table names every firmware/*.c and *.def (it
    lacked three stage files once)."""
    import re
    text = (ROOT / "docs" / "design" / "firmware.md").read_text()
    table = text[:text.index("## Two contexts")]
    named = set(re.findall(r"`([A-Za-z0-9_]+\.(?:c|def))`", table))
    files = {p.name for p in (ROOT / "firmware").glob("*.c")} | \
        {p.name for p in (ROOT / "firmware").glob("*.def")}
    assert files - named == set(), \
        f"docs/design/firmware.md's file table lacks {sorted(files - named)}"


# Files that rename or make temporary files for another reason than writing
# an output atomically: a scratch copy removed after use, a test fixture.
RENAME_ALLOWED = {
    "tools/hdtools/safeio.py": "the one atomic writer",
    "tools/hdtools/fleet/chunks.py": "a scratch log of one chunk, removed after the job",
    "tests/corpus/make_inputs.py": "builds a fixture bag (a test input, not an output)",
}


def test_every_atomic_write_goes_through_safeio():
    """os.replace / rename / mkstemp appear only in hdtools.safeio (and the
    allowed non-output uses): a doc generator or tool with its own
    temporary-file-and-rename is a second copy of it."""
    pattern = re.compile(r"\bos\.(?:replace|rename)\(|\.rename\(|\bmkstemp\(|\btmp\.replace\(")
    found = sorted(str(p.relative_to(ROOT)) for top in ("tools", "tests") for p in
                   (ROOT / top).rglob("*.py") if pattern.search(p.read_text()))
    assert [f for f in found if f not in RENAME_ALLOWED] == [], \
        "atomic writers beside hdtools.safeio"
    assert [f for f in RENAME_ALLOWED if f not in found] == [], "stale RENAME_ALLOWED entries"
