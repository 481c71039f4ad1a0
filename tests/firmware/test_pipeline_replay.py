"""The firmware and the analysis replay run the same torque path: one sensor
log (ripple, a slow load, a reversal, the motor current, feed-forward frames
with a dropout that makes them stale) goes through the firmware's tick on the
mock HAL (fw_replay_dump) and, from what the tick logged (raw torque,
increments, feed-forward after its fallback, current), through
hdtools.analysis.cfilter.run (hd_pipeline_run, the call `hdsense analyze`
makes).  The filtered torque, T_exp and its variance must agree bit for bit:
any slow-torque term the firmware added outside filter/hd_slow.c, or the
replay left out, shows here.  The analysis's own path is compared too: one
configuration text boots the firmware and, read by Model.with_config_text,
gives the model hdtools.analysis.replay runs on the tick's log as a CSV."""
from __future__ import annotations

import struct
import subprocess

import numpy as np
import pytest

from hdtools import native
from hdtools.analysis import cfilter

GEAR, CPR, TS = 100.0, 4096, 1e-3
VPC, GAIN = 0.0003, 10.0
CURRENT = {"nm_per_a": 10.0, "coulomb_nm": 0.2, "viscous_nm_s_rad": 0.1, "inertia_kgm2": 0.01}
CONFIG = f"""gear_ratio = {GEAR:g}
motor_cpr = {CPR}
output_cpr = {CPR}
adc_volts_per_count = {VPC:g}
calib_gain_nm_per_v = {GAIN:g}
inertia_kgm2 = 0.05
viscous_nm_s_rad = 0.5
coulomb_nm = 0.3
feedforward_timeout_ms = 20
feedforward_ramp_ms = 300
current_nm_per_a = {CURRENT['nm_per_a']:g}
current_coulomb_nm = {CURRENT['coulomb_nm']:g}
current_viscous_nm_s_rad = {CURRENT['viscous_nm_s_rad']:g}
current_inertia_kgm2 = {CURRENT['inertia_kgm2']:g}
current_filter_hz = 10
"""
N = 5000


def write_log(path):
    """A joint turning up to 60 rad/s at the motor and back (a reversal),
    with motor and output ripple, a slow load, sensor noise; the current
    carries the load; feed-forward every tick but 2.0-2.6 s."""
    rng = np.random.default_rng(7)
    t = np.arange(N) * TS
    w = 60.0 * np.sin(2 * np.pi * 0.25 * t)
    theta_m = np.cumsum(w) * TS
    theta_o = theta_m / GEAR
    load = 3.0 + 2.0 * np.sin(2 * np.pi * 0.3 * t)
    torque = (load + 0.8 * np.cos(2 * theta_m + 0.3) + 0.4 * np.cos(theta_o - 0.7)
              + 0.02 * rng.standard_normal(N))
    counts = np.round(torque / (GAIN * VPC)).astype(np.int64)
    rad_per_count = 2 * np.pi / CPR
    motor = np.round(theta_m / rad_per_count).astype(np.int64) % 2**32
    output = np.round(theta_o / rad_per_count).astype(np.int64) % 2**32
    current = load / CURRENT["nm_per_a"] + 0.01 * rng.standard_normal(N)
    ff = np.where((t >= 2.0) & (t < 2.6), np.nan, 0.9 * load)
    with open(path, "w") as f:
        f.write("bridge_counts,motor_counts,output_counts,motor_current_a,feedforward_nm\n")
        for row in zip(counts, motor, output, current, ff):
            f.write("%d,%d,%d,%.9g,%.9g\n" % row)


def read_dump(path):
    raw = path.read_bytes()
    magic, n, kf_size = struct.unpack_from("<4sII", raw)
    assert magic == b"HDRD"
    assert kf_size == ctypes_size(cfilter.KfConfig)
    off = 12
    kf = cfilter.KfConfig.from_buffer_copy(raw, off)
    off += kf_size
    expected = cfilter.ExpectedConfig.from_buffer_copy(raw, off)
    off += ctypes_size(cfilter.ExpectedConfig)
    (bw,) = struct.unpack_from("<f", raw, off)
    ticks = np.frombuffer(raw, np.float32, offset=off + 4).reshape(n, 8)
    return kf, expected, bw, ticks


def ctypes_size(t):
    import ctypes
    return ctypes.sizeof(t)


@pytest.fixture(scope="module")
def firmware(tmp_path_factory):
    d = tmp_path_factory.mktemp("replay")
    (d / "config.txt").write_text(CONFIG)
    write_log(d / "log.csv")
    subprocess.run([str(native.executable("fw_replay_dump")), str(d / "config.txt"),
                    str(d / "log.csv"), str(d / "out.bin")], check=True)
    return read_dump(d / "out.bin")


def bits(a):
    return np.ascontiguousarray(a, np.float32).view(np.uint32)


