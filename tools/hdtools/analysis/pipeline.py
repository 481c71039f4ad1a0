"""The whole analysis as one function (used by the CLI, tests and the
benchmark)."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from . import augment, gear, loading, report as rep, spectra
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
    slow = float(np.median([slow_step_nm(p.torque_nm, data.ts_s) for p in data.pieces]))
    m0 = Model.starting(g["value"], data.ts_s, noise, motor_orders, output_orders, inertia_kgm2,
                        slow_step_nm=slow)
    res = augment.run_loop(data, m0, log=log)
    m1 = res["model"]
    effects = _merge(res["effects"])
    # Every identified line: amplitude in the filtered torque with the
    # starting and with the final model.
    for e in effects:
        if e["kind"] in ("motor_order", "output_order", "fixed_frequency"):
            o = e.get("order_per_motor_rev") if e["kind"] == "motor_order" else (
                e.get("order_per_output_rev") if e["kind"] == "output_order" else e["frequency_hz"])
            e["line_amplitude_in_filtered_before_nm"] = augment.line_amplitude(
                res["runs_before"], e["kind"], o)
            e["line_amplitude_in_filtered_after_nm"] = augment.line_amplitude(
                res["runs_after"], e["kind"], o)
    mb, ma = res["metrics_before"], res["metrics_after"]
    report = {
        "input": str(path),
        "gear_ratio": g,
        "data": {"samples": data.n, "pieces": len(data.pieces), "ts_s": data.ts_s,
                 "has_motor_angle": data.has_motor, "has_output_angle": data.has_output,
                 "has_truth": data.has_truth, "source": data.source, "notes": data.notes,
                 "cleaning": data.cleaning, "noise_nm": noise, "slow_step_nm": slow,
                 "torque_std_nm": float(np.std(np.concatenate([p.torque_nm for p in data.pieces])))},
        "model_before": m0.to_dict(),
        "model_after": m1.to_dict(),
        "effects": effects,
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
