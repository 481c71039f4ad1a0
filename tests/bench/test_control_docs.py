"""Staleness of the control benchmark's outputs (docs/results/control.json,
written by `tools/bench --only control --update-docs`):
  * the law's default torque gains (control/hd_ctrl.c) are the gains the
    bench's tuning found for the filtered feedback, and its integral limit
    the one the bench derived from the open-loop drive train;
  * the generated section of docs/results/control.md is the tables of that JSON."""
import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

from hdmaint.bench import control_report  # noqa: E402

RESULTS = json.loads((ROOT / "docs" / "results" / "control.json").read_text())


def _default(field: str) -> float:
    src = (ROOT / "control" / "hd_ctrl.c").read_text()
    return float(re.search(rf"\.{field} = ([0-9.eE+-]+)f,", src).group(1))


def test_default_gains_are_the_tuned_ones():
    t = RESULTS["tuning"]["filtered"]
    assert t["met"]
    assert _default("torque_kp") == t["kp"]
    assert _default("torque_ki_per_s") == t["ki_per_s"]
    assert _default("torque_kd_s") == t["kd_s"]
    assert _default("integral_limit_nm") == RESULTS["integral_limit_nm"]


def test_doc_section_is_the_results_tables():
    text = (ROOT / "docs" / "results" / "control.md").read_text()
    section = text.split(control_report.BEGIN, 1)[1].split(control_report.END, 1)[0]
    header, body = section.strip("\n").split("\n\n", 1)
    assert header.startswith("_hdsense bench, ")
    assert body.strip() == control_report.markdown(control_report.tables(RESULTS)).strip()
