"""Build step of `pip install ./tools` (metadata in pyproject.toml): the
version from the top CMakeLists.txt (the one place it is written), and the
files hdtools reads at run time copied from firmware/ into hdtools/data
(hdtools/paths.py says how they and the C libraries are found)."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
from hdtools.paths import DATA_FILES  # noqa: E402  (stdlib only)


def version() -> str:
    text = (ROOT / "CMakeLists.txt").read_text()
    return re.search(r"project\(\s*hdjoint\s+VERSION\s+([0-9.]+)", text).group(1)


def git_revision() -> str:
    try:
        r = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short=12", "HEAD"],
                           capture_output=True, text=True, timeout=10)
        return r.stdout.strip() if r.returncode == 0 else ""
    except (OSError, subprocess.SubprocessError):
        return ""


class BuildPy(build_py):
    def run(self):
        super().run()
        data = Path(self.build_lib) / "hdtools" / "data"
        data.mkdir(parents=True, exist_ok=True)
        for rel in DATA_FILES:
            shutil.copy2(ROOT / rel, data / Path(rel).name)
        (data / "build_info.txt").write_text(
            f"version = {version()}\ngit = {git_revision()}\nsource_root = {ROOT}\n")


setup(version=version(), cmdclass={"build_py": BuildPy})
