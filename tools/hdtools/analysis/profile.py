"""profile.json: the artifact profile learned from a log, referenced to the
absolute angles of the log, for the firmware's profile record (issue 12).

Schema (docs/design/analyze.md "Profile"; kept simple on purpose):

  {"schema": "hdjoint-profile/1",
   "gear_ratio": N,
   "angle_convention": "...",
   "ripple_load_coeff_per_nm": k,
   "load_nm": L,
   "lines": [{"lock": "motor" | "output", "order": k, "a_nm": a, "b_nm": b}, ...],
   "source": {...}}

load_nm: the record's mean |slow torque| (measured - feed-forward, in
0.2 s blocks) where the motor turns at least 0.05 rad per sample
(loadlevel.py): the load its line amplitudes are averages at, which the
firmware's held output rows take as T_c (hd_kf.h, output_row_follow).

ripple = sum a cos(order alpha) + b sin(order alpha), alpha the absolute
motor angle (motor lines) or output angle (output lines) in rad, with the
zero of the log's motor_angle_rad / output_angle_rad columns.  Motor lines
are at zero load when k > 0 (the filter scales them by 1 + k |T|).

Output lines come from the geometry-vs-load fit (geometry.py, fold A,
checked on fold B).  Motor lines are least-squares fits of the measured
torque over fold A at the model's motor orders, kept when they explain
part of fold B's line (held-out explained fraction > 0).  A line is written
only if its angle is absolute in the log: a CSV column (or a bag's
channel, docs/how-to/ros2.md) of that angle (an
output angle derived from the motor angle, or a motor angle derived from the
output angle, has an unknown zero; a candump log's angle is an integral of
velocity)."""
from __future__ import annotations

import math

import numpy as np

from ..profile_record import SCHEMA
from . import replay as rp, spectra
from .loadlevel import load_of
CONVENTION = ("ripple_nm = sum over lines of a_nm cos(order alpha) + b_nm sin(order alpha); "
              "alpha = the absolute motor angle (lock motor) or output angle (lock output) in rad, "
              "zero and sign as the log's motor_angle_rad / output_angle_rad columns (the "
              "encoders' absolute counts); motor lines at zero load (the filter multiplies them "
              "by 1 + ripple_load_coeff_per_nm |T|)")


LOAD_SMOOTH_S = 0.2


