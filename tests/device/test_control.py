"""`hdsense control` against the emulated joint with a drive (the dynamic
joint behind hal/simdyn, the firmware's control stage closing its loop) on
python-can's virtual bus: one-off setpoints, the step test judged by the
simulation's truth, the joint's refusals, bad input before any bus, no
answer.  The step metrics are checked against closed forms."""
from __future__ import annotations

import math
import re

import can
import pytest

from conftest import ROOT, run_cli, summary
from hdtools import cmd_control, emu


@pytest.fixture
def dyn_joint(channel):
    """A dynamic joint against a damped spring (300 N m/rad, 30 N m s/rad), on
    the bus; its true output torque recorded every few ticks: (ticks, N m).
    The filter is off (filtered = raw gauge torque), so what the joint
    reports is the truth plus the gauge's sensing artifact (1.5 N m at twice
    the motor angle) and noise, however the scheduling of a loaded machine
    times the frames; a fresh filter at a standstill could not tell the
    artifact from torque either."""
    with emu.Emulator(dynamic=True, config="filter = off\n") as j:
        j.set_environment(stiffness_nm_rad=300.0, damping_nm_s_rad=30.0)
        truth = []
        with j.attach("virtual", channel,
                      on_chunk=lambda e: truth.append((e.ticks, e.truth().output_torque_nm))) \
                as att:
            yield j, att, truth


def ctl(capsys, channel, *args):
    return run_cli(capsys, "control", "-i", "virtual", channel, *args)


# ------------------------------------------------------------ closed forms
def test_step_metrics_first_order():
    """y = 1 - exp(-t / tau): rise 10-90 % = tau ln 9, 2 % settling = tau ln 50,
    no overshoot."""
    tau, dt = 0.02, 1e-3
    t = [k * dt for k in range(-300, 700)]
    y = [0.0 if tt < 0 else 1.0 - math.exp(-tt / tau) for tt in t]
    m = cmd_control.step_metrics(t, y, 0.0, t[-1], 0.3, None)
    assert m["rise_time_s"] == pytest.approx(tau * math.log(9.0), abs=1.5 * dt)
    assert m["settling_time_s"] == pytest.approx(tau * math.log(50.0), abs=1.5 * dt)
    assert m["overshoot_pct"] == pytest.approx(0.0, abs=1e-9)
    assert m["final_nm"] == pytest.approx(1.0, abs=1e-6)


def test_step_metrics_second_order_overshoot():
    """Underdamped second order: overshoot exp(-pi z / sqrt(1 - z^2))."""
    z, wn, dt = 0.3, 60.0, 1e-4
    wd = wn * math.sqrt(1 - z * z)
    t = [k * dt for k in range(-1000, 10000)]
    y = [0.0 if tt < 0 else 5.0 * (1 - math.exp(-z * wn * tt) *
                                   (math.cos(wd * tt) + z / math.sqrt(1 - z * z) *
                                    math.sin(wd * tt))) for tt in t]
    m = cmd_control.step_metrics(t, y, 0.0, t[-1], 0.1, 0.1)
    want = 100.0 * math.exp(-math.pi * z / math.sqrt(1 - z * z))
    assert m["overshoot_pct"] == pytest.approx(want, rel=2e-3)
    # |envelope| 5 exp(-z wn t) / sqrt(1 - z^2) < 0.1: an upper bound of the settling
    assert 0 < m["settling_time_s"] <= math.log(5 / 0.1 / math.sqrt(1 - z * z)) / (z * wn)


def test_tables_match_the_headers():
    """The local mode / limit / flag names are the C headers' (one fact)."""
    ctrl = (ROOT / "control" / "hd_ctrl.h").read_text()
    modes = dict((int(v), n) for n, v in re.findall(r"HD_CTRL_(\w+) = (\d+),", ctrl)
                 if n in cmd_control.MODES)
    assert [modes[i] for i in range(len(cmd_control.MODES))] == list(cmd_control.MODES)
    assert re.search(rf"HD_CTRL_MODE_COUNT = {len(cmd_control.MODES)},", ctrl)
    lims = {n: int(v, 16) for n, v in re.findall(r"#define HD_CTRL_LIM_(\w+)\s+0x([0-9A-Fa-f]+)u",
                                                 ctrl)}
    assert lims == {n: b for b, n in cmd_control.CTRL_LIMITS.items()}
    proto = (ROOT / "firmware" / "hd_can_proto.h").read_text()
    flags = {n: int(v, 16) for n, v in
             re.findall(r"#define HD_CAN_CTRL_FLAG_(\w+)\s+0x([0-9A-Fa-f]+)u", proto)}
    assert flags == {n: b for b, n in cmd_control.CTRL_FLAGS.items()}


# ------------------------------------------------------------ on the bus
def test_set_torque_reaches_the_loop(capsys, channel, dyn_joint):  # noqa: ARG001
    rc, out, err = ctl(capsys, channel, "set", "torque", "--torque", "5", "--hold", "0.3")
    assert rc == 0, err
    s = summary(out)
    assert s["mode_asked"] == "TORQUE" and s["mode_run"] == "TORQUE"
    assert float(s["torque_ref_nm"]) == pytest.approx(5.0, abs=0.01)
    assert "ENABLED" in s["flags"]


