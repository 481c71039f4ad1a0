"""The whole analysis as one function (used by the CLI, tests and the
benchmark)."""
from __future__ import annotations

import time

import numpy as np

from . import augment, gear, geometry, loading, profile as prof, replay as rp, report as rep
from .findings import (ENVELOPE_MARGIN, ENVELOPE_NOISE_SIGMAS, ONE_SPEED_BAND,  # noqa: F401
                       ONE_SPEED_SHARE, correction_envelope, label, lines_table as _lines_table,
                       note_fixed_ambiguity as _note_fixed_ambiguity, one_speed_hz)
from .model import Model, estimate_noise_nm, slow_step_nm

DEFINITIONS = {
    "residual": (
        "Residuals. The innovation e = (T_meas - T_exp) - C x_prior is the filter's one-step "
        "prediction error: what the model cannot predict (`innovation_rms`). The model "
        "residual r = T_filtered - T_expected is what is left of the measured torque after "
        "removing the estimated ripple and the expected torque; un-modelled lines, friction, "
        "inertia errors and drift end up in it (and so does real load torque). Effects are "
        "detected in r. Metrics skip each piece's first 2 s (filter convergence)."),
    "folds": (
        "In-sample / out-of-sample. The log is cut into time blocks that alternate between "
        "fold A (in-sample: detection and every fitted number) and fold B (out-of-sample: "
        "held out). A change is kept only if fold B's innovation does not grow and fold B "
        "shows the change doing what it is for; the in-sample numbers are shown beside them."),
    "stopping_rule": (
        "Stopping rule: a round tries candidates in order (the output-angle profile, lines "
        "strongest first, expected-torque terms, drift last) and keeps the first that passes "
        "fold B; the loop stops when no candidate passes detection, when every candidate was "
        "tried, or after 8 rounds."),
}


def gear_of(data, given, log):
    """The gear ratio: given, else inferred from the encoders or the torque's
    order spectrum, else the paper's 100 (said so)."""
    if given is not None:
        return {"value": float(given), "source": "given"}
    if data.has_motor and data.has_output:
        n = gear.from_encoders(data)
        if n and n >= 1:
            return {"value": float(f"{n:.6g}"), "source": "inferred", "method": "motor/output encoder "
                    "increments (least squares)", "confidence": "high"}
    if data.has_output and not data.has_motor:
        g = gear.infer_from_spectrum(data)
        if g is not None:
            log(f"gear ratio inferred: {g['value']:g} (confidence {g['confidence']})")
            return g
    return {"value": 100.0, "source": "assumed", "confidence": "none",
            "method": "not inferable from this data (motor angle only, or no lines): "
                      "the paper's 100 is assumed"}


GRAVITY_DEGREE = 5


