"""Firmware telemetry from a `candump -l` log, as analysis columns: decoded
through the project's DBC (hdtools.canproto.decode_log, device time from
the telemetry sequence) and turned into columns by hdtools.telemetry:

  t_s               device time (sequence x telemetry period)
  torque_nm         TorqueRaw (calibrated, before the filter); "not available"
                    samples become NaN (dropped and counted by the loader)
  motor_angle_rad   from TELEM_C's raw encoder counts (motor_cpr from the
                    log's GET_PARAM answers), interpolated between TELEM_C
                    frames with the velocity; the integral of MotorVelocity
                    only when the log has no TELEM_C or no motor_cpr
  output_angle_rad  likewise, with an output encoder
  segment           a new one after every BOOT frame
The node is found in the log."""
from __future__ import annotations

from pathlib import Path

from .errors import InputError


def read(path: str | Path) -> dict:
    from .. import canproto, telemetry
    from ..safeio import HdError
    try:
        log = canproto.decode_log(path, None)    # the node is found in the log
    except HdError as exc:
        raise InputError(f"no firmware telemetry: {exc}") from None
    except Exception as exc:  # python-can/cantools parse errors
        raise InputError(f"{path}: cannot read as a candump -l log: {exc}") from exc
    if len(log["telemetry"]) < 2:
        raise InputError(f"{path}: fewer than 2 paired telemetry frames (TELEM_A + TELEM_B) "
                         f"of node {log['node']}: no firmware telemetry to analyse")
    col, _notes = telemetry.columns(log)
    keep = ("t_s", "torque_nm", "motor_angle_rad", "output_angle_rad", "segment")
    return {k: col[k] for k in keep if k in col}
