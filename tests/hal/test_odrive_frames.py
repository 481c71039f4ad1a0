"""hal/odrive's CAN Simple frames against the odrive-can package (PyPI,
pinned in tools/requirements.txt) as an independent reference: the C
encoder's bytes decode through the package's own DBC (cantools), and
heartbeats that DBC encodes decode in C to the same fields.  The layout
checked is the package's 0.6.10 DBC (0.5.6's heartbeat differs: per-error
flags instead of the axis error word)."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

import odrive_can  # noqa: E402
from odrive_can.enums import AxisState  # noqa: E402
from odrive_can.utils import extract_ids  # noqa: E402

BUILD = Path(os.environ.get("HD_BUILD_DIR", "build/host-debug"))
DUMP = BUILD / "tests" / "hal" / "odrive_dump"
NODE = 5


@pytest.fixture(scope="module")
def frames():
    out = subprocess.run([str(DUMP)], check=True, capture_output=True, text=True).stdout
    return {d["frame"]: d for d in map(json.loads, out.splitlines())}


@pytest.fixture(scope="module")
def db():
    return odrive_can.get_dbc("odrive-cansimple-0.6.10")


def decode(db, f, name):
    assert f["ext"] == 0, "CAN Simple uses 11-bit identifiers"
    msg = db.get_message_by_frame_id(f["id"])
    assert msg.name == f"Axis{NODE}_{name}"
    return msg.decode(bytes.fromhex(f["data"]), decode_choices=False)


def test_commands_decode_through_the_odrive_dbc(frames, db):
    st = decode(db, frames["Set_Axis_State"], "Set_Axis_State")
    assert st["Axis_Requested_State"] == AxisState.CLOSED_LOOP_CONTROL.value
    cm = decode(db, frames["Set_Controller_Mode"], "Set_Controller_Mode")
    assert cm["Control_Mode"] == 1 and cm["Input_Mode"] == 1  # torque, passthrough
    tq = decode(db, frames["Set_Input_Torque"], "Set_Input_Torque")
    assert tq["Input_Torque"] == -0.3125
    ce = decode(db, frames["Clear_Errors"], "Clear_Errors")
    assert ce["Identify"] == 0


@pytest.mark.parametrize("err,state,result,done", [(0, 8, 0, 1), (0x10000, 1, 3, 0),
                                                   (0xDEADBEEF, 8, 255, 1)])
def test_heartbeat_encoded_by_the_dbc_decodes_in_c(db, err, state, result, done):
    msg = db.get_message_by_name(f"Axis{NODE}_Heartbeat")
    data = msg.encode({"Axis_Error": err, "Axis_State": state, "Procedure_Result": result,
                       "Trajectory_Done_Flag": done})
    out = subprocess.run([str(DUMP), str(msg.frame_id), data.hex()], check=True,
                         capture_output=True, text=True).stdout
    assert json.loads(out) == {"axis_error": err, "axis_state": state,
                               "procedure_result": result, "trajectory_done": done}


def test_ids_agree_with_the_packages_own_split(frames):
    for f in frames.values():
        axis, _cmd = extract_ids(f["id"])
        assert axis == NODE