def position_feedforward(data, fold):
    """A stand-in for the controller's gravity model on a joint that sweeps
    back and forth over part of a turn (output-angle coverage below
    geometry.MIN_COVERAGE over the whole record, so a log split by gaps is
    judged whole) and has no torque_feedforward_nm column: a degree-5
    polynomial in the output angle, fitted on fold A (per segment where
    fold A holds enough of it, else one for the record), used as the
    expected-torque feed-forward.  It goes into T_exp only (the filtered
    torque keeps gravity); it lets the ripple blocks see the ripple instead
    of the gravity changes.  On the robot the controller sends its gravity
    model over CAN as feed-forward; the firmware has no position term.
    Returns (data with the feed-forward set, description) or (data, None)."""
    from dataclasses import replace
    if data.has_feedforward or not data.has_output:
        return data, None
    cov, _ = geometry.coverage([p.output_angle_rad for p in data.pieces])
    if cov >= geometry.MIN_COVERAGE:
        return data, None
    by_seg = {}
    for k, p in enumerate(data.pieces):
        by_seg.setdefault(p.segment, []).append(k)
    th_all = np.concatenate([p.output_angle_rad for p in data.pieces])
    c0, sc = float(th_all.mean()), float(np.ptp(th_all) / 2) or 1.0
    a_all = np.concatenate(fold) == rp.TRAIN
    tq_all = np.concatenate([p.torque_nm for p in data.pieces])
    if a_all.sum() < 10 * GRAVITY_DEGREE or np.ptp(th_all[a_all]) < 1e-3:
        return data, None
    # One polynomial for the record (the same link, the same gravity), and a
    # segment's own where fold A holds enough of it (another posture).
    common = np.polyfit((th_all[a_all] - c0) / sc, tq_all[a_all], GRAVITY_DEGREE)
    ff = [None] * len(data.pieces)
    tot = {f: 0.0 for f in (rp.TRAIN, rp.HELD_OUT)}
    expl = {f: 0.0 for f in (rp.TRAIN, rp.HELD_OUT)}
    own = 0
    for ks in by_seg.values():
        th = np.concatenate([data.pieces[k].output_angle_rad for k in ks])
        tq = np.concatenate([data.pieces[k].torque_nm for k in ks])
        fo = np.concatenate([fold[k] for k in ks])
        a = fo == rp.TRAIN
        coef = common
        if (a.sum() >= 0.2 * len(a) and a.sum() >= 10 * GRAVITY_DEGREE
                and np.ptp(th[a]) > 0.5 * np.ptp(th)):
            coef = np.polyfit((th[a] - c0) / sc, tq[a], GRAVITY_DEGREE)
            own += 1
        for k in ks:
            ff[k] = np.polyval(coef, (data.pieces[k].output_angle_rad - c0) / sc)
        fit = np.polyval(coef, (th - c0) / sc)
        for f in tot:
            m = fo == f
            if m.any():
                tot[f] += float(np.sum((tq[m] - tq[m].mean()) ** 2))
                expl[f] += float(np.sum((tq[m] - tq[m].mean()) ** 2)
                                 - np.sum((tq[m] - fit[m]) ** 2))
    pieces = [replace(p, feedforward_nm=f) for p, f in zip(data.pieces, ff)]
    out = data.subset(pieces)
    out.cleaning, out.notes = data.cleaning, data.notes
    desc = {"kind": f"polynomial of degree {GRAVITY_DEGREE} in the output angle, fitted on fold A "
                    "(per segment where fold A holds 20 % of it, else one for the record)",
            "segments_with_their_own_fit": own, "segments": len(by_seg),
            "output_angle_coverage": round(cov, 3),
            "in_sample_explained_fraction": expl[rp.TRAIN] / tot[rp.TRAIN] if tot[rp.TRAIN] else 0.0,
            "out_of_sample_explained_fraction": (expl[rp.HELD_OUT] / tot[rp.HELD_OUT]
                                                 if tot[rp.HELD_OUT] else 0.0),
            "note": "stands for the controller's gravity model (torque_feedforward_nm): on the "
                    "robot the controller sends it as CAN feed-forward; it enters the expected "
                    "torque only, so the filtered torque keeps gravity"}
    return out, desc


NOISE_GRID = (1.0, 3.0, 10.0, 30.0, 100.0)
NYQUIST_GRID = (0.9, 0.7, 0.5)
TUNE_MAX_SAMPLES = 200_000


def _tune_subset(data, fold):
    """The first TUNE_MAX_SAMPLES samples (a long piece is cut) and their
    folds: the grid is scored on their fold-A samples."""
    pieces, folds, total = [], [], 0
    for p, f in zip(data.pieces, fold):
        if total >= TUNE_MAX_SAMPLES:
            break
        k = min(len(p), TUNE_MAX_SAMPLES - total)
        if k < loading.MIN_PIECE:
            break
        sl = slice(0, k)
        pieces.append(loading.Piece(
            p.segment, p.t_s[sl], p.torque_nm[sl],
            None if p.motor_angle_rad is None else p.motor_angle_rad[sl],
            None if p.output_angle_rad is None else p.output_angle_rad[sl],
            None if p.torque_true_nm is None else p.torque_true_nm[sl],
            None, None if p.feedforward_nm is None else p.feedforward_nm[sl]))
        folds.append(f[sl])
        total += k
    return data.subset(pieces), folds


