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

from hdtools.torque_loop import (  # noqa: F401 - the method's names for them
    GM_DB, KD_GRID_S, KP_GRID, MARGINS_ONLY, PEAK_DB, PM_DEG, WI_GRID_RAD_S, PlantAt,
    acceptable, bandwidth_hz, candidates, predict)

from . import control_loop as cl

RATED_MAX = 4             # candidates that hold, compared by `rate` (the cost: three
                          # chirps each)
CHECKED_MAX = 60          # candidates measured again, best predicted first (the first
                          # that meets the margins is taken: a variant that met within
                          # 30 is unchanged; the ideal sensor's first is its 42nd)


def measure_plants(v: cl.Variant, conditions, measure=cl.measure_loop) -> list[PlantAt]:
    out = []
    for c in conditions:
        r = measure(v, cl.scene_of(c))
        out.append(PlantAt(c, r.freq_hz, r.plant, r.true_plant))
    return out


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
    rank = next(i for i, c in enumerate(found) if c is cand) + 1
    _set_gains(v, cand)
    ms = {s: cl.margins(r.freq_hz, r.loop) for s, r in checked.items()}
    log(f"{v.key}: kp {v.kp:.3g}, ki {v.ki:.3g}/s, kd {v.kd:.3g} s; measured "
        + ", ".join(f"{s}: PM {m['pm_deg']:.0f} deg GM {m['gm_db']:.1f} dB" for s, m in ms.items()))
    return {"method": "grid", "met": True, "rank": rank,
            "kp": v.kp, "ki_per_s": v.ki, "kd_s": v.kd, "predicted": cand[3], "measured": ms,
            "wall": walls, "wall_rejected": rejected, "fallback": fallback,
            "loops": {s: r.to_json() for s, r in checked.items()}}
