"""Shared helpers for the analyze tests: the simulated joint (hdsim) and the
analysis entry point, both from the CMake build tree (HD_BUILD_DIR)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

from hdtools import native  # noqa: E402

SCENARIOS = Path(__file__).resolve().parent / "scenarios"


@pytest.fixture(scope="session")
def hdsim():
    try:
        return native.find_file("hdsim", target="hdsim_cli")
    except (FileNotFoundError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"hdsim not built: {exc}")


@pytest.fixture(scope="session")
def simulate(hdsim, tmp_path_factory):
    """simulate(name, *--set overrides) -> path of the CSV (cached)."""
    cache = {}
    out_dir = tmp_path_factory.mktemp("sim")

    def run(name, *sets):
        key = (name,) + sets
        if key not in cache:
            out = out_dir / f"{name}_{len(cache)}.csv"
            cmd = [str(hdsim), str(SCENARIOS / f"{name}.ini"), "--csv", str(out)]
            for s in sets:
                cmd += ["--set", s]
            subprocess.run(cmd, check=True, capture_output=True)
            cache[key] = out
        return cache[key]
    return run


def read_csv(path):
    """The CSV as a dict of columns (numpy, independent of the tool's loader)."""
    with open(path) as fh:
        header = fh.readline().strip().split(",")
    arr = np.loadtxt(path, delimiter=",", skiprows=1)
    return header, arr


def write_csv(path, header, arr, fmt="%.9g"):
    np.savetxt(path, arr, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    return path


def analyze(path, **kw):
    from hdtools.analysis import pipeline
    kw.setdefault("log", lambda *a: None)
    return pipeline.analyze(str(path), **kw)


@pytest.fixture(scope="session")
def analyzed(simulate):
    """analyzed(name, *--set overrides) -> the report of the simulated log
    (each analysed once per session)."""
    cache = {}

    def run(name, *sets):
        key = (name,) + sets
        if key not in cache:
            cache[key] = analyze(simulate(name, *sets))
        return cache[key]
    return run


def added(report):
    return [e for e in report["effects"] if e["added"]]
