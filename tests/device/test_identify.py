"""`hdsense control identify` and `hdsense tune` (hdtools.cmd_tune) against
the emulated joint with a drive (the dynamic joint behind hal/simdyn) on
python-can's virtual bus:

- the excitation the firmware adds (IDENT frames: drive - law's current)
  is the control benchmark's multisine, hdtools.torque_loop.multisine(),
  sample for sample to the frames' resolution (one waveform, two
  implementations held equal);
- the plant measured under one set of gains predicts, through the law's PI
  in closed form, the loop measured under another (the premise of the
  tuning method), above the band where the motor's friction sticks;
- tune: gains meeting the margins from measurements; bad files, two
  measurements of one condition, gains the grid cannot find: one line and
  its exit status; identify's refusals and bad command lines likewise.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_cli, summary
from hdtools import cfgtext, cmd_control, cmd_tune, emu, torque_loop as tl
from hdtools.joint import Joint, open_bus

CLAMP_NM_RAD = 2e4      # the output held by a stiff spring: "clamped"
RMS_A = 0.9             # beyond the motor's break-away at the output (3 N m): a linear test


@pytest.fixture
def clamped(channel):
    """A dynamic joint on the bus with its output clamped, fed back on the
    raw gauge (so the loop's plant does not depend on what the filter has
    learned at a standstill)."""
    with emu.Emulator(dynamic=True, config="ctrl_feedback = 1\n") as j:
        j.set_environment(stiffness_nm_rad=CLAMP_NM_RAD)
        with j.attach("virtual", channel) as att:
            yield j, att


def identify(capsys, channel, out, *extra):
    return run_cli(capsys, "control", "-i", "virtual", channel, "identify", "--condition",
                   "clamped", "--rms", str(RMS_A), "--periods", "1", "--settle", "0.5",
                   "--out", out, *extra)


def test_the_firmware_plays_the_benchmarks_multisine(channel, clamped):
    bus = open_bus("virtual", channel)
    try:
        ctl = cmd_control.Controller(bus, 1, 0.5)
        result, rows = cmd_tune.measure(ctl, Joint(bus, 1, 0.5), "clamped", 10.0, RMS_A, 1,
                                        0.3, 200.0)
    finally:
        bus.shutdown()
    cmd, drive = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    one, bins = tl.multisine(rms=RMS_A)
    want = np.tile(one, 2)
    assert len(rows) == len(want) == 2 * tl.MS_PERIOD
    # each of drive and cmd is rounded to the frame's 1 mA; the table to 1/32767 of its peak
    err = np.abs(drive - cmd - want)
    print(f"identify: |drive - cmd - multisine| worst {err.max() * 1e3:.2f} mA")
    assert err.max() <= 1e-3 + result["peak_a"] / 32767 + 1e-9
    assert result["peak_a"] == pytest.approx(np.abs(one).max(), rel=1e-5)
    f = bins / (tl.MS_PERIOD * tl.TS_S)       # at rest: the lines the benchmark keeps at 0 rad/s
    assert abs(result["motor_speed_rad_s"]) < 0.5
    assert result["freq_hz"] == pytest.approx(list(f[tl.off_the_ripple(f, 0.0)]))


def test_a_measured_plant_predicts_the_loop_under_other_gains(capsys, channel, clamped,
                                                              tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    rc, out, err = identify(capsys, channel, a)
    assert rc == 0, err
    for key, value in (("ctrl_torque_kp", "0.3"), ("ctrl_torque_ki_per_s", "10"),
                       ("ctrl_torque_kd_s", "0")):
        rc, _, err = run_cli(capsys, "device", "-i", "virtual", channel, "set", key, value)
        assert rc == 0, err
    rc, out, err = identify(capsys, channel, b)
    assert rc == 0, err
    assert summary(out)["gains"] == "kp 0.3, ki 10/s, kd 0 s, ff 1"
    ma, mb = json.loads(a.read_text()), json.loads(b.read_text())
    f = np.array(ma["freq_hz"])
    plant = np.array(ma["plant"][0]) + 1j * np.array(ma["plant"][1])
    measured = np.array(mb["loop"][0]) + 1j * np.array(mb["loop"][1])
    predicted = tl.pi_response(f, 0.3, 10.0, 0.0) * plant
    # Below ~10 Hz the motor's friction sticks and slips under the excitation
    # (a nonlinear plant: docs/how-to/tune-torque-loop.md); above, linear,
    # down to where the law's response nears the frames' 1 mA (-35 dB).
    band = (f >= 10.0) & (np.abs(measured) > 10 ** (-35 / 20))
    db = np.abs(20 * np.log10(np.abs(measured[band] / predicted[band])))
    deg = np.abs(np.degrees(np.angle(measured[band] / predicted[band])))
    print(f"identify: prediction vs measurement above 10 Hz ({band.sum()} lines): median "
          f"{np.median(db):.2f} dB, {np.median(deg):.1f} deg; worst {db.max():.2f} dB, "
          f"{deg.max():.1f} deg")
    assert np.median(db) < 1.5 and np.median(deg) < 10.0
    # the gains the plant was measured under do not predict it (the test can fail)
    other = tl.pi_response(f, 0.86, 27.0, 1.5e-3) * plant
    other_db = np.median(np.abs(20 * np.log10(np.abs(measured[band] / other[band]))))
    print(f"identify: under the first gains instead: median {other_db:.2f} dB")
    assert other_db > 5.0


def test_a_turning_joint_drops_the_lines_near_its_ripple(capsys, channel, tmp_path):
    """A person turns the free output against a damper (5 N m on 5 N m s/rad:
    about 1 rad/s, 100 rad/s at the motor): the excited lines within
    RIPPLE_GUARD_HZ of the 2x and 4x motor lines at the run's speed are
    dropped, the speed is the truth's."""
    out_file = tmp_path / "free.json"
    speeds = []
    with emu.Emulator(dynamic=True, config="ctrl_feedback = 1\n") as j:
        j.set_environment(damping_nm_s_rad=5.0, person_torque_nm=5.0)
        with j.attach("virtual", channel,
                      on_chunk=lambda e: speeds.append(e.truth().output_velocity_rad_s)):
            rc, out, err = run_cli(capsys, "control", "-i", "virtual", channel, "identify",
                                   "--condition", "free", "--periods", "1", "--settle", "1",
                                   "--out", out_file)
    assert rc == 0, err
    m = json.loads(out_file.read_text())
    true_motor = 100.0 * float(np.mean(speeds[len(speeds) // 3:]))   # gear ratio 100
    assert true_motor > 50.0
    assert m["motor_speed_rad_s"] == pytest.approx(true_motor, rel=0.05)
    f = np.array(m["freq_hz"])
    every = tl.multisine()[1] / (tl.MS_PERIOD * tl.TS_S)
    near = np.zeros(len(every), dtype=bool)
    for order in (2, 4):
        line = order * m["motor_speed_rad_s"] / (2 * np.pi)
        assert np.all(np.abs(f - line) > tl.RIPPLE_GUARD_HZ)
        near |= np.abs(every - line) <= tl.RIPPLE_GUARD_HZ
    # exactly those were dropped, and there were some (64 Hz near the 4x line)
    assert m["lines_dropped"] == int(near.sum()) >= 1
    assert f == pytest.approx(list(every[~near]))


def test_identify_refusals_and_bad_input(capsys, channel, clamped, tmp_path):
    out_file = tmp_path / "m.json"
    # rms 3 A: peak 12.5 A beyond half the 8 A current limit; the joint refuses
    rc, out, err = run_cli(capsys, "control", "-i", "virtual", channel, "identify",
                           "--condition", "wall", "--rms", "3", "--periods", "1",
                           "--settle", "0.1", "--out", out_file)
    assert rc == 1 and out == "" and err.count("\n") == 1
    assert "IDENT_START refused (OUT_OF_RANGE" in err and not out_file.exists()
    for args, what in ((["--periods", "0"], "--periods 0 outside 1..60"),
                       (["--rms", "0"], "--rms 0 outside"),
                       (["--torque", "99"], "--torque 99 outside")):
        rc, out, err = run_cli(capsys, "control", "-i", "virtual", channel, "identify",
                               "--condition", "clamped", "--out", out_file, *args)
        assert rc == 2 and err.count("\n") == 1 and what in err, err
    rc, _, err = run_cli(capsys, "control", "-i", "virtual", channel + "-nobody", "--timeout",
                         "0.2", "identify", "--condition", "free", "--out", out_file)
    assert rc == 5 and err.count("\n") == 1 and not out_file.exists()


# ------------------------------------------------------------------ tune
def _write(path, condition, plant, f, ff=1.0):
    path.write_text(json.dumps({
        "format": cmd_tune.FORMAT, "condition": condition, "freq_hz": list(f),
        "plant": [list(plant.real), list(plant.imag)], "joint": {"ff": ff}}))
    return path


def _lag_plant(f, tau_s, delay_ticks=2):
    """A first-order lag with a transport delay, discretized at the tick:
    the closed-form loop of tests/bench/test_control_margins.py."""
    z = np.exp(1j * 2 * np.pi * np.asarray(f) * tl.TS_S)
    a = np.exp(-tl.TS_S / tau_s)
    return (1 - a) / (z - a) * z ** (-(delay_ticks - 1))


def test_tune_finds_gains_meeting_the_margins(capsys, tmp_path):
    f = tl.multisine()[1] / (tl.MS_PERIOD * tl.TS_S)
    files = [_write(tmp_path / "c.json", "clamped", _lag_plant(f, 0.004), f),
             _write(tmp_path / "w.json", "wall", _lag_plant(f, 0.006), f)]
    cfg = tmp_path / "gains.cfg"
    rc, out, err = run_cli(capsys, "tune", *files, "--config", cfg)
    assert rc == 0, err
    s = summary(out)
    # the configuration text is the gains printed, as the firmware's own parser reads it
    parsed = cfgtext.parse(cfg.read_text())
    assert parsed.blocks is None
    got = {p.key: v for _, p, v in parsed.values}
    assert got == {k: pytest.approx(float(s[k]), rel=1e-6)
                   for k in ("ctrl_torque_kp", "ctrl_torque_ki_per_s", "ctrl_torque_kd_s")}
    kp, ki = float(s["ctrl_torque_kp"]), float(s["ctrl_torque_ki_per_s"])
    kd = float(s["ctrl_torque_kd_s"])
    for tau in (0.004, 0.006):  # the margins of the gains printed, in closed form
        m = tl.margins(f, tl.pi_response(f, kp, ki, kd) * _lag_plant(f, tau))
        assert m["pm_deg"] >= tl.PM_DEG - 1.0 and m["gm_db"] >= tl.GM_DB - 0.2
    assert "phase margin" in s["predicted_clamped"] and "phase margin" in s["predicted_wall"]
    nxt = [s[f"next_{i}"] for i in (1, 2, 3)]       # the ranking's next, for step 4 by hand
    assert len(set(nxt)) == 3 and "next_4" not in s


def test_tune_bad_input_is_one_line(capsys, tmp_path):
    f = tl.multisine()[1] / (tl.MS_PERIOD * tl.TS_S)
    good = _write(tmp_path / "c.json", "clamped", _lag_plant(f, 0.004), f)
    junk = tmp_path / "junk.json"
    junk.write_text("{not json")
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"format": "something else"}))
    cases = [([junk], 2, "junk.json"), ([other], 2, "not an identify measurement"),
             ([good, good], 2, "one measurement per condition"),
             ([good, _write(tmp_path / "w.json", "wall", _lag_plant(f, 0.004), f, ff=0.5)], 2,
              "different ctrl_torque_ff"),
             ([tmp_path / "missing.json"], 2, "missing.json"),
             # a plant no PI on the grid holds: 60 ticks of delay
             ([_write(tmp_path / "slow.json", "wall", 50 * _lag_plant(f, 0.004, 60), f)], 1,
              "no gains on the grid")]
    for files, code, what in cases:
        rc, out, err = run_cli(capsys, "tune", *files)
        assert rc == code and out == "" and err.count("\n") == 1 and what in err, (files, err)

