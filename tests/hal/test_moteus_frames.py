"""hal/moteus's register protocol bytes against the moteus package (PyPI,
pinned in tools/requirements.txt), an independent encoder and parser: the
torque-only position command and the stop are byte-for-byte the package's
make_position / make_stop, the package parses them back to the values we
meant, and replies the test writes by hand from the register table parse to
the same values in C and in the package's parse_registers."""
from __future__ import annotations

import json
import math
import os
import struct
import subprocess
from pathlib import Path

import pytest

import moteus  # noqa: E402

BUILD = Path(os.environ.get("HD_BUILD_DIR", "build/host-debug"))
DUMP = BUILD / "tests" / "hal" / "moteus_dump"
R = moteus.Register


@pytest.fixture(scope="module")
def ours():
    return json.loads(subprocess.run([str(DUMP)], check=True, capture_output=True,
                                     text=True).stdout)


def test_torque_command_is_the_packages(ours):
    c = moteus.Controller(id=3)
    ref = c.make_position(position=math.nan, velocity=0.0, feedforward_torque=0.25,
                          kp_scale=0.0, kd_scale=0.0, query=True)
    assert ours["torque_query"] == ref.data.hex()
    ref = c.make_position(position=math.nan, velocity=0.0, feedforward_torque=-1.5,
                          kp_scale=0.0, kd_scale=0.0, query=False)
    assert ours["torque"] == ref.data.hex()
    assert ours["stop"] == c.make_stop(query=False).data.hex()


def test_package_parses_our_command_to_what_we_meant(ours):
    p = moteus.parse_registers(bytes.fromhex(ours["torque"]))
    assert p.command[R.MODE] == 10  # position mode
    assert math.isnan(p.command[R.COMMAND_POSITION])
    assert p.command[R.COMMAND_VELOCITY] == 0.0
    assert p.command[R.COMMAND_FEEDFORWARD_TORQUE] == -1.5
    assert p.command[R.COMMAND_KP_SCALE] == 0.0 and p.command[R.COMMAND_KD_SCALE] == 0.0


def test_frame_is_fd_with_reply_bit(ours):
    # 0x8000 reply wanted | source 0 << 8 | destination 3 (moteus transport.py's rule)
    assert ours["id"] == 0x8003 and ours["fd"] == 1
    assert ours["len"] >= len(ours["torque_query"]) // 2 and ours["len"] in (
        0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def reply_float():
    return (bytes([0x21, 0x00, 10, 0x2F, 0x01]) + struct.pack("<fff", 1.25, -0.5, 0.75) +
            bytes([0x23, 0x0D, 48, 35, 0]))


def reply_int16_fault():
    return (bytes([0x21, 0x00, 1, 0x25, 0x03]) + struct.pack("<h", -123) +
            bytes([0x23, 0x0D, 50, 40, 33, 0x50, 0x50]))


@pytest.mark.parametrize("data", [reply_float(), reply_int16_fault()])
def test_replies_parse_alike(data):
    ref = moteus.parse_registers(data).response
    out = json.loads(subprocess.run([str(DUMP), data.hex()], check=True, capture_output=True,
                                    text=True).stdout)
    assert out["mode"] == ref[R.MODE]
    assert out["torque"] == pytest.approx(ref[R.TORQUE], abs=1e-6)
    assert out["voltage"] == pytest.approx(ref[R.VOLTAGE], abs=1e-6)
    assert out["temperature"] == pytest.approx(ref[R.TEMPERATURE], abs=1e-6)
    assert out["fault"] == ref[R.FAULT]
    if R.POSITION in ref:
        assert out["position"] == pytest.approx(ref[R.POSITION], abs=1e-6)
        assert out["velocity"] == pytest.approx(ref[R.VELOCITY], abs=1e-6)


def test_garbage_is_refused():
    r = subprocess.run([str(DUMP), "4f0001"], capture_output=True, text=True)
    assert r.returncode == 2
