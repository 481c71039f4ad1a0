"""The load coefficient of the ripple, fitted on the measured torque.

Harmonic-drive ripple grows with the transmitted torque: a line is
A0 (1 + c |T|) (hd_kf.h, "measurement row").  The firmware scales its
lines by 1 + c |T_ref|, T_ref its own slow torque (expected + offset), so c
is fitted against the same T_ref, taken from the replay of the log.

Per motor-locked order the torque is regressed on

    cos(k th), sin(k th), |T_ref| cos(k th), |T_ref| sin(k th)

after one moving-average high-pass applied to the torque and to every
regressor alike.  The model is linear, so the high-pass keeps it exact while
it removes the unknown slow load, the output-locked lines and the offset;
lines slowed below the high-pass near a reversal lose weight in the fit
instead of biasing it.  The order's coefficient is the |T_ref| part's
projection on its zero-load phasor, c_k = (a alpha + b beta) / (a^2 + b^2),
with its standard error by the delta method; the orders are pooled by
inverse variance.

The windowed envelope correlation this replaces saw |mean measured torque|,
which carries the slow output-locked lines, and leaked neighbouring lines
into windows of about one cycle: on random loaded joints it found a fraction
of the coefficient (docs/decisions/load-coefficient-fit.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

HIGHPASS_S = 0.2            # moving-average length of the high-pass
CHUNK_S = 60.0              # pieces are fitted in chunks of at most this (memory)
T_MIN = 5.0                 # a coefficient proposed: estimate over standard error
MIN_LOAD_SPREAD_NM = 0.1    # |T_ref| must vary at least this much (std) to be fitted
AGREE = 0.3                 # a held-out fit within this fraction of the proposal replicates it
INNOV_GAIN = 0.05           # or the held-out innovation falls by this fraction


@dataclass
class LoadFit:
    coeff_per_nm: float
    std_err_per_nm: float
    per_order: list          # (order, zero-load amplitude N m, c, standard error)
    load_spread_nm: float

    @property
    def t_stat(self) -> float:
        return self.coeff_per_nm / self.std_err_per_nm if self.std_err_per_nm > 0 else 0.0

    def significant(self) -> bool:
        return self.coeff_per_nm > 0 and self.t_stat >= T_MIN


def _columns(angle_rad, load_nm, orders):
    cols = []
    for k in orders:
        c, s = np.cos(k * angle_rad), np.sin(k * angle_rad)
        cols += [c, s, load_nm * c, load_nm * s]
    return np.stack(cols, 1)


def fit(torque, motor_angle, load_ref, ts_s: float, orders) -> LoadFit | None:
    """The coefficient over pieces (lists of arrays: measured torque, motor
    angle, |T_ref|); None without motor orders, data or load variation."""
    orders = [float(k) for k in orders]
    if not orders:
        return None
    w = max(3, int(round(HIGHPASS_S / ts_s)))
    chunk = max(4 * w, int(round(CHUNK_S / ts_s)))
    p = 4 * len(orders)
    xtx, xty, yty, n = np.zeros((p, p)), np.zeros(p), 0.0, 0
    load_sum = load_sq = 0.0
    for y_all, th_all, l_all in zip(torque, motor_angle, load_ref):
        for i in range(0, len(y_all) - 2 * w + 1, chunk):
            y = np.asarray(y_all[i:i + chunk], float)
            load = np.asarray(l_all[i:i + chunk], float)
            x = _columns(np.asarray(th_all[i:i + chunk], float), load, orders)
            yh = y - uniform_filter1d(y, w, mode="nearest")
            xh = x - uniform_filter1d(x, w, axis=0, mode="nearest")
            xtx += xh.T @ xh
            xty += xh.T @ yh
            yty += float(yh @ yh)
            n += len(y)
            load_sum += float(load.sum())
            load_sq += float(load @ load)
    if n <= 2 * p:
        return None
    spread = math.sqrt(max(load_sq / n - (load_sum / n) ** 2, 0.0))
    if spread < MIN_LOAD_SPREAD_NM:
        return None
    try:
        inv = np.linalg.inv(xtx)
    except np.linalg.LinAlgError:
        return None
    beta = inv @ xty
    sigma2 = max(yty - float(beta @ xty), 0.0) / (n - p)
    cov = sigma2 * inv
    per, wsum, cw = [], 0.0, 0.0
    for j, k in enumerate(orders):
        a, b, al, be = beta[4 * j:4 * j + 4]
        a2 = a * a + b * b
        if not a2 > 0:
            continue
        c = (a * al + b * be) / a2
        # d c / d (a, b, alpha, beta)
        grad = np.array([(al - 2 * a * c) / a2, (be - 2 * b * c) / a2, a / a2, b / a2])
        var = float(grad @ cov[4 * j:4 * j + 4, 4 * j:4 * j + 4] @ grad)
        if not var > 0:
            continue
        per.append((k, math.sqrt(a2), float(c), math.sqrt(var)))
        wsum += 1.0 / var
        cw += c / var
    if not wsum > 0:
        return None
    return LoadFit(cw / wsum, 1.0 / math.sqrt(wsum), per, spread)


def fit_view(view, ts_s: float, orders) -> LoadFit | None:
    """fit() over replayed runs (replay.analysis_view): their measured
    torque and motor angle after the warm-up, against |expected + offset|."""
    w = [r.warm for r in view]
    return fit([np.asarray(r.torque_nm[i:], float) for r, i in zip(view, w)],
               [np.asarray(r.motor_angle_rad[i:], float) for r, i in zip(view, w)],
               [np.abs(r.out["torque_expected_nm"][i:] + r.out["offset_nm"][i:]).astype(float)
                for r, i in zip(view, w)], ts_s, orders)


def replicated(coeff_per_nm: float, view, orders) -> tuple[bool, dict]:
    """Whether the held-out fold (view) shows the proposed coefficient on
    its own: its fit significant and within AGREE of the proposal; and the
    evidence."""
    ts = float(np.median(np.diff(view[0].t_s[:100]))) if view else 1e-3
    f = fit_view(view, ts, orders)
    if f is None:
        return False, {}
    ev = {"held_out_load_coefficient_per_nm": float(f"{f.coeff_per_nm:.3g}"),
          "held_out_load_coefficient_t": round(f.t_stat, 1)}
    return f.significant() and abs(f.coeff_per_nm - coeff_per_nm) <= AGREE * coeff_per_nm, ev


def judge(coeff_per_nm: float, innov_change: float, view, orders) -> tuple[bool, dict]:
    """The analysis' rule for a proposed coefficient (augment.judge, after
    the held-out innovation did not grow): kept when that innovation falls
    by INNOV_GAIN, or when the held-out fold replicates it; (keep, evidence
    with rejected_because when not)."""
    if innov_change <= -INNOV_GAIN:
        return True, {}
    ok, ev = replicated(coeff_per_nm, view, orders)
    if not ok:
        ev["rejected_because"] = ("the held-out innovation did not fall by 5 % and the held-out "
                                  "fold does not show the same load coefficient")
    return ok, ev


def motor_orders(model) -> list:
    return [b.order for b in model.blocks if b.lock == "motor"]
