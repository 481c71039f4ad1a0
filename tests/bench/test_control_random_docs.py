"""Staleness of the random-joint control bench's outputs
(docs/results/control-random.json, written by `tools/bench --only control_random
--update-docs`; no build needed):
  * the generated section of docs/results/control-random.md is the tables of
    that JSON, and its distributions are those of its joints;
  * its joints are the ones the seeds draw today (the space, the stream and
    the seeds unchanged since), on REPORT_SEEDS, disjoint from TUNE_SEEDS;
  * its product row is the law's defaults (control/hd_ctrl.c), its filtered
    row the control benchmark's tuned gains (docs/results/control.json), and
    on the default joint it measures the control benchmark's margins;
  * the per-joint tuning's summary is that of its joints, and a joint where
    it kept the defaults ran the defaults."""
import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

from hdmaint.bench import control_random as cr  # noqa: E402
from hdmaint.bench import control_random_report as crr  # noqa: E402
from hdmaint.bench import control_report  # noqa: E402

RESULTS = json.loads((ROOT / "docs" / "results" / "control-random.json").read_text())
CONTROL = json.loads((ROOT / "docs" / "results" / "control.json").read_text())


def test_doc_section_is_the_results_tables():
    text = (ROOT / "docs" / "results" / "control-random.md").read_text()
    section = text.split(crr.BEGIN, 1)[1].split(crr.END, 1)[0]
    header, body = section.strip("\n").split("\n\n", 1)
    assert header.startswith("_hdsense bench, ")
    assert body.strip() == crr.markdown(RESULTS).strip()


def test_distributions_are_those_of_the_joints():
    joints = RESULTS["joints"]
    for key, stored in RESULTS["summary"].items():
        assert control_report.clean(cr.summary(joints, key)) == stored, key
    assert control_report.clean(cr.sensitivity(joints, cr.PRODUCT)) == RESULTS["sensitivity"]
    for key, stored in RESULTS["failures"].items():
        assert control_report.clean(cr.failures(joints, key)) == stored, key
    assert control_report.clean(cr.autotune_summary(joints)) == RESULTS["autotune"]


def test_autotune_keeps_the_defaults_where_nothing_held():
    """Where the per-joint tuning found nothing that holds, its gains are
    the product row's (the firmware keeps what it has)."""
    p = RESULTS["rows"][cr.PRODUCT]
    for j in RESULTS["joints"]:
        a = j["autotune"]
        assert a["kp"] > 0 and a["ki_per_s"] >= 0 and a["kd_s"] >= 0, j["name"]
        if not a["met"]:
            assert (a["kp"], a["ki_per_s"], a["kd_s"]) == (p["kp"], p["ki"], p["kd"]), j["name"]


def test_joints_are_the_seeds_draws_on_the_report_seeds():
    assert not set(cr.TUNE_SEEDS) & set(cr.REPORT_SEEDS)
    seeds = [j["seed"] for j in RESULTS["joints"]]
    assert seeds == list(cr.REPORT_SEEDS[:cr.N_REPORT])
    assert RESULTS["seeds"] == f"REPORT_SEEDS[:{cr.N_REPORT}] = {seeds[0]}..{seeds[-1]}"
    assert RESULTS["stream"] == cr.STREAM
    assert [(p["key"], p["option"], p["draw"], p["lo"], p["hi"], p["why"])
            for p in RESULTS["space"]] == [(p.key, p.option, p.draw, p.lo, p.hi, p.why)
                                           for p in cr.SPACE]
    for j in RESULTS["joints"]:
        drawn = cr.draw_factors(j["seed"])
        assert j["name"] == f"c{j['seed']}"
        assert j["factors"] == {k: float(f"{x:.6g}") for k, x in drawn.items()}, j["name"]
        assert all(p.lo <= drawn[p.key] <= p.hi for p in cr.SPACE)


def _default(field: str) -> float:
    src = (ROOT / "control" / "hd_ctrl.c").read_text()
    return float(re.search(rf"\.{field} = ([0-9.eE+-]+)f,", src).group(1))


def test_rows_are_the_defaults_and_the_tuned_filtered_gains():
    p = RESULTS["rows"][cr.PRODUCT]
    src = (ROOT / "control" / "hd_ctrl.c").read_text()
    assert re.search(r"\.feedback = HD_CTRL_FB_NARROW,", src) and p["feedback"] == "narrow"
    assert (p["kp"], p["ki"], p["kd"], p["ff"], p["ilim"], p["friction_rest_nm"],
            p["artifact_hz"]) == (_default("torque_kp"), _default("torque_ki_per_s"),
                                  _default("torque_kd_s"), _default("torque_ff"),
                                  _default("integral_limit_nm"), _default("friction_rest_nm"),
                                  _default("artifact_hz"))
    f, t = RESULTS["rows"][cr.COMPARE], CONTROL["tuning"][cr.COMPARE]
    assert (f["feedback"], f["kp"], f["ki"], f["kd"]) == ("filtered", t["kp"], t["ki_per_s"],
                                                         t["kd_s"])
    assert {k: v for k, v in f.items() if k not in ("feedback", "kp", "ki", "kd")} == \
        {k: v for k, v in p.items() if k not in ("feedback", "kp", "ki", "kd")}


def test_default_joint_measures_the_control_benchmarks_margins():
    """The margins are measured at a constant setpoint, where the friction
    compensation at rest (on in the control benchmark, off as flashed) does
    nothing: on its joint this bench reproduces the control benchmark's."""
    for key, fixed in ((cr.PRODUCT, "narrow"), (cr.COMPARE, cr.COMPARE)):
        ours = RESULTS["default_joint"]["rows"][key]["margins"]
        theirs = CONTROL["tuning"][fixed]["measured"]
        assert ours.keys() == theirs.keys()
        for c in ours:
            for m in ("pm_deg", "gm_db"):
                a, b = ours[c][m], theirs[c][m]
                assert (a is None and b is None) or abs(a - b) < 0.01 * max(1.0, abs(b)), \
                    (key, c, m, a, b)


def test_range_ends_are_one_parameter_at_a_time():
    base = RESULTS["default_joint"]["factors"]
    want = [(p.key, end) for p in cr.SPACE if p.draw != "phase" for end in (p.lo, p.hi)]
    got = []
    for j in RESULTS["range_ends"]:
        moved = [k for k, x in j["factors"].items() if x != base[k]]
        assert len(moved) == 1 and list(j["rows"]) == [cr.PRODUCT], j["name"]
        got.append((moved[0], j["factors"][moved[0]]))
    assert got == want
