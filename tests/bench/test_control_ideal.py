"""The control benchmark's ideal-sensor bound (tools/hdmaint/bench/control.py,
IDEAL_KEY; hdctrl-bench --sensor ideal), a diagnostic, not a product variant:

  * its feedback is the simulation's logged true output torque (a tick late,
    as the gauge reads the joint at the start of the tick) to the ADC's
    resolution, with the motor turning (the gauge's 2x artifact at 95 Hz
    and the real meshing ripple both present): no sensing artifact and no
    noise leak in; the same run on the ordinary gauge is off by the
    artifact and carries the noise (the check can tell);
  * the goals' bound rows: per speed, the bound's bandwidth over the best
    low-pass's, not a goal (met None), unreachable below 2x; the bound is
    never the best low-pass."""
import math
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]

from hdmaint.bench import control, control_report  # noqa: E402
from hdmaint.bench import control_loop as cl  # noqa: E402

# the firmware's ADC: 6.6 N m/V (nominal calibration) x 10 V / 2^15 counts
LSB_NM = 6.6 * 10.0 / 32768.0
SPEED = 3.0


def _run(sensor: str) -> dict:
    v = next(x for x in control.variants() if x.key == control.IDEAL_KEY)
    assert (v.feedback, v.sensor) == ("raw", "ideal")
    v.sensor = sensor
    t = np.arange(1500) * cl.TS_S
    sp = 10.0 + 2.0 * np.sin(2 * math.pi * 7.0 * t)   # the loop moves the torque
    return cl.simulate(v, cl.torque_scene(SPEED), sp)


def _residual(d: dict) -> np.ndarray:
    """The feedback against the truth logged at the end of the tick before."""
    return d["fb_nm"][1:] - d["true_torque_nm"][:-1]


def test_ideal_feedback_is_the_true_torque():
    d = _run("ideal")
    r = _residual(d)
    assert np.all(np.isfinite(r))
    # half an ADC count, and the CSV's 7 digits of ~10 N m
    assert np.max(np.abs(r)) <= 0.5 * LSB_NM + 2e-5
    # the real meshing ripple (it moves the output) is in the truth and so fed back
    th = d["motor_angle_rad"][:-1]
    assert control.line_amplitude(d["fb_nm"][1:], th, 2) > 0.05


def test_the_check_sees_the_gauge_artifact_and_noise():
    d = _run("gauge")
    r = _residual(d)
    th = d["motor_angle_rad"][:-1]
    # the artifact: a 2x line of gauge_ripple_nm (1.5 N m in the simulated joint)
    assert control.line_amplitude(r, th, 2) > 1.0
    a = np.column_stack([np.ones_like(r), np.sin(2 * th), np.cos(2 * th)])
    rest = r - a @ np.linalg.lstsq(a, r, rcond=None)[0]
    assert np.std(rest) > 5 * LSB_NM   # the noise (0.02 N m rms)


def _row(bw: dict, sensor: str = "gauge") -> dict:
    return {"config": {"feedback": "raw", "sensor": sensor},
            "speeds": {str(s): {"chirp": {"bandwidth_hz": b, "above_band": False},
                                "ripple": None if s == 0.0 else {"line2_nm": 1.0}}
                       for s, b in bw.items()}}


def test_bound_rows_per_speed():
    s0, s1, s2 = control.SPEEDS_RAD_S
    rows = {"filtered": _row({s0: 8.8, s1: 34.2, s2: 73.6}),
            control.PRODUCT_KEY: _row({s0: 8.4, s1: 66.3, s2: 66.2}),
            "butter1": _row({s0: 6.8, s1: 30.8, s2: 30.8}),
            control.IDEAL_KEY: _row({s0: 9.0, s1: 80.0, s2: None}, "ideal")}
    g = control.goals(rows, "butter1", {"3.0": {"ratio": 0.02}},
                      {"rows": [{"kind": "stiffness", "error_pct": 1.0, "commanded": 100.0}]},
                      [{"torque_ki_per_s": 1.0, "limit_cycle": False, "p2p_nm": 0.1,
                        "kd_nm_s_rad": 2.0}])
    bw = next(x for x in g if x["goal"].startswith("bandwidth"))
    assert "butter1" in bw["goal"] and bw["met"] is False
    # the goal is the product feedback's; the filtered loop's ratio a comparison, no goal
    assert control.PRODUCT_KEY in bw["goal"] and bw["where"] == f"{s0} rad/s"
    assert bw["worst"] == pytest.approx(8.4 / 6.8)
    assert bw["ratios"][str(s1)] == pytest.approx(66.3 / 30.8)
    cmp_, = (x for x in g if x.get("kind") == "comparison")
    assert cmp_["met"] is None and cmp_["worst"] == pytest.approx(34.2 / 30.8)
    assert cmp_["status"] == "would NOT be met" and "filtered" in cmp_["goal"]
    bounds = [x for x in g if x.get("kind") == "bound"]
    assert [b["speed_rad_s"] for b in bounds] == list(control.SPEEDS_RAD_S)
    assert all(b["met"] is None and control.IDEAL_LABEL in b["goal"] for b in bounds)
    assert [b["worst"] for b in bounds] == pytest.approx([9.0 / 6.8, 80.0 / 30.8, 1.0 / 30.8])
    assert [b["reachable"] for b in bounds] == [False, True, False]
    md = control_report.markdown(control_report.tables({
        "speeds_rad_s": list(control.SPEEDS_RAD_S), "goals": g, "tuning": {}, "rows": {},
        "best_butterworth": "butter1", "margins": {"pm_deg": 45, "gm_db": 6},
        "integral_limit_nm": 1.0, "transparency": {}, "impedance": {"rows": []}, "wall": []}))
    assert md.count("2x UNREACHABLE by any feedback") == 2 and "| 2x reachable |" in md
    # a bound whose tuning missed the margins bounds nothing
    g = control.goals(rows, "butter1", {"3.0": {"ratio": 0.02}},
                      {"rows": [{"kind": "stiffness", "error_pct": 1.0, "commanded": 100.0}]},
                      [{"torque_ki_per_s": 1.0, "limit_cycle": False, "p2p_nm": 0.1,
                        "kd_nm_s_rad": 2.0}], {control.IDEAL_KEY: {"met": False}})
    assert all(b["reachable"] is None for b in g if b.get("kind") == "bound")


def test_the_bound_is_not_a_low_pass():
    vs = control.variants()
    ideal = [v for v in vs if v.sensor == "ideal"]
    assert [v.key for v in ideal] == [control.IDEAL_KEY] and vs[-1] is ideal[0]
    assert not ideal[0].key.startswith("butter") and ideal[0].feedback != "lowpass"
    assert all(v.sensor == "gauge" for v in vs[:-1])
