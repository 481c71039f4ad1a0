"""Gear ratio: from two encoders if present, else inferred from the
spectrum of the measured torque over the output angle.

A strain-wave gear's ripple sits at integer multiples of the wave-generator
(motor) frequency, i.e. at output orders k N.  For each candidate N the
score is the summed log peak-over-floor ratio at k N for k = 1..4 (only
orders the data can show below Nyquist count).  The best N is reported with
how it stands out: its score's robust z-score among all candidates and the
runner-up that is not a harmonic relative (N/2, 2N, ...)."""
from __future__ import annotations

import math

import numpy as np

from . import spectra

HARMONICS = (1, 2, 3, 4)


def from_encoders(data):
    num, den = 0.0, 0.0
    for p in data.pieces:
        dm, do = np.diff(p.motor_angle_rad), np.diff(p.output_angle_rad)
        mv = np.abs(do) > 0
        num += float(np.sum(dm[mv] * do[mv]))
        den += float(np.sum(do[mv] ** 2))
    if den <= 0:
        return None
    return num / den


def _detrended_runs(data):
    """Measured torque per monotonic output-angle run, minus a cubic in
    angle (removes gravity and slow load; keeps lines of order >> 1)."""
    sig, ang = [], []
    for p in data.pieces:
        th = p.output_angle_rad
        for a, b in spectra.monotonic_runs(th, min_len=64):
            x, t = p.torque_nm[a:b].astype(float), th[a:b].astype(float)
            tn = (t - t.mean()) / (np.ptp(t) / 2 + 1e-12)
            x = x - np.polyval(np.polyfit(tn, x, 3), tn)
            sig.append(x)
            ang.append(t)
    return sig, ang


def infer_from_spectrum(data, lo=50.0, hi=200.0, step=0.25):
    sig, ang = _detrended_runs(data)
    if not sig:
        return None
    spec = spectra.order_spectrum(sig, ang)
    if spec is None:
        return None
    # Highest output order the data can show: Nyquist at the slowest
    # third of the runs (slow runs reach the highest orders).
    speeds = [np.median(np.abs(np.diff(a))) / data.ts_s for a in ang]
    max_order = 0.45 / data.ts_s * 2 * math.pi / max(np.percentile(speeds, 30), 1e-9)
    cands = np.arange(lo, hi + step / 2, step)
    fl = spectra.local_floor(spec.amp2)
    ratio = spec.amp2 / fl
    do = spec.axis[1] - spec.axis[0]

    def r_at(order):
        i = int(round(order / do))
        if i < 2 or i >= len(ratio) - 2 or order > min(max_order, spec.axis[-1]):
            return None
        return float(np.max(ratio[i - 1:i + 2]))

    scores, used = [], []
    for n in cands:
        rs = [r_at(k * n) for k in HARMONICS]
        rs = [r for r in rs if r is not None]
        scores.append(sum(math.log(max(r, 1.0)) for r in rs) / max(len(rs), 1))
        used.append(len(rs))
    scores = np.array(scores)
    i = int(np.argmax(scores))
    best = float(cands[i])
    med = float(np.median(scores))
    mad = max(float(np.median(np.abs(scores - med))) * 1.4826, 0.05)
    z = (scores[i] - med) / mad
    # Runner-up outside +-3 % of the best and its harmonic relatives.
    rel = [best * f for f in (0.25, 1 / 3, 0.5, 2 / 3, 1.5, 2, 3, 4)] + [best]
    mask = np.ones(len(cands), bool)
    for r in rel:
        mask &= np.abs(cands - r) > 0.03 * r
    j = int(np.argmax(np.where(mask, scores, -np.inf)))
    lines = {f"k={k}": round(r_at(k * best) or 0.0, 1) for k in HARMONICS}
    margin = float(scores[i] - scores[j])
    conf = "high" if z > 8 and margin > 0.8 else ("medium" if z > 5 and margin > 0.3 else "low")
    kmax = max([k for k in HARMONICS if r_at(k * best) is not None] or [1])
    return {"value": best, "source": "inferred", "method": "torque order spectrum over output angle",
            "confidence": conf, "robust_z": round(float(z), 2),
            "peak_ratio_at_multiples": lines,
            "runner_up": float(cands[j]), "runner_up_score": round(float(scores[j]), 3),
            "score": round(float(scores[i]), 3), "margin_over_runner_up": round(margin, 3),
            "uncertainty": round(float(do) / (2 * kmax), 2),
            "order_resolution_per_output_rev": round(float(do), 3),
            "max_usable_output_order": round(float(max_order), 1),
            "candidates": [lo, hi, step]}
