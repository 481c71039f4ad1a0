"""Staleness of the control benchmark's outputs (docs/results/control.json,
written by `tools/bench --only control --update-docs`):
  * the law's default feedback (control/hd_ctrl.c) is the bench's product
    feedback (control.PRODUCT_KEY), its default torque gains the gains the
    bench's tuning found for that feedback, and its integral limit
    the one the bench derived from the open-loop drive train;
  * the generated section of docs/results/control.md is the tables of that JSON."""
import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

from hdmaint.bench import control, control_report  # noqa: E402

RESULTS = json.loads((ROOT / "docs" / "results" / "control.json").read_text())


def _default(field: str) -> float:
    src = (ROOT / "control" / "hd_ctrl.c").read_text()
    return float(re.search(rf"\.{field} = ([0-9.eE+-]+)f,", src).group(1))


FEEDBACK_ENUM = {"filtered": "HD_CTRL_FB_FILTERED", "raw": "HD_CTRL_FB_RAW",
                 "lowpass": "HD_CTRL_FB_LOWPASS", "none": "HD_CTRL_FB_NONE",
                 "narrow": "HD_CTRL_FB_NARROW"}


def test_default_feedback_is_the_product_one():
    src = (ROOT / "control" / "hd_ctrl.c").read_text()
    default = re.search(r"\.feedback = (HD_CTRL_FB_[A-Z]+),", src).group(1)
    assert RESULTS["product"] == control.PRODUCT_KEY
    assert default == FEEDBACK_ENUM[RESULTS["rows"][control.PRODUCT_KEY]["config"]["feedback"]]
    assert RESULTS["goals"][0]["goal"].startswith(f"bandwidth {control.PRODUCT_KEY} ")


def test_default_gains_are_the_tuned_ones():
    t = RESULTS["tuning"][control.PRODUCT_KEY]
    assert t["met"] and t["wall"] and not any(w["limit_cycle"] for w in t["wall"])
    assert _default("torque_kp") == t["kp"]
    assert _default("torque_ki_per_s") == t["ki_per_s"]
    assert _default("torque_kd_s") == t["kd_s"]
    assert _default("integral_limit_nm") == RESULTS["integral_limit_nm"]


def test_best_low_pass_is_one_that_met_the_margins():
    """The goal compares at equal margins: the best low-pass is an order
    whose tuning met them, and it has the most bandwidth at its worst speed
    of those that did."""
    best = RESULTS["best_butterworth"]
    met = [k for k, t in RESULTS["tuning"].items() if k.startswith("butter") and t.get("met")]
    assert best in met

    def worst(k):
        return min(RESULTS["rows"][k]["speeds"][s]["chirp"]["bandwidth_hz"] or 0.0
                   for s in RESULTS["rows"][k]["speeds"])
    assert worst(best) == max(worst(k) for k in met)


def test_doc_section_is_the_results_tables():
    text = (ROOT / "docs" / "results" / "control.md").read_text()
    section = text.split(control_report.BEGIN, 1)[1].split(control_report.END, 1)[0]
    header, body = section.strip("\n").split("\n\n", 1)
    assert header.startswith("_hdsense bench, ")
    assert body.strip() == control_report.markdown(control_report.tables(RESULTS)).strip()
