"""The control benchmark's loop measurement (tools/hdmaint/bench/
control_loop.py) against loops with a closed-form L:

  * margins() on L(jw) = K exp(-jwT) / (1 + jw tau): the crossover
    sqrt(K^2 - 1) / tau, PM = 180 - wc T - atan(wc tau), and GM at the
    root of w T + atan(w tau) = pi (scipy's brentq on the closed form);
  * the injection measurement (multisine, whole periods, L = -CMD / X) on a
    discrete first-order plant with a delay under a PI, simulated here
    tick by tick: the measured lines equal C(z) P(z) in closed form, and
    its margins those of the closed form on a dense grid;
  * pi_response against the law's recursion (u = kp e + I, I += ki ts e);
  * bandwidth_hz of a first-order response: its corner.
"""
import math
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

ROOT = Path(__file__).resolve().parents[2]

from hdmaint.bench import control_loop as cl  # noqa: E402
from hdmaint.bench import control_tune as ct  # noqa: E402


def test_margins_of_first_order_plus_delay():
    k, t_s, tau = 4.0, 2e-3, 0.01
    f = np.geomspace(0.5, 2000.0, 4000)
    w = 2 * math.pi * f
    loop = k * np.exp(-1j * w * t_s) / (1 + 1j * w * tau)
    m = cl.margins(f, loop)
    wc = math.sqrt(k * k - 1) / tau
    pm = 180.0 - math.degrees(wc * t_s + math.atan(wc * tau))
    w180 = brentq(lambda x: x * t_s + math.atan(x * tau) - math.pi, 1.0, 1e5)
    gm = -20 * math.log10(k / math.sqrt(1 + (w180 * tau) ** 2))
    assert abs(m["crossover_hz"] - wc / (2 * math.pi)) < 0.01 * wc / (2 * math.pi)
    assert abs(m["pm_deg"] - pm) < 0.2
    assert abs(m["gm_db"] - gm) < 0.05
    assert abs(m["phase_crossover_hz"] - w180 / (2 * math.pi)) < 0.01 * w180 / (2 * math.pi)


def test_no_crossover_is_infinite_margin():
    f = np.geomspace(1, 100, 50)
    m = cl.margins(f, 0.1 / (1 + 1j * f / 10))
    assert m["pm_deg"] == math.inf and m["gm_db"] == math.inf and m["crossover_hz"] is None


def _simulate_loop(inject, kp, ki, a, b, delay):
    """y_k = a y_(k-1) + b x_(k-delay); the law's PI on e = -y (setpoint 0);
    x = cmd + inject.  Returns (cmd, x)."""
    n = len(inject)
    y, x, cmd = np.zeros(n), np.zeros(n), np.zeros(n)
    integ = 0.0
    for k in range(n):
        y[k] = (a * y[k - 1] if k else 0.0) + (b * x[k - delay] if k >= delay else 0.0)
        e = -y[k]
        cmd[k] = kp * e + integ
        integ += ki * cl.TS_S * e
        x[k] = cmd[k] + inject[k]
    return cmd, x


def test_injection_measures_the_closed_form_loop():
    kp, ki, a, delay = 3.0, 60.0, math.exp(-cl.TS_S / 0.004), 2
    b = 1 - a
    one, bins = cl.multisine()
    cmd, x = _simulate_loop(np.tile(one, 3), kp, ki, a, b, delay)
    measured = -cl.line_spectrum(cmd, cl.MS_PERIOD, bins) / cl.line_spectrum(x, cl.MS_PERIOD, bins)
    f = bins / (cl.MS_PERIOD * cl.TS_S)

    def closed(freq):
        z = np.exp(1j * 2 * math.pi * freq * cl.TS_S)
        return cl.pi_response(freq, kp, ki) * b * z ** (-delay) / (1 - a / z)
    assert np.max(np.abs(measured / closed(f) - 1)) < 1e-6
    dense = np.geomspace(f[0], f[-1], 5000)
    m_meas, m_true = cl.margins(f, measured), cl.margins(dense, closed(dense))
    assert abs(m_meas["pm_deg"] - m_true["pm_deg"]) < 2.0
    assert abs(m_meas["gm_db"] - m_true["gm_db"]) < 0.5


