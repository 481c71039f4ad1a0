"""Shared helpers for the device tests: the emulated joint (the real
firmware on the mock HAL with the simulated joint, tools/hdtools/emu.py)
on python-can's in-process virtual bus, and the hdsense CLI in-process."""
from __future__ import annotations

import uuid
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

from hdtools import cli, emu, summary as key_values

# The paper's drive with its ripple lines and noise (sim/scenarios/paper_156.ini),
# long enough for any test.
PAPER = (ROOT / "sim" / "scenarios" / "paper_156.ini").read_text().replace(
    "duration_s = 10", "duration_s = 3600")
assert "duration_s = 3600" in PAPER


@pytest.fixture(scope="session")
def paper_scenario():
    return PAPER


@pytest.fixture
def channel():
    return f"hd-{uuid.uuid4().hex[:10]}"


@pytest.fixture
def joint():
    """joint(config=None, scenario=PAPER) -> an Emulator (closed at the end)."""
    made = []

    def make(config=None, scenario=PAPER):
        j = emu.Emulator(scenario=scenario, config=config)
        made.append(j)
        return j
    yield make
    for j in made:
        j.close()


def run_cli(capsys, *args):
    """(exit status, stdout, stderr) of one hdsense command run in-process."""
    capsys.readouterr()
    try:
        rc = cli.main([str(a) for a in args])
    except SystemExit as exc:     # argparse's exit (usage errors, --version)
        rc = exc.code
    out, err = capsys.readouterr()
    return rc, out, err


def summary(text: str) -> dict:
    return key_values.parse(text)
