"""Geometry versus load (issue 13, item 2; issue 12's log contract): an
artifact locked to the output angle repeats with the angle, a load does
not.  slowload.ini turns whole revolutions at varying speed with reversals
under an unknown load of 0.5-3 N m varying over 5-10 s; an undeclared
output order k is added with --set.  Truth comes from the simulation; the
tool sees only the CSV (and, where said, the controller's slow torque as
torque_feedforward_nm)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import added, analyze, read_csv, write_csv, never_worse_out_of_sample

NOISE_NM = 0.02           # slowload.ini noise_nm: the floor the error is judged against
LINES = {1: (0.5, -0.7), 2: (0.8, 0.4), 3: (0.4, 1.0)}   # order: (amplitude, phase)


def _truth_ab(order):
    amp, phase = LINES.get(order, (0.0, 0.0))
    # hdsim: A sin(k theta + phase) = (A sin phase) cos k theta + (A cos phase) sin k theta
    return amp * math.sin(phase), amp * math.cos(phase)


def _never_worse_out_of_sample(r):
    never_worse_out_of_sample(r["history"])


def _profile_matches_truth(r, orders):
    prof = {p["order"]: p for p in r["model_after"]["profile"]}
    assert set(prof) == set(orders), prof
    for k in orders:
        a, b = _truth_ab(k)
        amp = math.hypot(a, b)
        err = math.hypot(prof[k]["a_nm"] - a, prof[k]["b_nm"] - b)
        assert err < 0.05 * amp, (k, prof[k], a, b)


@pytest.mark.parametrize("order", [2, 3])
def test_undeclared_output_order_is_found_under_a_slow_load(case_report, order):
    # Before: an output-order-2 line of 0.8 N m was not found at all on
    # such a joint (the output-order-1 block and the offset traded the load).
    r = case_report(f"slowload-out{order}")
    adds = added(r)
    assert [e["kind"] for e in adds] == ["output_order"], r["effects"]
    assert adds[0]["order_per_output_rev"] == order
    _profile_matches_truth(r, [1, order])
    _never_worse_out_of_sample(r)
    # The load stays in the output: the error against truth is at the noise
    # floor, far below the paper model's (adaptive output block).
    assert r["error_rms_after_nm"] < 1.5 * NOISE_NM
    assert r["metrics_reference"]["error_rms_nm"] > 10 * NOISE_NM


def test_output_order_one_is_found_when_not_declared(case_report):
    r = case_report("slowload-out1+2-undeclared")
    orders = sorted(e["order_per_output_rev"] for e in added(r) if e["kind"] == "output_order")
    assert orders == [1.0, 2.0], r["effects"]
    _profile_matches_truth(r, [1, 2])
    assert r["error_rms_after_nm"] < 1.5 * NOISE_NM


def test_known_slow_torque_brings_the_error_to_the_noise_floor(case_report):
    # Issue 12's contract: torque_feedforward_nm is added to T_exp as the
    # firmware adds the CAN feed-forward.  Goal: <= 1.5 x the noise floor.
    r = case_report("slowload-out2-ff")
    assert r["data"]["has_feedforward"] is True
    _profile_matches_truth(r, [1, 2])
    assert r["error_rms_after_nm"] <= 1.5 * NOISE_NM
    assert r["out_of_sample_error_rms_after_nm"] <= 1.5 * NOISE_NM
    _never_worse_out_of_sample(r)


def test_no_output_line_claimed_from_a_slow_load(simulate, tmp_path):
    # The same joint and load without any output-locked line (the simulated
    # misalignment line, known exactly, taken out of the measurement):
    # nothing is added, no profile line, the load stays in the output.
    h, a = read_csv(simulate("slowload", "seed=12"))
    a = a.copy()
    amp, phase = LINES[1]
    a[:, h.index("torque_nm")] -= amp * np.sin(a[:, h.index("output_angle_rad")] + phase)
    r = analyze(write_csv(tmp_path / "nolines.csv", h, a), output_orders=())
    assert added(r) == [], r["effects"]
    assert r["model_after"]["profile"] == []
    assert r["error_rms_after_nm"] < 1.5 * NOISE_NM


def test_200_hz_jitter_and_gaps(case_report):
    # 200 Hz, output speed 0.6-1.4 rad/s with reversals, 120 s; time stamps
    # jitter by +-20 % of a period and two logger pauses split the record.
    r = case_report("slowload-200hz")
    assert r["data"]["cleaning"]["gaps"] == 2 and r["data"]["cleaning"]["resampled_pieces"] == 3
    assert any(e["kind"] == "output_order" and e["order_per_output_rev"] == 2 for e in added(r))
    prof = {p["order"]: p for p in r["model_after"]["profile"]}
    a2, b2 = _truth_ab(2)
    assert math.hypot(prof[2.0]["a_nm"] - a2, prof[2.0]["b_nm"] - b2) < 0.05 * LINES[2][0]
    assert r["error_rms_after_nm"] < 0.2 * r["error_rms_before_nm"]
    _never_worse_out_of_sample(r)


@pytest.fixture(scope="module")
def swing(case_report):
    """swing.ini: an arm link swinging +-120 deg under 12 N m of gravity
    (12 sin(theta + 0.3), added to the measured and the true torque: the
    simulator has no position-dependent load), without and with the
    controller's gravity model (3 % and 0.02 rad off) as feed-forward."""
    r = case_report("swing-gravity")
    th = np.linspace(-2.0944, 2.0944, 10001)     # the swing's range, evenly
    return r, case_report("swing-gravity-ff"), float(np.std(12.0 * np.sin(th + 0.3)))