def test_replay_matches_the_firmware_bit_for_bit(firmware):
    kf, expected, bw, ticks = firmware
    raw, dm, do, ff, cur, filt, texp, var = ticks.T
    term = cfilter.CurrentTerm(**CURRENT)
    out = cfilter.run(kf, expected, raw, dm, do, ff, track_bandwidth_hz=bw,
                      motor_current_a=cur, current=cfilter.current_config(term, 10.0, GEAR, TS))
    valid = np.isfinite(raw)
    assert valid.all()
    assert np.array_equal(bits(out["torque_expected_nm"]), bits(texp))
    assert np.array_equal(bits(out["torque_expected_var_nm2"]), bits(var))
    assert np.array_equal(bits(out["torque_filtered_nm"]), bits(filt))
    # the log exercised what it claims to: the current term, a stale ramp, motion
    stale = (np.arange(len(ff)) * TS > 2.03) & (np.arange(len(ff)) * TS < 2.3)
    assert np.all(np.abs(ff[stale]) < np.abs(ff[stale][0]) + 1e-6) and ff[stale][-1] != ff[stale][0]
    assert np.max(var) > 0.0 and np.max(np.abs(dm)) > 0.05
    assert np.std(raw - filt) > 0.3  # the ripple was removed, not passed through


def test_replay_without_the_current_differs(firmware):
    """The comparison has teeth: leaving the current term out of the replay
    (the analysis's feed-forward-only replay before hd_pipeline_sample)
    changes T_exp and the filtered torque."""
    kf, expected, bw, ticks = firmware
    raw, dm, do, ff, _cur, filt, texp, _var = ticks.T
    out = cfilter.run(kf, expected, raw, dm, do, ff, track_bandwidth_hz=bw)
    assert not np.array_equal(bits(out["torque_expected_nm"]), bits(texp))
    assert not np.array_equal(bits(out["torque_filtered_nm"]), bits(filt))


def analysis_log(path, ticks):
    """What the tick logged, in the analysis's log contract (docs/design/analyze.md
    "Input"): absolute angles summed from the increments in float64 (exact, so
    the loader's differences give the increments back), the feed-forward as
    the tick used it, the motor current."""
    raw, dm, do, ff, cur = ticks.T[:5]
    th_m = np.cumsum(dm.astype(np.float64))
    th_o = np.cumsum(do.astype(np.float64))
    with open(path, "w") as f:
        f.write("t_s,torque_nm,motor_angle_rad,output_angle_rad,torque_feedforward_nm,"
                "motor_current_a\n")
        for k, row in enumerate(zip(raw, th_m, th_o, ff, cur)):
            f.write("%.17g,%.9g,%.17g,%.17g,%.9g,%.9g\n" % ((k * TS,) + row))


@pytest.fixture(scope="module")
def analysis_path(tmp_path_factory):
    """One configuration text, the whole filter model as `hdsense analyze`
    writes it (model.cfg) plus the joint's sensor, feed-forward and
    motor-current keys, boots the firmware and, through the analysis's own
    reading (Model.with_config_text), builds the model the analysis replays."""
    from hdtools.analysis.model import Model
    d = tmp_path_factory.mktemp("analysis")
    start = Model.starting(GEAR, TS, 0.02, [2, 4], [1], inertia_kgm2=0.05)
    start.viscous_nm_s_rad, start.coulomb_nm = 0.5, 0.3
    # model.cfg gives gear_ratio and the expected-torque keys; the rest is the joint's
    joint = [ln for ln in CONFIG.splitlines() if ln.split(" =")[0] not in start.config_text()]
    # learning_mode 0: model.cfg does not write it, and the firmware's default
    # (operating, scale 0) would hold the output block the model lets learn
    text = start.config_text() + "\n".join(joint) + "\nlearning_mode = 0\n"
    (d / "config.txt").write_text(text)
    write_log(d / "log.csv")
    subprocess.run([str(native.executable("fw_replay_dump")), str(d / "config.txt"),
                    str(d / "log.csv"), str(d / "out.bin")], check=True)
    _kf, _exp, _bw, ticks = read_dump(d / "out.bin")
    analysis_log(d / "analysis.csv", ticks)
    model = Model(1.0, TS, 1.0).with_config_text(text)
    return text, model, d / "analysis.csv", ticks


def test_analysis_replay_from_the_config_text_matches_the_firmware(analysis_path):
    from hdtools.analysis import loading, replay
    _text, model, log, ticks = analysis_path
    assert model.current_nm_per_a == CURRENT["nm_per_a"] and len(model.blocks) == 3
    data = loading.load(log)
    assert len(data.pieces) == 1 and len(data.pieces[0]) == N and data.has_current
    (run,) = replay.replay(data, model)
    _raw, _dm, _do, _ff, _cur, filt, texp, var = ticks.T
    assert np.array_equal(bits(run.out["torque_expected_nm"]), bits(texp))
    assert np.array_equal(bits(run.out["torque_expected_var_nm2"]), bits(var))
    assert np.array_equal(bits(run.out["torque_filtered_nm"]), bits(filt))
    assert np.max(var) > 0.0


def test_model_cfg_carries_the_current_term(analysis_path):
    """model.cfg written back from that model gives the firmware's parser the
    same current term (float32 round trip), and a model without one writes
    no current line (logs without current: model.cfg unchanged)."""
    from hdtools.analysis.model import CURRENT_KEYS, Model
    _text, model, _log, _ticks = analysis_path
    again = Model(1.0, TS, 1.0).with_config_text(model.config_text())
    assert all(getattr(again, k) == getattr(model, k) for k in CURRENT_KEYS)
    bare = Model.starting(GEAR, TS, 0.02, [2, 4], [1])
    assert "current_" not in bare.config_text()
