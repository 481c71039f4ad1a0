"""Tables of the control benchmark (bench/control.py): plain text, Markdown
for the generated section of docs/results/control.md, JSON for
docs/results/control.json and the README headline row."""
from __future__ import annotations

import json
import math

from hdtools import docblock

from .control import IDEAL_LABEL

BLOCK = "control-results"
BEGIN, END = docblock.markers(BLOCK)
INTEGRAL_NOTE = "1.25x the largest open-loop back-drive torque of the transparency rows"
FRICTION_REST_NOTE = "ctrl_friction_rest_nm: the open-loop back-drive torque at the slowest row"


def clean(x):
    """JSON-safe: numpy scalars to float, inf and NaN to None (no crossover
    within the band measured), recursively."""
    if isinstance(x, dict):
        return {str(k): clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [clean(v) for v in x]
    if isinstance(x, bool) or x is None or isinstance(x, (int, str)):
        return x
    f = float(x)
    return f if math.isfinite(f) else None


def to_json(res: dict) -> str:
    return json.dumps(clean(res), indent=1) + "\n"


def _n(x, fmt="{:.1f}", none="-"):
    return none if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def _bw(chirp: dict) -> str:
    if chirp.get("above_band"):
        return f"> {chirp['bandwidth_hz']:g}"
    return _n(chirp["bandwidth_hz"], "{:.1f}", "< 1")


def tables(res: dict) -> list[tuple[str, list[str], list[list[str]]]]:
    speeds = [str(s) for s in res["speeds_rad_s"]]
    rows, out = res["rows"], []
    out.append(("The joint controller's goals against this run (benchmark numbers, not pass/fail tests)",
                ["goal", "worst", "where", "status"],
                [[g["goal"], _n(g["worst"], "{:.3g}"), g["where"],
                  g.get("status") or ("met" if g["met"] else "NOT met")]
                 for g in res["goals"]]))
    conds = sorted({c for t in res["tuning"].values() for c in t.get("measured", {})},
                   key=lambda c: (c == "wall", c))
    tab = []
    wall_kds = " / ".join(f"{c['kd_nm_s_rad']:g}" for c in res["wall"]
                          if c["torque_ki_per_s"] > 0)
    for key, t in res["tuning"].items():
        cfg = rows[key]["config"]
        what = cfg["feedback"]
        if cfg.get("sensor") == "ideal":
            what = IDEAL_LABEL
        elif cfg["feedback"] == "lowpass":
            what = f"Butterworth order {cfg['lowpass_order']}, {cfg['lowpass_hz']:g} Hz"
        elif cfg["feedback"] == "narrow":
            what = ("narrowed: raw minus the filter's artifact estimate held to the motor "
                    "angle (ctrl_artifact_hz: the law's default)")
        elif cfg["notch_mask"]:
            what = f"raw, notches at orders 2 and 4 ({cfg['notch_width_hz']:g} Hz wide)"
        if "measured" not in t:
            note = ("open loop: no loop" if cfg["feedback"] == "none"
                    else "NO (no gains on the grid meet them)")
            tab.append([key, what, "-", "-", "-"] + ["-"] * len(conds) + ["-", "-", note])
            continue
        cells = [f"{_n(t['measured'][c]['pm_deg'], '{:.0f}', 'no crossover')} / "
                 f"{_n(t['measured'][c]['gm_db'], '{:.1f}', 'no phase crossover')}"
                 for c in conds]
        walls = t.get("wall", [])
        wall = " / ".join(f"{w['p2p_nm']:.2f}" + (" (CYCLE)" if w["limit_cycle"] else "")
                          for w in walls) or "-"
        tab.append([key, what, f"{t['kp']:.3g}", f"{t['ki_per_s']:.3g}",
                    f"{1e3 * t.get('kd_s', 0.0):.3g}"] + cells
                   + [wall, str(len(t.get("wall_rejected", [])))]
                   + ["yes" if t["met"] else "NO"])
    out.append((f"Tuned gains and the margins measured by breaking the loop (phase margin deg / "
                f"gain margin dB; goal >= {res['margins']['pm_deg']:g} / "
                f">= {res['margins']['gm_db']:g}); every loop's integral within "
                f"+-{res['integral_limit_nm']:.3g} N m ({INTEGRAL_NOTE})"
                + (f"; every loop's friction compensated at rest "
                   f"{res['friction_rest_nm']:.3g} N m ({FRICTION_REST_NOTE})"
                   if res.get("friction_rest_nm") else ""),
                ["variant", "feedback", "kp", "ki [1/s]", "kd [ms]"]
                + [{"wall": "wall contact", "free": "free output"}.get(c, f"{c} rad/s")
                   for c in conds]
                + [f"stiff-wall contact peak to peak N m (IMPEDANCE kd {wall_kds}; "
                   "the goals' wall rows)",
                   "candidates rejected for a wall limit cycle", "margins met, no cycle"], tab))
    best = res["best_butterworth"]
    tab = []
    for key, r in rows.items():
        sp = r["speeds"]
        tab.append([key + (" (best low-pass)" if key == best else "")
                    + (f" ({IDEAL_LABEL})" if r["config"].get("sensor") == "ideal" else "")]
                   + [_bw(sp[s]["chirp"]) for s in speeds]
                   + [f"{_n(sp[s]['step']['overshoot_pct'], '{:.0f}')} / "
                      f"{_n(sp[s]['step']['settle_ms'], '{:.0f}')}" for s in speeds])
    out.append(("Torque tracking, true output torque against the setpoint: -3 dB bandwidth "
                "[Hz] (chirp 0.5-200 Hz, +-2 N m about 10 N m) and a 5 -> 10 N m step "
                "(overshoot % / 5 % settling ms; 1000 = not settled within 1 s)",
                ["variant"] + [f"bandwidth {s} rad/s" for s in speeds]
                + [f"step {s} rad/s" for s in speeds], tab))
    moving = [s for s in speeds if float(s) > 0]
    tab = [[key] + [_n(r["speeds"][s]["ripple"]["line2_nm"], "{:.3f}") for s in moving]
           + [_n(r["speeds"][s]["ripple"]["rms_nm"], "{:.3f}") for s in moving]
           for key, r in rows.items()]
    out.append(("Ripple in the true output torque at a constant 10 N m [N m]: the 2x "
                "motor-angle line and the rms about the mean",
                ["variant"] + [f"2x line {s} rad/s" for s in moving]
                + [f"rms {s} rad/s" for s in moving],
                tab))
    prod = res.get("product", "filtered")
    out.append(("Transparency: the torque needed to back-drive the output (ZERO_TORQUE on the "
                f"product feedback, {prod}, tuned gains) against the open-loop drive (zero current) [N m]",
                ["speed rad/s", "ZERO_TORQUE", "open-loop drive", "ratio"],
                [[s, f"{t['zero_torque_nm']:.4f}", f"{t['open_loop_nm']:.3f}",
                  f"{t['ratio']:.4f}"] for s, t in res["transparency"].items()]))
    out.append((f"Impedance (the product feedback, {prod}): rendered against commanded (stiffness: a "
                "10 N m push on the free output; damping: the slope of the torque between "
                "0.5 and 1 rad/s at kp 0; the push's deflection is the mean of the last "
                "second, over which it moves by the peak to peak)",
                ["what", "commanded", "rendered", "error %", "deflection peak to peak %"],
                [[r["kind"], f"{r['commanded']:g}", f"{r['rendered']:.2f}",
                  f"{r['error_pct']:+.1f}", _n(r.get("p2p_pct"), "{:.1f}")]
                 for r in res["impedance"]["rows"]]))
    out.append(("Contact with a 2e4 N m/rad wall (IMPEDANCE kp 500 N m/rad, the product "
                f"feedback, {prod}): the true torque over the last second",
                ["kd N m s/rad", "torque loop ki_t 1/s (IMPEDANCE runs ki_t sqrt(kp / "
                 "ctrl_integral_stiffness_nm_rad))", "mean N m", "commanded (mean) N m",
                 "the filter's torque - true N m", "peak to peak N m", "contact losses",
                 "ticks without a valid torque", "limit cycle"],
                [[f"{c['kd_nm_s_rad']:g}",
                  f"{c['torque_ki_per_s']:.3g}" + ("" if c["torque_ki_per_s"] else
                                                   " (diagnostic: the tuned kp, no integral)"),
                  f"{c['mean_nm']:.2f}", f"{c['commanded_nm']:.2f}",
                  _n(c["filtered_error_nm"], "{:+.2f}"), f"{c['p2p_nm']:.2f}",
                  str(c["contact_losses"]), str(c["invalid_ticks"]),
                  "YES" if c["limit_cycle"] else "no"]
                 for c in res["wall"]]))
    return out


def markdown(tabs) -> str:
    parts = []
    for title, head, rows in tabs:
        parts.append(f"**{title}**\n")
        parts.append("| " + " | ".join(head) + " |")
        parts.append("|" + "---|" * len(head))
        parts += ["| " + " | ".join(r) + " |" for r in rows]
        parts.append("")
    return "\n".join(parts)


def text(tabs) -> str:
    parts = []
    for title, head, rows in tabs:
        w = [max(len(str(x)) for x in col) for col in zip(head, *rows)]
        parts.append(title)
        parts.append("  ".join(h.ljust(n) for h, n in zip(head, w)))
        parts += ["  ".join(str(x).ljust(n) for x, n in zip(r, w)) for r in rows]
        parts.append("")
    return "\n".join(parts)


def headline_rows(c: dict) -> list[tuple[str, str, str]]:
    """The README's row (tools/hdmaint/headline.py)."""
    g = {x["goal"].split(" ")[0]: x for x in c["goals"]}
    bw = next(x for x in c["goals"] if x["goal"].startswith("bandwidth"))
    prod = c.get("product", "filtered")
    f = c["rows"][prod]["speeds"]
    speeds = [str(s) for s in c["speeds_rad_s"]]
    src = "[control.json](docs/results/control.json), [control.md](docs/results/control.md)"
    ratios = " / ".join(f"{bw['ratios'][s]:.2f}x" for s in speeds)
    status = lambda x: "met" if x["met"] else "**not met**"  # noqa: E731
    return [(
        "Torque loop on the simulated joint, gains from the project's own tuning "
        f"(PM >= {c['margins']['pm_deg']:g} deg, GM >= {c['margins']['gm_db']:g} dB, measured "
        "by breaking the loop)"
        + (f"; friction compensated at rest by the joint's measured back-drive torque "
           f"(`ctrl_friction_rest_nm` {c['friction_rest_nm']:.3g} N m; 0 as flashed)"
           if c.get("friction_rest_nm") else ""),
        f"{prod} feedback (the product's) -3 dB bandwidth " + " / ".join(_bw(f[s]["chirp"]) for s in speeds)
        + f" Hz at {' / '.join(speeds)} rad/s = {ratios} the best low-pass-fed loop "
        f"(goal 2x: {status(bw)}); true-torque ripple {g['true-torque']['worst']:.2f}x raw "
        f"({status(g['true-torque'])}); back-drive {g['back-drive']['worst']:.3f}x the open "
        f"loop ({status(g['back-drive'])}); stiffness within {g['rendered']['worst']:.1f} % "
        f"({status(g['rendered'])}); stiff wall {status(g['stiff-wall'])}", src)]


def splice(text_: str, md: str) -> str:
    return docblock.splice(text_, BLOCK, md, "docs/results/control.md")
