"""REPORT.json, the Markdown report and the PNG plots."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from . import spectra


def _clean(o):
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, (np.floating, float)):
        f = float(o)
        return f if math.isfinite(f) else None
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o


def write_json(path, report):
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as fh:
        json.dump(_clean(report), fh, indent=2)
        fh.write("\n")


def _spectra_of(runs, ts_s):
    from .replay import analysis_view
    runs = analysis_view(runs)
    sig = [r.residual[r.warm:] for r in runs]
    thm = [r.motor_angle_rad[r.warm:] for r in runs]
    return spectra.order_spectrum(sig, thm), spectra.time_spectrum(sig, ts_s)


def plots(out_dir: Path, res, data, model_before, model_after, title=""):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out_dir.mkdir(parents=True, exist_ok=True)
    files = []
    sb = _spectra_of(res["runs_before"], data.ts_s)
    sa = _spectra_of(res["runs_after"], data.ts_s)
    for idx, (name, unit, xlabel) in enumerate(
            [("order_spectrum", "/rev", "order [cycles per motor rev]"),
             ("time_spectrum", "Hz", "frequency [Hz]")]):
        fig, ax = plt.subplots(figsize=(7, 3.2), dpi=80)
        for spec, lab in ((sb[idx], "before"), (sa[idx], "after")):
            if spec is not None:
                ax.semilogy(spec.axis[1:], spec.amplitude()[1:], lw=0.7, label=lab)
        for e in res["effects"]:
            x = e.get("order_per_motor_rev") if idx == 0 else e.get("frequency_hz")
            if x and e["added"]:
                ax.axvline(x, color="r", ls=":", lw=0.8)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("residual amplitude [N m]")
        ax.set_title(f"{title} residual {name.replace('_', ' ')}", fontsize=9)
        if idx == 0 and sb[0] is not None:
            top = max(8.0, max([b.order for b in model_after.blocks if b.lock == "motor"] or [4]) * 1.5)
            ax.set_xlim(0, top)
        ax.legend(fontsize=8)
        fig.tight_layout()
        f = out_dir / f"{name}.png"
        fig.savefig(f)
        plt.close(fig)
        files.append(f.name)
    # Torque traces: a 2 s window after warm-up of the longest piece; the
    # lower panel removes a 0.2 s moving average so the ripple is visible
    # even on a large, changing load (gravity).
    k = int(np.argmax([len(r.t_s) for r in res["runs_after"]]))
    rb, ra = res["runs_before"][k], res["runs_after"][k]
    n = min(len(ra.t_s) - ra.warm, int(2.0 / data.ts_s))
    s = slice(ra.warm, ra.warm + n)
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7, 4.6), dpi=80, sharex=True)
    t = ra.t_s[s]
    traces = [("raw", np.asarray(ra.torque_nm, float), dict(lw=0.6, color="0.6")),
              ("filtered (before)", rb.filtered, dict(lw=0.8)),
              ("filtered (after)", ra.filtered, dict(lw=0.8))]
    if ra.torque_true_nm is not None:
        traces.append(("truth", np.asarray(ra.torque_true_nm, float),
                       dict(lw=0.8, ls="--", color="k")))
    w = max(3, int(round(0.2 / data.ts_s)))
    for lab, x, kw in traces:
        ax.plot(t, x[s], label=lab, **kw)
        hp = x - np.convolve(x, np.ones(w) / w, mode="same")
        ax2.plot(t, hp[s], **kw)
    ax.set_ylabel("torque [N m]")
    ax2.set_ylabel("minus 0.2 s mean [N m]")
    ax2.set_xlabel("t [s]")
    ax.set_title(f"{title} torque", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    f = out_dir / "torque.png"
    fig.savefig(f)
    plt.close(fig)
    files.append(f.name)
    return files


def markdown(report: dict, plot_files: list[str]) -> str:
    g = report["gear_ratio"]
    L = [f"# Analysis of `{report['input']}`", ""]
    L.append(f"- samples: {report['data']['samples']} in {report['data']['pieces']} contiguous "
             f"pieces, {1 / report['data']['ts_s']:.5g} Hz")
    for n in report["data"]["notes"]:
        L.append(f"- {n}")
    L.append(f"- gear ratio: {g['value']:g} ({g['source']}"
             + (f", confidence {g['confidence']}" if "confidence" in g else "") + ")")
    L += ["", "## Error before and after each step", "",
          "| step | change | innovation RMS [N m] | filtered - expected RMS [N m] |"
          + (" error vs truth RMS [N m] |" if report.get("error_rms_before_nm") is not None else ""),
          "|---|---|---|---|" + ("---|" if report.get("error_rms_before_nm") is not None else "")]
    for h in report["history"]:
        row = (f"| {h['step']} | {h['change']} | {h['innovation_rms_nm']:.4g} | "
               f"{h['model_residual_rms_nm']:.4g} |")
        if "error_rms_nm" in h:
            row += f" {h['error_rms_nm']:.4g} |"
        L.append(row)
    L += ["", "## Lines of the final model", "",
          "Least-squares fit with one global phase (fit) and averaged-spectrum peak (spec; "
          "tolerates a drifting phase, includes the floor).", "",
          "| block | raw: fit / spec [N m] | filtered, start: fit / spec | "
          "filtered, final: fit / spec |", "|---|---|---|---|"]
    for ln in report.get("lines", []):
        L.append(f"| {ln['block']} | {ln['raw_amplitude_nm']:.3g} / {ln['spectral_raw_amplitude_nm']:.3g} | "
                 f"{ln['filtered_amplitude_before_nm']:.3g} / {ln['spectral_filtered_before_nm']:.3g} | "
                 f"{ln['filtered_amplitude_after_nm']:.3g} / {ln['spectral_filtered_after_nm']:.3g} |")
    L += ["", "## Findings", "",
          "| kind | order / frequency | amplitude [N m] | added | evidence |", "|---|---|---|---|---|"]
    for e in report["effects"]:
        where = (f"{e['order_per_motor_rev']:.4g}/motor rev = {e['order_per_output_rev']:.4g}/output rev"
                 if "order_per_motor_rev" in e else
                 f"{e['frequency_hz']:.4g} Hz" if "frequency_hz" in e else
                 ", ".join(f"{k} {v:+.3g}" for k, v in e.get("parameters", {}).items()))
        ev = e["evidence"]
        keys = ["peak_ratio_order_spectrum", "peak_ratio_time_spectrum", "band_ratio",
                "fit_explained_fraction", "partial_explained_fraction", "ambiguous",
                "line_amplitude_before_nm", "line_amplitude_after_nm",
                "envelope_load_correlation", "rejected_because", "not_added_because"]
        evs = "; ".join(f"{k}={ev[k]:.4g}" if isinstance(ev[k], float) else f"{k}={ev[k]}"
                        for k in keys if k in ev)
        L.append(f"| {e['kind']} | {where} | {e['amplitude_nm']:.3g} | {e['added']} | {evs} |")
    L += ["", "## Model", "", "Before:", "", "```", report["config_before"].rstrip(), "```",
          "", "After (written to `model.cfg`; CAN commands in `model.can`):", "", "```",
          report["config_after"].rstrip(), "```", ""]
    L += ["## Plots", ""] + [f"![{f}]({f})" for f in plot_files]
    L += ["", report["definitions"]["residual"], "", report["definitions"]["stopping_rule"], ""]
    return "\n".join(L)
