"""Smoke test of the slow-torque benchmark (tools/hdmaint/bench/slow.py):
one scenario on tiny sizes, checked only for well-formed output (the
benchmark prints numbers; its goals are not pass/fail tests)."""
import math

from hdmaint.bench import report, slow


def test_slow_bench_quick_is_well_formed(tmp_path):
    res = slow.run(quick=True, workdir=tmp_path, scenarios=["slow_loads"])
    sc = res["scenarios"]["slow_loads"]
    assert set(sc["rows"]) >= {"fw_default", "fw_adaptive", "butter_20db", "order_notch",
                               "fourier_table", "kf_paper6", "raw", "ideal"}
    for key, m in sc["rows"].items():
        assert math.isfinite(m["rms_nm"]) and m["rms_nm"] >= 0, key
        assert math.isfinite(m["load_kept"]), key
    # every firmware row says what it was told, and was never told the plant
    for key, told in sc["told"].items():
        assert "pending" in told or {"config", "profile", "slow_torque"} <= set(told), key
        text = told.get("config_text", "")
        assert "inertia_kgm2 = 0.1\n" not in text and "coulomb_nm = 0.8\n" not in text
    tabs = report.slow_tables(res)
    assert any(t[0].startswith("Slow torque: RMS error") for t in tabs)
    assert "fw_profile_ff" in report.markdown(tabs)


def test_each_scenario_is_the_joint_of_its_commissioning_run():
    """The firmware rows boot from the profile of a commissioning run
    (slow.Scenario.commission): the scenario files type the joint out
    again, so they must agree on every key but the motion."""
    from hdmaint.bench import joint
    for sc in slow.SCENARIOS:
        run = joint.joint_key(slow.SCENARIO_DIR / f"{sc.name}.ini")
        com = joint.joint_key(slow.SCENARIO_DIR / f"{sc.commission}.ini")
        assert run == com, (sc.name, sorted(set(run) ^ set(com)))