def _first_near_least(table, current, key="in_sample_innovation_rms_nm"):
    """Among the grid entries (ordered by preference) whose in-sample
    innovation (its RMS, or for R its likelihood: key) is no worse than the
    current model's (the keep rule, in fold A), the first whose modelled
    ripple left is within 25 % of the least."""
    ok = [r for r in table if r[key] <= current[key] + 1e-9 * abs(current[key])]
    ok = ok or [current]
    lo = min(r["lines_left_nm"] for r in ok)
    return next(r for r in ok if r["lines_left_nm"] <= 1.25 * lo + 1e-12)


def tune_grid(data, fold, variants, name):
    """Each variant of the model replayed over the tuning subset; the
    modelled ripple left in fold A's filtered torque (averaged-spectrum
    amplitudes of the model's motor-locked and fixed lines)."""
    sub, sfold = _tune_subset(data, fold)
    table = []
    for v, m in variants:
        runs = rp.replay(sub, m, sfold)
        view = rp.analysis_view(runs, rp.TRAIN)
        met = rp.metrics(runs, rp.TRAIN)
        table.append({name: v, "lines_left_nm": augment.lines_left(view, m),
                      "in_sample_innovation_rms_nm": met["innovation_rms_nm"],
                      "in_sample_innovation_nll": met["innovation_nll"]})
    return table


def tune(session, noise_est):
    """R and nyquist_fraction, each chosen on fold A like this: the third-
    difference noise estimate is far too low on logs low-pass filtered before
    logging (the iiwa's), and near the sample-rate Nyquist limit a block is
    barely observable; either way the blocks chase torque changes and put
    ripple *into* the output.  So each is picked on a grid (ordered by
    preference) as the first value whose filtered torque keeps within 25 %
    of the least of the model's own motor-locked and fixed lines, among the
    values that do not raise fold A's innovation, and kept only if fold B
    agrees (augment.judge, set_tuning)."""
    m = session.model
    noise_table = tune_grid(session.data, session.fold,
                            [(noise_est * f, m.with_noise(noise_est * f)) for f in NOISE_GRID],
                            "noise_nm")
    best = _first_near_least(noise_table, noise_table[0], "in_sample_innovation_nll")
    if best is not noise_table[0]:
        c = augment.detect.Candidate("tuning", best["noise_nm"], action="set_tuning",
                                     params={"noise_nm": best["noise_nm"]},
                                     evidence={"grid": noise_table})
        session.try_candidate(c)
    m = session.model
    variants = []
    for f in NYQUIST_GRID:
        mv = m.copy()
        mv.nyquist_fraction = f
        variants.append((f, mv))
    nyq_table = tune_grid(session.data, session.fold, variants, "nyquist_fraction")
    best = _first_near_least(nyq_table, nyq_table[0])
    if abs(best["nyquist_fraction"] - m.nyquist_fraction) > 1e-6:
        c = augment.detect.Candidate("tuning", best["nyquist_fraction"], action="set_tuning",
                                     params={"nyquist_fraction": best["nyquist_fraction"]},
                                     evidence={"grid": nyq_table})
        session.try_candidate(c)
    return noise_table, nyq_table


def starting_profile(data, fold, model, output_orders, log):
    """The declared output orders as a fixed angle profile (geometry.fit over
    fold A, restricted to those orders; checked on fold B).  Returns (the
    model with its output blocks replaced by that profile, the fit)."""
    m = model.copy()
    m.blocks = [b for b in m.blocks if b.lock != "output"]
    declared = sorted({int(round(o)) for o in output_orders if abs(o - round(o)) < 1e-9 and o >= 1})
    if not declared:
        return m, {"verifiable": False, "why": "no output orders declared", "orders": []}
    runs = rp.replay(data, m, fold)
    inp = augment.profile_inputs(runs, m, rp.TRAIN)
    # Selection over every candidate order (an undeclared line must not
    # push the time constant down), then the declared ones that it keeps,
    # refitted with the others as nuisance.
    g = geometry.fit(inp)
    g["declared_orders"] = declared
    selected = [o["order"] for o in g["orders"]]
    keep = [o for o in selected if int(o) in declared]
    g["selected_orders"] = selected
    if g.get("verifiable") and keep:
        g["orders"] = geometry.refit(inp, keep, g["tau_s"], selected)
        hold = augment.profile_inputs(runs, m, rp.HELD_OUT)
        without, with_ = geometry.check(hold, g["orders"], g["tau_s"], selected)
        g["out_of_sample_rms_without_nm"], g["out_of_sample_rms_with_nm"] = without, with_
        if with_ < (1 - augment.PROFILE_GAIN) * without:
            m = augment.with_profile(m, g["orders"]) or m
        else:
            g["rejected_because"] = "fold B: the profile does not lower the angle-locked residual"
    else:
        g["orders"] = []
    log("starting profile: " + (", ".join(f"output order {p.order:g} {p.amplitude_nm:.3g} N m"
                                          for p in m.profile) or
                                f"none ({g.get('why') or g.get('rejected_because') or 'no declared order verified'})"))
    return m, g


