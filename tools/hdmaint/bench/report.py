"""Tables (plain text and Markdown), JSON and the plot."""
from __future__ import annotations

import json
import math

import numpy as np

SCENARIO_ORDER = ["const156", "ripple_drift", "ramp", "speed_step", "reversal", "torque_step",
                  "torque_step_slow", "slow_load", "slow_load_sync", "load_ripple", "standstill"]


def _f(x, scale=1.0, fmt="{:.0f}"):
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if isinstance(x, float) and math.isinf(x):
        return "never"
    return fmt.format(x * scale)


def _get(res, sc, m, key):
    try:
        return res["scenarios"][sc]["methods"][m][key]
    except KeyError:
        return None


def _rms_cell(rms, x_floor) -> str:
    return "-" if rms is None else f"{rms * 1e3:.0f} ({x_floor:.2f}x)"


def goal_table(goals: list[dict] | None) -> list:
    """Issue 12's goals against the measured worst cases (goals.evaluate)."""
    if not goals:
        return []
    rows = [[g["goal"], g["rows"], g.get("text", "-"), g["where"] or "-",
             {True: "met", False: "NOT met", None: "reported" if g["n"] else "not run"}[g["met"]]]
            for g in goals]
    return [("The slow-torque goals against the measured worst case (tools/hdmaint/bench/goals.py)",
             ["goal", "rows", "worst case", "where", "status"], rows)]


def tables(results: dict) -> list[tuple[str, list[str], list[list[str]]]]:
    """[(title, header, rows)]"""
    acc = results.get("accuracy")
    out = goal_table(results.get("goals"))
    if acc:
        scs = [s for s in SCENARIO_ORDER if s in acc["scenarios"]]
        rows = [[m] + [_rms_cell(_get(acc, s, m, "rms_nm"), _get(acc, s, m, "x_floor"))
                       for s in scs] for m in acc["methods"]]
        out.append(("RMS error against the ripple-free truth [mN m] (x the noise floor = the "
                    "`ideal` row; simulated joint)", ["method"] + scs, rows))
        rows = []
        for m in acc["methods"]:
            r = [m]
            for sc in ("const156", "ripple_drift"):
                att = _get(acc, sc, m, "attenuation_db") or {}
                r += [_f(att.get(k), 1, "{:.1f}") for k in ("motor 2", "motor 4", "output 1")]
            rows.append(r)
        out.append(("Line attenuation [dB] (least-squares line amplitude of the error vs "
                    "unfiltered)",
                    ["method", "156: 2x", "156: 4x", "156: out 1", "drift: 2x", "drift: 4x",
                     "drift: out 1"], rows))
        rows = []
        for m in acc["methods"]:
            rows.append([m,
                         _f(_get(acc, "torque_step", m, "step0_delay_s"), 1e3),
                         _f(_get(acc, "torque_step", m, "step0_settle_s"), 1e3),
                         _f(_get(acc, "torque_step", m, "step1_settle_s"), 1e3),
                         _f(_get(acc, "torque_step_slow", m, "step0_settle_s"), 1e3),
                         _f(_get(acc, "speed_step", m, "recover_speed_change_s"), 1e3),
                         _f(_get(acc, "reversal", m, "rms_through_zero_nm"), 1e3),
                         _f(_get(acc, "standstill", m, "rms_stopped_nm"), 1e3),
                         _f(_get(acc, "standstill", m, "step0_settle_s"), 1e3),
                         _f(_get(acc, "standstill", m, "recover_restart_s"), 1e3)])
        out.append(("Dynamics [ms] and standstill [mN m]",
                    ["method", "step delay", "step up settle", "step down settle",
                     "slow-speed step settle", "speed change reconverge",
                     "through-zero RMS mNm", "stopped RMS mNm", "step while stopped settle",
                     "restart reconverge"], rows))
        out += told_table(acc)
    out += slow_tables(results.get("slow"))
    real = results.get("real")
    if real:
        rows = []
        files = list(real["files"])
        methods = list(real["files"][files[0]]["median"]) if files else []
        for m in methods:
            r = [m]
            for f in files:
                s = real["files"][f]["median"].get(m)
                if s is None:
                    r += ["-"] * 3
                    continue
                la = s["line_amplitude_nm"]
                r += [_f(max(la.values()), 1e3), _f(s["removed_rms_nm"], 1e3),
                      _f(s["removed_below_1hz_rms_nm"], 1e3)]
            rows.append(r)
        head = ["method"]
        for f in files:
            j = f.replace("iiwa_", "").replace("_constvel.csv", "")
            head += [f"{j}: max WG line", f"{j}: removed", f"{j}: removed <1 Hz"]
        out.append((f"Real iiwa logs [mN m], median over segments, second halves; WG angle = "
                    f"{real['gear_ratio_assumed']:g} x output angle (assumed)", head, rows))
    comp = results.get("compute", {}).get("host")
    if comp:
        rows = [[c["model"], str(c["states"]), c["impl"], f"{c['updates_per_s']:.3g}",
                 f"{c['ns_median']:.0f}", f"{c['time_ratio_vs_hd_kf']:.2f}",
                 f"{c['max_diff_vs_f64_nm']:.1e}"] for c in comp["compute"]]
        out.append((f"Host updates per second ({comp['steps']} steps x {comp['reps']} reps, "
                    f"median)", ["model", "states", "implementation", "updates/s", "ns/update",
                                 "time vs hd_kf", "max diff vs f64 [Nm]"], rows))
        rows = [[str(m["capacity_blocks"]), str(m["capacity_states"]), str(m["hd_kf_bytes"]),
                 str(m["pipeline_bytes"]), str(m["dense_f32_bytes"]),
                 str(m["dense_f32_stack_bytes"])] for m in comp["memory"]]
        out.append(("Filter state memory [bytes] by compile-time capacity",
                    ["HD_KF_MAX_BLOCKS", "max states", "hd_kf_t", "hd_pipeline_t",
                     "dense_kf_f32_t", "dense step stack"], rows))
    return out


