"""The load a record's ripple lines are averages at: the profile's load_nm
(hd_kf.h, output_row_follow), which `hdsense analyze` writes and its replay
gives the filter (profile.py, replay.py)."""
from __future__ import annotations

import numpy as np

LOAD_MIN_MOTOR_RAD = 0.05   # as the firmware's HD_KF_FOLLOW_MIN_RAD at order 1
LOAD_BLOCK_S = 0.2


def load_of(pieces, ts_s) -> float | None:
    """learned_load over (torque_nm, feedforward_nm or None, motor_angle_rad)
    triples, on LOAD_BLOCK_S block means (one pass, no copy of a long
    record): |mean slow torque| of the blocks whose motor turns at least
    LOAD_MIN_MOTOR_RAD per sample on average."""
    w = max(1, int(round(LOAD_BLOCK_S / ts_s)))
    total, n = 0.0, 0
    for torque, ff, motor in pieces:
        nb = len(torque) // w
        if nb == 0:
            continue
        x = np.asarray(torque[:nb * w], float).reshape(nb, w).mean(axis=1)
        if ff is not None:
            x = x - np.asarray(ff[:nb * w], float).reshape(nb, w).mean(axis=1)
        m = np.asarray(motor[:nb * w], float).reshape(nb, w)
        steps = np.abs(np.diff(m, axis=1))
        moving = np.mean(np.minimum(steps, np.pi), axis=1) >= LOAD_MIN_MOTOR_RAD
        total += float(np.abs(x[moving]).sum()) * w
        n += int(moving.sum()) * w
    return total / n if n else None
