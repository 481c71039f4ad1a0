"""Smoke test of the accuracy table's product row `fw_commissioned`
(tools/hdmaint/bench/accuracy.py): the firmware, commissioned by its own
learning_mode 2 + PROFILE_SAVE on a separate run of each distinct joint,
then run in operating mode from that profile.  Short runs (--quick sizes):
the output is checked for form and for what the firmware was told, not for
accuracy (the benchmark prints numbers; docs/results/bench.md)."""
import math

from hdmaint.bench import accuracy, joint, report

ROW = "fw_commissioned"
# The benchmark joint's true plant (tests/bench/scenarios/*.ini): the
# firmware must never be told it.
PLANT = {"load_inertia_kgm2": "0.1", "viscous_nm_s_rad": "1.0", "coulomb_nm": "0.8"}


def test_product_row_runs_quick_and_is_well_formed(tmp_path):
    scs = ["const156", "ripple_drift", "ramp", "load_ripple"]
    res = accuracy.run(None, duration_scale=0.3, scenarios=scs, workdir=tmp_path)
    assert ROW not in res["pending"]
    for name in scs:
        m = res["scenarios"][name]["methods"][ROW]
        assert math.isfinite(m["rms_nm"]) and m["rms_nm"] > 0.0, name
        assert math.isfinite(m["x_floor"]) and m["x_floor"] > 0.0, name
    att = res["scenarios"]["const156"]["methods"][ROW]["attenuation_db"]
    assert set(att) == {"motor 2", "motor 4", "output 1"}

    told = res["told"][ROW]
    # one commissioning per distinct joint: ramp is const156's joint,
    # ripple_drift is commissioned on it (as the Fourier table is calibrated
    # on it), load_ripple is another joint (its load coefficient)
    assert told["commissioned_joints"] == ["const156", "load_ripple"]
    for name in scs:
        s = told["summaries"][name]
        assert s["profile_status"] == "0" and int(s["profile_imports"]) > 0, (name, s)
        assert s["expected_model"].startswith("J 0 kg m^2, b 0 N m s/rad, Fc 0 N m"), s
        assert s["fault_ticks"] == "0", (name, s)
    # the profile is the one thing it was told: the output line (not learned
    # in operating mode, ~0 dB without it: kf_recommended 12 dB at full
    # length) comes from the stored profile
    assert att["output 1"] > 20.0, att

    tabs = report.tables({"accuracy": res})
    md = report.markdown(tabs)
    assert f"| {ROW} |" in md and "runs booted from the profile" in md
    assert "| 4 of 4 |" in md


def test_commissioning_run_is_the_joint_under_the_commissioning_motion(tmp_path):
    """The commissioning scenario keeps every joint key of the scenario and
    takes duration, seed and speed from commission.ini (no load)."""
    src = accuracy.SCENARIO_DIR / "load_ripple.ini"
    out = joint.with_motion(src, accuracy.COMMISSION_MOTION, tmp_path / "c.ini")
    got = dict(joint.cfg_lines(out.read_text()))
    motion = dict(joint.cfg_lines(accuracy.COMMISSION_MOTION.read_text()))
    scen = dict(joint.cfg_lines(src.read_text()))
    for k in ("duration_s", "seed", "motor_speed_profile"):
        assert got[k] == motion[k], k
    assert got["seed"] not in {dict(joint.cfg_lines(p.read_text()))["seed"]
                               for p in accuracy.SCENARIO_DIR.glob("*.ini")}
    assert "load_torque_profile" not in got
    for k in ("ripple_load_coeff_per_nm", "gear_ratio", "noise_nm", "output_encoder_cpr",
              *PLANT):
        assert got[k] == scen[k], k
    ripple = [v for k, v in joint.cfg_lines(out.read_text()) if k == "ripple"]
    assert ripple == [v for k, v in joint.cfg_lines(src.read_text()) if k == "ripple"]
    assert joint.joint_key(out) == joint.joint_key(src)
    assert joint.joint_key(src) != joint.joint_key(accuracy.SCENARIO_DIR / "const156.ini")
    assert (joint.joint_key(accuracy.SCENARIO_DIR / "ramp.ini")
            == joint.joint_key(accuracy.SCENARIO_DIR / "const156.ini"))
    # the simulator takes it as it is (no key given twice)
    nom = joint.nominal(out)
    assert nom["output_cpr"] == 4096.0
