"""The simulated suite: each scenario hides one effect the starting model
(motor orders 2 and 4, output order 1 as an angle profile, no
friction/inertia, offset as real torque) does not declare.  Ground truth
comes from the simulated joint (hdsim); the tool never sees the scenario,
only the CSV (torque_true_nm is used for reporting only).  Every kept change
must not grow the held-out (fold B) innovation."""
from __future__ import annotations

import math
import re

import pytest

from conftest import added, never_worse_out_of_sample


def _only(report, kind):
    adds = added(report)
    assert adds, f"nothing added; findings: {report['effects']}"
    assert {e["kind"] for e in adds} == {kind}, f"added: {adds}"
    return adds


def _never_worse_out_of_sample(r):
    never_worse_out_of_sample(r["history"])


def test_clean_case_adds_nothing(analyzed):
    r = analyzed("clean")
    assert added(r) == []
    assert r["model_after"] == r["model_before"]
    assert r["residual_rms_after_nm"] == r["residual_rms_before_nm"]
    # The declared misalignment line (0.5 N m at output order 1, phase
    # -0.7 in clean.ini: 0.5 sin(theta - 0.7)) is the starting profile.
    (p,) = r["model_before"]["profile"]
    assert p["order"] == 1.0
    assert p["a_nm"] == pytest.approx(-0.5 * math.sin(0.7), abs=0.02)
    assert p["b_nm"] == pytest.approx(0.5 * math.cos(0.7), abs=0.02)
    # Error at the noise floor (0.02 N m).
    assert r["error_rms_after_nm"] < 1.5 * 0.02


@pytest.mark.parametrize("name,kind,field,value,tol", [
    ("motor6", "motor_order", "order_per_motor_rev", 6.0, 0.05),
    ("motor1", "motor_order", "order_per_motor_rev", 1.0, 0.05),
    ("output3", "output_order", "order_per_output_rev", 3.0, 0.1),
    ("mains", "fixed_frequency", "frequency_hz", 50.0, 0.1),
])
def test_hidden_line_is_found_and_removed(analyzed, name, kind, field, value, tol):
    r = analyzed(name)
    adds = _only(r, kind)
    assert abs(adds[0][field] - value) <= tol, adds[0]
    _never_worse_out_of_sample(r)
    # Both order fields for order kinds, consistent through the gear ratio.
    if kind != "fixed_frequency":
        e = adds[0]
        assert e["order_per_output_rev"] == pytest.approx(
            e["order_per_motor_rev"] * r["gear_ratio"]["value"], rel=1e-6)
    assert r["error_rms_after_nm"] < 0.7 * r["error_rms_before_nm"]
    # The line is gone from the filtered torque.
    assert adds[0]["line_amplitude_in_filtered_after_nm"] < \
        0.3 * adds[0]["line_amplitude_in_filtered_before_nm"]
    # A time-locked line is told from an order-locked one by sharpness.
    ev = adds[0]["evidence"]
    if kind == "fixed_frequency":
        assert ev["peak_ratio_time_spectrum"] > 4 * ev["peak_ratio_order_spectrum"]
    elif kind == "motor_order":
        assert ev["peak_ratio_order_spectrum"] > 4 * ev["peak_ratio_time_spectrum"]


def test_friction_is_found_with_its_coefficients(analyzed):
    # friction.ini: viscous 1.0 N m s/rad, Coulomb 2.0 N m, reversals; the
    # simulated joint's load inertia (0.1 kg m^2, its default) shows in the
    # 1 s reversals and is found as well.  The declared output-order-1 line
    # cannot be told from the friction steps before friction is modelled;
    # it joins the profile after.
    r = analyzed("friction")
    adds = added(r)
    assert {e["kind"] for e in adds} <= {"velocity", "acceleration", "output_order"}, adds
    assert all(e["order_per_output_rev"] == 1.0 for e in adds if e["kind"] == "output_order")
    fr = next(e for e in adds if e["kind"] == "velocity")
    assert fr["parameters"]["viscous_nm_s_rad"] == pytest.approx(1.0, rel=0.25)
    assert fr["parameters"]["coulomb_nm"] == pytest.approx(2.0, rel=0.25)
    acc = next(e for e in adds if e["kind"] == "acceleration")
    assert acc["parameters"]["inertia_kgm2"] == pytest.approx(0.1, rel=0.25)
    assert r["residual_rms_after_nm"] < r["residual_rms_before_nm"]
    _never_worse_out_of_sample(r)


