"""Locate the project's C libraries and host executables.

The tools never re-implement the filter: they load the same C code the
firmware runs, built as shared libraries by CMake.  They are looked up in
$HD_BUILD_DIR if set (CTest sets it), else in the package itself (the wheel
of `pip install ./tools` carries them in hdtools/lib and hdtools/bin:
cmake/HdWheel.cmake), else in build/host-release of the source tree.
Nothing here runs a build: a missing artefact is a NativeMissing error that
names the command building it (the CLIs print it as one line, exit status 1).
"""
from __future__ import annotations

import ctypes
import os
from pathlib import Path

from . import paths
from .safeio import HdError

# The source tree ($HD_ROOT, this checkout, or the one an installed package
# was built from: hdtools/paths.py).
ROOT = paths.source_root() or Path(__file__).resolve().parents[2]


class NativeMissing(HdError, FileNotFoundError):
    """A C library or host executable is not built; the message says how to
    build it.  A FileNotFoundError too, for callers that catch that."""
    code = 1


def build_dir() -> Path:
    env = os.environ.get("HD_BUILD_DIR")
    if not env and paths.source_root() is None:
        raise NativeMissing("no build of the C libraries: set HD_BUILD_DIR to a build "
                            "directory or HD_ROOT to the project's source tree")
    return Path(env) if env else ROOT / "build" / "host-release"


def build_command(target: str | None = None) -> str:
    """The shell command that builds `target` (everything if None) in build_dir()."""
    tail = f" --target {target}" if target else ""
    if os.environ.get("HD_BUILD_DIR"):
        return f"cmake --build {build_dir()}{tail}"
    return (f"cd {ROOT} && cmake --preset host-release && "
            f"cmake --build --preset host-release{tail}")


def _missing(what: str, target: str | None) -> NativeMissing:
    return NativeMissing(f"{what} is not built in {build_dir()}: run `{build_command(target)}`"
                         " (or set HD_BUILD_DIR to a build tree that has it)")


# Where the wheel puts the libraries (lib) and executables (bin).
PACKAGED = (Path(__file__).resolve().parent / "lib", Path(__file__).resolve().parent / "bin")


def _packaged(name: str, want_exec: bool = False) -> Path | None:
    """The wheel's copy of an artefact; None in a source checkout or when
    HD_BUILD_DIR names a build tree to use instead."""
    if os.environ.get("HD_BUILD_DIR"):
        return None
    for folder in PACKAGED:
        path = folder / name
        if path.is_file() and (not want_exec or os.access(path, os.X_OK)):
            return path
    return None


# Parts of a build tree that hold no artefacts of ours but scratch files that
# tests create and delete while other tests run (a walk must not trip on them).
_SKIP_DIRS = {"CMakeFiles", "Testing", "vm", "cache"}


def _walk_for(bdir: Path, name: str, want_exec: bool = False) -> list[Path]:
    hits = []
    for dirpath, dirnames, filenames in os.walk(bdir):  # ignores vanished dirs
        dirnames[:] = [d for d in dirnames if d not in _SKIP_DIRS]
        if name in filenames:
            path = Path(dirpath) / name
            if not want_exec or os.access(path, os.X_OK):
                hits.append(path)
    return sorted(hits)


def find_file(name: str, target: str | None = None) -> Path:
    """Path of a built artefact (library or executable) by file name."""
    packaged = _packaged(name)
    if packaged is not None:
        return packaged
    bdir = build_dir()
    hits = _walk_for(bdir, name) if bdir.is_dir() else []
    if not hits:
        raise _missing(name, target or name)
    return hits[0]


def load_library(stem: str) -> ctypes.CDLL:
    """Loads lib<stem>.so from the build tree (CMake target <stem>_shared)."""
    return ctypes.CDLL(str(find_file(f"lib{stem}.so", target=f"{stem}_shared")))


# Executables whose CMake target name differs from the file name.
_TARGET_OF = {"hdsim": "hdsim_cli"}


def executable(name: str) -> Path:
    """Path of a built host executable by file name."""
    packaged = _packaged(name, want_exec=True)
    if packaged is not None:
        return packaged
    bdir = build_dir()
    hits = _walk_for(bdir, name, want_exec=True) if bdir.is_dir() else []
    if not hits:
        raise _missing(f"executable {name}", _TARGET_OF.get(name, name))
    return hits[0]