def test_gravity_is_kept_on_a_swinging_arm(swing):
    # Before: the final model removed the gravity torque (9.1 N m RMS
    # error).  Over part of a turn the angle-locked torque cannot be told
    # from gravity: no output line is claimed, gravity stays in the output.
    for r in swing[:2]:
        assert r["model_after"]["profile"] == []
        assert not [b for b in r["model_after"]["blocks"] if b["lock"] == "output"]
        assert "part of a turn" in r["starting_profile_fit"]["why"]
        # What is left is the 0.5 N m misalignment line the log cannot
        # separate (0.35 N m RMS), not the 8.5 N m RMS of gravity.
        assert r["error_rms_after_nm"] < 0.45
    plain, with_ff, gravity_rms = swing
    assert gravity_rms > 8
    # Without the log's feed-forward the analysis stands in for the
    # controller's gravity model; the firmware may get none.  Replayed
    # without any feed-forward, the final model still keeps gravity, while
    # the paper model's adaptive output-order-1 block takes the swing.
    for r in swing[:2]:
        bare = r["metrics_without_feedforward"]
        assert bare["after"]["error_rms_nm"] < 0.5
        assert bare["reference"]["error_rms_nm"] > 0.5 * gravity_rms


def test_logger_pause_is_a_split_not_a_drift(case_report):
    # pause.ini: 5 N m of load that creeps while the logger is paused for
    # 60 s (results.logger_pause removes t in [40, 100) s).  Before: the
    # pause was read as sensor drift, the offset became a sensor error and
    # the load was removed (error 0.02 -> 4.9 N m).
    r = case_report("pause")
    assert r["data"]["cleaning"]["gaps"] == 1
    assert r["model_after"]["offset_is_sensor_error"] is False
    assert not [e for e in added(r) if e["kind"] == "offset_drift"]
    assert r["error_rms_after_nm"] < 1.5 * 0.02


def test_results_doc_slow_tables_are_current(case_report):
    from conftest import assert_doc_current
    from hdtools.analysis import results
    reports = {c.name: case_report(c.name) for c in results.SLOW}
    assert_doc_current([("slow", results.suite_table(reports, results.SLOW)),
                        ("slow-bands", results.bands_table(reports, results.SLOW))])
    from conftest import assert_summary_current
    assert_summary_current("cases", {c.name: results.case_summary(reports[c.name], c.what)
                                     for c in results.SLOW})


