"""Accuracy metrics.  Everything is computed against the simulator's
ripple-free truth (torque_true_nm), never against another method."""
from __future__ import annotations

import numpy as np
from scipy import signal

SLOW_HZ = 1.0          # "slow": below this


def window(t_s, t0, t1):
    return (t_s >= t0) & (t_s < t1)


def rms(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def line_amplitudes(err_nm, motor_rad, output_rad, motor_orders=(2, 4), output_orders=(1,)):
    """Least-squares amplitude [N m] of each line in err (constant removed).
    Returns {"motor 2": A, ..., "output 1": A}."""
    cols, names = [np.ones(len(err_nm))], []
    for o in motor_orders:
        cols += [np.cos(o * motor_rad), np.sin(o * motor_rad)]
        names.append(f"motor {o:g}")
    for o in output_orders:
        cols += [np.cos(o * output_rad), np.sin(o * output_rad)]
        names.append(f"output {o:g}")
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), err_nm, rcond=None)
    return {n: float(np.hypot(coef[1 + 2 * i], coef[2 + 2 * i])) for i, n in enumerate(names)}


def load_kept(err_slow, load_slow, ripple_slow=None) -> float:
    """The fraction of a slow external load an output keeps: 1 + the
    least-squares slope of its error's slow part on the load's slow part (0
    when the output lost the load, 1 when it follows it).  ripple_slow, the
    slow part of the simulator's true ripple, is a second regressor: a line
    the output leaves in (an output-locked line turns below 1 Hz at slow
    output speeds) is correlated with any load over a finite record by
    chance, and counted on the load it would score the raw measurement,
    which keeps the load whole, at other than 1.  Means are removed."""
    y = np.asarray(err_slow, float)
    cols = [np.asarray(load_slow, float)]
    if ripple_slow is not None:
        cols.append(np.asarray(ripple_slow, float))
    a = np.column_stack([c - c.mean() for c in cols])
    coef, *_ = np.linalg.lstsq(a, y - y.mean(), rcond=None)
    return 1.0 + float(coef[0])


def slow_part(x, ts_s: float):
    """x below SLOW_HZ (4th-order Butterworth, forward and back: no lag)."""
    b, a = signal.butter(4, SLOW_HZ, fs=1.0 / ts_s)
    return signal.filtfilt(b, a, x)


def slow_load_kept(err_nm, sim: dict, after) -> float | None:
    """load_kept of an output whose error against the truth is err_nm, on a
    simulated run (its load_torque_nm + gravity_nm is the external load, its
    ripple_true_nm the nuisance), over the samples `after`; None when the
    run's load does not vary below SLOW_HZ."""
    t = sim["t_s"]
    ts = float(t[1] - t[0])
    load = np.zeros(len(t))
    for k in ("load_torque_nm", "gravity_nm"):
        if k in sim:
            load = load + sim[k]
    lp_load = slow_part(load - load.mean(), ts)[after]
    if rms(lp_load) <= 1e-6:
        return None
    return load_kept(slow_part(err_nm, ts)[after], lp_load,
                     slow_part(sim["ripple_true_nm"], ts)[after])


def attenuation_db(before_nm: float, after_nm: float) -> float:
    return float(20.0 * np.log10(before_nm / max(after_nm, 1e-12)))


def add_line_attenuations(rows: dict) -> None:
    """Each row's "attenuation_db" per line, against the "raw" row's amplitude of
    that line (rows without line amplitudes are left alone)."""
    raw = rows["raw"]["line_amplitude_nm"]
    for r in rows.values():
        if "line_amplitude_nm" in r:
            r["attenuation_db"] = {ln: attenuation_db(raw[ln], a)
                                   for ln, a in r["line_amplitude_nm"].items()}


def moving_rms(x, n: int):
    x2 = np.asarray(x, dtype=float) ** 2
    c = np.concatenate([[0.0], np.cumsum(x2)])
    out = np.empty(len(x2))
    k = np.arange(len(x2))
    lo = np.maximum(k + 1 - n, 0)
    out[:] = np.sqrt((c[k + 1] - c[lo]) / (k + 1 - lo))
    return out


def step_delay_s(y, truth, t_s, t_step, t_end):
    """Delay of y behind the truth in crossing the step's midpoint.  The
    step size and levels come from the truth (mean over 0.2 s before and
    the end of the window).  NaN if y never crosses."""
    pre = window(t_s, t_step - 0.2, t_step)
    post = window(t_s, t_end - 0.2, t_end)
    lo, hi = truth[pre].mean(), truth[post].mean()
    mid = 0.5 * (lo + hi)
    sign = 1.0 if hi > lo else -1.0
    w = window(t_s, t_step, t_end)
    tt, yy, tr = t_s[w], y[w], truth[w]
    cy = np.nonzero(sign * (yy - mid) >= 0.0)[0]
    ct = np.nonzero(sign * (tr - mid) >= 0.0)[0]
    if not len(cy) or not len(ct):
        return float("nan")
    return float(tt[cy[0]] - tt[ct[0]])


def recovery_s(err, t_s, t_event, t_end, threshold_nm, win_s=0.02, ts_s=1e-3):
    """Time after t_event until the moving RMS error (win_s) stays below
    threshold_nm up to t_end.  0 if it never exceeds; inf if it has not
    recovered by t_end."""
    w = window(t_s, t_event, t_end)
    m = moving_rms(err[w], max(1, int(round(win_s / ts_s))))
    over = np.nonzero(m > threshold_nm)[0]
    if not len(over):
        return 0.0
    if over[-1] >= len(m) - 1:
        return float("inf")
    return float(t_s[w][over[-1] + 1] - t_event)
