"""Per joint, each indicator over time: a robust trend (Theil-Sen slope with
its 95 % interval), a change-point test (the one split of the series that
best separates two levels), and the alarm rules of THRESHOLDS
(docs/results/fleet.md, "Alarms"; a thresholds file overrides any of them).

An alarm compares the joint's recent level (median of the records in the
last `recent_days`) with its own baseline (median of its first
`baseline_days`): every joint is its own reference, so a joint born with a
strong 2x line is not a worn one.  `first_flagged_day` evaluates the rule
causally, on the records up to each day, as a daily run would have."""
from __future__ import annotations

import json
import math

import numpy as np
from scipy import stats

from ..safeio import UsageError, read_text

# Indicator -> (record column, rule, limit).  Rules:
#   rise      recent / baseline - 1 > limit
#   drift     |recent / baseline - 1| > limit
#   shift     |recent - baseline| > limit (N m)
#   new_line  recent > max(limit N m, NEW_LINE_FACTOR x baseline)
THRESHOLDS = {
    "baseline_days": 3.0,
    "recent_days": 1.0,
    "min_baseline_records": 2,
    "new_line_factor": 3.0,
    "change_point_min_score": 8.0,
    "indicators": {
        "meshing 2x": ["motor2_amp_nm", "rise", 0.30],
        "meshing 4x": ["motor4_amp_nm", "rise", 0.30],
        "viscous friction": ["viscous_nm_s_rad", "rise", 0.50],
        "Coulomb friction": ["coulomb_nm", "rise", 0.50],
        "gauge gain": ["gain_vs_feedforward", "drift", 0.01],
        "gauge offset": ["offset_nm", "shift", 0.5],
        "new line motor 1x": ["motor1_amp_nm", "new_line", 0.05],
        "new line motor 3x": ["motor3_amp_nm", "new_line", 0.05],
        "new line output 2x": ["output2_amp_nm", "new_line", 0.05],
        "innovation (out of sample)": ["out_of_sample_innovation_rms_nm", "none", 0.0],
    },
}
RULE_TEXT = {"rise": "recent / baseline - 1 > {:g}", "drift": "|recent / baseline - 1| > {:g}",
             "shift": "|recent - baseline| > {:g} N m",
             "new_line": "recent > max({:g} N m, new_line_factor x baseline)", "none": "none"}


def load_thresholds(path=None) -> dict:
    """THRESHOLDS, with a JSON file's entries over them (UsageError on a bad file)."""
    th = json.loads(json.dumps(THRESHOLDS))
    if path is None:
        return th
    try:
        over = json.loads(read_text(path, 1 << 20))
    except ValueError as exc:
        raise UsageError(f"{path}: not JSON ({exc})") from None
    if not isinstance(over, dict):
        raise UsageError(f"{path}: expected a JSON object")
    for k, v in over.items():
        if k == "indicators":
            if not isinstance(v, dict):
                raise UsageError(f"{path}: indicators must be an object")
            for name, spec in v.items():
                if (not isinstance(spec, list) or len(spec) != 3 or spec[1] not in RULE_TEXT
                        or not isinstance(spec[2], (int, float))):
                    raise UsageError(f"{path}: indicator {name!r}: expected [column, rule, limit]"
                                     f" with rule one of {', '.join(RULE_TEXT)}")
                th["indicators"][name] = spec
        elif k in th and isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0:
            th[k] = v
        else:
            raise UsageError(f"{path}: unknown or bad entry {k!r}")
    return th


def flagged_by(rule, limit, base, recent, factor):
    if not (math.isfinite(base) and math.isfinite(recent)):
        return False
    if rule == "rise":
        return base > 0 and recent / base - 1 > limit
    if rule == "drift":
        return base != 0 and abs(recent / base - 1) > limit
    if rule == "shift":
        return abs(recent - base) > limit
    if rule == "new_line":
        return recent > max(limit, factor * base)
    return False


def change_point(days, values):
    """(day of the first record after the split, score).  The split is the
    one that leaves the least absolute deviation of each side from its own
    median (robust: one odd log does not move it); the score is the step
    between the two medians over its standard error, sigma from the pooled
    absolute deviations (scaled to a standard deviation)."""
    n = len(values)
    if n < 4:
        return None, 0.0
    best_k, best_cost = None, math.inf
    for k in range(2, n - 1):
        a, b = values[:k], values[k:]
        cost = float(np.abs(a - np.median(a)).sum() + np.abs(b - np.median(b)).sum())
        if cost < best_cost:
            best_k, best_cost = k, cost
    a, b = values[:best_k], values[best_k:]
    mad = np.r_[np.abs(a - np.median(a)), np.abs(b - np.median(b))]
    sigma = max(1.4826 * float(np.median(mad)), 1e-3 * float(np.median(np.abs(values))), 1e-12)
    score = abs(float(np.median(b) - np.median(a))) / (sigma * math.sqrt(1 / best_k + 1 / (n - best_k)))
    return float(days[best_k]), float(score)


def _levels(days, values, upto, th):
    base = values[days < days[0] + th["baseline_days"]]
    sel = (days > upto - th["recent_days"]) & (days <= upto)
    return (float(np.median(base)) if len(base) else math.nan, len(base),
            float(np.median(values[sel])) if sel.any() else math.nan)


def indicator(days, values, rule, limit, th):
    ok = np.isfinite(values)
    days, values = days[ok], values[ok]
    out = {"rule": rule, "limit": limit, "days": days.tolist(), "values": values.tolist(),
           "flagged": False, "first_flagged_day": None}
    if len(values) == 0:
        return out
    base, nbase, recent = _levels(days, values, days[-1], th)
    out.update(baseline=base, recent=recent,
               change=(recent / base - 1) if base else math.nan)
    if len(values) >= 3 and np.ptp(days) > 0:
        s = stats.theilslopes(values, days, alpha=0.95)
        out.update(slope_per_day=float(s.slope), slope_low=float(s.low_slope),
                   slope_high=float(s.high_slope))
    cp_day, score = change_point(days, values)
    out.update(change_point_day=cp_day, change_point_score=score,
               change_point=bool(score >= th["change_point_min_score"]))
    if nbase < th["min_baseline_records"]:
        out["note"] = f"baseline of {nbase} record(s): not judged"
        return out
    for d in days[days >= days[0] + th["baseline_days"]]:
        b, _, r = _levels(days, values, d, th)
        if flagged_by(rule, limit, b, r, th["new_line_factor"]):
            out["first_flagged_day"] = float(d)
            break
    out["flagged"] = flagged_by(rule, limit, base, recent, th["new_line_factor"])
    return out


def joints(rows, th) -> list[dict]:
    """rows: the store's records (status ok).  One entry per joint, flagged
    joints first (then by joint name)."""
    by = {}
    for r in rows:
        by.setdefault(r["joint"], []).append(r)
    out = []
    for name, rs in by.items():
        rs.sort(key=lambda r: r["start_day"])
        days = np.array([r["start_day"] for r in rs])
        ind = {}
        for label, (col, rule, limit) in th["indicators"].items():
            vals = np.array([np.nan if r.get(col) is None else r[col] for r in rs], float)
            ind[label] = indicator(days, vals, rule, limit, th)
        alarms = [k for k, v in ind.items() if v["flagged"]]
        out.append({"joint": name, "records": len(rs), "first_day": float(days[0]),
                    "last_day": float(days[-1]),
                    "hours": float(sum(r["duration_s"] for r in rs) / 3600.0),
                    "flagged": bool(alarms), "alarms": alarms, "indicators": ind})
    out.sort(key=lambda j: (not j["flagged"], j["joint"]))
    return out
