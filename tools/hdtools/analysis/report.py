"""REPORT.json, the Markdown report, the PNG plots, model.cfg, model.can and
profile.json, written whole: every file goes to a temporary name first and
all are renamed at the end, so a failed or interrupted run never leaves a
mix of old and new files (known output files an earlier run left and this
run does not produce are removed)."""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from ..safeio import OutputError, Outputs as Staged
from . import profile as prof, replay as rp, spectra

PNG_SIZE_IN = (12.8, 5.0)     # at 100 dpi: 1280 px wide
PNG_DPI = 100
OUT_FILES = ("report.md", "model.cfg", "model.can", "profile.json", "order_spectrum.png",
             "output_spectrum.png", "time_spectrum.png", "torque.png", "profile.png")


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
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    return o


def json_text(obj) -> str:
    return json.dumps(_clean(obj), indent=2) + "\n"


def _writable_place(path: Path, what: str):
    """The nearest existing ancestor of path must be a writable directory."""
    p = path
    while not p.exists():
        if p.parent == p:
            break
        p = p.parent
    if not p.is_dir():
        raise OutputError(f"{what} {path}: {p} is not a directory")
    if not os.access(p, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: {p} is not writable")


class Outputs:
    """The output places, checked when constructed (before the long
    computation), written by write() at the end."""

    def __init__(self, out_dir, json_path):
        self.out_dir = Path(out_dir) if out_dir else None
        self.json_path = Path(json_path) if json_path else None
        if self.out_dir is not None:
            if self.out_dir.exists() and not self.out_dir.is_dir():
                raise OutputError(f"--out {self.out_dir}: exists and is not a directory")
            _writable_place(self.out_dir, "--out")
        if self.json_path is not None:
            if self.json_path.is_dir():
                raise OutputError(f"--json {self.json_path}: is a directory")
            _writable_place(self.json_path.parent, "--json")

    def write(self, report, res, data, model_after, title="", node_id=1):
        """Every output staged under a temporary name, then all renamed
        (hdtools.safeio.Outputs); known output files of an earlier run that
        this run does not produce are removed after."""
        with Staged() as out:
            made = set()
            if self.out_dir is not None:
                od = self.out_dir
                try:
                    od.mkdir(parents=True, exist_ok=True)
                except OSError as exc:
                    raise OutputError(f"--out {od}: cannot create: {exc.strerror}") from None
                plots = []
                for name, make in plot_makers(res, data, model_after, report, title):
                    fig = make()
                    if fig is None:
                        continue
                    with out.path(od / name) as tmp:
                        _save(fig, tmp)
                    plots.append(name)
                    made.add(name)
                texts = {"model.cfg": model_after.config_text(),
                         "model.can": can_text(report, node_id)}
                if report["profile"]["writable"]:
                    texts["profile.json"] = json_text(prof.file_content(report["profile"]))
                report["files"] = ["report.md"] + sorted(texts) + sorted(plots)
                texts["report.md"] = markdown(report, sorted(plots))
                for name, text in texts.items():
                    out.write_text(od / name, text)
                    made.add(name)
            if self.json_path is not None:
                out.write_text(self.json_path, json_text(report))
            out.commit()
        if self.out_dir is not None:
            for name in OUT_FILES:
                stale = self.out_dir / name
                if name not in made and stale.is_file():
                    try:
                        stale.unlink()
                    except OSError as exc:
                        raise OutputError(f"{stale}: cannot remove the old file: "
                                          f"{exc.strerror}") from None


def can_text(report, node_id):
    """model.can: one frame per line in plain cansend notation, then the
    meaning of each as comments after a blank line (so `grep -v '^#'`
    or reading up to the first blank line gives the frames)."""
    frames = report.get("can_commands") or []
    lines = [c["candump"] for c in frames]
    lines += ["", f"# node {node_id}: send each line above with `cansend IFACE FRAME`"]
    lines += [f"# {c['candump']}  {c['what']}" for c in frames]
    if report.get("can_error"):
        lines.append(f"# not expressible over CAN: {report['can_error']}")
    return "\n".join(lines) + "\n"


# --- plots ---------------------------------------------------------------------

def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plt.rcParams.update({"font.size": 11, "axes.titlesize": 12, "legend.fontsize": 10})
    return plt


def _save(fig, path):
    import matplotlib.pyplot as plt
    try:
        fig.tight_layout()
        fig.savefig(path, dpi=PNG_DPI, format="png")
    finally:
        plt.close(fig)


def _traces():
    """(label, signal-getter, style) for raw / reference / before / after."""
    return [("raw (measured)", lambda r: np.asarray(r.torque_nm, float), dict(color="0.55", lw=0.8)),
            ("filtered, paper model (adaptive output blocks)", lambda r: r.filtered,
             dict(color="tab:orange", lw=0.8)),
            ("filtered, starting model", lambda r: r.filtered, dict(color="tab:blue", lw=0.9)),
            ("filtered, final model", lambda r: r.filtered, dict(color="tab:green", lw=0.9))]


def _views(res):
    v = res["views"]
    return [v["before"], v["reference"], v["before"], v["after"]]


def plot_makers(res, data, m1, report, title):
    """(file name, make() -> figure or None when there is nothing to show)."""
    views = _views(res)
    traces = _traces()

    def spectrum(kind):
        def draw():
            plt = _plt()
            fig, ax = plt.subplots(figsize=PNG_SIZE_IN)
            drawn = 0
            for (lab, get, kw), view in zip(traces, views):
                sig = [get(r) for r in view]
                if kind == "time":
                    spec = spectra.time_spectrum(sig, data.ts_s)
                else:
                    ang = [r.motor_angle_rad if kind == "motor" else r.output_angle_rad
                           for r in view]
                    spec = spectra.order_spectrum(sig, ang)
                if spec is None:
                    continue
                ax.semilogy(spec.axis[1:], np.maximum(spec.amplitude()[1:], 1e-7), label=lab, **kw)
                drawn += 1
            if not drawn:
                plt.close(fig)
                return None
            if kind == "motor":
                top = max(8.0, 1.5 * max([b.order for b in m1.blocks if b.lock == "motor"] or [4]))
                ax.set_xlim(0, top)
                ax.set_xlabel("order [cycles per motor revolution]")
                marks = [e.get("order_per_motor_rev") for e in report["effects"]
                         if e["added"] and e["kind"] == "motor_order"]
            elif kind == "output":
                ax.set_xlim(0, 16)
                ax.set_xlabel("order [cycles per output revolution]")
                marks = [p.order for p in m1.profile if p.lock == "output"]
            else:
                ax.set_xlabel("frequency [Hz]")
                marks = [e.get("frequency_hz") for e in report["effects"]
                         if e["added"] and e["kind"] == "fixed_frequency"]
            for x in marks:
                if x:
                    ax.axvline(x, color="r", ls=":", lw=1.0)
            ax.set_ylabel("line amplitude [N m]")
            name = {"motor": "order spectrum over the motor angle",
                    "output": "order spectrum over the output angle",
                    "time": "time spectrum"}[kind]
            ax.set_title(f"{title}: {name} (raw torque and filtered torque; dotted: lines added)")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(loc="upper right")
            return fig
        return draw

    def torque():
        plt = _plt()
        w = res["windows"]
        wins = [w["before"], w["reference"], w["before"], w["after"]]
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(12.8, 7.2), sharex=True)
        t = w["after"]["t_s"]
        k = max(3, int(round(0.2 / data.ts_s)))

        def hp(x):
            return x - np.convolve(x, np.ones(k) / k, mode="same")
        for i, ((lab, _, kw), win) in enumerate(zip(traces, wins)):
            x = win["torque_nm"] if i == 0 else win["filtered_nm"]
            n = min(len(t), len(x))
            ax.plot(t[:n], x[:n], label=lab, **kw)
            ax2.plot(t[:n], hp(x)[:n], **kw)
        if w["after"]["true_nm"] is not None:
            x = w["after"]["true_nm"]
            ax.plot(t, x, label="truth (simulation)", color="k", ls="--", lw=1.0)
            ax2.plot(t, hp(x), color="k", ls="--", lw=1.0)
        ax.set_ylabel("torque [N m]")
        ax2.set_ylabel("torque minus its 0.2 s mean [N m]")
        ax2.set_xlabel("time [s]")
        ax.set_title(f"{title}: torque, 4 s after the warm-up of the longest stretch")
        ax.grid(True, alpha=0.3)
        ax2.grid(True, alpha=0.3)
        ax.legend(loc="upper right", ncol=2)
        return fig

    def profile_plot():
        outs = [p for p in m1.profile if p.lock == "output"]
        if not outs:
            return None
        plt = _plt()
        from . import augment
        inp = augment.profile_inputs(res["views"]["after"], m1, None)
        th = np.mod(np.concatenate(inp.angles), 2 * np.pi)
        z = np.concatenate([x - np.mean(x) for x in inp.signals])
        bins = np.linspace(0, 2 * np.pi, 73)
        idx = np.clip(np.digitize(th, bins) - 1, 0, 71)
        cnt = np.bincount(idx, minlength=72)
        mean = np.bincount(idx, weights=z, minlength=72) / np.maximum(cnt, 1)
        fig, ax = plt.subplots(figsize=PNG_SIZE_IN)
        mid = 0.5 * (bins[1:] + bins[:-1])
        ax.plot(mid[cnt > 0], mean[cnt > 0], "o", ms=4, color="0.5",
                label="residual + profile, mean per 5 deg of output angle (load included)")
        grid = np.linspace(0, 2 * np.pi, 721)
        ax.plot(grid, rp.profile_torque(m1, grid * 0, grid), color="tab:green", lw=2,
                label="fitted profile: " + ", ".join(f"order {p.order:g} {p.amplitude_nm:.3g} N m"
                                                     for p in outs))
        ax.set_xlabel("output angle mod 2 pi [rad]")
        ax.set_ylabel("torque [N m]")
        ax.set_title(f"{title}: angle-referenced output profile (geometry vs load fit)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right")
        return fig

    return [("order_spectrum.png", spectrum("motor")), ("output_spectrum.png", spectrum("output")),
            ("time_spectrum.png", spectrum("time")), ("torque.png", torque),
            ("profile.png", profile_plot)]


