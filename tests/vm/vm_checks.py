"""Checks shared by the host sides of the VM tests (test_vm_socketcan.py,
test_vm_monitor.py)."""
from __future__ import annotations

import numpy as np

# DBC signal, runner CSV column, LSB (firmware/hdjoint.dbc)
TELEMETRY_COLUMNS = (("TorqueFiltered", "torque_filtered_nm", 0.01),
                     ("TorqueRaw", "torque_raw_nm", 0.01),
                     ("Ripple", "ripple_nm", 0.001),
                     ("MotorVelocity", "motor_velocity_rad_s", 0.001))


def assert_telemetry_matches_csv(telem: list[dict], csv) -> None:
    """Decoded telemetry rows (hdtools.canproto.decode_log) against the
    runner's per-sample CSV, one row per sample at 1 kHz: sequence numbers
    0..255 continuous, torques / ripple / velocity within half an LSB (the
    CSV prints 6 significant digits, hence the relative term; int16 fields
    saturate at their DBC range, hd_can_proto.h), fault and KF status bits
    equal."""
    n = len(csv)
    assert len(telem) == n, f"{len(telem)} telemetry rows for {n} samples"
    assert [int(r["SeqA"]) for r in telem] == [i % 256 for i in range(n)]
    for signal, column, lsb in TELEMETRY_COLUMNS:
        got = np.array([float(r[signal]) for r in telem])
        want = csv[column]
        if signal != "MotorVelocity":
            want = np.clip(want, -32767 * lsb, 32767 * lsb)
        err = np.abs(got - want) - (lsb / 2 + 1e-5 * np.abs(want))
        at = int(np.argmax(err))
        assert np.max(err) <= 1e-9, (signal, at, got[at], want[at])
    col = lambda key: np.array([int(r[key]) for r in telem])  # noqa: E731
    assert np.array_equal(col("Faults"), csv["faults"].astype(int))
    assert np.array_equal(col("KfStatus"), csv["kf_status"].astype(int))
