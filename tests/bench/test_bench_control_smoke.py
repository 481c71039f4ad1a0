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
    assert set(res["rows"]) == {"filtered", "butter2", "open_loop"}
    assert res["best_butterworth"] == "butter2"
    for key, row in res["rows"].items():
        assert set(row["speeds"]) == {str(s) for s in control.SPEEDS_RAD_S}, key
        for s, m in row["speeds"].items():
            bw = m["chirp"]["bandwidth_hz"]
            assert bw is None or 1.0 <= bw <= control.CHIRP_F1_HZ or bw == math.inf, (key, s)
            assert math.isfinite(m["step"]["overshoot_pct"]) and m["step"]["settle_ms"] >= 0
            assert (m["ripple"] is None) == (float(s) == 0.0)
    # the tuned loops' margins were measured in every condition, and met
    for key in ("filtered", "butter2"):
        t = res["tuning"][key]
        assert set(t["measured"]) == set(control.CONDITIONS)
        assert t["met"], key
    assert {g["goal"].split(" ")[0] for g in res["goals"]} == {
        "bandwidth", "back-drive", "rendered", "stiff-wall"}
    for g in res["goals"]:
        assert isinstance(g["met"], bool) and _finite_or_none(float(g["worst"]))
    def no_constants(c):
        raise AssertionError(f"{c} in control.json")
    js = json.loads(control_report.to_json(res), parse_constant=no_constants)
    assert js["rows"]["filtered"]["config"]["feedback"] == "filtered"
    md = control_report.markdown(control_report.tables(res))
    assert "The joint controller's goals" in md and "| filtered |" in md
    doc = f"# x\n{control_report.BEGIN}\nold\n{control_report.END}\ntail\n"
    new = control_report.splice(doc, md)
    assert "old" not in new and new.endswith(f"{control_report.END}\ntail\n")
    (what, measured, src), = control_report.headline_rows(js | {"goals": js["goals"] + [
        {"goal": "true-torque 2x ripple filtered <= 0.5x raw", "worst": 0.4, "met": True}]})
    assert "bandwidth" in measured and "control.json" in src