def told_table(acc: dict) -> list:
    """What each firmware row of the accuracy table was told, and whether
    every run booted from its profile (profile_status 0, imports > 0)."""
    rows = []
    for key, t in acc.get("told", {}).items():
        for sc, why in t.get("pending", {}).items():
            rows.append([key, f"pending on {sc}: {why}", "-", "-", "-"])
        runs = t["summaries"].values()
        if not runs:
            continue
        booted = sum(1 for s in runs if s.get("profile_status") == "0"
                     and int(s.get("profile_imports") or 0) > 0)
        models = sorted({s.get("expected_model") or "-" for s in runs})
        joints = ", ".join(t["commissioned_joints"])
        rows.append([key, t["config"], f"{t['profile']} (joints of: {joints})", "; ".join(models),
                     f"{booted} of {len(runs)}"])
    if not rows:
        return []
    return [("What the firmware rows of the accuracy table were told (no oracle)",
             ["row", "configuration", "profile", "T_exp model in the firmware",
              "runs booted from the profile"], rows)]


def _slow_get(slow, sc, row, key):
    try:
        return slow["scenarios"][sc]["rows"][row][key]
    except KeyError:
        return None


def slow_tables(slow: dict | None) -> list:
    """The slow-torque benchmark (tools/hdmaint/bench/slow.py)."""
    if not slow:
        return []
    scs = list(slow["scenarios"])  # in the order of slow.SCENARIOS
    rows = list(slow["rows"])
    out = []

    def cell(r, s):
        return _rms_cell(_slow_get(slow, s, r, "rms_nm"), _slow_get(slow, s, r, "x_floor"))
    out.append(("Slow torque: RMS error after the first second [mN m] (x the noise floor)",
                ["row"] + scs, [[r] + [cell(r, s) for s in scs] for r in rows]))
    out.append(("Slow torque: slow load kept [%] (1 + slope of the error below 1 Hz on the "
                "load below 1 Hz, the true ripple below 1 Hz a second regressor: the raw "
                "measurement keeps 100 %)", ["row"] + scs,
                [[r] + [_f(_slow_get(slow, s, r, "load_kept"), 100, "{:.1f}") for s in scs]
                 for r in rows]))
    out.append(("Slow torque: boot, RMS error in the first second [mN m]", ["row"] + scs,
                [[r] + [_f(_slow_get(slow, s, r, "first_s_rms_nm"), 1e3) for s in scs]
                 for r in rows]))
    steady = [s for s in scs if any("attenuation_db" in m
                                    for m in slow["scenarios"][s]["rows"].values())]
    if steady:
        head, body = ["row"], []
        for s in steady:
            lines = list(slow["scenarios"][s]["rows"]["raw"]["attenuation_db"])
            head += [f"{s}: {ln}" for ln in lines] + [f"{s}: x floor"]
        for r in rows:
            line = [r]
            for s in steady:
                att = _slow_get(slow, s, r, "attenuation_db") or {}
                lines = list(slow["scenarios"][s]["rows"]["raw"]["attenuation_db"])
                line += [_f(att.get(ln), 1, "{:.0f}") for ln in lines]
                st = _slow_get(slow, s, r, "steady_rms_nm")
                fl = _slow_get(slow, s, "ideal", "steady_rms_nm")
                line.append(_f(st / fl if st is not None and fl else None, 1, "{:.2f}"))
            body.append(line)
        out.append(("Slow torque: ripple band in the constant-speed windows, line attenuation "
                    "[dB] and RMS over the noise floor", head, body))
    first = slow["scenarios"][scs[0]]["told"] if scs else {}
    told = [[r, t.get("config", "-"), t.get("profile", "-"), t.get("slow_torque", "-")]
            if "pending" not in t else [r, "pending: " + t["pending"], "-", "-"]
            for r, t in first.items()]
    if told:
        out.append((f"Slow torque: what each firmware row was told ({scs[0]}; the others "
                    "alike with their own commissioning run)",
                    ["row", "configuration", "profile", "slow torque"], told))
    return out