def _per_order(e, gear_ratio):
    """A profile change as one finding per output order it adds (or, for a
    refit of the same orders, per order it changes)."""
    before = e["evidence"].get("orders_before", [])
    lines = e.get("profile") or []
    fresh = [o for o in lines if o["order"] not in before] or lines
    out = []
    for o in fresh:
        f = dict(e)
        f["order_per_output_rev"] = o["order"]
        f["order_per_motor_rev"] = o["order"] / gear_ratio
        f["amplitude_nm"] = o["amplitude_nm"]
        f["parameters"] = {"a_nm": o["a_nm"], "b_nm": o["b_nm"]}
        out.append(f)
    return out


def _merge(effects, gear_ratio):
    """Repeated refinements of one slow term become one finding; a profile
    change becomes one finding per output order."""
    out, slow = [], {}
    for e in effects:
        if e.get("action") == "set_profile":
            out.extend(_per_order(e, gear_ratio))
            continue
        if e["kind"] in ("velocity", "acceleration") and e["added"]:
            if e["kind"] in slow:
                f = slow[e["kind"]]
                for k, v in e.get("parameters", {}).items():
                    f["parameters"][k] = f["parameters"].get(k, 0.0) + v
                f["evidence"].setdefault("refinements", 1)
                f["evidence"]["refinements"] += 1
                for k in ("in_sample_after", "out_of_sample_after"):
                    f[k] = e.get(k)
                continue
            slow[e["kind"]] = e
        out.append(e)
    return out