def test_pi_response_is_the_laws_recursion():
    """u = kp e + I + kd (e - e_prev) / ts, I += ki ts e after u (the law's
    recursion on a constant setpoint, where the feedback's rate is -e's)."""
    f, n = 7.0, 4000
    for kp, ki, kd in ((0.8, 50.0, 0.0), (0.8, 50.0, 2e-3)):
        e = np.sin(2 * math.pi * f * cl.TS_S * np.arange(n))
        u, integ = np.zeros(n), 0.0
        for k in range(n):
            u[k] = kp * e[k] + integ + (kd * (e[k] - e[k - 1]) / cl.TS_S if k else 0.0)
            integ += ki * cl.TS_S * e[k]
        u -= u[n // 2:].mean()   # the integral's constant from the start
        t = np.arange(n // 2, n)
        basis = np.exp(1j * 2 * math.pi * f * cl.TS_S * t)
        gain = (u[t] @ basis.conj()) / (e[t] @ basis.conj())
        assert abs(gain / cl.pi_response(f, kp, ki, kd) - 1) < 1e-3


def test_bandwidth_of_a_first_order_response():
    f = np.geomspace(1, 200, 300)
    assert abs(ct.bandwidth_hz(f, 1 / (1 + 1j * f / 25.0)) - 25.0) < 0.25
    assert ct.bandwidth_hz(f, 0.5 + 0 * f) is None
    assert ct.bandwidth_hz(f, 1 + 0 * f) == math.inf


def _closed_form_measure(a=math.exp(-cl.TS_S / 0.004), delay=2):
    """measure_loop's stand-in: the discrete first-order plant with a delay
    of test_injection_measures_the_closed_form_loop, L = C(v) P."""
    f = cl.multisine()[1] / (cl.MS_PERIOD * cl.TS_S)
    z = np.exp(1j * 2 * math.pi * f * cl.TS_S)
    p = (1 - a) * z ** (-delay) / (1 - a / z)

    def measure(v, scene):
        return cl.Response(f, cl.pi_response(f, v.kp, v.ki, v.kd) * p, p, p)
    return measure


def _rounded(c):
    return tuple(float(f"{x:.3g}") for x in c[:3])


def test_tune_rejects_a_candidate_that_limit_cycles_on_the_wall():
    """Step 4: a candidate meeting every margin but limit-cycling in the
    wall contact is rejected and the next one taken; without a cycle the
    best is kept."""
    measure, conds = _closed_form_measure(), ("0.5",)
    found = ct.candidates(ct.measure_plants(cl.Variant("x", "raw"), conds, measure), 1.0)
    assert len(found) > 2 and _rounded(found[0]) != _rounded(found[1])
    calls = []

    def contact(v):   # the best candidate cycles, every other one rests
        calls.append((v.kp, v.ki, v.kd))
        return [{"limit_cycle": len(calls) == 1, "p2p_nm": 3.0 if len(calls) == 1 else 0.01}]
    v = cl.Variant("x", "raw")
    t = ct.tune(v, conds, measure, contact=contact)
    assert calls == [_rounded(found[0]), _rounded(found[1])]
    assert (v.kp, v.ki, v.kd) == _rounded(found[1]) and t["met"]
    assert t["wall_rejected"] == [dict(zip(("kp", "ki_per_s", "kd_s"), _rounded(found[0])),
                                       wall_p2p_nm=3.0)]
    assert not t["wall"][0]["limit_cycle"]
    v = cl.Variant("x", "raw")
    t = ct.tune(v, conds, measure, contact=lambda v: [{"limit_cycle": False, "p2p_nm": 0.0}])
    assert (v.kp, v.ki, v.kd) == _rounded(found[0]) and t["met"] and t["wall_rejected"] == []


def test_tune_reports_not_met_when_every_candidate_limit_cycles():
    measure = _closed_form_measure()
    v = cl.Variant("x", "raw")
    t = ct.tune(v, ("0.5",), measure, contact=lambda v: [{"limit_cycle": True, "p2p_nm": 1.0}])
    assert not t["met"] and len(t["wall_rejected"]) == min(
        ct.CHECKED_MAX, len(ct.candidates(ct.measure_plants(
            cl.Variant("x", "raw"), ("0.5",), measure), 1.0)))


def test_fallback_order_halves_from_the_conservative_end():
    """The last candidate first, then halving toward the first unchecked one."""
    assert ct._fallback_order(100, 60) == [99, 79, 69, 64, 62, 61]
    assert ct._fallback_order(61, 60) == [60]
    assert ct._fallback_order(60, 60) == [] and ct._fallback_order(3, 60) == []


def _cycling_above(found, holds_from: int):
    """A wall contact that cycles for every candidate of `found` before
    index holds_from and rests for the others; the calls it saw."""
    index = {_rounded(c): i for i, c in enumerate(found)}
    calls = []

    def contact(v):
        i = index[(v.kp, v.ki, v.kd)]
        calls.append(i)
        return [{"limit_cycle": i < holds_from, "p2p_nm": 1.0 if i < holds_from else 0.01}]
    return contact, calls


def test_tune_falls_back_to_the_conservative_end_when_the_best_all_fail():
    """Every one of the best CHECKED_MAX limit-cycles: the method checks the
    rest of the list from its conservative end, halving, and keeps the best
    that held (the last holding index of the halving before the first that
    fails)."""
    measure, conds = _closed_form_measure(), ("0.5",)
    found = ct.candidates(ct.measure_plants(cl.Variant("x", "raw"), conds, measure), 1.0)
    assert len(found) > ct.CHECKED_MAX + 8
    holds_from = ct.CHECKED_MAX + (len(found) - ct.CHECKED_MAX) // 3
    contact, calls = _cycling_above(found, holds_from)
    v = cl.Variant("x", "raw")
    t = ct.tune(v, conds, measure, contact=contact)
    order = ct._fallback_order(len(found), ct.CHECKED_MAX)
    tried = order[:next(k for k, i in enumerate(order) if i < holds_from) + 1]
    assert calls == list(range(ct.CHECKED_MAX)) + tried
    best = tried[-2]
    assert t["met"] and t["fallback"] and best >= holds_from
    assert (v.kp, v.ki, v.kd) == _rounded(found[best])


def test_tune_keeps_the_gains_it_came_with_when_nothing_holds():
    measure, conds = _closed_form_measure(), ("0.5",)
    v = cl.Variant("x", "raw", kp=0.3, ki=4.0, kd=0.0)
    t = ct.tune(v, conds, measure, contact=lambda v: [{"limit_cycle": True, "p2p_nm": 1.0}])
    assert not t["met"] and (v.kp, v.ki, v.kd) == (0.3, 4.0, 0.0)


def test_tune_takes_the_best_rated_of_the_first_that_hold():
    """Step 5: with a measure of the tracking, the first RATED_MAX
    candidates that hold (every one here) are rated; a later one replaces
    the kept one only by more than the resolution.  A candidate after them
    is not rated, and one that cycles is not rated."""
    measure, conds = _closed_form_measure(), ("0.5",)
    found = ct.candidates(ct.measure_plants(cl.Variant("x", "raw"), conds, measure), 1.0)
    assert len(found) > ct.RATED_MAX + 2
    index = {_rounded(c): i for i, c in enumerate(found)}
    contact, _ = _cycling_above(found, 1)          # the best cycles, the rest rest

    def tuned(scores, resolution=0.1):
        rated = []

        def rate(v):
            i = index[(v.kp, v.ki, v.kd)]
            rated.append(i)
            return scores.get(i, 0.0), resolution
        v = cl.Variant("x", "raw")
        t = ct.tune(v, conds, measure, contact=contact, rate=rate)
        assert rated == list(range(1, 1 + ct.RATED_MAX)) and t["met"]
        return index[(v.kp, v.ki, v.kd)]
    assert tuned({3: 1.0}) == 3                     # better by more than the resolution
    assert tuned({3: 0.05}) == 1                    # within it: the ranking's first
    assert tuned({2: 0.15, 3: 0.2}) == 2            # 3 is within the resolution of 2
    assert tuned({}) == 1                           # equals: the first


def test_tune_keeps_the_gains_it_came_with_when_the_grid_has_none():
    """No gains on the grid meet the margins (a plant no PI holds): the
    gains it came with stay, as when nothing checked holds."""
    f = cl.multisine()[1] / (cl.MS_PERIOD * cl.TS_S)
    z = np.exp(1j * 2 * math.pi * f * cl.TS_S)

    def measure(v, scene):   # gain 1e4 and four ticks of delay: no PI on the grid holds
        p = 1e4 * z ** -4
        return cl.Response(f, cl.pi_response(f, v.kp, v.ki, v.kd) * p, p, p)
    assert ct.candidates(ct.measure_plants(cl.Variant("x", "raw"), ("0.5",), measure), 1.0) == []
    v = cl.Variant("x", "raw", kp=0.3, ki=4.0, kd=0.001)
    t = ct.tune(v, ("0.5",), measure)
    assert not t["met"] and (v.kp, v.ki, v.kd) == (0.3, 4.0, 0.001)


def test_ripple_bound_is_the_open_loop_over_raw():
    """control.ripple_bound: the open-loop drive's true 2x ripple over raw
    feedback's at the speed given (hand-made rows), reachable only at or
    below 0.5; a bound, never a met goal."""
    from hdmaint.bench import control

    def rows(open_loop, raw):
        lines = {"open_loop": open_loop, control.PRODUCT_KEY: 0.42, "raw": raw}
        return {k: {"speeds": {"3.0": {"ripple": {"line2_nm": v}}}} for k, v in lines.items()}
    b = control.ripple_bound(rows(0.4, 0.8), "3.0")
    assert b["worst"] == 0.5 and b["met"] is None and b["status"] == "0.5x reachable"
    b = control.ripple_bound(rows(0.4, 0.7), "3.0")
    assert b["worst"] == 0.4 / 0.7 and "UNREACHABLE" in b["status"]
    assert b["where"] == "3.0 rad/s: open_loop 0.400, narrow 0.420, raw 0.700 N m"