# --- Markdown --------------------------------------------------------------------

def fmt(x, spec=".4g", none="n/a"):
    """A number for a table; None or non-finite -> n/a (never `nan`)."""
    if x is None:
        return none
    if isinstance(x, bool):
        return str(x)
    try:
        f = float(x)
    except (TypeError, ValueError):
        return str(x)
    return format(f, spec) if math.isfinite(f) else none


def markdown(report: dict, plot_files: list[str]) -> str:
    g = report["gear_ratio"]
    d = report["data"]
    L = [f"# Analysis of `{report['input']}`", ""]
    L.append(f"- samples: {d['samples']} in {d['pieces']} contiguous pieces, "
             f"{fmt(1 / d['ts_s'], '.5g')} Hz")
    for n in d["notes"]:
        L.append(f"- {n}")
    L.append(f"- gear ratio: {fmt(g['value'], 'g')} ({g['source']}"
             + (f", confidence {g['confidence']}" if "confidence" in g else "") + ")")
    f = d["folds"]
    L.append(f"- folds: {fmt(f['in_sample_s'], '.4g')} s in-sample (A: detection and fits), "
             f"{fmt(f['out_of_sample_s'], '.4g')} s out-of-sample (B: judges every change)")
    truth = report.get("error_rms_before_nm") is not None
    L += ["", "## Every step, in-sample (A) and out-of-sample (B)", "",
          "| step | change | innovation RMS A / B [N m] | model residual RMS A / B [N m] |"
          + (" error vs truth A / B [N m] |" if truth else ""),
          "|---|---|---|---|" + ("---|" if truth else "")]
    for h in report["history"]:
        row = (f"| {h['step']} | {h['change']} | {fmt(h.get('in_sample_innovation_rms_nm'))} / "
               f"{fmt(h.get('out_of_sample_innovation_rms_nm'))} | "
               f"{fmt(h.get('in_sample_model_residual_rms_nm'))} / "
               f"{fmt(h.get('out_of_sample_model_residual_rms_nm'))} |")
        if truth:
            row += (f" {fmt(h.get('in_sample_error_rms_nm'))} / "
                    f"{fmt(h.get('out_of_sample_error_rms_nm'))} |")
        L.append(row)
    mr = report["metrics_reference"]
    L += ["", "Paper model (output lines as adaptive blocks, what the firmware runs without a "
          f"profile): innovation A / B {fmt(mr.get('in_sample_innovation_rms_nm'))} / "
          f"{fmt(mr.get('out_of_sample_innovation_rms_nm'))} N m"
          + (f", error vs truth {fmt(mr.get('error_rms_nm'))} N m" if truth else "") + "."]
    L += ["", "## Lines", "",
          "Least-squares fit with one global phase (fit) and averaged-spectrum peak (spec; "
          "tolerates a drifting phase, includes the floor).", "",
          "| line | raw: fit / spec [N m] | filtered, starting: fit / spec | "
          "filtered, final: fit / spec |", "|---|---|---|---|"]
    for ln in report.get("lines", []):
        L.append(f"| {ln['block']} | {fmt(ln['raw_amplitude_nm'], '.3g')} / "
                 f"{fmt(ln['spectral_raw_amplitude_nm'], '.3g')} | "
                 f"{fmt(ln['filtered_amplitude_before_nm'], '.3g')} / "
                 f"{fmt(ln['spectral_filtered_before_nm'], '.3g')} | "
                 f"{fmt(ln['filtered_amplitude_after_nm'], '.3g')} / "
                 f"{fmt(ln['spectral_filtered_after_nm'], '.3g')} |")
    p = report["profile"]
    L += ["", "## Angle profile (profile.json)", ""]
    if p["writable"]:
        L += ["| lock | order | a [N m] | b [N m] | amplitude [N m] |", "|---|---|---|---|---|"]
        for ln in p["lines"]:
            L.append(f"| {ln['lock']} | {fmt(ln['order'], 'g')} | {fmt(ln['a_nm'])} | "
                     f"{fmt(ln['b_nm'])} | {fmt(ln['amplitude_nm'])} |")
    else:
        L.append(f"Not written: {p.get('why_not', 'n/a')}.")
    sp = report.get("starting_profile_fit") or {}
    if sp.get("why"):
        L += ["", f"Output lines: {sp['why']}."]
    L += ["", "## Findings", "",
          "| kind | order / frequency | amplitude [N m] | kept | innovation B before -> after "
          "[N m] | evidence |", "|---|---|---|---|---|---|"]
    for e in report["effects"]:
        where = (f"{fmt(e['order_per_motor_rev'])}/motor rev = "
                 f"{fmt(e['order_per_output_rev'])}/output rev" if "order_per_motor_rev" in e else
                 f"{fmt(e['frequency_hz'])} Hz" if "frequency_hz" in e else
                 ", ".join(f"{k} {fmt(v, '+.3g')}" for k, v in e.get("parameters", {}).items()
                           if isinstance(v, (int, float))))
        ev = e["evidence"]
        keys = ["peak_ratio_order_spectrum", "peak_ratio_time_spectrum", "band_ratio",
                "fit_explained_fraction", "partial_explained_fraction", "ambiguous",
                "line_amplitude_before_nm", "line_amplitude_after_nm",
                "envelope_load_correlation", "rejected_because", "not_added_because"]
        evs = "; ".join(f"{k}={fmt(ev[k])}" for k in keys if k in ev)
        ob, oa = e.get("out_of_sample_before") or {}, e.get("out_of_sample_after") or {}
        L.append(f"| {e['kind']} | {where} | {fmt(e['amplitude_nm'], '.3g')} | {e['added']} | "
                 f"{fmt(ob.get('innovation_rms_nm'))} -> {fmt(oa.get('innovation_rms_nm'))} | "
                 f"{evs} |")
    L += ["", "## Model", "", "Starting:", "", "```", report["config_before"].rstrip(), "```",
          "", "Final (written to `model.cfg`; CAN commands in `model.can`; output lines in "
          "`profile.json`):", "", "```", report["config_after"].rstrip(), "```", ""]
    L += ["## Plots", ""] + [f"![{f}]({f})" for f in plot_files]
    L += ["", report["definitions"]["residual"], "", report["definitions"]["folds"], "",
          report["definitions"]["stopping_rule"], ""]
    return "\n".join(L)
