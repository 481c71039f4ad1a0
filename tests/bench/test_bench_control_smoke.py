"""Smoke test of the control benchmark (tools/hdmaint/bench/control.py):
--quick sizes through the firmware's loop on the dynamic joint, checked
only for well-formed output (its goals are benchmark numbers, not pass/fail
tests), and its tables, JSON, docs section and README row rendered."""
import json
import math
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

from hdmaint.bench import control, control_report  # noqa: E402


def _finite_or_none(x):
    return x is None or (isinstance(x, float) and math.isfinite(x))


def test_control_bench_quick_is_well_formed():
    res = control.run(quick=True)
    assert set(res["rows"]) == {"filtered", "narrow", "butter2", "open_loop"}
    assert res["product"] == control.PRODUCT_KEY == "narrow"
    assert res["best_butterworth"] == "butter2"
    for key, row in res["rows"].items():
        assert set(row["speeds"]) == {str(s) for s in control.SPEEDS_RAD_S}, key
        for s, m in row["speeds"].items():
            bw = m["chirp"]["bandwidth_hz"]
            assert bw is None or 1.0 <= bw <= control.CHIRP_F1_HZ or bw == math.inf, (key, s)
            assert math.isfinite(m["step"]["overshoot_pct"]) and m["step"]["settle_ms"] >= 0
            assert (m["ripple"] is None) == (float(s) == 0.0)
    # the tuned loops' margins were measured in every condition, and met
    for key in ("filtered", "narrow", "butter2"):
        t = res["tuning"][key]
        assert set(t["measured"]) == set(control.CONDITIONS)
        assert t["met"], key
        # and were run against the stiff wall (tune's contact check) without a cycle
        assert [w["kd_nm_s_rad"] for w in t["wall"]] == list(control.WALL["kds"][:1]), key
        assert not any(w["limit_cycle"] for w in t["wall"]), key
    assert {g["goal"].split(" ")[0] for g in res["goals"]} == {
        "bandwidth", "comparison", "back-drive", "rendered", "stiff-wall"}
    # the goals are the product feedback's; the filtered one is a comparison, no goal
    bw = res["goals"][0]
    assert bw["goal"].startswith("bandwidth narrow (the product feedback")
    for s, x in bw["ratios"].items():
        assert x == control._bw(res["rows"]["narrow"], float(s)) / control._bw(
            res["rows"]["butter2"], float(s))
    cmp_, = (g for g in res["goals"] if g["goal"].startswith("comparison"))
    assert cmp_["met"] is None and "filtered" in cmp_["goal"]
    for g in res["goals"]:
        if g is not cmp_:
            assert isinstance(g["met"], bool)
        assert _finite_or_none(float(g["worst"]))
    def no_constants(c):
        raise AssertionError(f"{c} in control.json")
    js = json.loads(control_report.to_json(res), parse_constant=no_constants)
    assert js["rows"]["filtered"]["config"]["feedback"] == "filtered"
    md = control_report.markdown(control_report.tables(res))
    assert "The joint controller's goals" in md and "| filtered |" in md and "| narrow |" in md
    doc = f"# x\n{control_report.BEGIN}\nold\n{control_report.END}\ntail\n"
    new = control_report.splice(doc, md)
    assert "old" not in new and new.endswith(f"{control_report.END}\ntail\n")
    (what, measured, src), = control_report.headline_rows(js | {"goals": js["goals"] + [
        {"goal": "true-torque 2x ripple filtered <= 0.5x raw", "worst": 0.4, "met": True}]})
    assert "bandwidth" in measured and "control.json" in src
    assert measured.startswith("narrow feedback (the product's)")
