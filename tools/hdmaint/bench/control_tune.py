"""The torque loop's tuning method (docs/results/control.md, "Tuning"), per feedback.

1. Break the loop in the simulation at every benchmark speed and with the
   output pressed against a stiff wall (the conditions)
   (control_loop.measure_loop, with the variant's current gains): the plant
   the controller sees, P_fb(jw) (feedback torque per drive current), and
   the true output torque's, P_true(jw), on the same run.
2. On a grid of PI gains (kp, ki = kp w_i) compute, from P in closed form,
   L = C P_fb (margins) and the predicted tracking response
   H = P_true (ff + C) / (1 + C P_fb) (its -3 dB bandwidth).
3. Keep the gains whose loop has phase margin >= 45 deg and gain margin
   >= 6 dB, and whose predicted tracking peak |H| is at most 10 dB, in EVERY
   condition (one set of gains for all: what the
   firmware runs), and take the one with the largest predicted bandwidth at
   the worst speed (ties: the larger worst crossover).
4. Measure the chosen loop again by breaking it (its margins are the ones
   reported) and, if a speed misses a margin (the plant's nonlinearity:
   friction at standstill), step kp down by 10 % until all are met.
The open-loop current (feedback none) has no loop and no tuning.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import control_loop as cl

PM_DEG, GM_DB = 45.0, 6.0
PEAK_DB = 10.0
KP_GRID = np.geomspace(0.05, 40.0, 48)
WI_GRID_RAD_S = 2 * math.pi * np.array([1.0, 2.0, 5.0, 10.0, 20.0, 40.0])  # ki / kp


def bandwidth_hz(freq_hz, h) -> float | None:
    """The lowest frequency where |h| falls below 1/sqrt(2) (log-linear
    interpolation); None if |h| is below it at the lowest line, inf if
    never within the band."""
    f = np.asarray(freq_hz, dtype=float)
    below = np.abs(h) < 1.0 / math.sqrt(2.0)
    if below[0]:
        return None
    idx = np.flatnonzero(below)
    if len(idx) == 0:
        return math.inf
    i = idx[0]
    a0, a1 = 20 * np.log10(np.abs(h[i - 1])), 20 * np.log10(np.abs(h[i]))
    t = (a0 + 3.0103) / (a0 - a1) if a0 != a1 else 0.0
    return float(np.exp(np.log(f[i - 1]) + t * (np.log(f[i]) - np.log(f[i - 1]))))


@dataclasses.dataclass
class PlantAt:
    condition: str
    freq_hz: np.ndarray
    p_fb: np.ndarray
    p_true: np.ndarray


def measure_plants(v: cl.Variant, conditions, measure=cl.measure_loop) -> list[PlantAt]:
    out = []
    for c in conditions:
        r = measure(v, cl.scene_of(c))
        out.append(PlantAt(c, r.freq_hz, r.plant, r.true_plant))
    return out


def predict(p: PlantAt, kp: float, ki: float, ff: float) -> tuple[dict, float | None]:
    """Margins of C P_fb and the predicted tracking bandwidth; margins gets
    the tracking peak (peak_db) too."""
    c = cl.pi_response(p.freq_hz, kp, ki)
    loop = c * p.p_fb
    h = p.p_true * (ff + c) / (1.0 + loop)
    m = cl.margins(p.freq_hz, loop)
    m["peak_db"] = float(20 * np.log10(np.abs(h).max()))
    return m, bandwidth_hz(p.freq_hz, h)


def acceptable(m: dict) -> bool:
    """The margins, and no tracking peak above PEAK_DB (a loop whose
    feedback lags can meet the margins with a proportional kick that
    overshoots many-fold: the peak rules it out)."""
    return cl.meets(m, PM_DEG, GM_DB) and m.get("peak_db", 0.0) <= PEAK_DB


def _score(bws, crossovers) -> tuple[float, float]:
    """(mean log crossover, mean log predicted bandwidth) over the conditions:
    a crossover or bandwidth below the lowest line counts as 0.5 Hz, a
    bandwidth beyond the band as 500 Hz."""
    w = [0.5 if x is None else x for x in crossovers]
    b = [0.5 if x is None else min(x, 500.0) for x in bws]
    return float(np.mean(np.log(w))), float(np.mean(np.log(b)))


def search(plants: list[PlantAt], ff: float) -> tuple[float, float, dict] | None:
    """The grid's best gains meeting the margins at every speed:
    (kp, ki, {speed: predicted margins and bandwidth}) or None."""
    best, best_score = None, None
    for kp in KP_GRID:
        for wi in WI_GRID_RAD_S:
            ki = float(kp * wi)
            if ki > 5000.0:
                continue
            preds = [predict(p, float(kp), ki, ff) for p in plants]
            if not all(acceptable(m) for m, _ in preds):
                continue
            score = _score([b for _, b in preds], [m["crossover_hz"] for m, _ in preds])
            if best_score is None or score > best_score:
                best_score = score
                best = (float(kp), ki, {p.condition: {"margins": m, "bandwidth_hz": b}
                                        for p, (m, b) in zip(plants, preds)})
    return best


def tune(v: cl.Variant, conditions, measure=cl.measure_loop, log=lambda s: None) -> dict:
    """Tunes v in place; returns what the method found (for the results)."""
    if v.feedback == "none":
        return {"method": "none (open loop)"}
    plants = measure_plants(v, conditions, measure)
    found = search(plants, v.ff)
    if found is None:
        # reported with the grid's weakest loop, marked as not meeting the margins
        v.kp, v.ki = float(KP_GRID[0]), float(KP_GRID[0] * WI_GRID_RAD_S[0])
        log(f"{v.key}: no gains on the grid meet the margins in every condition")
        return {"method": "grid", "met": False, "kp": v.kp, "ki_per_s": v.ki}
    v.kp, v.ki, predicted = found
    v.kp, v.ki = float(f"{v.kp:.3g}"), float(f"{v.ki:.3g}")   # as the law's defaults hold them
    checked = {}
    for _ in range(25):
        checked = {c: measure(v, cl.scene_of(c)) for c in conditions}
        ms = {s: cl.margins(r.freq_hz, r.loop) for s, r in checked.items()}
        if all(cl.meets(m, PM_DEG, GM_DB) for m in ms.values()):
            break
        v.kp, v.ki = float(f"{0.9 * v.kp:.3g}"), float(f"{0.9 * v.ki:.3g}")
    ms = {s: cl.margins(r.freq_hz, r.loop) for s, r in checked.items()}
    log(f"{v.key}: kp {v.kp:.3g}, ki {v.ki:.3g}/s; measured "
        + ", ".join(f"{s}: PM {m['pm_deg']:.0f} deg GM {m['gm_db']:.1f} dB" for s, m in ms.items()))
    return {"method": "grid", "met": all(cl.meets(m, PM_DEG, GM_DB) for m in ms.values()),
            "kp": v.kp, "ki_per_s": v.ki, "predicted": predicted, "measured": ms,
            "loops": {s: r.to_json() for s, r in checked.items()}}
