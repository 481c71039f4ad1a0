"""Locate (and if needed build) the project's C libraries for ctypes.

The tools never re-implement the filter: they load the same C code the
firmware runs, built as shared libraries by CMake.  The build directory is
$HD_BUILD_DIR if set (CTest sets it), else build/host-release, which is
configured and built on first use.
"""
from __future__ import annotations

import ctypes
import os
import subprocess
from pathlib import Path

from . import paths

# The source tree ($HD_ROOT, this checkout, or the one an installed package
# was built from: hdtools/paths.py).
ROOT = paths.source_root() or Path(__file__).resolve().parents[2]


def build_dir() -> Path:
    env = os.environ.get("HD_BUILD_DIR")
    if not env and paths.source_root() is None:
        raise FileNotFoundError("no build of the C libraries: set HD_BUILD_DIR to a build "
                                "directory or HD_ROOT to the project's source tree")
    return Path(env) if env else ROOT / "build" / "host-release"


def ensure_built(target: str | None = None) -> Path:
    """Configures/builds build_dir() if it is the default and not built yet."""
    bdir = build_dir()
    if not (bdir / "build.ninja").exists() and not os.environ.get("HD_BUILD_DIR"):
        subprocess.run(["cmake", "--preset", "host-release"], cwd=ROOT, check=True,
                       stdout=subprocess.DEVNULL)
    if not os.environ.get("HD_BUILD_DIR"):
        cmd = ["cmake", "--build", str(bdir)]
        if target:
            cmd += ["--target", target]
        subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return bdir


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
    bdir = ensure_built(target)
    hits = _walk_for(bdir, name)
    if not hits:
        raise FileNotFoundError(f"{name} not found under {bdir}; build the project first")
    return hits[0]


def load_library(stem: str) -> ctypes.CDLL:
    """Loads lib<stem>.so from the build tree (CMake target <stem>_shared)."""
    return ctypes.CDLL(str(find_file(f"lib{stem}.so", target=f"{stem}_shared")))


# Executables whose CMake target name differs from the file name.
_TARGET_OF = {"hdsim": "hdsim_cli"}


def executable(name: str) -> Path:
    """Path of a built host executable by file name (built if needed)."""
    bdir = ensure_built(_TARGET_OF.get(name, name))
    hits = _walk_for(bdir, name, want_exec=True)
    if not hits:
        raise FileNotFoundError(f"executable {name} not found under {bdir}")
    return sorted(hits)[0]