REFERENCE_BOUND_X = 0.6   # the loop's error over the paper model's (measured 0.51)
WHOLE_COST_X = 1.05       # whole error after / before (measured 1.014)
SLOW_GAIN_X = 0.9         # slow band after / before (measured 0.83)


def test_friction_lowers_the_error(analyzed):
    # T_exp enters the filter only through y = T_meas - T_exp; with the
    # offset kept as real torque, a correct friction and inertia model lowers
    # the error against truth by what the offset no longer has to follow:
    # the slow band (below 2 Hz), where friction and inertia torque live.
    # Measured: slow band 0.0075 -> 0.0062 N m, whole error 0.0220 -> 0.0223
    # N m = 1.1x the scenario's 0.02 N m noise: with the declared line now in
    # the starting profile (0.503 N m; it was 0.523 before the per-block
    # smoother choice, slow band 0.016) the fast band's cost at reversals
    # (below) is as large as the slow band's gain (the paper model, with an
    # adaptive output block: 0.044; 0.087 while the offset-jump gate could
    # cascade, docs/design/filter.md).  Before the filter turned by each sample's own
    # increment the start was worse (0.038 -> 0.030: the lag at reversals).
    r = analyzed("friction")
    from hdtools.analysis import results
    noise_nm = float(re.search(r"^noise_nm\s*=\s*(\S+)", (results.SCENARIOS / "friction.ini")
                               .read_text(), re.M).group(1))
    assert r["error_rms_after_nm"] < WHOLE_COST_X * r["error_rms_before_nm"]
    assert r["error_rms_after_nm"] < 1.25 * noise_nm
    assert r["error_rms_after_nm"] < REFERENCE_BOUND_X * r["metrics_reference"]["error_rms_nm"]
    assert r["error_split_hz"] == 2.0
    assert r["error_slow_rms_after_nm"] < SLOW_GAIN_X * r["error_slow_rms_before_nm"]
    # The ripple band must not rise by much: at each reversal the Coulomb
    # term switches on the tracked velocity's zero crossing, not the true
    # one.
    assert r["error_fast_rms_after_nm"] < 1.25 * r["error_fast_rms_before_nm"]


def test_offset_drift_is_found_and_removed(analyzed):
    # drift.ini: 0.05 N m/s over 20 s.
    r = analyzed("drift")
    e = _only(r, "offset_drift")[0]
    assert e["parameters"]["drift_nm_per_s"] == pytest.approx(0.05, rel=0.3)
    assert r["model_after"]["offset_is_sensor_error"] is True
    assert r["error_rms_after_nm"] < 0.5 * r["error_rms_before_nm"]


def test_load_dependent_ripple_is_traced_to_its_line(analyzed):
    # loadripple.ini: every ripple line grows with |load| as (1 + 0.3 |T|).
    # The motor lines' amplitude in the measured torque grows with the
    # filter's slow torque (loadcoef.py, one regression per order, pooled):
    # the coefficient is identified, significant on both folds, and added
    # (hd_kf ripple_load_coeff_per_nm).
    r = analyzed("loadripple")
    found = [e for e in r["effects"] if e["kind"] == "motor_order"
             and e.get("action") == "load_scale"]
    assert found, r["effects"]
    e = found[0]
    assert e["added"], e
    assert e["order_per_motor_rev"] in (2.0, 4.0)
    assert e["evidence"]["load_coefficient_t"] >= 5
    assert sorted(p["order"] for p in e["evidence"]["per_order"]) == [2.0, 4.0]
    assert e["parameters"]["ripple_load_coeff_per_nm"] == pytest.approx(0.3, rel=0.25)
    assert r["model_after"]["ripple_load_coeff_per_nm"] == \
        e["parameters"]["ripple_load_coeff_per_nm"]
    # Nothing wrong is added.
    assert all(e["kind"] == "motor_order" for e in added(r))


def test_load_coefficient_is_not_claimed_without_load_changes(analyzed):
    # Constant load (clean.ini, 2 N m): no load scaling anywhere.
    r = analyzed("clean")
    assert r["model_after"]["ripple_load_coeff_per_nm"] == 0.0
    assert not [e for e in r["effects"] if e.get("action") == "load_scale"]


