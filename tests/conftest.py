"""The build tree every Python test uses, and what happens without one.

CTest sets HD_BUILD_DIR to its build tree; a missing artefact there is a
failure.  Run by hand (`.venv/bin/python -m pytest tests/...`), the tests use
$HD_BUILD_DIR, else build/host-debug, else build/host-release, whichever has
been configured; a test needing a C library or host executable that is not
built is skipped with the command that builds it.  Nothing here (nor in
hdtools.native) runs a build.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from hdtools import native

ROOT = Path(__file__).resolve().parents[1]
# HD_BUILD_DIR from the caller (CTest): the build must hold what the tests need.
GIVEN = bool(os.environ.get("HD_BUILD_DIR"))


def _default_build() -> Path | None:
    for preset in ("host-debug", "host-release"):
        bdir = ROOT / "build" / preset
        if (bdir / "build.ninja").is_file():
            return bdir
    return None


if not GIVEN and _default_build() is not None:
    # subprocesses (hdsense, the scripts) see the same tree as this process
    os.environ["HD_BUILD_DIR"] = str(_default_build())


@pytest.fixture(scope="session")
def build_dir() -> Path:
    """The build tree (a Path); skips the test when there is none."""
    bdir = os.environ.get("HD_BUILD_DIR")
    if not bdir:
        pytest.skip("no build of the C libraries: run `cmake --preset host-debug && "
                    "cmake --build --preset host-debug` (or set HD_BUILD_DIR)")
    if not Path(bdir).is_dir():
        message = f"HD_BUILD_DIR={bdir} is not a directory"
        if GIVEN:
            pytest.fail(message)
        pytest.skip(message)
    return Path(bdir)


def _not_built_is_a_skip():
    """Wraps a test's setup (its fixtures) or call: a C artefact missing
    (hdtools.native.NativeMissing) skips it, unless the caller named the
    build tree."""
    try:
        return (yield)
    except native.NativeMissing as exc:
        if GIVEN:
            raise
        pytest.skip(str(exc))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item):
    return (yield from _not_built_is_a_skip())


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item):
    return (yield from _not_built_is_a_skip())
