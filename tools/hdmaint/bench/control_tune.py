"""The torque loop's tuning method (docs/results/control.md, "Tuning"), per feedback.

1. Break the loop in the simulation at every benchmark speed, with the
   output pressed against a stiff wall and with the output free (the
   conditions)
   (control_loop.measure_loop, with the variant's current gains): the plant
   the controller sees, P_fb(jw) (feedback torque per drive current), and
   the true output torque's, P_true(jw), on the same run.
2. On a grid of gains (kp, ki = kp w_i, and kd on the feedback's rate)
   compute, from P in closed form, L = C_fb P_fb (margins) and the
   predicted tracking response H = P_true (ff + C_ref) / (1 + L) (its -3 dB
   bandwidth; C_ref is C_fb without the rate term).
3. Keep the gains whose loop has phase margin >= 45 deg and gain margin
   >= 6 dB, and whose predicted tracking peak |H| is at most 10 dB, in EVERY
   condition (one set of gains for all: what the firmware runs; the free
   output is judged on the margins alone: it tracks nothing, its "response"
   is the free flexspline mode), ranked by crossover (geometric mean over
   the conditions), then predicted bandwidth.
4. Measure the chosen loop again by breaking it (its margins are the ones
   reported) and run the benchmark's stiff-wall contact with it (`contact`:
   control.wall_contact, its limit-cycle criterion); if a condition misses a
   margin (the plant's nonlinearity: friction at standstill, the stick-slip
   of a stiff contact) or the contact limit-cycles, take the next best
   candidate of the grid, up to CHECKED_MAX of them.
5. With a measure of the tracking itself (`rate`: the benchmark's chirps),
   the first RATED_MAX candidates that hold are measured, and a later one
   replaces the one kept only where it tracks better by more than the
   measure's resolution (one bin of the response): the ranking's order
   (crossover, then damping) decides between equals.  The crossover rewards a rate term
   that raises the loop gain but not the tracking (the rate acts on the
   feedback only), whose response can graze -3 dB at half the bandwidth
   of the next candidate (docs/decisions/control-bandwidth.md).
The open-loop current (feedback none) has no loop and no tuning.
"""
from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from . import control_loop as cl

PM_DEG, GM_DB = 45.0, 6.0
PEAK_DB = 10.0
KP_GRID = np.geomspace(0.05, 40.0, 48)
WI_GRID_RAD_S = 2 * math.pi * np.array([1.0, 2.0, 5.0, 10.0, 20.0, 40.0])  # ki / kp
RATED_MAX = 4             # candidates that hold, compared by `rate` (the cost: three
                          # chirps each)
CHECKED_MAX = 60          # candidates measured again, best predicted first (the first
                          # that meets the margins is taken: a variant that met within
                          # 30 is unchanged; the ideal sensor's first is its 42nd)
MARGINS_ONLY = ("free",)   # conditions judged on the margins alone
KD_GRID_S = (0.0, 5e-4, 1e-3, 1.5e-3, 2e-3, 3e-3, 4e-3)   # the feedback's rate term


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


def predict(p: PlantAt, kp: float, ki: float, ff: float,
            kd: float = 0.0) -> tuple[dict, float | None]:
    """Margins of C P_fb and the predicted tracking bandwidth; margins gets
    the tracking peak (peak_db) too.  The rate term acts on the feedback
    only: L = C_fb P_fb, H = P_true (ff + C_ref) / (1 + L)."""
    loop = cl.pi_response(p.freq_hz, kp, ki, kd) * p.p_fb
    h = p.p_true * (ff + cl.pi_response(p.freq_hz, kp, ki)) / (1.0 + loop)
    m = cl.margins(p.freq_hz, loop)
    m["peak_db"] = float(20 * np.log10(np.abs(h).max()))
    return m, bandwidth_hz(p.freq_hz, h)


