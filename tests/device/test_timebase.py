"""Time from the device: decoded telemetry placed by the sequence counter,
whatever the host's time stamps (jitter, USB-style batches, gaps longer
than the 8-bit sequence), angles from TELEM_C counts, and an analysis of a
badly stamped log equal to that of the clean one."""
from __future__ import annotations

import copy
import csv
import re

import numpy as np
import pytest

from conftest import PAPER, run_cli, summary
from hdtools import canproto, cli, emu, protocol, telemetry
from hdtools.cmd_monitor import candump_line

RNG = np.random.default_rng(17)
N = 5000


@pytest.fixture(scope="module")
def frames():
    """4 s of the emulated joint at 1 kHz, TELEM_C with every pair, and the
    same run with TELEM_C every 10th pair (the default)."""
    out = {}
    for every in (1, 10):
        with emu.Emulator(scenario=PAPER, config=f"angle_telemetry_every = {every}\n") as j:
            out[every] = j.run_frames(N)
    return out


def write_log(path, msgs, stamps=None):
    if stamps is not None:
        msgs = [copy.copy(m) for m in msgs]      # the fixture's frames keep device time
        for m, t in zip(msgs, stamps):
            m.timestamp = t
    path.write_text("".join(candump_line(m, "can0") for m in msgs))
    return path


def restamp(msgs, how):
    """Host time stamps as a USB adapter or a busy host would give them,
    from the device time of each frame (+ 1.7e9 s of epoch)."""
    t = np.array([m.timestamp for m in msgs]) + 1.7e9
    if how == "jitter":                  # 0.5 ms RMS, order kept
        t = t + np.abs(RNG.normal(0, 0.5e-3, len(t)))
        t = np.maximum.accumulate(t)
    elif how == "batch":                 # delivered in 4 ms batches, one stamp per batch
        t = np.ceil(t / 4e-3) * 4e-3 + 0.3e-3
    return t


def test_tick_constant_is_the_firmware_s():
    header = (protocol.FIRMWARE / "hd_fw_config.h").read_text()
    assert re.search(r"#define HD_FW_TS_US (\d+)u", header).group(1) == str(
        round(1e6 / telemetry.TICK_HZ))


@pytest.mark.parametrize("how", ["clean", "jitter", "batch"])
def test_sample_times_are_exact(frames, tmp_path, how):
    msgs = [m for m in frames[10]]
    log = write_log(tmp_path / f"{how}.log", msgs, restamp(msgs, how))
    res = canproto.decode_log(log, 1)
    t = np.array([r["t_s"] for r in res["telemetry"]])
    assert len(t) == N and res["lost_telemetry"] == 0
    assert np.array_equal(t, np.arange(N) * 0.001)       # exactly k x period
    assert "snapped to 1 tick" in res["period_source"]
    if how != "clean":
        host = np.array([r["t_host_s"] for r in res["telemetry"]])
        err = host - host[0] - t
        print(f"{how}: host stamp error vs device time: max {np.ptp(err) * 1e3:.2f} ms")


def test_gaps_longer_than_the_sequence_are_counted(frames, tmp_path):
    """300 and 3 samples lost (a cable pulled, a busy adapter), batched stamps."""
    ids = {canproto.BASE_IDS[n] + 1 for n in ("TELEM_A", "TELEM_B", "TELEM_C")}
    lost = set(range(1000, 1300)) | {2500, 2501, 2502}
    keep = [m for m in frames[10] if not (m.arbitration_id in ids and
                                          round(m.timestamp * 1000) in lost)]
    log = write_log(tmp_path / "gaps.log", keep, restamp(keep, "batch"))
    res = canproto.decode_log(log, 1)
    t = np.array([r["t_s"] for r in res["telemetry"]])
    want = np.array([k for k in range(N) if k not in lost]) * 0.001
    assert res["lost_telemetry"] == 303
    assert np.array_equal(t, want)


