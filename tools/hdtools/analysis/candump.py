"""Firmware telemetry from a `candump -l` log, decoded through the project's
DBC (firmware/hdjoint.dbc via hdtools.canproto), as analysis columns.

  t_s             candump time stamp of TELEM_A, from the first frame
  torque_nm       TorqueRaw (calibrated, before the filter); "not available"
                  samples become NaN (dropped and counted by the loader)
  motor_angle_rad integral of MotorVelocity (TELEM_B; the firmware's output
                  tracker velocity x gear ratio).  There is no angle in the
                  telemetry, so order lines are only as sharp as this
                  integral: small phase drift smears high orders a little.
The node is found in the log (canproto.decode_log)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .loading import InputError


def read(path: str | Path) -> dict:
    from .. import canproto
    from ..safeio import HdError
    try:
        log = canproto.decode_log(path, None)    # the node is found in the log
    except HdError as exc:
        raise InputError(f"no firmware telemetry: {exc}") from None
    except Exception as exc:  # python-can/cantools parse errors
        raise InputError(f"{path}: cannot read as a candump -l log: {exc}") from exc
    rows = log["telemetry"]
    if len(rows) < 2:
        raise InputError(f"{path}: fewer than 2 paired telemetry frames (TELEM_A + TELEM_B) "
                         f"of node {log['node']}: no firmware telemetry to analyse")
    t = np.array([r["t_s"] for r in rows], float)
    t -= t[0]
    torque = np.array([r["TorqueRaw"] if r["valid"] else np.nan for r in rows], float)
    vel = np.array([r["MotorVelocity"] for r in rows], float)
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * np.diff(t))])
    return {"t_s": t, "torque_nm": torque, "motor_angle_rad": angle}