def test_load_dependent_ripple_lowers_the_ripple_band_error(analyzed):
    # The load coefficient makes the motor-locked lines follow the load at
    # once; their error lives in the ripple band (> 2 Hz; motor order 2 is
    # at 25-64 Hz here): measured 0.077 -> 0.026 N m.
    r = analyzed("loadripple")
    assert r["error_fast_rms_after_nm"] < 0.5 * r["error_fast_rms_before_nm"]


def test_load_dependent_ripple_under_load_steps_lowers_the_ripple_band(analyzed):
    # loadsteps.ini: the same joint and ripple law as loadripple.ini, under a
    # load that steps 0 <-> 6 N m and holds for 3-4 s (a payload), not at the
    # output revolution's period.  The coefficient is found and the ripple
    # band error falls (measured 0.158 -> 0.055 N m).
    r = analyzed("loadsteps")
    found = [e for e in added(r) if e.get("action") == "load_scale"]
    assert found, r["effects"]
    assert found[0]["parameters"]["ripple_load_coeff_per_nm"] == pytest.approx(0.3, rel=0.25)
    # nothing but the lines the scenario has (motor orders, the output line's profile)
    assert all(e["kind"] == "motor_order" or e.get("action") == "set_profile" for e in added(r))
    assert r["error_fast_rms_after_nm"] < 0.5 * r["error_fast_rms_before_nm"]
    _never_worse_out_of_sample(r)


def test_a_line_growing_with_the_load_under_load_steps_is_profiled(analyzed):
    # loadsteps.ini: the output-order-1 line grows with the load as the motor
    # lines do (1 + 0.3 |T|: 0.5 -> 1.4 N m).  Once the load coefficient is
    # kept, the profile is fitted and judged with the growth the firmware's
    # held output rows give it ((1 + c |T_ref|) / (1 + c T_c)), and the
    # replay's rows carry that growth too (a profile of output lines only:
    # the modelled factor), so a fixed angle profile at the record's load
    # predicts the held-out fold.  Measured: error 0.736 -> 0.073 N m (0.325
    # while the replay's rows stayed at 1; the line in the output, 0.72 N m
    # below 2 Hz, before the profile followed the load).  The order-1 line
    # leads the profile; another order the fit keeps is a small remainder of
    # the growth the rows miss (T_ref lags a step).
    r = analyzed("loadsteps")
    assert any(e.get("action") == "set_profile" for e in added(r)), r["effects"]
    lines = {ln["order"]: math.hypot(ln["a_nm"], ln["b_nm"])
             for ln in r["profile"]["lines"] if ln["lock"] == "output"}
    assert 1.0 in lines, lines
    assert all(a < 0.1 * lines[1.0] for o, a in lines.items() if o != 1.0), lines
    assert r["error_rms_after_nm"] < 0.2 * r["error_rms_before_nm"]
    assert r["error_slow_rms_after_nm"] < 0.2 * r["error_slow_rms_before_nm"]
    _never_worse_out_of_sample(r)


LOAD_AT_THE_OUTPUT_PERIOD = (
    "limit (docs/design/analyze.md 'Known limits'): loadripple.ini ramps its load 0 <-> 6 N m "
    "every 4 s, within the output revolution's 3-8 s, over three revolutions: a load that "
    "keeps time with the angle is not told from an output-locked line by the record alone "
    "(the profile fitted absorbs load, 2.6 N m against the line's 0.5-1.4, and fold B "
    "rejects it), so the line stays in the output (0.70 N m, below 2 Hz).  The ripple band, "
    "which the load coefficient is for, falls 3x")


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=LOAD_AT_THE_OUTPUT_PERIOD)
def test_load_dependent_ripple_at_the_output_period_lowers_the_error(analyzed):
    r = analyzed("loadripple")
    assert r["error_rms_after_nm"] < 0.8 * r["error_rms_before_nm"]


def test_results_doc_suite_tables_are_current(analyzed):
    """docs/results/analyze-results.md's suite tables are these reports' (generated
    by `tools/hdsense analyze --results-doc`, never typed)."""
    from conftest import assert_doc_current
    from hdtools.analysis import results
    reports = {c.name: analyzed(c.name) for c in results.SUITE}
    assert_doc_current([("suite", results.suite_table(reports, results.SUITE)),
                        ("bands", results.bands_table(reports, results.SUITE))])
    from conftest import assert_summary_current
    assert_summary_current("cases", {c.name: results.case_summary(reports[c.name], c.what)
                                     for c in results.SUITE})