def test_set_impedance_with_gains(capsys, channel, dyn_joint):  # noqa: ARG001
    rc, out, err = ctl(capsys, channel, "set", "impedance", "--position", "0.01", "--kp", "200",
                       "--kd", "2", "--hold", "0.3")
    assert rc == 0, err
    s = summary(out)
    assert s["mode_asked"] == "IMPEDANCE" and s["mode_run"] == "IMPEDANCE"
    # kp (q_d - q) + kd (v_d - v) with the output near rest near 0: about 200 x 0.01 N m
    assert 0.5 < float(s["torque_ref_nm"]) < 3.0


def test_step_against_truth(capsys, channel, dyn_joint, tmp_path):
    j, att, truth = dyn_joint
    csv = tmp_path / "step.csv"
    rc, out, err = ctl(capsys, channel, "--rate", "200", "step", "--to", "8", "--before", "0.3",
                       "--after", "0.7", "--csv", csv)
    end = j.ticks          # within the watchdog's 100 ms of the last setpoint: still TORQUE
    assert rc == 0, err
    assert att.error is None
    s = summary(out)
    assert float(s["torque_ref_nm"]) == pytest.approx(8.0, abs=0.01)
    # The loop holds the gauge's mean at the setpoint: the true output torque
    # over the last 0.2 s is the setpoint up to the artifact's 1.5 N m.
    tail = [nm for k, nm in truth if end - 300 <= k <= end - 100]
    assert len(tail) > 20
    assert sum(tail) / len(tail) == pytest.approx(8.0, abs=1.6)
    # what the joint reported (its filtered torque) is within the same of the truth
    assert float(s["final_nm"]) == pytest.approx(sum(tail) / len(tail), abs=1.6)
    rise = float(s["rise_time_s"])
    assert 0.0 < rise < 0.3
    assert float(s["overshoot_pct"]) >= 0.0
    lines = csv.read_text().splitlines()
    assert lines[0] == ",".join(cmd_control.CSV_COLUMNS)
    rows = [l.split(",") for l in lines[1:]]
    assert len(rows) == int(s["samples"]) > 500     # ~1 kHz telemetry over 1 s
    t = [float(r[0]) for r in rows]
    assert t == sorted(t) and t[0] < 0.0 < t[-1]
    assert {r[1] for r in rows if float(r[0]) >= 0.0} == {"8.0000"}


def test_csv_not_written_is_exit_3(capsys, channel, dyn_joint, tmp_path):
    rc, out, err = ctl(capsys, channel, "step", "--to", "4", "--before", "0.1", "--after",
                       "0.2", "--csv", tmp_path)     # a directory
    assert rc == 3 and out == "" and err.count("\n") == 1 and "is a directory" in err


def test_joint_refuses_beyond_its_limit(capsys, channel, dyn_joint):
    # within the frame's range (65.5 N m), beyond ctrl_torque_limit_nm (40)
    rc, out, err = ctl(capsys, channel, "set", "torque", "--torque", "45")
    assert rc == 1 and out == ""
    assert err.count("\n") == 1 and "refused (OUT_OF_RANGE)" in err


def test_joint_without_a_drive_refuses(capsys, channel, joint):
    with joint().attach("virtual", channel):
        rc, out, err = ctl(capsys, channel, "set", "torque", "--torque", "1")
    assert rc == 1 and "refused (UNSUPPORTED)" in err and err.count("\n") == 1


@pytest.mark.parametrize("args, says", [
    (["set", "torque", "--torque", "nan"], "is not finite"),
    (["set", "torque", "--torque", "inf"], "is not finite"),
    (["set", "torque", "--torque", "1e9"], "outside the frame's range"),
    (["set", "warp"], "unknown mode"),
    (["set", "impedance", "--kp", "-1"], "outside the frame's range"),
    (["set", "impedance", "--kd", "51"], "outside the frame's range"),
    (["set", "impedance", "--position", "40"], "outside the frame's range"),
    (["step", "--to", "70"], "outside the frame's range"),
    (["step", "--to", "5", "--mode", "damp"], "a torque step needs"),
    (["--rate", "5", "set", "stop"], "--rate must be"),
    (["set", "stop", "--hold", "-1"], "--hold must be"),
])
def test_bad_input_is_one_line_and_nothing_sent(capsys, channel, args, says):
    listener = can.Bus(interface="virtual", channel=channel)
    try:
        rc, out, err = ctl(capsys, channel, *args)
        assert listener.recv(timeout=0.05) is None      # nothing reached the bus
    finally:
        listener.shutdown()
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and says in err


def test_no_answer(capsys, channel):
    rc, out, err = ctl(capsys, channel, "--timeout", "0.05", "set", "stop")
    assert rc == 5 and "no CTRL_STATE" in err and err.count("\n") == 1