def analyze(path, gear_ratio=None, motor_orders=(2, 4), output_orders=(1,), inertia_kgm2=0.0,
            fs_hz=None, out_dir=None, json_path=None, node_id=1, log=print, time_unit=None,
            angle_unit=None, joint=None, window_ns=None, config_text=None):
    """config_text: a joint configuration whose motor-current keys
    (model.CURRENT_KEYS) the models carry, replayed and written back."""
    t0 = time.perf_counter()
    rp.REPLAYED["samples"] = 0
    outputs = rep.Outputs(out_dir, json_path)      # refuses unwritable places now
    if gear_ratio is not None and not gear_ratio >= 1:
        raise loading.InputError(f"--gear-ratio must be >= 1 (got {gear_ratio})")
    if config_text is not None:     # refused before the long computation
        _with_current(Model(1.0, 1e-3, 1.0), config_text, None, log)
    data = loading.load(path, fs_hz, time_unit, angle_unit, joint, window_ns)
    for n in data.notes:
        log(n)
    g = gear_of(data, gear_ratio, log)
    noise_est = float(np.median([estimate_noise_nm(p.torque_nm) for p in data.pieces]))
    fold = rp.folds(data)
    data, ff_desc = position_feedforward(data, fold)
    if ff_desc:
        log(f"position feed-forward (gravity stand-in): explains "
            f"{100 * ff_desc['out_of_sample_explained_fraction']:.1f} % of the held-out torque "
            "variance")
    slow = float(np.median([slow_step_nm(p.torque_nm - (0 if p.feedforward_nm is None
                                                        else p.feedforward_nm), data.ts_s)
                            for p in data.pieces]))
    # The paper's structure with the recommended tuning: output-locked lines
    # as adaptive blocks (what the firmware runs today).  Reported as the
    # reference; the analysis starts from the same model with its output
    # lines as a fixed angle profile (geometry.py).
    m_ref = Model.starting(g["value"], data.ts_s, noise_est, motor_orders, output_orders,
                           inertia_kgm2, slow_step_nm=slow)
    if config_text is not None:
        m_ref = _with_current(m_ref, config_text, data, log)
    ref_runs = rp.replay(data, m_ref, fold)
    ref_met = rp.metrics(ref_runs, bands=True)
    # The report keeps thinned copies of the reference and starting replays
    # (lines, spectra, plots), not the replays: one hour at 1 kHz is 0.1 GB
    # a replay.
    v_ref, w_ref = rp.analysis_view(ref_runs, copy=True), rp.window(ref_runs)
    del ref_runs
    m0, start_fit = starting_profile(data, fold, m_ref, output_orders, log)
    session = augment.Session(data, m0, log=log, noise_estimate_nm=noise_est,
                              output_orders=output_orders)
    met_before = rp.metrics(session.runs, bands=True)
    vb, w_b = rp.analysis_view(session.runs, copy=True), rp.window(session.runs)
    noise_table, nyq_table = tune(session, noise_est)
    session.loop()
    m1 = session.model
    met_after = rp.metrics(session.runs, bands=True)
    no_ff = _without_feedforward(data, fold, {"reference": m_ref, "after": m1})
    va = rp.analysis_view(session.runs)
    res = {"views": {"reference": v_ref, "before": vb, "after": va},
           "windows": {"reference": w_ref, "before": w_b, "after": rp.window(session.runs)},
           "effects": session.effects}
    effects = _merge(session.effects, g["value"])
    _note_fixed_ambiguity(effects, data, g["value"], log)
    for e in effects:
        if e["kind"] in ("motor_order", "output_order", "fixed_frequency"):
            o = e.get("order_per_motor_rev") if e["kind"] == "motor_order" else (
                e.get("order_per_output_rev") if e["kind"] == "output_order" else e["frequency_hz"])
            e["line_amplitude_in_filtered_before_nm"] = augment.line_amplitude(vb, e["kind"], o)
            e["line_amplitude_in_filtered_after_nm"] = augment.line_amplitude(va, e["kind"], o)
    lines = _lines_table(m_ref, m1, v_ref, vb, va)
    m1.correction_max_nm = correction_envelope(lines, _noise_of(m1))
    profile_doc = prof.build(data, m1, g, session.runs)
    report = {
        "input": str(path),
        "gear_ratio": g,
        "data": {"samples": data.n, "pieces": len(data.pieces), "ts_s": data.ts_s,
                 "has_motor_angle": data.has_motor, "has_output_angle": data.has_output,
                 "has_truth": data.has_truth, "has_feedforward": data.has_feedforward,
                 "has_motor_current": data.has_current, "units": data.units,
                 "source": data.source, "notes": data.notes, "cleaning": data.cleaning,
                 "noise_estimate_nm": noise_est, "noise_nm": _noise_of(m1),
                 "noise_tuning": noise_table, "nyquist_tuning": nyq_table, "slow_step_nm": slow,
                 "folds": _fold_summary(session),
                 "torque_std_nm": float(np.std(np.concatenate([p.torque_nm
                                                               for p in data.pieces])))},
        "model_reference": m_ref.to_dict(),
        "model_before": m0.to_dict(),
        "model_after": m1.to_dict(),
        "starting_profile_fit": start_fit,
        "effects": effects,
        "tuning": session.tuning,
        "lines": lines,
        "profile": profile_doc,
        "position_feedforward": ff_desc,
        "metrics_reference": ref_met,
        "metrics_before": met_before,
        "metrics_after": met_after,
        "metrics_without_feedforward": no_ff,
        "history": session.history,
        "config_before": m0.config_text(),
        "config_after": m1.config_text(),
        "definitions": DEFINITIONS,
    }
    try:
        report["can_commands"] = m1.can_commands(node_id)
    except ValueError as exc:    # an order CAN cannot carry (checked before adding)
        report["can_commands"] = []
        report["can_error"] = str(exc)
    for when, met in (("before", met_before), ("after", met_after)):
        report[f"residual_rms_{when}_nm"] = met["innovation_rms_nm"]
        report[f"model_residual_rms_{when}_nm"] = met["model_residual_rms_nm"]
        for f in ("in_sample", "out_of_sample"):
            report[f"{f}_residual_rms_{when}_nm"] = met[f"{f}_innovation_rms_nm"]
        if "error_rms_nm" in met:
            report[f"error_rms_{when}_nm"] = met["error_rms_nm"]
            for f in ("in_sample", "out_of_sample"):
                report[f"{f}_error_rms_{when}_nm"] = met[f"{f}_error_rms_nm"]
            if "error_fast_rms_nm" in met:
                report["error_split_hz"] = met["error_split_hz"]
                for band in ("fast", "slow"):
                    report[f"error_{band}_rms_{when}_nm"] = met[f"error_{band}_rms_nm"]
    if "error_rms_nm" in met_before:
        report["raw_error_rms_nm"] = met_before["raw_error_rms_nm"]
    added = [e for e in effects if e["added"]]
    s = (f"gear ratio {g['value']:g} ({g['source']}); {len(added)} change(s) kept: "
         + (", ".join(label(e) for e in added) or "none")
         + f"; innovation RMS in/out of sample {met_before['in_sample_innovation_rms_nm']:.4g}"
           f"/{met_before['out_of_sample_innovation_rms_nm']:.4g} -> "
           f"{met_after['in_sample_innovation_rms_nm']:.4g}"
           f"/{met_after['out_of_sample_innovation_rms_nm']:.4g} N m")
    if "error_rms_nm" in met_before:
        s += f"; error vs truth {met_before['error_rms_nm']:.4g} -> {met_after['error_rms_nm']:.4g} N m"
    report["summary"] = s
    report["elapsed_s"] = time.perf_counter() - t0
    report["data"]["replays_full_record_equivalent"] = rp.REPLAYED["samples"] / max(data.n, 1)
    outputs.write(report, res, data, m1, title=_stem(path), node_id=node_id)
    return report


