"""hdtools.native never builds: a C artefact missing from the build tree is
one line on stderr naming the command that builds it, exit status 1, and no
build is started (checked by refusing any subprocess running cmake, ninja or
make)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from conftest import ROOT
from hdtools import cli, native


@pytest.fixture
def empty_build(tmp_path, monkeypatch):
    monkeypatch.setenv("HD_BUILD_DIR", str(tmp_path))

    real_run, real_popen = subprocess.run, subprocess.Popen

    def guard(real):
        def call(cmd, *args, **kwargs):
            prog = os.path.basename(str(cmd[0] if isinstance(cmd, (list, tuple)) else cmd))
            assert prog not in ("cmake", "ninja", "make"), f"hdtools started a build: {cmd}"
            return real(cmd, *args, **kwargs)
        return call
    monkeypatch.setattr(subprocess, "run", guard(real_run))
    monkeypatch.setattr(subprocess, "Popen", guard(real_popen))
    return tmp_path


def test_missing_library_names_the_build_command(empty_build):
    with pytest.raises(native.NativeMissing) as exc:
        native.load_library("hdfilter")
    assert f"cmake --build {empty_build} --target hdfilter_shared" in str(exc.value)
    assert isinstance(exc.value, FileNotFoundError)
    assert list(empty_build.iterdir()) == []


def test_missing_executable_is_one_line_and_status_1(empty_build, capsys):
    assert cli.main(["sim", str(ROOT / "sim" / "scenarios" / "paper_156.ini")]) == 1
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1, err
    assert err.startswith("hdsense sim: executable hdsim is not built")
    assert f"cmake --build {empty_build} --target hdsim_cli" in err
    assert list(empty_build.iterdir()) == []


def test_default_build_tree_names_the_preset(tmp_path):
    """Without HD_BUILD_DIR the tools look in build/host-release of HD_ROOT and
    say how to configure and build it (a fresh interpreter: no monkeypatching)."""
    (tmp_path / "CMakeLists.txt").write_text("")
    env = {k: v for k, v in os.environ.items() if k != "HD_BUILD_DIR"}
    env.update(HD_ROOT=str(tmp_path), PYTHONPATH=str(ROOT / "tools"))
    r = subprocess.run([sys.executable, "-m", "hdtools.cli", "sim", "x.ini"], env=env,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stdout == "", r
    assert r.stderr.count("\n") == 1, r.stderr
    assert "cmake --preset host-release && cmake --build --preset host-release" in r.stderr
    assert not (tmp_path / "build").exists()