def _smoothed(x, ts_s):
    """x averaged over LOAD_SMOOTH_S (centred; the mean of x when shorter)."""
    w = max(1, int(round(LOAD_SMOOTH_S / ts_s)))
    if len(x) <= w:
        return np.full(len(x), x.mean())
    c = np.cumsum(np.r_[0.0, x])
    return np.interp(np.arange(len(x)), np.arange(w // 2, w // 2 + len(x) - w + 1),
                     (c[w:] - c[:-w]) / w)


def _slow_torque(r):
    return np.asarray(r.torque_nm, float) - (0.0 if r.feedforward_nm is None else r.feedforward_nm)


def learned_load(view, ts_s) -> float | None:
    """loadlevel.load_of over runs with torque_nm, feedforward_nm and
    motor_angle_rad (PieceRun); None when the motor never turns fast enough."""
    return load_of(((r.torque_nm, r.feedforward_nm, r.motor_angle_rad) for r in view), ts_s)


def _motor_fit(view, order, k_load, ts_s):
    """(a, b) of the motor line in measured - feed-forward, slow torque
    (output lines included) removed, load scale divided out."""
    sig, ph, sc = [], [], []
    for r in view:
        x = _slow_torque(r)
        sig.append(x)
        ph.append(order * r.motor_angle_rad)
        if k_load > 0:
            sc.append(1 + k_load * np.abs(_smoothed(x, ts_s)))
        else:
            sc.append(np.ones(len(x)))
    hp = spectra.highpass_for_line(sig, ph, ts_s)
    y = np.concatenate(hp)
    p = np.concatenate(ph)
    s = np.concatenate(sc)
    A = np.column_stack([s * np.cos(p), s * np.sin(p)])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return float(coef[0]), float(coef[1])


def _explained(view, order, a, b, ts_s):
    sig = [np.asarray(r.torque_nm, float) for r in view]
    ph = [order * r.motor_angle_rad for r in view]
    hp = spectra.highpass_for_line(sig, ph, ts_s)
    y = np.concatenate(hp)
    p = np.concatenate(ph)
    pred = a * np.cos(p) + b * np.sin(p)
    return 1.0 - float(np.sum((y - pred) ** 2) / max(np.sum(y ** 2), 1e-30))


def build(data, model, gear, runs) -> dict:
    """The profile document (always returned, for the report) with
    `writable` and, if not, `why_not`."""
    load = learned_load(rp.analysis_view(runs), data.ts_s)
    doc = {"schema": SCHEMA, "gear_ratio": gear["value"], "angle_convention": CONVENTION,
           "ripple_load_coeff_per_nm": model.ripple_load_coeff_per_nm,
           "load_nm": None if load is None else round(load, 4), "lines": [],
           "not_written": [], "source": {"samples": data.n, "ts_s": data.ts_s}}
    csv_abs = data.source in ("csv", "bag")     # a column (a bag's channel) of that angle
    out_abs = csv_abs and data.has_output
    mot_abs = csv_abs and data.has_motor
    for p in model.profile:
        entry = {"lock": p.lock, "order": p.order, "a_nm": p.a_nm, "b_nm": p.b_nm,
                 "amplitude_nm": p.amplitude_nm, "from": "geometry-vs-load fit (fold A), "
                 "checked on fold B"}
        (doc["lines"] if out_abs else doc["not_written"]).append(entry)
    va, vb = rp.analysis_view(runs, rp.TRAIN), rp.analysis_view(runs, rp.HELD_OUT)
    for b in model.blocks:
        if b.lock != "motor" or not va or not vb:
            continue
        a_nm, b_nm = _motor_fit(va, b.order, model.ripple_load_coeff_per_nm, data.ts_s)
        expl = _explained(vb, b.order, a_nm, b_nm, data.ts_s)
        entry = {"lock": "motor", "order": b.order, "a_nm": a_nm, "b_nm": b_nm,
                 "amplitude_nm": math.hypot(a_nm, b_nm),
                 "held_out_explained_fraction": round(expl, 4),
                 "from": "least squares over fold A, checked on fold B"}
        if expl > 0 and mot_abs:
            doc["lines"].append(entry)
        else:
            entry["why_not"] = ("explains nothing of fold B's line (the phase is not steady over "
                                "the record)" if expl <= 0 else "no absolute motor angle")
            doc["not_written"].append(entry)
    why = []
    if not csv_abs:
        why.append("the log has no absolute angle (candump telemetry: the angle is an integral "
                   "of the velocity)")
    else:
        if not data.has_output and any(p.lock == "output" for p in model.profile):
            why.append("no output_angle_rad column: the output angle derived from the motor angle "
                       "has an unknown zero")
        if not data.has_motor:
            why.append("no motor_angle_rad column: motor lines have no absolute reference")
    doc["writable"] = bool(doc["lines"])
    if not doc["writable"]:
        doc["why_not"] = "; ".join(why) or "no line of the final model is verified"
    elif why:
        doc["notes"] = why
    return doc


def file_content(doc) -> dict:
    """What goes into profile.json (the schema fields only)."""
    return {"schema": doc["schema"], "gear_ratio": doc["gear_ratio"],
            "angle_convention": doc["angle_convention"],
            "ripple_load_coeff_per_nm": doc["ripple_load_coeff_per_nm"],
            "load_nm": doc["load_nm"],
            "lines": [{k: ln[k] for k in ("lock", "order", "a_nm", "b_nm")} for ln in doc["lines"]],
            "source": doc["source"]}
