"""The keep rule (issue 13, item 1), on its own: a change is kept only if it
helps in fold B, the part of the log it was not found or fitted in.  The
replays here are synthetic (a line in the torque, an innovation), so the
rule is tested apart from detection; the scenario tests check it end to end
(history never worse out of sample)."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import analyze, read_csv, write_csv
from hdtools.analysis import augment, detect, replay as rp
from hdtools.analysis.model import Model


def _runs(line_nm, innov_a, innov_b, n=40000, ts=1e-3):
    """One piece: a motor-order-3 line of line_nm in the filtered torque,
    white innovations of rms innov_a in fold A and innov_b in fold B."""
    rng = np.random.default_rng(1)
    t = np.arange(n) * ts
    th_m = 150.0 * t
    fold = np.where(np.arange(n) < n // 2, rp.TRAIN, rp.HELD_OUT).astype(np.int8)
    fold[:100] = rp.WARMUP
    filt = 2.0 + line_nm * np.sin(3 * th_m) + 0.01 * rng.standard_normal(n)
    e = np.where(fold == rp.HELD_OUT, innov_b, innov_a) * rng.standard_normal(n)
    out = {"torque_filtered_nm": filt.astype(np.float32),
           "torque_expected_nm": np.zeros(n, np.float32),
           "innovation_nm": e.astype(np.float32),
           "innovation_var_nm2": np.full(n, 1e-4, np.float32),
           "output_velocity_rad_s": np.full(n, 1.5, np.float32),
           "status": np.zeros(n, np.uint32), "reset_count": 0}
    run = rp.PieceRun(t, th_m, th_m / 100, filt, None, out, 100, fold, None, "")
    return [run]


def _judge(before, after):
    c = detect.Candidate("motor_order", 3.0, 0.3, action="add_block")
    m = Model.starting(100.0, 1e-3, 0.02, [2, 4], [])
    return augment.judge(c, before, rp.metrics(before), after, rp.metrics(after), m)


def test_a_line_that_drops_is_kept_when_fold_b_agrees():
    keep, ev = _judge(_runs(0.3, 0.05, 0.05), _runs(0.0, 0.03, 0.03))
    assert keep, ev


def test_held_out_innovation_growth_rejects_the_change():
    # The line is gone and the in-sample innovation falls, but fold B's
    # innovation grows: the change is not kept (before this rule, the
    # innovation over the whole log, used to find the change, decided; a
    # real arm log got a 1x line and drift "added" while its innovation
    # grew 0.244 -> 0.313 N m).
    keep, ev = _judge(_runs(0.3, 0.05, 0.05), _runs(0.0, 0.02, 0.06))
    assert not keep
    assert "held-out innovation grew" in ev["rejected_because"]
    assert ev["after"]["in_sample_innovation_rms_nm"] < ev["before"]["in_sample_innovation_rms_nm"]


def test_in_sample_growth_alone_does_not_reject():
    # Fold A is where the change was found: only fold B decides.
    keep, ev = _judge(_runs(0.3, 0.05, 0.05), _runs(0.0, 0.08, 0.03))
    assert keep, ev


@pytest.fixture(scope="module")
def drift_with_load(simulate, tmp_path_factory):
    """drift.ini (sensor drift 0.05 N m/s) under a constant 2 N m load the
    model does not know, and the same with the controller's slow torque as
    feed-forward."""
    tmp = tmp_path_factory.mktemp("dl")
    h, a = read_csv(simulate("drift", "load_torque_profile=0:2, 20:2"))
    plain = write_csv(tmp / "dl.csv", h, a)
    ff = write_csv(tmp / "dlff.csv", h + ["torque_feedforward_nm"],
                   np.column_stack([a, a[:, h.index("torque_true_nm")]]))
    return analyze(plain), analyze(ff)


def test_a_trend_on_an_unexplained_load_is_not_called_sensor_drift(drift_with_load):
    # The offset read as a sensor error removes all the slow torque the
    # expected torque misses: with 2 N m of load nobody explained, a trend
    # is found and reported, but not kept (it would remove the load too).
    plain, _ = drift_with_load
    d = [e for e in plain["effects"] if e["kind"] == "offset_drift"]
    assert d and not d[0]["added"] and "not_added_because" in d[0]["evidence"]
    assert plain["model_after"]["offset_is_sensor_error"] is False
    assert plain["error_rms_after_nm"] < 1.0      # the 2 N m load is kept


def test_with_the_slow_torque_known_the_drift_is_removed(drift_with_load):
    _, ff = drift_with_load
    d = [e for e in ff["effects"] if e["kind"] == "offset_drift" and e["added"]]
    assert d and d[0]["parameters"]["drift_nm_per_s"] == pytest.approx(0.05, rel=0.1)
    assert ff["error_rms_after_nm"] < 1.5 * 0.02
    # Same q, so the same innovation: never worse out of sample.
    assert ff["out_of_sample_residual_rms_after_nm"] == pytest.approx(
        ff["out_of_sample_residual_rms_before_nm"], rel=1e-6)
