"""Where the tools find what they read at run time, in a source tree and
as an installed package (`pip install ./tools`).

In the source tree (tools/hdtools next to firmware/): the files themselves.
Installed: the wheel's build (cmake/HdWheel.cmake) copies the files of
DATA_FILES (the parameter table, the protocol vocabulary, the DBC and the
headers whose constants the tools read) into hdtools/data/ and records the
source tree it was built from and its version (hdtools/data/build_info.txt);
no second copy lives in git.

The C libraries (libhdfilter.so, libhd_emu.so, ...) and host executables
are built into the wheel too (hdtools/lib, hdtools/bin); $HD_BUILD_DIR, if
set, names a build tree to use instead, and a source checkout uses its
build/host-release ($HD_ROOT if set, else this tree).  Nothing builds them
on demand (hdtools/native.py says how).
"""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
DATA = PACKAGE / "data"
# Source-tree files the tools read at run time (copied into the wheel by
# cmake/HdWheel.cmake, which reads this tuple).
DATA_FILES = ("firmware/hd_params.def", "firmware/hd_protocol.def", "firmware/hdjoint.dbc",
              "firmware/hd_fw_records.h", "filter/hd_kf.h", "control/hd_ctrl.h",
              "firmware/hd_can_proto.h")
_TREE = PACKAGE.parents[1]


def in_source_tree() -> bool:
    return (_TREE / "firmware" / "hd_params.def").is_file() and not DATA.is_dir()


def build_info() -> dict[str, str]:
    """key = value lines the build step wrote (installed package only)."""
    try:
        text = (DATA / "build_info.txt").read_text()
    except OSError:
        return {}
    from . import summary
    return summary.parse(text)


def source_root() -> Path | None:
    """The project's source tree: $HD_ROOT, this tree, or the one the
    installed package was built from (if it still exists)."""
    env = os.environ.get("HD_ROOT")
    if env:
        return Path(env)
    if in_source_tree():
        return _TREE
    recorded = build_info().get("source_root")
    if recorded and (Path(recorded) / "CMakeLists.txt").is_file():
        return Path(recorded)
    return None


_CMAKE_VERSION = re.compile(r"project\(\s*hdjoint\s+VERSION\s+([0-9.]+)")


def project_version(root: Path) -> str | None:
    """The version in root/CMakeLists.txt (the one place it is written),
    None if it names none; OSError if the file cannot be read."""
    m = _CMAKE_VERSION.search((Path(root) / "CMakeLists.txt").read_text())
    return m.group(1) if m else None


def git_revision(root: Path) -> str:
    """The commit root is checked out at (12 hex digits), "" if it is not a
    git checkout or git is missing."""
    try:
        r = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"],
                           capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return ""
    return r.stdout.strip() if r.returncode == 0 else ""


def source_file(rel: str) -> Path:
    """A file of DATA_FILES: in the source tree, or the installed copy."""
    if in_source_tree():
        return _TREE / rel
    copy = DATA / Path(rel).name
    if copy.is_file():
        return copy
    root = source_root()
    return (root or _TREE) / rel


def firmware_file(name: str) -> Path:
    """firmware/<name> of the source tree, or the installed copy."""
    return source_file(f"firmware/{name}")
