"""Text/JSON report in the shape of Table I of Taghirad 1997, and the plot."""
from __future__ import annotations

import math

from . import lib as L


def _f(x: float, fmt: str) -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


def to_dict(rep: L.Report, exps: list[L.ExperimentData], rc: int,
            thresholds: L.Thresholds) -> dict:
    def num(x):
        return None if math.isnan(x) else float(x)
    fits = []
    for i, e in enumerate(exps):
        f = rep.fit[i]
        fits.append({
            "experiment": e.name, "position_deg": num(f.position_deg), "n_points": f.n_points,
            "full_scale_nm": num(f.full_scale_nm), "gain_nm_per_v": num(f.gain_nm_per_v),
            "gain_se_nm_per_v": num(f.gain_se_nm_per_v), "offset_v": num(f.offset_v),
            "offset_se_v": num(f.offset_se_v), "residual_rms_v": num(f.residual_rms_v),
            "nonlinearity_pct_fs": num(f.nonlinearity_pct_fs),
            "nonlinearity_p": num(f.nonlinearity_p),
            "nonlinearity_detected": bool(f.nonlinearity_detected),
            "nonlinearity_measurable": bool(f.nonlinearity_measurable),
            "hysteresis_pct_fs": num(f.hysteresis_pct_fs), "hysteresis_p": num(f.hysteresis_p),
            "hysteresis_detected": bool(f.hysteresis_detected),
            "hysteresis_measurable": bool(f.hysteresis_measurable)})
    return {
        "experiments": fits,
        "n_experiments": len(exps),
        "gain_nm_per_v": num(rep.gain_mean_nm_per_v),
        "gain_std_nm_per_v": num(rep.gain_std_nm_per_v),
        "consistency": num(rep.consistency),
        "offset_v": num(rep.offset_mean_v),
        "nonlinearity_pct_fs": num(rep.nonlinearity_pct_fs),
        "nonlinearity_detected": bool(rep.nonlinearity_detected),
        "nonlinearity_measurable": bool(rep.nonlinearity_measurable),
        "hysteresis_pct_fs": num(rep.hysteresis_pct_fs),
        "hysteresis_detected": bool(rep.hysteresis_detected),
        "hysteresis_measurable": bool(rep.hysteresis_measurable),
        "position": {"testable": bool(rep.position_testable),
                     "detected": bool(rep.position_detected),
                     "amplitude_pct": num(rep.position_amplitude_pct),
                     "phase_deg": num(rep.position_phase_deg), "p": num(rep.position_p)},
        "accepted": bool(rep.accepted),
        "reject_reasons": L.reasons(rep.reject_reasons),
        "warning": L.strerror(rc) if rc else None,
        "thresholds": {name: float(getattr(thresholds, name)) for name, _ in L.Thresholds._fields_},
    }