def acceptable(m: dict, tracking: bool = True) -> bool:
    """The margins, and no tracking peak above PEAK_DB (a loop whose
    feedback lags can meet the margins with a proportional kick that
    overshoots many-fold: the peak rules it out).  A margins-only
    condition (the free output: nothing holds the torque, it tracks no
    setpoint; its "response" is the free flexspline mode) has no peak bound."""
    return cl.meets(m, PM_DEG, GM_DB) and (not tracking or m.get("peak_db", 0.0) <= PEAK_DB)


def _score(bws, crossovers) -> tuple[float, float]:
    """(mean log crossover, mean log predicted bandwidth) over the conditions:
    a crossover or bandwidth below the lowest line counts as 0.5 Hz, a
    bandwidth beyond the band as 500 Hz."""
    w = [0.5 if x is None else x for x in crossovers]
    b = [0.5 if x is None else min(x, 500.0) for x in bws]
    return float(np.mean(np.log(w))), float(np.mean(np.log(b)))


def candidates(plants: list[PlantAt], ff: float) -> list[tuple[float, float, float, dict]]:
    """The grid's gains meeting the margins in every condition, best first:
    (kp, ki, kd, {condition: predicted margins and bandwidth})."""
    scored = []
    tracking = [p.condition not in MARGINS_ONLY for p in plants]
    for kp, wi, kd in itertools.product(KP_GRID, WI_GRID_RAD_S, KD_GRID_S):
        ki = float(kp * wi)
        if ki > 5000.0:
            continue
        preds = [predict(p, float(kp), ki, ff, float(kd)) for p in plants]
        if not all(acceptable(m, t) for (m, _), t in zip(preds, tracking)):
            continue
        score = _score([b for (_, b), t in zip(preds, tracking) if t],
                       [m["crossover_hz"] for m, _ in preds])
        scored.append((score, (float(kp), ki, float(kd),
                               {p.condition: {"margins": m, "bandwidth_hz": b}
                                for p, (m, b) in zip(plants, preds)})))
    scored.sort(key=lambda x: x[0], reverse=True)
    return [c for _, c in scored]


def search(plants: list[PlantAt], ff: float) -> tuple[float, float, float, dict] | None:
    """The best of `candidates`, or None."""
    found = candidates(plants, ff)
    return found[0] if found else None


def _set_gains(v: cl.Variant, cand) -> None:
    """v takes the candidate's gains as the law's defaults hold them (3 digits)."""
    v.kp, v.ki, v.kd = (float(f"{x:.3g}") for x in cand[:3])


def _check(v: cl.Variant, cand, conditions, measure, contact) -> tuple[bool, dict, list]:
    """Sets v to the candidate's gains (as the law's defaults hold them) and
    measures its loop in every condition and, if it meets the margins
    there, its wall contact: (accepted, {condition: Response}, walls)."""
    _set_gains(v, cand)
    checked = {c: measure(v, cl.scene_of(c)) for c in conditions}
    if not all(cl.meets(cl.margins(r.freq_hz, r.loop), PM_DEG, GM_DB)
               for r in checked.values()):
        return False, checked, []
    walls = contact(v) if contact is not None else []
    return not any(w["limit_cycle"] for w in walls), checked, walls


def _best_rated(rated: list) -> tuple:
    """Of (score, resolution, held) in the ranking's order, the kept one:
    a later one replaces it only by more than the larger resolution."""
    keep = rated[0]
    for r in rated[1:]:
        if r[0] > keep[0] + max(r[1], keep[1]):
            keep = r
    return keep[2]


def _fallback_order(n: int, first: int) -> list[int]:
    """The candidates after the first `first` (all failed) to try, most
    conservative (the last) first, then halving toward the best: the
    crossover falls along the list, so a plant whose nonlinearity (friction,
    stick-slip) defeats the prediction near the top is met lower down in
    log2 checks, not in hundreds."""
    if n <= first:
        return []
    order, lo, hi = [n - 1], first, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        order.append(mid)
        hi = mid          # optimistic: the caller stops at the first that fails
    return order


