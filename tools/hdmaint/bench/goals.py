"""Issue 12's goals, checked from the benchmark's own results (nothing typed):
each goal, the rows it is judged on, the measured worst case, where it
occurs, and whether it is met.  The thresholds live here and nowhere else;
report.py renders the list, cli.py stores it as results["goals"].

Rows (docs/results/bench.md): `fw_commissioned` is the firmware on the classic
accuracy scenarios booted from its own commissioning profile; the `fw_*`
rows of the slow-torque part are the firmware on the slow scenarios.
"""
from __future__ import annotations

import math

# Issue 12, "Goals (benchmark numbers, not timed tests)".
SLOW_TORQUE_KNOWN_MAX_X_FLOOR = 1.5   # profile + feed-forward or motor current
LOAD_KEPT_MIN = 0.98                  # slow load kept without slow-torque information
LINE_ATTENUATION_MIN_DB = 30.0        # every modelled line
CONSTANT_SPEED_MAX_X_FLOOR = 1.05     # RMS over the noise floor at constant speed

PRODUCT_ROW = "fw_commissioned"                     # accuracy table
CONSTANT_SPEED_SCENARIOS = ("const156", "ripple_drift")
BUTTERWORTHS = ("butter_20db", "butter_40db")
# slow-torque rows, by what they were told
SLOW_KNOWN_ROWS = ("fw_profile_ff", "fw_selfprofile_ff", "fw_profile_current")
SLOW_UNKNOWN_ROWS = ("fw_profile", "fw_default")
SLOW_PROFILE_ROWS = ("fw_profile", "fw_profile_ff", "fw_profile_current", "fw_selfprofile_ff")
BOOT_FROM_PROFILE, BOOT_FROM_ZERO = "fw_profile", "fw_default"


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v)


def _acc(results, row, key):
    """[(scenario, value)] of one accuracy-table row."""
    acc = results.get("accuracy") or {}
    return [(name, sc["methods"][row][key]) for name, sc in acc.get("scenarios", {}).items()
            if row in sc["methods"] and key in sc["methods"][row]]


def _slow(results, row, key):
    """[(scenario, value)] of one slow-torque row."""
    slow = results.get("slow") or {}
    return [(name, sc["rows"][row][key]) for name, sc in slow.get("scenarios", {}).items()
            if row in sc["rows"] and key in sc["rows"][row]]


def _goal(goal, rows, pairs, worst, fmt, threshold=None, better=None) -> dict:
    """One line: the worst of pairs [(where, value)] (max or min), met if it
    is on the right side of threshold (None: reported, no threshold)."""
    pairs = [(w, v) for w, v in pairs if _finite(v)]
    out = {"goal": goal, "rows": rows, "worst": None, "where": None, "met": None,
           "n": len(pairs)}
    if not pairs:
        return out
    where, value = (max if worst == "max" else min)(pairs, key=lambda p: p[1])
    out.update(worst=value, where=where, text=fmt.format(value))
    if threshold is not None:
        out["met"] = bool(value <= threshold if better == "below" else value >= threshold)
    return out


def _vs_butterworth(results, table, row):
    """[(scenario, row RMS / best Butterworth RMS)]"""
    get = _acc if table == "accuracy" else _slow
    best = {}
    for b in BUTTERWORTHS:
        for name, v in get(results, b, "rms_nm"):
            best[name] = min(v, best.get(name, math.inf))
    return [(name, v / best[name]) for name, v in get(results, row, "rms_nm")
            if best.get(name, 0.0) > 0.0]


def _attenuations(results, table, row):
    """[("scenario: line", dB)] of every modelled line the row was scored on."""
    get = _acc if table == "accuracy" else _slow
    return [(f"{name}: {line}", db) for name, att in get(results, row, "attenuation_db")
            for line, db in att.items()]