def text(d: dict) -> str:
    out = []
    out.append("TORQUE SENSOR CALIBRATION RESULTS (Taghirad 1997, Table I)")
    out.append("")
    out.append(f"  {'Torque Sensor Gain':<22}{'Consistency Measure':<22}Experiments")
    cons = d["consistency"]
    out.append(f"  {_f(d['gain_nm_per_v'], '.2f') + ' Nm/Volts':<22}"
               f"{(_f(100 * cons, '.1f') + '%') if cons is not None else 'n/a':<22}"
               f"{d['n_experiments']}")
    out.append("")
    out.append("Per experiment (least squares, bridge_v = offset + torque/gain):")
    out.append(f"  {'exp':>4} {'pos deg':>7} {'FS Nm':>7} {'gain Nm/V':>10} {'+-se':>8} "
               f"{'offset mV':>9} {'+-se':>6} {'rms mV':>7} {'nonlin %FS':>11} {'hyst %FS':>9}")
    for f in d["experiments"]:
        nl = (_f(f["nonlinearity_pct_fs"], ".3f") + ("*" if f["nonlinearity_detected"] else " ")
              if f["nonlinearity_measurable"] else "n/m ")
        hy = (_f(f["hysteresis_pct_fs"], ".3f") + ("*" if f["hysteresis_detected"] else " ")
              if f["hysteresis_measurable"] else "n/m ")
        se_off = None if f["offset_se_v"] is None else 1e3 * f["offset_se_v"]
        out.append(f"  {f['experiment']:>4} {_f(f['position_deg'], '.1f'):>7} "
                   f"{_f(f['full_scale_nm'], '.2f'):>7} {_f(f['gain_nm_per_v'], '.4f'):>10} "
                   f"{_f(f['gain_se_nm_per_v'], '.4f'):>8} {_f(1e3 * f['offset_v'], '.2f'):>9} "
                   f"{_f(se_off, '.2f'):>6} {_f(1e3 * f['residual_rms_v'], '.2f'):>7} "
                   f"{nl:>11} {hy:>9}")
    out.append("  (* = significant at alpha and above the resolution floor; n/m = not measurable "
               "from this experiment's points)")
    out.append("")
    t = d["thresholds"]
    pos = d["position"]
    out.append("Extra measures:")
    out.append(f"  gain std            {_f(d['gain_std_nm_per_v'], '.4f')} Nm/V")
    out.append(f"  offset (mean)       {_f(1e3 * d['offset_v'], '.3f')} mV")
    for name, need in (("nonlinearity", ">= 3 load levels"),
                       ("hysteresis", "loading and unloading at a nonzero load")):
        n_unmeasured = sum(not f[f"{name}_measurable"] for f in d["experiments"])
        label = f"  {name:<20}"
        if d[f"{name}_pct_fs"] is None:
            out.append(f"{label}NOT MEASURABLE in any experiment (needs {need})")
            continue
        verdict = "DETECTED" if d[f"{name}_detected"] else "none detected"
        extra = (f"; NOT MEASURABLE in {n_unmeasured} of {len(d['experiments'])} experiments "
                 f"(needs {need})" if n_unmeasured else "")
        out.append(f"{label}{_f(d[f'{name}_pct_fs'], '.3f')} % FS (worst)  {verdict}{extra}")
    if pos["testable"]:
        out.append(f"  position dependence {_f(pos['amplitude_pct'], '.3f')} % of gain "
                   f"(order 2, peak at {_f(pos['phase_deg'], '.1f')} deg, p = {_f(pos['p'], '.3g')})  "
                   f"{'DETECTED' if pos['detected'] else 'not significant'}")
    else:
        out.append("  position dependence NOT MEASURABLE (needs >= 3 positions mod 180 deg "
                   "and >= 4 experiments)")
    out.append("")
    out.append(f"Limits: consistency <= {100 * t['max_consistency']:.2f} %, nonlinearity <= "
               f"{t['max_nonlinearity_pct_fs']:.2f} % FS, hysteresis <= "
               f"{t['max_hysteresis_pct_fs']:.2f} % FS, position <= {t['max_position_pct']:.2f} %, "
               f"alpha = {t['alpha']:.3g}")
    if d["warning"]:
        out.append(f"Warning: {d['warning']}")
    if d["accepted"]:
        out.append("Decision: ACCEPTED")
    else:
        out.append("Decision: REJECTED: " + "; ".join(d["reject_reasons"]))
    return "\n".join(out) + "\n"


def plot(d: dict, exps: list[L.ExperimentData], path: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, (ax, axr) = plt.subplots(2, 1, figsize=(8, 8), sharex=False,
                                  gridspec_kw={"height_ratios": [2, 1]})
    cmap = plt.get_cmap("tab10")
    for i, (e, f) in enumerate(zip(exps, d["experiments"])):
        col = cmap(i % 10)
        v = np.asarray(e.bridge_v)
        t = np.asarray(e.torque_nm)
        u = np.asarray(e.unload)
        ax.plot(v[~u], t[~u], "o", color=col, ms=4)
        ax.plot(v[u], t[u], "x", color=col, ms=5)
        vv = np.linspace(v.min(), v.max(), 2)
        g, off = f["gain_nm_per_v"], f["offset_v"]
        ax.plot(vv, g * (vv - off), "-", color=col, lw=0.8,
                label=f"{e.name} @ {e.position_deg:g} deg: {g:.3f} Nm/V")
        # Residuals against load in % of each experiment's own full scale, so
        # low- and full-range experiments overlay.
        fs = f["full_scale_nm"]
        resid = 100 * (t - g * (v - off)) / fs
        axr.plot(100 * t[~u] / fs, resid[~u], "o", color=col, ms=3)
        axr.plot(100 * t[u] / fs, resid[u], "x", color=col, ms=4)
    cons = d["consistency"]
    ax.set_title(f"Torque sensor calibration: {d['gain_nm_per_v']:.3f} Nm/V, consistency "
                 + (f"{100 * cons:.2f} %" if cons is not None else "n/a"))
    ax.set_xlabel("bridge output [V]")
    ax.set_ylabel("applied torque [Nm]")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(True, alpha=0.3)
    axr.set_xlabel("applied torque [% of the experiment's full scale]")
    axr.set_ylabel("residual [% FS]  (o load, x unload)")
    axr.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100, format="png")
    plt.close(fig)