def test_rate_from_the_log_answers_even_with_useless_stamps(tmp_path):
    """200 Hz telemetry, a GET_PARAM answer in the log, and host stamps that
    tell nothing (everything delivered in 50 ms lumps)."""
    import can
    with emu.Emulator(scenario=PAPER, config="telemetry_rate_hz = 200\n") as j:
        db = canproto.load_db(1)
        fid, data = canproto.command(db, "GET_PARAM", 7, GetParamId="TELEMETRY_RATE_HZ")
        j.push(can.Message(arbitration_id=fid, data=data))
        msgs = j.run_frames(3000)
    stamps = np.ceil(np.array([m.timestamp for m in msgs]) / 0.05) * 0.05
    res = canproto.decode_log(write_log(tmp_path / "r.log", msgs, stamps), 1)
    t = np.array([r["t_s"] for r in res["telemetry"]])
    assert res["params"]["telemetry_rate_hz"] == 200 and res["period_s"] == 0.005
    assert np.array_equal(t, np.arange(len(t)) * 0.005) and len(t) == 600
    # and without the answer, estimated from batched stamps: 5 ms as well
    plain = [m for m in msgs if m.arbitration_id != canproto.BASE_IDS["ACK"] + 1]
    res = canproto.decode_log(write_log(tmp_path / "p.log", plain, restamp(plain, "batch")), 1)
    assert res["period_s"] == 0.005 and "estimated" in res["period_source"]
    # --rate overrides everything
    res = canproto.decode_log(write_log(tmp_path / "p.log", plain), 1, rate_hz=100)
    assert res["period_s"] == 0.01


def test_a_reboot_starts_a_new_segment(tmp_path):
    with emu.Emulator(scenario=PAPER) as j:
        msgs = j.run_frames(700)
        j.power_cycle()
        msgs += j.run_frames(700)
    res = canproto.decode_log(write_log(tmp_path / "b.log", msgs, restamp(msgs, "batch")), 1)
    seg = [r["segment"] for r in res["telemetry"]]
    assert seg == [0] * 700 + [1] * 700 and res["lost_telemetry"] == 0
    t = np.array([r["t_s"] for r in res["telemetry"]])
    assert np.all(np.diff(t) > 0)
    assert np.allclose(np.diff(t[700:]), 0.001, rtol=0, atol=1e-12)


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    head = rows[0]
    return {k: [r[i] for r in rows[1:]] for i, k in enumerate(head)}


def test_angles_from_counts(frames, tmp_path, capsys):
    """Angles with TELEM_C at every sample are the counts themselves
    (2 pi / cpr apart); with TELEM_C every 10th sample the interpolation
    stays within a count of them."""
    cols = {}
    for every in (1, 10):
        log = write_log(tmp_path / f"e{every}.log", list(frames[every]),
                        restamp(frames[every], "batch"))
        out = tmp_path / f"e{every}.csv"
        rc, text, err = run_cli(capsys, "canlog", "decode", log, "--csv", out, "--cpr", "4096")
        assert rc == 0, err
        assert "angles from TELEM_C counts" in summary(text)["angles"]
        cols[every] = read_csv(out)
    exact = np.array(cols[1]["motor_angle_rad"], float)
    counts = np.round(exact / (2 * np.pi / 4096))
    assert np.allclose(exact, counts * 2 * np.pi / 4096, atol=1e-6)
    assert np.all(np.diff(counts) >= 0)            # the drive turns one way
    interp = np.array(cols[10]["motor_angle_rad"], float)
    measured = np.array(cols[10]["angle_measured"], int) == 1
    assert measured.sum() == N // 10
    assert np.allclose(interp[measured], exact[measured], atol=1e-6)
    count = 2 * np.pi / 4096
    err = np.abs(interp - exact) / count
    steady = np.arange(N) >= 1000                  # the drive accelerates over the first 0.5 s
    print(f"interpolated motor angle: max error {err.max():.2f} counts, "
          f"{err[steady].max():.2f} counts at constant speed")
    assert err.max() < 3 and err[steady].max() < 1


def test_analysis_of_batched_log_equals_clean(frames, tmp_path, capsys):
    """The decoded CSV of a log with 4 ms batches equals that of the clean
    log in every column but the host stamps, and so does its analysis."""
    reports = {}
    for how in ("clean", "batch"):
        msgs = list(frames[10])
        log = write_log(tmp_path / f"{how}.log", msgs, restamp(msgs, how))
        out = tmp_path / f"{how}.csv"
        rc, _, err = run_cli(capsys, "canlog", "decode", log, "--csv", out, "--cpr", "4096")
        assert rc == 0, err
        reports[how] = read_csv(out)
    for key in reports["clean"]:
        if key != "t_host_s":
            assert reports["clean"][key] == reports["batch"][key], key
    import json
    res = {}
    for how in ("clean", "batch"):
        assert cli.main(["analyze", str(tmp_path / f"{how}.csv"), "--json",
                         str(tmp_path / f"{how}.json"), "--quiet"]) == 0
        res[how] = json.loads((tmp_path / f"{how}.json").read_text())
    for key in res["clean"]:
        if key not in ("input", "elapsed_s"):
            assert res["clean"][key] == res["batch"][key], key
    assert res["clean"]["config_after"] and res["clean"]["residual_rms_after_nm"] > 0
