"""Writing measured tables into the docs (tests/reliability/rel_doc.py,
tests/vm/vm_doc.py).

A generated block sits in a Markdown file between hdtools.docblock's
markers (`<!-- BEGIN generated:NAME -->`, `<!-- END generated:NAME -->`);
NAME has a hyphen (`reliability-faults`), so hdtools.protocol, which
renders its own `\\w+` blocks in every docs/**/*.md, leaves these alone.
The measuring programs are run with the command lines CTest has for them
(`ctest --show-only=json-v1`), so a table is what the CTest test measures.
"""
from __future__ import annotations

import datetime
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))


class GenDocError(Exception):
    """One line for stderr: what failed and where."""


def ctest_commands(build: Path) -> dict[str, list[str]]:
    """{test name: command line} of every CTest test in `build`."""
    if not (build / "CTestTestfile.cmake").is_file():
        raise GenDocError(f"{build}: not a configured CMake build folder (no CTestTestfile.cmake)")
    try:
        out = subprocess.run(["ctest", "--test-dir", str(build), "--show-only=json-v1"],
                             capture_output=True, text=True, timeout=120, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise GenDocError(f"ctest --show-only in {build}: {exc}") from None
    if out.returncode != 0:
        raise GenDocError(f"ctest --show-only in {build} failed: {out.stderr.strip()[:200]}")
    tests = json.loads(out.stdout).get("tests", [])
    return {t["name"]: t["command"] for t in tests if t.get("command")}


def command_of(commands: dict[str, list[str]], name: str, build: Path) -> list[str]:
    if name not in commands:
        raise GenDocError(f"{build} has no CTest test {name} (configured and built?)")
    return commands[name]


def run(cmd: list[str], timeout_s: float, cwd: Path | None = None) -> str:
    """stdout of cmd, which must exit 0."""
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, cwd=cwd,
                             check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise GenDocError(f"{Path(cmd[0]).name}: {exc}") from None
    if out.returncode != 0:
        tail = (out.stdout + out.stderr).strip().splitlines()[-3:]
        raise GenDocError(f"{Path(cmd[0]).name} exited with {out.returncode}: "
                          + " / ".join(tail))
    return out.stdout


def replace_blocks(text: str, blocks: dict[str, str], where: str) -> str:
    """text with each named block's body replaced (hdtools.docblock)."""
    from hdtools import docblock
    from hdtools.safeio import UsageError
    for name, body in blocks.items():
        try:
            text = docblock.splice(text, name, body.rstrip(), where)
        except UsageError as exc:
            raise GenDocError(str(exc)) from None
    return text


def update_doc(path: Path, blocks: dict[str, str], check: bool, regenerate: str) -> str:
    """Writes the blocks into path atomically (hdtools.safeio), or with check=True raises GenDocError naming
    `regenerate` when the file differs.  Returns a one-line report."""
    try:
        old = path.read_text()
    except OSError as exc:
        raise GenDocError(f"{path}: {exc.strerror}") from None
    new = replace_blocks(old, blocks, str(path))
    names = ", ".join(blocks)
    if check:
        if new != old:
            stale = [n for n in blocks if replace_blocks(old, {n: blocks[n]}, str(path)) != old]
            raise GenDocError(f"{path}: generated block(s) {', '.join(stale)} out of date "
                              f"with what the tests just measured: run {regenerate}")
        return f"{path}: {names} up to date"
    from hdtools.safeio import OutputError, Outputs
    try:
        with Outputs() as out:
            out.write_text(path, new)
            out.commit()
    except OutputError as exc:
        raise GenDocError(str(exc)) from None
    return f"{path}: {names} written"


def build_info(build: Path) -> str:
    """Build type and compiler of a CMake build folder."""
    cache: dict[str, str] = {}
    try:
        for line in (build / "CMakeCache.txt").read_text().splitlines():
            key, sep, value = line.partition("=")
            if sep and ":" in key:
                cache[key.split(":", 1)[0]] = value
    except OSError:
        return build.name
    compiler = cache.get("CMAKE_C_COMPILER", "cc")
    try:
        version = subprocess.run([compiler, "--version"], capture_output=True, text=True,
                                 timeout=30, check=False).stdout.splitlines()[0]
    except (OSError, subprocess.TimeoutExpired, IndexError):
        version = Path(compiler).name
    return f"{cache.get('CMAKE_BUILD_TYPE') or 'no build type'} build, {version}"


def machine() -> str:
    """Date, processor and core count, for tables of numbers that vary
    from run to run (not checked)."""
    from hdmaint.bench.compute import cpu_model
    load = ""
    if hasattr(os, "getloadavg"):
        load = f", load average {os.getloadavg()[0]:.1f} at the start"
    day = datetime.date.today().isoformat()
    return f"{day}, {cpu_model()} ({os.cpu_count()} logical CPUs{load})"
