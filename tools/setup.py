"""Build step of `pip install ./tools` (metadata in pyproject.toml): the
version from the top CMakeLists.txt (the one place it is written), and the
files hdtools reads at run time copied from firmware/ into hdtools/data
(hdtools/paths.py says how they and the C libraries are found)."""
import shutil
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
from hdtools.paths import DATA_FILES, git_revision, project_version  # noqa: E402  (stdlib only)


def version() -> str:
    ver = project_version(ROOT)
    if ver is None:
        raise SystemExit(f"{ROOT / 'CMakeLists.txt'}: no project(hdjoint VERSION ...)")
    return ver


class BuildPy(build_py):
    def run(self):
        super().run()
        data = Path(self.build_lib) / "hdtools" / "data"
        data.mkdir(parents=True, exist_ok=True)
        for rel in DATA_FILES:
            shutil.copy2(ROOT / rel, data / Path(rel).name)
        (data / "build_info.txt").write_text(
            f"version = {version()}\ngit = {git_revision(ROOT)}\nsource_root = {ROOT}\n")


setup(version=version(), cmdclass={"build_py": BuildPy})