def text(tabs) -> str:
    lines = []
    for title, head, rows in tabs:
        w = [max(len(str(r[i])) for r in [head] + rows) for i in range(len(head))]
        lines += ["", title]
        lines.append("  ".join(h.ljust(w[i]) if i == 0 else h.rjust(w[i])
                               for i, h in enumerate(head)))
        for r in rows:
            lines.append("  ".join(str(c).ljust(w[i]) if i == 0 else str(c).rjust(w[i])
                                   for i, c in enumerate(r)))
    return "\n".join(lines)


def markdown(tabs) -> str:
    out = []
    for title, head, rows in tabs:
        out += ["", f"**{title}**", "", "| " + " | ".join(head) + " |",
                "|" + "---|" * len(head)]
        out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out) + "\n"


def to_json(results: dict) -> str:
    """results.json's text (traces left out, inf/nan as strings/null)."""
    def clean(o):
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items() if k != "traces"}
        if isinstance(o, list):
            return [clean(v) for v in o]
        if isinstance(o, float) and (math.isnan(o) or math.isinf(o)):
            return None if math.isnan(o) else ("inf" if o > 0 else "-inf")
        if isinstance(o, np.generic):
            return o.item()
        return o
    return json.dumps(clean(results), indent=1) + "\n"


PLOT_METHODS = ["kf_recommended", "fw_commissioned", "kf_paper6", "butter_20db", "order_notch",
                "fourier_table"]


def plot(results: dict, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    acc = results["accuracy"]
    fig, ax = plt.subplots(1, 2, figsize=(11, 3.8), dpi=80)
    tr = acc["traces"].get("torque_step")
    if tr:
        t = tr["t_s"]
        w = (t >= 2.9) & (t < 3.3)
        ax[0].plot(t[w], tr["raw"][w], color="0.8", lw=0.8, label="measured")
        for m in PLOT_METHODS:
            if m in tr:
                ax[0].plot(t[w], tr[m][w], lw=1, label=m)
        ax[0].plot(t[w], tr["truth"][w], "k--", lw=1, label="truth")
        ax[0].set(xlabel="t [s]", ylabel="torque [N m]",
                  title="1 -> 11 N m load step at 156 rad/s")
        ax[0].legend(fontsize=7, ncol=2)
    scs = [s for s in SCENARIO_ORDER if s in acc["scenarios"]]
    ms = [m for m in acc["methods"] if m != "raw"]
    x = np.arange(len(scs))
    wdt = 0.8 / len(ms)
    for i, m in enumerate(ms):
        v = [acc["scenarios"][s]["methods"][m]["rms_nm"] * 1e3 for s in scs]
        ax[1].bar(x + i * wdt, v, wdt, label=m)
    ax[1].set_yscale("log")
    ax[1].set_xticks(x + 0.4, scs, rotation=45, ha="right", fontsize=7)
    ax[1].set(ylabel="RMS error [mN m]", title="RMS error vs truth (log)")
    ax[1].legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)
