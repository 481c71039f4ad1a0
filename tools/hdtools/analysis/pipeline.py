"""The whole analysis as one function (used by the CLI, tests and the
benchmark)."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from . import augment, gear, loading, report as rep
from .model import Model, estimate_noise_nm, slow_step_nm

DEFINITIONS = {
    "residual": (
        "Residuals. The innovation e = (T_meas - T_exp) - C x_prior is the filter's one-step "
        "prediction error: what the model cannot predict (`residual_rms_*`). The model "
        "residual r = T_filtered - T_expected is what is left of the measured torque after "
        "removing the estimated ripple and the expected torque; un-modelled lines, friction, "
        "inertia errors and drift end up in it (and so does real load torque). Effects are "
        "detected in r. Metrics skip each piece's first 2 s (filter convergence)."),
    "stopping_rule": (
        "Stopping rule: a round tries candidates strongest first (lines, then expected-torque "
        "terms, drift last) and keeps the first that helps; the loop stops when no candidate "
        "passes detection (line: peak >= 30x the local floor and >= 0.2 % of the residual "
        "variance; slow term: >= 2 % of the slow residual variance), when every candidate was "
        "tried, or after 8 rounds."),
}


def _gear(data, given, log):
    if given is not None:
        if not given >= 1:
            raise loading.InputError(f"--gear-ratio must be >= 1 (got {given})")
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


def position_feedforward(data):
    """Position-dependent torque (gravity) on a joint that sweeps back and
    forth over less than a turn: a degree-5 polynomial in the output angle,
    fitted per segment to the measured torque, used as the expected-torque
    feed-forward (hd_pipeline's feedforward_nm).  On the robot this is the
    controller's gravity model; here it is estimated from the log.  Returns
    (list per piece or None, description)."""
    if not data.has_output:
        return None, None
    if max(np.ptp(p.output_angle_rad) for p in data.pieces) >= 2 * np.pi:
        return None, None   # turning joint: position torque is output-order lines
    by_seg = {}
    for k, p in enumerate(data.pieces):
        by_seg.setdefault(p.segment, []).append(k)
    ff = [None] * len(data.pieces)
    total, explained = 0.0, 0.0
    for seg, ks in by_seg.items():
        th = np.concatenate([data.pieces[k].output_angle_rad for k in ks])
        tq = np.concatenate([data.pieces[k].torque_nm for k in ks])
        c0, sc = float(th.mean()), float(np.ptp(th) / 2) or 1.0
        if np.ptp(th) < 1e-3 or len(th) < 10 * GRAVITY_DEGREE:
            for k in ks:
                ff[k] = np.zeros(len(data.pieces[k]))
            continue
        coef = np.polyfit((th - c0) / sc, tq, GRAVITY_DEGREE)
        for k in ks:
            ff[k] = np.polyval(coef, (data.pieces[k].output_angle_rad - c0) / sc)
        fit = np.polyval(coef, (th - c0) / sc)
        total += float(np.sum((tq - tq.mean()) ** 2))
        explained += float(np.sum((fit - tq.mean()) ** 2))
    desc = {"kind": f"polynomial of degree {GRAVITY_DEGREE} in the output angle, per segment",
            "explained_fraction_of_torque_variance": explained / total if total else 0.0,
            "note": "host-side expected torque (gravity); on the robot the controller sends "
                    "it as feed-forward, the firmware model itself has no position term"}
    return ff, desc


NOISE_GRID = (1.0, 3.0, 10.0, 30.0, 100.0)
TUNE_MAX_SAMPLES = 200_000


def _tune_subset(data, ff):
    """The first TUNE_MAX_SAMPLES samples (whole pieces) and their feed-forward."""
    from .loading import Data
    pieces, ffs, total = [], [], 0
    for k, p in enumerate(data.pieces):
        if total >= TUNE_MAX_SAMPLES:
            break
        pieces.append(p)
        ffs.append(None if ff is None else ff[k])
        total += len(p)
    sub = Data(pieces, data.ts_s, data.has_motor, data.has_output, data.has_truth, data.source)
    return sub, (None if ff is None else ffs)


def _lines_left(runs, model):
    """Sum of the averaged-spectrum amplitudes of the model's motor-locked and
    fixed lines in the filtered torque (output-locked lines are left out: at a
    joint's low output orders they may be real torque)."""
    kinds = {"motor": "motor_order", "fixed": "fixed_frequency"}
    amps = [augment.spectral_line_amplitude(runs, kinds[b.lock], b.order)
            for b in model.blocks if b.lock in kinds]
    return float(np.nansum(amps)) if amps else 0.0


def _first_near_least(table):
    """The first grid entry (grids are ordered by preference) whose
    modelled ripple left is within 25 % of the least."""
    lo = min(r["lines_left_nm"] for r in table)
    return next(r for r in table if r["lines_left_nm"] <= 1.25 * lo + 1e-12)


def tune_noise(data, ff, noise, make_model, log):
    """R of the starting model.  The third-difference noise estimate is far
    too low on logs low-pass filtered before logging (the iiwa's), and then
    the filter trusts every sample, lets its blocks chase torque changes and
    injects ripple.  So R is chosen on a grid of multiples of the estimate:
    the smallest value whose filtered torque keeps (within 25 %) the least of the model's own
    motor-locked and fixed lines (averaged-spectrum amplitude, which does
    not need a coherent phase), ties broken by the smaller multiple.  Uses
    the first TUNE_MAX_SAMPLES samples.  Output-locked lines are left out
    of the criterion: at a joint's low output orders they may be real
    torque."""
    from . import replay as rp
    sub, ffs = _tune_subset(data, ff)
    table = []
    for f in NOISE_GRID:
        m = make_model(noise * f)
        runs = rp.replay(sub, m, ffs)
        met = rp.metrics(runs)
        table.append({"noise_nm": noise * f, "lines_left_nm": _lines_left(runs, m),
                      "innovation_rms_nm": met["innovation_rms_nm"]})
    best = _first_near_least(table)   # ties: keep R small
    log(f"starting R: noise {best['noise_nm']:.3g} N m (grid of {len(NOISE_GRID)}: least "
        "modelled ripple left in the filtered torque)")
    return best["noise_nm"], table


NYQUIST_GRID = (0.9, 0.7, 0.5)


def tune_nyquist(data, ff, model, log):
    """nyquist_fraction of the starting model.  A block whose phase advance
    per sample nears pi is barely observable, and on logs low-pass filtered
    before logging (the iiwa's, 200 Hz) the line there is gone while the
    block still follows what is left: it can put a line *into* the output
    (iiwa joint 4: order 4, 0.09 -> 2.4 mN m at 0.9).  The same criterion as
    for R, on the same samples: the largest fraction whose filtered torque
    keeps (within 25 %) the least of the model's own motor-locked and fixed
    lines."""
    from . import replay as rp
    sub, ffs = _tune_subset(data, ff)
    table = []
    for f in NYQUIST_GRID:
        m = model.copy()
        m.nyquist_fraction = f
        runs = rp.replay(sub, m, ffs)
        table.append({"nyquist_fraction": f, "lines_left_nm": _lines_left(runs, m)})
    best = _first_near_least(table)   # ties: keep the default fraction
    if best["nyquist_fraction"] != model.nyquist_fraction:
        log(f"starting nyquist_fraction: {best['nyquist_fraction']:g} (least modelled ripple left)")
    return best["nyquist_fraction"], table


def _merge(effects):
    """Repeated refinements of one slow term become one finding."""
    out, slow = [], {}
    for e in effects:
        if e["kind"] in ("velocity", "acceleration") and e["added"]:
            if e["kind"] in slow:
                f = slow[e["kind"]]
                for k, v in e.get("parameters", {}).items():
                    f["parameters"][k] = f["parameters"].get(k, 0.0) + v
                f["evidence"].setdefault("refinements", 1)
                f["evidence"]["refinements"] += 1
                f["metrics_after"] = e.get("metrics_after")
                continue
            slow[e["kind"]] = e
        out.append(e)
    return out


def analyze(path, gear_ratio=None, motor_orders=(2, 4), output_orders=(1,), inertia_kgm2=0.0,
            fs_hz=None, out_dir=None, json_path=None, node_id=1, log=print):
    t0 = time.perf_counter()
    data = loading.load(path, fs_hz)
    for n in data.notes:
        log(n)
    g = _gear(data, gear_ratio, log)
    noise = float(np.median([estimate_noise_nm(p.torque_nm) for p in data.pieces]))
    ff, ff_desc = position_feedforward(data)
    if ff_desc:
        log(f"position feed-forward (gravity): {ff_desc['kind']}, explains "
            f"{100 * ff_desc['explained_fraction_of_torque_variance']:.1f} % of the torque variance")
    slow = float(np.median([slow_step_nm(p.torque_nm - (0 if ff is None else ff[k]), data.ts_s)
                            for k, p in enumerate(data.pieces)]))
    def make(nz):
        return Model.starting(g["value"], data.ts_s, nz, motor_orders, output_orders,
                              inertia_kgm2, slow_step_nm=slow)
    noise_est = noise
    noise, noise_table = tune_noise(data, ff, noise_est, make, log)
    m0 = make(noise)
    m0.nyquist_fraction, nyquist_table = tune_nyquist(data, ff, m0, log)
    res = augment.run_loop(data, m0, log=log, feedforward=ff, noise_estimate_nm=noise_est)
    from .replay import analysis_view
    vb, va = analysis_view(res["runs_before"]), analysis_view(res["runs_after"])
    m1 = res["model"]
    effects = _merge(res["effects"])
    # Every identified line: amplitude in the filtered torque with the
    # starting and with the final model.
    for e in effects:
        if e["kind"] in ("motor_order", "output_order", "fixed_frequency"):
            o = e.get("order_per_motor_rev") if e["kind"] == "motor_order" else (
                e.get("order_per_output_rev") if e["kind"] == "output_order" else e["frequency_hz"])
            e["line_amplitude_in_filtered_before_nm"] = augment.line_amplitude(vb, e["kind"], o)
            e["line_amplitude_in_filtered_after_nm"] = augment.line_amplitude(va, e["kind"], o)
    # Every line of the final model: amplitude in the raw torque and in the
    # filtered torque with the starting and the final model.
    kinds = {"motor": "motor_order", "output": "output_order", "fixed": "fixed_frequency"}
    lines = []
    for b in m1.blocks:
        k = kinds[b.lock]
        lines.append({"block": b.label(), "kind": k, "order": b.order,
                      "raw_amplitude_nm": augment.line_amplitude(vb, k, b.order, True),
                      "filtered_amplitude_before_nm": augment.line_amplitude(vb, k, b.order),
                      "filtered_amplitude_after_nm": augment.line_amplitude(va, k, b.order),
                      "spectral_raw_amplitude_nm": augment.spectral_line_amplitude(
                          vb, k, b.order, True),
                      "spectral_filtered_before_nm": augment.spectral_line_amplitude(
                          vb, k, b.order),
                      "spectral_filtered_after_nm": augment.spectral_line_amplitude(
                          va, k, b.order)})
    mb, ma = res["metrics_before"], res["metrics_after"]
    report = {
        "input": str(path),
        "gear_ratio": g,
        "data": {"samples": data.n, "pieces": len(data.pieces), "ts_s": data.ts_s,
                 "has_motor_angle": data.has_motor, "has_output_angle": data.has_output,
                 "has_truth": data.has_truth, "source": data.source, "notes": data.notes,
                 "cleaning": data.cleaning, "noise_nm": noise, "noise_estimate_nm": noise_est,
                 "noise_tuning": noise_table, "nyquist_tuning": nyquist_table,
                 "slow_step_nm": slow,
                 "torque_std_nm": float(np.std(np.concatenate([p.torque_nm for p in data.pieces])))},
        "model_before": m0.to_dict(),
        "model_after": m1.to_dict(),
        "effects": effects,
        "lines": lines,
        "position_feedforward": ff_desc,
        "residual_rms_before_nm": mb["innovation_rms_nm"],
        "residual_rms_after_nm": ma["innovation_rms_nm"],
        "model_residual_rms_before_nm": mb["model_residual_rms_nm"],
        "model_residual_rms_after_nm": ma["model_residual_rms_nm"],
        "history": res["history"],
        "config_before": m0.config_text(),
        "config_after": m1.config_text(),
        "can_commands": m1.can_commands(node_id),
        "can_not_settable": m1.not_settable_over_can(),
        "definitions": DEFINITIONS,
    }
    if "error_rms_nm" in mb:
        report["error_rms_before_nm"] = mb["error_rms_nm"]
        report["error_rms_after_nm"] = ma["error_rms_nm"]
        report["raw_error_rms_nm"] = mb["raw_error_rms_nm"]
        if "error_fast_rms_nm" in mb:
            # The error split at error_split_hz (replay.error_bands): the
            # ripple band and the slow band (output-locked lines, offset).
            report["error_split_hz"] = mb["error_split_hz"]
            for band in ("fast", "slow"):
                report[f"error_{band}_rms_before_nm"] = mb[f"error_{band}_rms_nm"]
                report[f"error_{band}_rms_after_nm"] = ma[f"error_{band}_rms_nm"]
    added = [e for e in effects if e["added"]]
    s = (f"gear ratio {g['value']:g} ({g['source']}); {len(added)} effect(s) added: "
         + (", ".join(_label(e) for e in added) or "none")
         + f"; residual RMS {mb['innovation_rms_nm']:.4g} -> {ma['innovation_rms_nm']:.4g} N m")
    if "error_rms_nm" in mb:
        s += f"; error vs truth {mb['error_rms_nm']:.4g} -> {ma['error_rms_nm']:.4g} N m"
    report["summary"] = s
    report["elapsed_s"] = time.perf_counter() - t0
    if out_dir:
        od = Path(out_dir)
        od.mkdir(parents=True, exist_ok=True)
        files = rep.plots(od, res, data, m0, m1, title=Path(path).stem)
        (od / "model.cfg").write_text(m1.config_text())
        (od / "model.can").write_text(
            "# CAN commands (candump notation, node %d); send with cansend IFACE FRAME\n" % node_id
            + "".join(f"{c['candump']}  # {c['what']}\n" for c in report["can_commands"]))
        (od / "report.md").write_text(rep.markdown(report, files))
        report["files"] = ["report.md", "model.cfg", "model.can"] + files
    if json_path:
        rep.write_json(json_path, report)
    return report


def _label(e):
    if e["kind"] == "motor_order":
        return f"motor order {e['order_per_motor_rev']:.4g}"
    if e["kind"] == "output_order":
        return f"output order {e['order_per_output_rev']:.4g}"
    if e["kind"] == "fixed_frequency":
        return f"{e['frequency_hz']:.4g} Hz line"
    if e["kind"] == "offset_drift":
        return "offset drift"
    return e["kind"] + " (" + ", ".join(f"{k} {v:+.3g}" for k, v in e.get("parameters", {}).items()) + ")"