def tune(v: cl.Variant, conditions, measure=cl.measure_loop, log=lambda s: None,
         contact=None, rate=None) -> dict:
    """Tunes v in place; returns what the method found (for the results).
    contact(v) -> a list of wall-contact results (control.wall_contact's
    dicts, each with "limit_cycle"): a candidate that meets the margins but
    limit-cycles on any of them is rejected like one that misses a margin
    (None: no contact check).  The best CHECKED_MAX candidates are checked
    in order; if none holds, the rest of the list from its conservative end
    (_fallback_order: the best that holds of the halving); if none of those
    holds either, v keeps the gains it came with and "met" is False.
    rate(v) -> (score, resolution), larger better (None: the first that
    holds is taken): of the first RATED_MAX candidates that hold, a later
    one replaces the kept one where its score is higher by more than the
    larger of the two resolutions."""
    if v.feedback == "none":
        return {"method": "none (open loop)"}
    start = (v.kp, v.ki, v.kd)
    plants = measure_plants(v, conditions, measure)
    found = candidates(plants, v.ff)
    if not found:
        # as when nothing checked holds: the gains it came with (a firmware
        # keeps what it has), marked as not meeting the margins
        log(f"{v.key}: no gains on the grid meet the margins in every condition; the gains "
            "it came with are kept")
        return {"method": "grid", "met": False, "kp": v.kp, "ki_per_s": v.ki, "kd_s": v.kd}
    checked, rejected, held, rated = {}, [], None, []
    for cand in found[:CHECKED_MAX]:
        ok, checked, walls = _check(v, cand, conditions, measure, contact)
        if ok and rate is None:
            held = (cand, checked, walls)
            break
        if ok:
            rated.append((*rate(v), (cand, checked, walls)))
            log(f"{v.key}: kp {v.kp:.3g}, ki {v.ki:.3g}/s, kd {v.kd:.3g} s holds, rated "
                f"{rated[-1][0]:.3g} +- {rated[-1][1]:.2g}")
            if len(rated) == RATED_MAX:
                break
            continue
        if walls:
            rejected.append({"kp": v.kp, "ki_per_s": v.ki, "kd_s": v.kd,
                             "wall_p2p_nm": max(w["p2p_nm"] for w in walls)})
            log(f"{v.key}: kp {v.kp:.3g}, ki {v.ki:.3g}/s, kd {v.kd:.3g} s meets the margins "
                "but limit-cycles on the wall; next")
    if rated:
        held = _best_rated(rated)
    fallback = held is None and len(found) > CHECKED_MAX
    if fallback:
        for i in _fallback_order(len(found), CHECKED_MAX):
            ok, checked, walls = _check(v, found[i], conditions, measure, contact)
            if not ok:
                break
            held = (found[i], checked, walls)
    if held is None:
        v.kp, v.ki, v.kd = start
        log(f"{v.key}: no candidate checked holds; the gains it came with are kept")
        ms = {s: cl.margins(r.freq_hz, r.loop) for s, r in checked.items()}
        return {"method": "grid", "met": False, "kp": v.kp, "ki_per_s": v.ki, "kd_s": v.kd,
                "measured": ms, "wall_rejected": rejected, "fallback": fallback}
    cand, checked, walls = held
    _set_gains(v, cand)
    ms = {s: cl.margins(r.freq_hz, r.loop) for s, r in checked.items()}
    log(f"{v.key}: kp {v.kp:.3g}, ki {v.ki:.3g}/s, kd {v.kd:.3g} s; measured "
        + ", ".join(f"{s}: PM {m['pm_deg']:.0f} deg GM {m['gm_db']:.1f} dB" for s, m in ms.items()))
    return {"method": "grid", "met": True,
            "kp": v.kp, "ki_per_s": v.ki, "kd_s": v.kd, "predicted": cand[3], "measured": ms,
            "wall": walls, "wall_rejected": rejected, "fallback": fallback,
            "loops": {s: r.to_json() for s, r in checked.items()}}
