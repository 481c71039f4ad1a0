"""`pip install ./tools` in a fresh virtual environment gives a working
`hdsense` that reads the parameter table, protocol and DBC from its own
installed copies and runs the C libraries and executables its wheel carries
(no source tree or build tree next to it), or a build tree's through
HD_BUILD_DIR.  Offline-safe: the dependencies (scikit-build-core included)
come from the project's environment (a .pth file), nothing is downloaded."""
from __future__ import annotations

import os
import re
import shutil
import site
import subprocess
import sys
import venv
from pathlib import Path

import pytest

from conftest import ROOT


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("install")
    # the parts of the tree the wheel's build reads (the C sources and
    # CMake files, the package), copied so that its scratch files never land
    # in the working tree and nothing of the tree is found after it
    src = tmp / "src"
    src.mkdir()
    shutil.copy2(ROOT / "CMakeLists.txt", src)
    for rel in ("cmake", "filter", "calib", "control", "hal", "firmware", "sim"):
        shutil.copytree(ROOT / rel, src / rel, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "tools" / "hdtools", src / "tools" / "hdtools",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy2(ROOT / "tools" / "pyproject.toml", src / "tools" / "pyproject.toml")
    env_dir = tmp / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    py = env_dir / "bin" / "python"
    purelib = subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    Path(purelib, "project_deps.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    r = subprocess.run([py, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                        "--no-index", str(src / "tools")], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    shutil.rmtree(src)                  # the installed package must not need it
    return env_dir


def run(env_dir, *args, env=None):
    e = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "HD_BUILD_DIR", "HD_ROOT")}
    e.update(env or {})
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=120,
                          env=e, cwd=env_dir)


def test_hdsense_version(installed):
    want = re.search(r"project\(\s*hdjoint\s+VERSION\s+([0-9.]+)",
                     (ROOT / "CMakeLists.txt").read_text()).group(1)
    r = run(installed, installed / "bin" / "hdsense", "--version")
    assert r.returncode == 0 and r.stdout.startswith(f"hdsense {want}"), r.stderr
    r = run(installed, installed / "bin" / "hdsense", "monitor", "--version")
    assert r.returncode == 0 and r.stdout.startswith(f"hdsense monitor {want}")


def test_the_wheel_carries_the_user_cli_only(installed):
    """The maintainer tools (tools/hdmaint: target, bench, headline, doc
    generators) stay in the checkout: none is importable from the wheel and
    hdsense has no bench subcommand."""
    r = run(installed, installed / "bin" / "python", "-c",
            "import importlib.util as u; print([m for m in ('hdmaint', 'hdtools.bench', "
            "'hdtools.target', 'hdtools.headline', 'hdtools.cmd_bench', 'hdtools.fleet.bench', "
            "'hdtools.rosio.bench') if u.find_spec(m)])")
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stdout + r.stderr
    r = run(installed, installed / "bin" / "hdsense", "bench", "--help")
    assert r.returncode == 2 and "invalid choice: 'bench'" in r.stderr, r.stderr


def test_installed_package_reads_its_own_copies(installed, tmp_path):
    py = installed / "bin" / "python"
    r = run(installed, py, "-c", "from hdtools import protocol; print(protocol.PARAMS_DEF); "
            "print(len(protocol.params()))")
    assert r.returncode == 0, r.stderr
    path, count = r.stdout.split()
    assert "site-packages" in path and str(ROOT) not in path
    assert int(count) == sum(1 for line in (ROOT / "firmware" / "hd_params.def").read_text()
                             .splitlines() if line.startswith("HD_PARAM("))
    # a bus with no joint: one line, exit 5, no traceback
    r = run(installed, installed / "bin" / "hdsense", "device", "-i", "virtual", "nobody",
            "--timeout", "0.1", "version")
    assert r.returncode == 5 and len(r.stderr.splitlines()) == 1 and "no answer" in r.stderr


def test_installed_package_finds_the_c_libraries(installed):
    build = os.environ.get("HD_BUILD_DIR")
    if not build:
        pytest.skip("HD_BUILD_DIR not set (CTest sets it)")
    py = installed / "bin" / "python"
    r = run(installed, py, "-c", "from hdtools import emu; j = emu.Emulator(); "
            "print(len(j.run_frames(10)))", env={"HD_BUILD_DIR": build})
    assert r.returncode == 0 and int(r.stdout) >= 20, r.stderr
    # a configuration text, read by the firmware's parser in those libraries
    cfg = installed / "m.cfg"
    cfg.write_text("r_nm2 = 0.0004\nblock = motor 2 1e-7\n")
    r = run(installed, installed / "bin" / "hdsense", "canlog", "commands", cfg,
            env={"HD_BUILD_DIR": build})
    assert r.returncode == 0 and len(r.stdout.splitlines()) == 3, r.stderr
    # no build directory and no source tree: says what to set
    r = run(installed, py, "-c", "from hdtools import native\ntry:\n native.build_dir()\n"
            "except FileNotFoundError as e:\n print(e)")
    assert "HD_BUILD_DIR" in r.stdout and "HD_ROOT" in r.stdout, r.stderr


def test_installed_hdsense_analyze_needs_no_build_tree(installed, tmp_path):
    """No HD_BUILD_DIR, no HD_ROOT, the source copy it was built from gone:
    the wheel's hdsim writes a log and the wheel's filter library analyses
    it, to the same model the source tree's build finds (the same C code;
    Release and Debug builds agree bit for bit, -ffp-contract=off)."""
    hd = installed / "bin" / "hdsense"
    scenario = tmp_path / "joint.ini"
    scenario.write_text((ROOT / "sim" / "scenarios" / "paper_156.ini").read_text())
    csv = tmp_path / "joint.csv"
    r = run(installed, hd, "sim", scenario, "--csv", csv)
    assert r.returncode == 0 and csv.stat().st_size > 0, r.stderr
    out = tmp_path / "model"
    r = run(installed, hd, "analyze", csv, "--out", out)
    assert r.returncode == 0, r.stderr
    assert (out / "model.cfg").is_file(), r.stdout
    r = run(installed, installed / "bin" / "python", "-c",
            "from hdtools import native; print(native.find_file('libhdfilter.so'))")
    assert r.returncode == 0 and "site-packages/hdtools/lib/" in r.stdout, r.stderr
    build = os.environ.get("HD_BUILD_DIR")
    if build:
        ref = tmp_path / "ref"
        r2 = run(installed, hd, "analyze", csv, "--out", ref, env={"HD_BUILD_DIR": build})
        assert r2.returncode == 0, r2.stderr
        assert (out / "model.cfg").read_text() == (ref / "model.cfg").read_text()
