"""The simulated suite: each scenario hides one effect the starting model
(motor orders 2 and 4, output order 1, no friction/inertia, offset as real
torque) does not declare.  Ground truth comes from the simulated joint
(hdsim); the tool never sees the scenario, only the CSV (torque_true_nm is
used for reporting only)."""
from __future__ import annotations

import pytest

from conftest import added, analyze


def _only(report, kind):
    adds = added(report)
    assert adds, f"nothing added; findings: {report['effects']}"
    assert {e["kind"] for e in adds} == {kind}, f"added: {adds}"
    return adds


def test_clean_case_adds_nothing(simulate):
    r = analyze(simulate("clean"))
    assert added(r) == []
    assert r["model_after"] == r["model_before"]
    assert r["residual_rms_after_nm"] == r["residual_rms_before_nm"]


@pytest.mark.parametrize("name,kind,field,value,tol", [
    ("motor6", "motor_order", "order_per_motor_rev", 6.0, 0.05),
    ("motor1", "motor_order", "order_per_motor_rev", 1.0, 0.05),
    ("output3", "output_order", "order_per_output_rev", 3.0, 0.1),
    ("mains", "fixed_frequency", "frequency_hz", 50.0, 0.1),
])
def test_hidden_line_is_found_and_removed(simulate, name, kind, field, value, tol):
    r = analyze(simulate(name))
    adds = _only(r, kind)
    assert abs(adds[0][field] - value) <= tol, adds[0]
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


def test_friction_is_found_with_its_coefficients(simulate):
    # friction.ini: viscous 1.0 N m s/rad, Coulomb 2.0 N m, reversals.
    r = analyze(simulate("friction"))
    e = _only(r, "velocity")[0]
    assert e["parameters"]["viscous_nm_s_rad"] == pytest.approx(1.0, rel=0.25)
    assert e["parameters"]["coulomb_nm"] == pytest.approx(2.0, rel=0.25)
    assert r["residual_rms_after_nm"] < r["residual_rms_before_nm"]


@pytest.mark.xfail(reason="filter limitation (reported to the lead): the slowly converging "
                          "output-order-1 block dominates the error; a correct T_exp does "
                          "not lower it yet", strict=False)
def test_friction_lowers_the_error(simulate):
    r = analyze(simulate("friction"))
    assert r["error_rms_after_nm"] < r["error_rms_before_nm"]


def test_offset_drift_is_found_and_removed(simulate):
    # drift.ini: 0.05 N m/s over 20 s.
    r = analyze(simulate("drift"))
    e = _only(r, "offset_drift")[0]
    assert e["parameters"]["drift_nm_per_s"] == pytest.approx(0.05, rel=0.3)
    assert r["model_after"]["offset_is_sensor_error"] is True
    assert r["error_rms_after_nm"] < 0.5 * r["error_rms_before_nm"]


def test_load_dependent_ripple_is_traced_to_its_line(simulate):
    # loadripple.ini: the order-2 (and 4) ripple grows with |load|.  The
    # residue is found around the modelled motor order 2 line.
    r = analyze(simulate("loadripple"))
    found = [e for e in r["effects"] if e["kind"] == "motor_order"
             and abs(e["order_per_motor_rev"] - 2.0) < 0.01]
    assert found, r["effects"]
    ev = found[0]["evidence"]
    assert max(ev.get("band_ratio", 0), ev.get("peak_ratio_order_spectrum", 0)) >= 30
    assert ev.get("existing_block") == 0   # traced to the modelled order-2 line
    # Nothing wrong is added.
    assert all(e["kind"] == "motor_order" for e in added(r))


@pytest.mark.xfail(reason="retuning the block (q x10) does not follow the load-driven "
                          "amplitude in the current filter; reported", strict=False)
def test_load_dependent_ripple_lowers_the_error(simulate):
    r = analyze(simulate("loadripple"))
    assert r["error_rms_after_nm"] < 0.8 * r["error_rms_before_nm"]
