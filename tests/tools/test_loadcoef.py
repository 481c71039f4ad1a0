"""The load coefficient's regression (hdtools.analysis.loadcoef) against
closed forms: motor lines A_k (1 + c |T|) on a joint whose slow load and
output-locked line are unknown to the fit, with white noise."""
from __future__ import annotations

import numpy as np
import pytest

from hdtools.analysis import loadcoef

TS_S = 1e-3
ORDERS = (2.0, 4.0)


def joint(c_per_nm, seed=1, n=40_000, load_const_nm=0.0):
    """(torque, motor angle, |T|): the motor at 40-120 rad/s with two
    reversals, a slow load of sines and a step, an output line of 1 N m."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * TS_S
    speed = 80.0 + 40.0 * np.sin(2 * np.pi * t / 7.0)
    speed *= np.where((t > 12) & (t < 25), -1.0, 1.0)
    motor = np.cumsum(speed) * TS_S
    load = (load_const_nm + 1.5 * np.sin(2 * np.pi * t / 9.0 + 0.3)
            + 0.8 * np.sin(2 * np.pi * t / 4.0) + np.where(t > 20, 1.2, 0.0))
    grow = 1.0 + c_per_nm * np.abs(load)
    lines = grow * (0.9 * np.sin(2 * motor + 0.7) + 0.4 * np.sin(4 * motor - 2.1))
    output = 1.0 * np.sin(motor / 100.0 + 1.1)
    torque = load + lines + output + 0.03 * rng.standard_normal(n)
    return torque, motor, np.abs(load)


@pytest.mark.parametrize("c_true", [0.02, 0.08, 0.3])
def test_the_coefficient_is_recovered_within_its_error(c_true):
    tq, th, ld = joint(c_true)
    f = loadcoef.fit([tq], [th], [ld], TS_S, ORDERS)
    assert f is not None and f.significant()
    assert abs(f.coeff_per_nm - c_true) < max(4 * f.std_err_per_nm, 0.02 * c_true), f
    # each order on its own, and the amplitude at zero load
    for (order, amp, c_k, _), a0 in zip(f.per_order, (0.9, 0.4)):
        assert amp == pytest.approx(a0, rel=0.03)
        assert c_k == pytest.approx(c_true, rel=0.1)


def test_lines_that_do_not_grow_are_not_claimed():
    hits = 0
    for seed in range(20):
        tq, th, ld = joint(0.0, seed=seed)
        f = loadcoef.fit([tq], [th], [ld], TS_S, ORDERS)
        assert f is not None
        hits += f.significant()
    assert hits <= 1          # T_MIN = 5: a false claim is far rarer than this


def test_a_constant_load_gives_no_fit():
    tq, th, _ = joint(0.1)
    assert loadcoef.fit([tq], [th], [np.full(len(tq), 2.0)], TS_S, ORDERS) is None


def test_no_motor_order_gives_no_fit():
    tq, th, ld = joint(0.1)
    assert loadcoef.fit([tq], [th], [ld], TS_S, ()) is None


def test_pieces_and_chunks_give_the_coefficient_of_the_whole():
    tq, th, ld = joint(0.08, n=60_000)
    whole = loadcoef.fit([tq], [th], [ld], TS_S, ORDERS)
    cut = [slice(0, 25_000), slice(25_000, 60_000)]
    parts = loadcoef.fit([tq[s] for s in cut], [th[s] for s in cut], [ld[s] for s in cut],
                         TS_S, ORDERS)
    assert parts.coeff_per_nm == pytest.approx(whole.coeff_per_nm, rel=0.02)


def test_the_held_out_fold_replicates_only_the_same_coefficient():
    class Run:        # the fields of replay.PieceRun the check reads
        def __init__(self, tq, th, ld):
            self.t_s = np.arange(len(tq)) * TS_S
            self.torque_nm, self.motor_angle_rad, self.warm = tq, th, 0
            self.out = {"torque_expected_nm": ld.astype(np.float32),
                        "offset_nm": np.zeros(len(tq), np.float32)}
    view = [Run(*joint(0.08, seed=5))]
    ok, ev = loadcoef.replicated(0.08, view, ORDERS)
    assert ok and ev["held_out_load_coefficient_per_nm"] == pytest.approx(0.08, rel=0.1)
    assert not loadcoef.replicated(0.16, view, ORDERS)[0]
    assert not loadcoef.replicated(0.08, [Run(*joint(0.0, seed=5))], ORDERS)[0]


def test_the_rule_keeps_a_coefficient_the_innovation_or_fold_b_supports():
    keep, ev = loadcoef.judge(0.08, -loadcoef.INNOV_GAIN - 0.01, [], ORDERS)
    assert keep and ev == {}
    keep, ev = loadcoef.judge(0.08, -loadcoef.INNOV_GAIN + 0.01, [], ORDERS)
    assert not keep and "rejected_because" in ev       # nothing in fold B to replicate it