def _record(load_of_t, seed=4, seconds=60.0, ts=1e-3):
    """A line of 0.5 N m at output order 1 (phase -0.7, as LINES) under the
    load load_of_t(t, rng), the output turning at 0.8-2 rad/s (speed
    changes every 5 s), noise NOISE_NM: what geometry.fit gets once the
    filter has removed the motor lines.  Returns the Inputs and the load."""
    from hdtools.analysis import geometry
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, ts)
    speed = np.array([1.2, 2.0, 0.8, 1.6])[(t // 5.0).astype(int) % 4]
    theta = np.cumsum(speed) * ts
    load = load_of_t(t, rng)
    amp, phase = LINES[1]
    z = amp * np.sin(theta + phase) + load + NOISE_NM * rng.standard_normal(len(t))
    return geometry.Inputs([z], [theta], [t], [speed], ts), load


def _payload_steps(t, rng):
    """0 <-> 6 N m, held 3-4 s."""
    return 6.0 * (np.searchsorted(np.cumsum(rng.uniform(3.0, 4.0, 40)), t) % 2)


def _step_columns(parts, n_orders):
    return parts[0][2].shape[1] - 2 * n_orders - 3    # after the orders and the motion


def test_a_line_under_payload_steps_is_verified():
    # A step of the load is a nuisance column of its own: the smoother cannot
    # follow one, and the steps filled the held-out blocks, so the line was
    # never verified (loadsteps.ini's kind of steps over 60 s: 0.74 N m left).
    from hdtools.analysis import geometry
    inp, load = _record(_payload_steps)
    parts, _ = geometry.series(inp, [1])
    assert _step_columns(parts, 1) == np.count_nonzero(np.diff(load))   # every step, no other
    g = geometry.fit(inp)
    assert g["verifiable"], g
    assert [o["order"] for o in g["orders"]] == [1.0], g["orders"]
    a, b = _truth_ab(1)
    (o,) = g["orders"]
    assert math.hypot(o["a_nm"] - a, o["b_nm"] - b) < 0.1 * math.hypot(a, b), (o, a, b)
    # and the held-out check, on another stretch of the same joint, keeps it
    hold, _ = _record(_payload_steps, seed=5)
    without, with_ = geometry.check(hold, g["orders"], g["tau_s"])
    assert with_ < 0.8 * without, (without, with_)


def test_a_slow_load_has_no_steps():
    # slowload.ini's kind of load (0.5-3 N m over 5-10 s) under the same line.
    from hdtools.analysis import geometry
    inp, _ = _record(lambda t, rng: 1.75 + 1.25 * np.sin(2 * math.pi * t / 7.0))
    parts, _ = geometry.series(inp, [1])
    assert _step_columns(parts, 1) == 0


def test_no_step_where_the_motion_explains_it_or_a_line_moves_fast():
    # The torque a speed change takes (inertia, friction's sign) is the
    # motion columns'; a line of 1 Hz moves the 0.1 s means as a step would
    # at one point, but as much a window pair earlier and later.  As steps,
    # they made the fit choose another smoother and a wrong profile: an
    # undeclared output-order-2 line went from 1.2x to 13x the floor on a
    # drawn joint (j100018+output2, analyze_op).
    from hdtools.analysis import geometry
    inp, _ = _record(lambda t, rng: 0.0 * t)
    t, th = inp.times[0], inp.angles[0]
    speed = np.clip((30.0 - t) / 0.02, -1.0, 1.0) * 1.5            # a reversal in 40 ms at 30 s
    friction = 1.0 * np.clip(speed / 0.05, -1.0, 1.0)              # Coulomb 1 N m: a step
    # 1 Hz for 6 s only: a line fast only while the joint is; the rest of
    # the record sets the robust scale the first test compares with
    fast = 0.6 * np.sin(2 * math.pi * 1.0 * t) * ((t > 20) & (t < 26))
    for what, extra, v in (("reversal", friction, speed), ("1 Hz line", fast, inp.velocities[0])):
        x = geometry.Inputs([inp.signals[0] + extra], [th], [t], [v], 1e-3)
        parts, _ = geometry.series(x, [1])
        assert _step_columns(parts, 1) == 0, what


def test_check_scores_both_signals_with_the_same_steps(monkeypatch):
    # The held-out check compares the error without and with the profile on
    # the same samples and nuisance: the load's steps are found once (without
    # the profile), not again on the profile-subtracted signal, where a wrong
    # profile's large line moves the robust scale the step test uses (here
    # 1 N m steps: all 17 found without it, none with it subtracted).
    from hdtools.analysis import geometry
    inp, load = _record(lambda t, rng: _payload_steps(t, rng) / 6.0, seed=5)
    wrong = [{"order": 1.0, "a_nm": 3.0, "b_nm": 0.0}]
    seen = []
    series = geometry.series

    def spy(x, orders, steps=None):
        parts, dt = series(x, orders, steps)
        seen.append([(np.isnan(z), A.shape[1]) for z, _, A in parts])
        return parts, dt
    monkeypatch.setattr(geometry, "series", spy)
    geometry.check(inp, wrong, 2.0)
    without, with_ = seen[-2], seen[-1]
    assert [c for _, c in without] == [c for _, c in with_]
    assert all(np.array_equal(a, b) for (a, _), (b, _) in zip(without, with_))
    assert without[0][1] - 3 == np.count_nonzero(np.diff(load))   # every step, found once