def _constant_speed_x(results):
    ideal = dict(_acc(results, "ideal", "rms_nm"))
    return [(name, v / ideal[name]) for name, v in _acc(results, PRODUCT_ROW, "rms_nm")
            if name in CONSTANT_SPEED_SCENARIOS and ideal.get(name)]


def _steady_x(results, row):
    ideal = dict(_slow(results, "ideal", "steady_rms_nm"))
    return [(name, v / ideal[name]) for name, v in _slow(results, row, "steady_rms_nm")
            if ideal.get(name)]


def _boot_ratio(results):
    zero = dict(_slow(results, BOOT_FROM_ZERO, "first_s_rms_nm"))
    return [(name, zero[name] / v) for name, v in _slow(results, BOOT_FROM_PROFILE,
                                                          "first_s_rms_nm")
            if name in zero and v > 0.0]


def evaluate(results: dict) -> list[dict]:
    """The goals with their measured worst cases (lines whose rows did not
    run have n = 0 and worst None)."""
    g = []
    for row in SLOW_KNOWN_ROWS:
        g.append(_goal(f"profile + slow torque known: RMS <= {SLOW_TORQUE_KNOWN_MAX_X_FLOOR:g}x "
                       "the noise floor in every scenario", f"slow: {row}",
                       _slow(results, row, "x_floor"), "max", "{:.2f}x",
                       SLOW_TORQUE_KNOWN_MAX_X_FLOOR, "below"))
    g.append(_goal("no slow-torque information: never worse than the best Butterworth",
                   f"accuracy: {PRODUCT_ROW}", _vs_butterworth(results, "accuracy", PRODUCT_ROW),
                   "max", "{:.2f}x the best Butterworth", 1.0, "below"))
    for row in SLOW_UNKNOWN_ROWS:
        g.append(_goal("no slow-torque information: never worse than the best Butterworth",
                       f"slow: {row}", _vs_butterworth(results, "slow", row), "max",
                       "{:.2f}x the best Butterworth", 1.0, "below"))
    for row in SLOW_UNKNOWN_ROWS:
        g.append(_goal(f"no slow-torque information: slow load kept >= {100 * LOAD_KEPT_MIN:g} %",
                       f"slow: {row}", _slow(results, row, "load_kept"),
                       "min", "{:.1%}", LOAD_KEPT_MIN, "above"))
    g.append(_goal(f"ripple band: >= {LINE_ATTENUATION_MIN_DB:g} dB on every modelled line",
                   f"accuracy: {PRODUCT_ROW}", _attenuations(results, "accuracy", PRODUCT_ROW),
                   "min", "{:.1f} dB", LINE_ATTENUATION_MIN_DB, "above"))
    for row in SLOW_PROFILE_ROWS:
        g.append(_goal(f"ripple band: >= {LINE_ATTENUATION_MIN_DB:g} dB on every modelled line "
                       "(constant-speed windows)", f"slow: {row}",
                       _attenuations(results, "slow", row), "min", "{:.1f} dB",
                       LINE_ATTENUATION_MIN_DB, "above"))
    g.append(_goal(f"ripple band: <= {CONSTANT_SPEED_MAX_X_FLOOR:g}x the noise floor at constant "
                   "speed", f"accuracy: {PRODUCT_ROW}", _constant_speed_x(results), "max",
                   "{:.2f}x", CONSTANT_SPEED_MAX_X_FLOOR, "below"))
    for row in SLOW_PROFILE_ROWS:
        g.append(_goal(f"ripple band: <= {CONSTANT_SPEED_MAX_X_FLOOR:g}x the noise floor at "
                       "constant speed (constant-speed windows)", f"slow: {row}",
                       _steady_x(results, row), "max", "{:.2f}x", CONSTANT_SPEED_MAX_X_FLOOR,
                       "below"))
    g.append(_goal("boot with a stored profile: first-second error, boot from zero / from the "
                   "profile (reported)", f"slow: {BOOT_FROM_ZERO} / {BOOT_FROM_PROFILE}",
                   _boot_ratio(results), "min", "{:.1f}x lower"))
    return g
