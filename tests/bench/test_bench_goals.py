"""Issue 12's goals as the benchmark checks them (tools/hdmaint/bench/goals.py)
and `tools/bench --update-docs` (tools/hdmaint/bench/cli.py): on results
made up here, whose worst cases are known by construction."""
import argparse
import json

import pytest

from hdmaint.bench import cli as cmd_bench
from hdmaint.bench import goals, report
from hdtools.safeio import OutputError, UsageError


def _acc(rows):
    """accuracy results {scenario: {method: metrics}}"""
    return {"methods": {}, "scenarios": {s: {"methods": m} for s, m in rows.items()}}


def _slow(rows):
    return {"rows": {}, "scenarios": {s: {"rows": m} for s, m in rows.items()}}


def made_up() -> dict:
    ideal = {"rms_nm": 0.020}
    acc = _acc({
        "const156": {"fw_commissioned": {"rms_nm": 0.0206, "attenuation_db": {
            "motor 2": 80.0, "output 1": 41.0}}, "ideal": ideal,
            "butter_20db": {"rms_nm": 0.40}, "butter_40db": {"rms_nm": 0.30}},
        "ripple_drift": {"fw_commissioned": {"rms_nm": 0.0220, "attenuation_db": {
            "motor 2": 29.5, "output 1": 50.0}}, "ideal": ideal,
            "butter_20db": {"rms_nm": 0.40}, "butter_40db": {"rms_nm": 0.30}},
        # not a constant-speed scenario: its 15x must not count there
        "load_ripple": {"fw_commissioned": {"rms_nm": 0.30}, "ideal": ideal,
                        "butter_20db": {"rms_nm": 0.25}, "butter_40db": {"rms_nm": 0.60}},
    })
    row = {"x_floor": 1.2, "rms_nm": 0.024, "load_kept": 0.999, "first_s_rms_nm": 0.05,
           "steady_rms_nm": 0.0204, "attenuation_db": {"motor 2": 70.0, "output 3": 31.0}}
    slow = _slow({
        "a": {"fw_profile_ff": dict(row, x_floor=1.6), "fw_profile": dict(row, load_kept=0.97),
              "fw_default": dict(row, rms_nm=0.5, first_s_rms_nm=0.3),
              "butter_20db": {"rms_nm": 0.4}, "butter_40db": {"rms_nm": 0.45},
              "ideal": {"steady_rms_nm": 0.02}},
        "b": {"fw_profile_ff": dict(row, x_floor=1.1), "fw_profile": row,
              "fw_default": dict(row, rms_nm=0.3, first_s_rms_nm=0.1),
              "butter_20db": {"rms_nm": 0.4}, "butter_40db": {"rms_nm": 0.45},
              "ideal": {"steady_rms_nm": 0.02}},
    })
    return {"accuracy": acc, "slow": slow}


def _line(gs, goal_start, rows):
    hit = [g for g in gs if g["goal"].startswith(goal_start) and g["rows"] == rows]
    assert len(hit) == 1, (goal_start, rows, [g["rows"] for g in gs])
    return hit[0]


def test_goals_worst_cases_of_made_up_results():
    gs = goals.evaluate(made_up())
    g = _line(gs, "profile + slow torque known", "slow: fw_profile_ff")
    assert (g["worst"], g["where"], g["met"]) == (1.6, "a", False)
    g = _line(gs, "profile + slow torque known", "slow: fw_profile_current")
    assert g["n"] == 0 and g["met"] is None               # that row did not run
    g = _line(gs, "no slow-torque information: never worse", "accuracy: fw_commissioned")
    assert g["where"] == "load_ripple" and g["worst"] == pytest.approx(0.30 / 0.25)
    assert g["met"] is False
    g = _line(gs, "no slow-torque information: never worse", "slow: fw_default")
    assert g["where"] == "a" and g["worst"] == pytest.approx(0.5 / 0.4) and g["met"] is False
    g = _line(gs, "no slow-torque information: slow load", "slow: fw_profile")
    assert (g["worst"], g["where"], g["met"]) == (0.97, "a", False)
    g = _line(gs, "ripple band: >= 30 dB", "accuracy: fw_commissioned")
    assert (g["worst"], g["where"], g["met"]) == (29.5, "ripple_drift: motor 2", False)
    g = _line(gs, "ripple band: >= 30 dB", "slow: fw_profile")
    assert (g["worst"], g["where"], g["met"]) == (31.0, "a: output 3", True)
    g = _line(gs, "ripple band: <= 1.05x", "accuracy: fw_commissioned")
    assert g["where"] == "ripple_drift" and g["worst"] == pytest.approx(1.10)
    assert g["met"] is False
    g = _line(gs, "ripple band: <= 1.05x", "slow: fw_profile")
    assert g["worst"] == pytest.approx(1.02) and g["met"] is True
    g = _line(gs, "boot with a stored profile", "slow: fw_default / fw_profile")
    assert g["where"] == "b" and g["worst"] == pytest.approx(2.0) and g["met"] is None

    rows = report.goal_table(gs)[0][2]
    assert len(rows) == len(gs)
    assert [r[-1] for r in rows].count("met") == sum(1 for g in gs if g["met"])
    assert "not run" in [r[-1] for r in rows] and "reported" in [r[-1] for r in rows]