def _without_feedforward(data, fold, models):
    """When the analysis had a feed-forward (the log's column or the gravity
    stand-in), the same models replayed without one: what the firmware does
    if the controller sends none (or it goes stale).  {} otherwise."""
    from dataclasses import replace
    if not any(p.feedforward_nm is not None for p in data.pieces):
        return {}
    bare = data.subset([replace(p, feedforward_nm=None) for p in data.pieces])
    out = {}
    for name, m in models.items():
        met = rp.metrics(rp.replay(bare, m, fold))
        out[name] = {k: met[k] for k in ("innovation_rms_nm", "in_sample_innovation_rms_nm",
                                         "out_of_sample_innovation_rms_nm", "error_rms_nm",
                                         "out_of_sample_error_rms_nm") if k in met}
    return out


def _with_current(model, text, data, log):
    """The model with the configuration's current term (InputError with the
    parser's message); said in the notes, and when the log cannot feed it."""
    from .model import CURRENT_KEYS
    try:
        m = model.with_config_text(text, keys=CURRENT_KEYS)
    except ValueError as exc:
        raise loading.InputError(f"--config: {exc}") from None
    if m.current_nm_per_a > 0 and data is not None:
        note = (f"motor-current term from --config (current_nm_per_a {m.current_nm_per_a:.6g}): "
                + ("replayed as the firmware runs it" if data.has_current else
                   "the log has no motor_current_a column, so it is not replayed"))
        data.notes.append(note)
        log(note)
    return m


def _stem(path):
    from pathlib import Path
    return Path(str(path)).stem


def _noise_of(model):
    return float(np.sqrt(model.r_nm2))


def _fold_summary(session):
    f = np.concatenate([x for x in session.fold])
    ts = session.data.ts_s
    return {"in_sample_s": float(np.sum(f == rp.TRAIN) * ts),
            "out_of_sample_s": float(np.sum(f == rp.HELD_OUT) * ts),
            "warmup_s": float(np.sum(f == rp.WARMUP) * ts),
            "block_s_min": rp.MIN_BLOCK_S, "max_blocks": rp.MAX_TIMELINE_BLOCKS}