def test_goals_met_when_every_case_is_inside():
    res = made_up()
    res["slow"]["scenarios"]["a"]["rows"]["fw_profile_ff"]["x_floor"] = 1.5   # the bound itself
    g = _line(goals.evaluate(res), "profile + slow torque known", "slow: fw_profile_ff")
    assert g["met"] is True and g["worst"] == 1.5


def _args(tmp_path, update_docs=True, quick=False):
    return argparse.Namespace(out=tmp_path / "out", skip=["accuracy", "slow", "random", "real",
                                                            "host", "target", "control",
                                                            "control_random"],
                              quick=quick, update_docs=update_docs, only=[], random_joints=32)


@pytest.fixture
def docs(tmp_path, monkeypatch):
    doc = tmp_path / "docs" / "bench.md"
    doc.parent.mkdir()
    (tmp_path / "docs" / "results").mkdir()
    (tmp_path / "docs" / "img").mkdir()
    doc.write_text(f"# head\n\n{cmd_bench.BEGIN}\nold\n{cmd_bench.END}\n\n## tail\n")
    monkeypatch.setattr(cmd_bench, "DOC", doc)
    monkeypatch.setattr(cmd_bench, "DOC_JSON", tmp_path / "docs" / "results" / "bench.json")
    monkeypatch.setattr(cmd_bench, "DOC_PLOT", tmp_path / "docs" / "img" / "bench_accuracy.png")
    return doc


def test_update_docs_writes_the_doc_and_the_same_json(tmp_path, docs):
    assert cmd_bench.run(_args(tmp_path)) == 0
    out_json = (tmp_path / "out" / "results.json").read_text()
    assert (tmp_path / "docs" / "results" / "bench.json").read_text() == out_json
    assert "goals" in json.loads(out_json)
    text = docs.read_text()
    assert text.startswith("# head\n\n" + cmd_bench.BEGIN) and text.endswith("\n## tail\n")
    assert "old" not in text and "The slow-torque goals" in text
    assert (tmp_path / "out" / "results.md").read_text() in text
    assert not [p for p in tmp_path.rglob("*.tmp")]


def test_update_docs_failing_write_changes_nothing(tmp_path, docs, monkeypatch):
    before = docs.read_text()
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "results.json").write_text("old results")
    # the JSON's folder is gone: that write fails after the others are staged
    monkeypatch.setattr(cmd_bench, "DOC_JSON", tmp_path / "gone" / "bench.json")
    with pytest.raises(OutputError):
        cmd_bench.run(_args(tmp_path))
    assert docs.read_text() == before
    assert (tmp_path / "out" / "results.json").read_text() == "old results"
    assert not (tmp_path / "out" / "results.md").exists()
    assert not [p for p in tmp_path.rglob("*.tmp")]


def test_update_docs_refuses_quick_and_missing_markers(tmp_path, docs):
    with pytest.raises(UsageError, match="--quick"):
        cmd_bench.run(_args(tmp_path, quick=True))
    docs.write_text("# no markers\n")
    with pytest.raises(UsageError, match="markers"):
        cmd_bench.run(_args(tmp_path))
    assert docs.read_text() == "# no markers\n"
    assert not (tmp_path / "out").exists()
