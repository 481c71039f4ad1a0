"""docs/results/control-random.md's generated part: the space of joints and the
default torque loop's margins, tracking and wall contact over the drawn
joints (hdmaint.bench.control_random), as Markdown, from the results as
stored in docs/results/control-random.json (no crossover: null)."""
from __future__ import annotations

from hdtools import docblock

from . import control_random as cr

BLOCK = "control-random-results"
BEGIN, END = docblock.markers(BLOCK)
LABELS = {cr.PRODUCT: "product: the firmware as flashed (`hdctrl-bench --defaults`)",
          cr.COMPARE: "comparison: filtered feedback, the fixed bench's tuned gains, "
                      "the rest as flashed",
          cr.AUTOTUNED: "per joint: the tuning method on the joint's own measurements at a "
                        "standstill (`control_autotune.autotune`), from the product row; the "
                        "gains below are where it starts"}
COND = {"wall": "wall contact", "free": "free output"}
TOP = 4   # the failing joints' table shows the factors of this many parameters


def _n(x, fmt="{:.1f}", none="-"):
    return none if x is None else fmt.format(x)


def _pm(x) -> str:
    return _n(None if x == float("inf") else x, "{:.0f}", "no crossover")


def _gm(x) -> str:
    return _n(None if x == float("inf") else x, "{:.1f}", "no phase crossover")


def _bw(x) -> str:
    return "< 1" if x is None or x == 0.0 else f"{x:.1f}"


def _margin_spread(pm: dict, gm: dict) -> str:
    """The median, tail and worst cells of a phase and a gain margin."""
    return (f"{_pm(pm['median'])} / {_gm(gm['median'])} | {_pm(pm['tail'])} / {_gm(gm['tail'])} | "
            f"{_pm(pm['worst'])} ({pm['worst_joint']}) / {_gm(gm['worst'])} ({gm['worst_joint']})")


def _cond(c: str) -> str:
    return COND.get(c, f"{c} rad/s")


def _pct(k: int, n: int) -> str:
    return f"{k} of {n} ({100 * k / n:.0f} %)"


def _factor(p: dict, x: float) -> str:
    return f"{x:.2f}x" if p["draw"] == "log" else f"{x:+.3f}" if p["draw"] == "add" \
        else f"{x:.2f}"


def reading(res: dict) -> list[str]:
    """One generated paragraph per row: the share within, what is missed
    most, and the parameter most tied to the least phase margin."""
    out = []
    for k, d in res["summary"].items():
        n, conds = d["joints"], d["conditions"]
        missed = sorted(((n - m["met"], c) for c, m in conds.items() if m["met"] < n),
                        reverse=True)
        cycles = {kd: w["cycles"] for kd, w in d["wall"].items() if w["cycles"]}
        parts = [f"**{k}**: {_pct(d['within'], n)} of the joints within"]
        parts += [f"margins missed in the {_cond(c)} condition on {m} of {n}" for m, c in missed]
        parts += [f"the wall cycles at kd {float(kd):g} on {c} of {n}" for kd, c in cycles.items()]
        w = d["worst_condition"]
        ref = res["default_joint"]["rows"][k]["margins"].values()
        parts.append(f"the least margins over the joints {_pm(w['pm']['worst'])} deg "
                     f"({w['pm']['worst_joint']}) and {_gm(w['gm']['worst'])} dB "
                     f"({w['gm']['worst_joint']}), the default joint's "
                     f"{_pm(min(_inf(m['pm_deg']) for m in ref))} deg and "
                     f"{_gm(min(_inf(m['gm_db']) for m in ref))} dB")
        if k == cr.PRODUCT and res["sensitivity"]:
            top = max(res["sensitivity"], key=lambda r: abs(r["rho_pm"]))
            parts.append(f"the least phase margin follows `{top['key']}` most "
                         f"(rank correlation {top['rho_pm']:+.2f})")
        out.append("; ".join(parts) + ".")
        out.append("")
    return out


def _inf(x):
    return float("inf") if x is None else x


def _least(row: dict) -> str:
    ms = row["margins"].values()
    return (f"{_pm(min(_inf(m['pm_deg']) for m in ms))} / "
            f"{_gm(min(_inf(m['gm_db']) for m in ms))}")


def ends_table(res: dict) -> list[str]:
    """The default joint with one parameter at each end of its range."""
    ends = res.get("range_ends") or []
    if not ends:
        return []
    slow = "0.5"
    out = ["", f"### One parameter at a time ({cr.PRODUCT} row)", "",
           "The default joint with one parameter at an end of its drawn range, the rest at "
           "the default: the least phase margin / gain margin over the conditions, the "
           f"bandwidth at {slow} rad/s (Hz), the wall, and whether the joint is within.", "",
           "| joint | least margins | bandwidth | wall cycles (kd) | within |",
           "|---|---|---|---|---|"]
    ref = res["default_joint"]
    for j in [ref] + ends:
        r = j["rows"][cr.PRODUCT]
        cyc = ", ".join(f"{w['kd_nm_s_rad']:g}" for w in r["wall"] if w["limit_cycle"])
        out.append(f"| {j['name']} | {_least(r)} | {_bw(r['speeds'][slow]['bandwidth_hz'])} | "
                   f"{cyc or 'none'} | {'yes' if r['within'] else '**no**'} |")
    return out


def space_table(res: dict) -> list[str]:
    rows = ["| parameter | hdctrl-bench option | default | drawn | why |", "|---|---|---|---|---|"]
    for p in res["space"]:
        drawn = {"log": f"default x log-uniform {p['lo']:g} .. {p['hi']:g}",
                 "add": f"default + uniform {p['lo']:+g} .. {p['hi']:+g}",
                 "phase": "uniform on the circle"}[p["draw"]]
        rows.append(f"| `{p['key']}` | `{p['option']}` | {p['default']:g} | {drawn} | "
                    f"{p['why']} |")
    return rows


def markdown(res: dict) -> str:
    rows, s, ref = res["rows"], res["summary"], res["default_joint"]["rows"]
    crit = res["criteria"]
    kds = " and ".join(f"{k:g}" for k in crit["wall_kds"])
    n = len(res["joints"])
    out = [f"Joints {res['seeds']} (numpy PCG64, stream [seed, {res['stream']}]); a change "
           f"this bench motivates is developed on {res['tune_seeds']}, disjoint. {n} joints and "
           f"the default one, {len(rows)} rows each, in {res['elapsed_s']:.0f} s on "
           f"{res['workers']} worker processes.", ""]
    out += reading(res)
    out += ["### The space of joints (`tools/hdmaint/bench/control_random.py`, `SPACE`)", ""]
    out += space_table(res)
    out += ["", "### What runs on every joint", "",
            "| row | what | feedback | kp | ki 1/s | kd ms | integral limit N m | "
            "friction compensation at rest N m |", "|---|---|---|---|---|---|---|---|"]
    for k, c in rows.items():
        out.append(f"| {k} | {LABELS.get(k, k)} | {c['feedback']} | {c['kp']:.3g} | "
                   f"{c['ki']:.3g} | {1e3 * c['kd']:.3g} | {c['ilim']:.3g} | "
                   f"{c['friction_rest_nm']:.3g} |")
    out += autotune_lines(res)
    out += ["", "### Within the margins and without a wall limit cycle", "",
            f"Within: phase margin >= {crit['pm_deg']:g} deg and gain margin >= "
            f"{crit['gm_db']:g} dB in every condition, and no limit cycle on the wall at "
            f"IMPEDANCE kd {kds}.", "",
            "| row | within | margins met | no wall cycle | the default joint |",
            "|---|---|---|---|---|"]
    for k, d in s.items():
        out.append(f"| {k} | **{_pct(d['within'], d['joints'])}** | "
                   f"{_pct(d['margins_met'], d['joints'])} | "
                   f"{_pct(d['no_wall_cycle'], d['joints'])} | "
                   f"{'within' if ref[k]['within'] else 'NOT within'} |")
    out += ["", "### Margins by condition (phase margin deg / gain margin dB)", "",
            "Median, 10th percentile and worst over the joints (order statistics); the worst "
            "joint in brackets; the least over the conditions per joint is the last row of "
            "each feedback.", "",
            "| row | condition | median | 10th percentile | worst | joints meeting both | "
            "the default joint |", "|---|---|---|---|---|---|---|"]
    for k, d in s.items():
        for c, m in d["conditions"].items():
            pm, gm, r = m["pm"], m["gm"], ref[k]["margins"][c]
            out.append(f"| {k} | {_cond(c)} | {_margin_spread(pm, gm)} | "
                       f"{_pct(m['met'], d['joints'])} | {_pm(r['pm_deg'])} / {_gm(r['gm_db'])} |")
        w = d["worst_condition"]
        out.append(f"| {k} | the least of every condition | {_margin_spread(w['pm'], w['gm'])} | "
                   f"{_pct(d['margins_met'], d['joints'])} | - |")
    out += ["", "### Torque tracking", "",
            "The true output torque's -3 dB bandwidth (Hz; chirp 0.5-200 Hz, +-2 N m about "
            "10 N m) and the 5 -> 10 N m step's overshoot (%): median, the 10th percentile on "
            "the bad side (bandwidth low, overshoot high), worst.", "",
            "| row | speed rad/s | bandwidth median | 10th percentile | worst | the default "
            "joint | overshoot median | 90th percentile | worst | the default joint |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for k, d in s.items():
        for sp, m in d["speeds"].items():
            b, o, r = m["bandwidth"], m["overshoot"], ref[k]["speeds"][sp]
            out.append(f"| {k} | {sp} | {_bw(b['median'])} | {_bw(b['tail'])} | "
                       f"{_bw(b['worst'])} ({b['worst_joint']}) | {_bw(r['bandwidth_hz'])} | "
                       f"{o['median']:.0f} | {o['tail']:.0f} | {o['worst']:.0f} "
                       f"({o['worst_joint']}) | {r['overshoot_pct']:.0f} |")
    out += ["", "### Stiff-wall contact", "",
            "IMPEDANCE kp 500 N m/rad toward 0.05 rad, a 2e4 N m/rad wall at 0.02 rad "
            "(`control.wall_contact`): the true torque's peak to peak over the last second "
            "(N m), the joints whose contact cycles, and how far the firmware's filtered "
            "torque is from the true one over that second (|mean error|, N m: what the "
            "contact force is off by, the loop tracking the filtered torque).", "",
            "| row | kd N m s/rad | peak to peak median | 90th percentile | worst | limit "
            "cycles | the default joint | filtered error median | 90th percentile | worst |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for k, d in s.items():
        for i, (kd, w) in enumerate(d["wall"].items()):
            p, r = w["p2p"], ref[k]["wall"][i]
            e = w.get("filtered_error")
            err = (f"{e['median']:.2f} | {e['tail']:.2f} | {e['worst']:.2f} ({e['worst_joint']})"
                   if e else "- | - | -")
            out.append(f"| {k} | {float(kd):g} | {p['median']:.2f} | {p['tail']:.2f} | "
                       f"{p['worst']:.2f} ({p['worst_joint']}) | "
                       f"{_pct(w['cycles'], d['joints'])} | {r['p2p_nm']:.2f}"
                       f"{' (cycle)' if r['limit_cycle'] else ''} | {err} |")
    out += ends_table(res)
    sens = res["sensitivity"]
    out += ["", f"### What moves the margins ({cr.PRODUCT} row)", "",
            "Spearman's rank correlation over the joints of each drawn parameter (its log "
            "factor; the kt error itself) with the joint's least phase margin, least gain "
            "margin and bandwidth at 0.5 rad/s; strongest first. With these many joints a "
            "|rho| below about 2 / sqrt(joints) is not told from none.", "",
            "| parameter | least phase margin | least gain margin | bandwidth 0.5 rad/s |",
            "|---|---|---|---|"]
    out += [f"| `{r['key']}` | {r['rho_pm']:+.2f} | {r['rho_gm']:+.2f} | "
            f"{r['rho_bandwidth']:+.2f} |" for r in sens]
    out += ["", "### Where in the space the joints outside are", "",
            "Joints within / joints drawn in each third of the drawn range (of the log "
            "factor) of the parameters that move the margins most.", "",
            "| row | parameter | " + " | ".join(["third"] * cr.BINS) + " |",
            "|---|---|" + "---|" * cr.BINS]
    for k, parts in res["by_range"].items():
        for b in parts:
            e = b["edges"]
            out.append(f"| {k} | `{b['key']}` | " + " | ".join(
                f"{e[i]:.2f}x-{e[i + 1]:.2f}x: {b['within'][i]} / {b['joints'][i]}"
                for i in range(cr.BINS)) + " |")
    top = [r["key"] for r in sens[:TOP]]
    space = {p["key"]: p for p in res["space"]}
    factors = {j["name"]: j["factors"] for j in res["joints"]}
    for k, fails in res["failures"].items():
        out += ["", f"### Joints outside ({k} row): {len(fails)}", ""]
        if not fails:
            out.append("None.")
            continue
        out += ["| joint | what it misses | " + " | ".join(f"`{t}`" for t in top) + " |",
                "|---|---|" + "---|" * len(top)]
        out += [f"| {f['name']} | {'; '.join(f['misses'])} | "
                + " | ".join(_factor(space[t], factors[f["name"]][t]) for t in top) + " |"
                for f in fails]
    return "\n".join(out) + "\n"


def autotune_lines(res: dict) -> list[str]:
    """What the per-joint tuning left on the joints (none without its row)."""
    a = res.get("autotune")
    if not a:
        return []
    n = a["joints"]
    g = {k: a[k] for k in ("kp", "ki_per_s", "kd_s")}
    return ["", f"### What the tuning on each joint chose ({cr.AUTOTUNED} row)", "",
            "Conditions measured on the joint: "
            + ", ".join("the output held at rest (the dynamometer at 0 rad/s: a fixture)"
                        if c not in COND else _cond(c) for c in cr.AUTOTUNE_CONDITIONS)
            + " (no moving dynamometer: the moving speeds are judged, not tuned on); the plant is the "
            "feedback's torque per drive current, the wall judged on the filtered torque. "
            f"Gains that hold in those conditions found on {_pct(a['met'], n)} "
            f"({a['fallback']} of them from the conservative end of the list), the defaults "
            f"kept on {_pct(a['kept_defaults'], n)}"
            + (f"; the prediction's best (steps 1-3, what `hdsense tune` prints before the "
               f"re-measurement) held on {_pct(a['first_held'], n)}" if "first_held" in a
               else "") + ".", "",
            "| gain | least | median | most (joint) |", "|---|---|---|---|",
            f"| kp | {g['kp']['min']:.3g} | {g['kp']['median']:.3g} | "
            f"{g['kp']['max']:.3g} ({g['kp']['at_max']}) |",
            f"| ki 1/s | {g['ki_per_s']['min']:.3g} | {g['ki_per_s']['median']:.3g} | "
            f"{g['ki_per_s']['max']:.3g} ({g['ki_per_s']['at_max']}) |",
            f"| kd ms | {1e3 * g['kd_s']['min']:.3g} | {1e3 * g['kd_s']['median']:.3g} | "
            f"{1e3 * g['kd_s']['max']:.3g} ({g['kd_s']['at_max']}) |"]


def splice(text: str, md: str) -> str:
    return docblock.splice(text, BLOCK, md, "docs/results/control-random.md")


def headline_rows(d: dict) -> list[tuple[str, str, str]]:
    """The README's row (tools/hdmaint/headline.py): the default loop on the
    report joints."""
    p, c = d["summary"]["product"], d["criteria"]
    bw = p["speeds"]["0.5"]["bandwidth"]
    still = d["default_joint"]["rows"]["product"]["speeds"]["0.0"]["bandwidth_hz"]
    src = ("[control-random.json](docs/results/control-random.json), "
           "[control-random.md](docs/results/control-random.md)")
    return [(
        f"The torque loop's defaults as flashed, no retuning, on {p['joints']} randomly drawn "
        f"joints of the 40 N m class ({d['seeds']}; inertias, friction, stiffness, damping, "
        "kt error, current loop, ripple and noise drawn)",
        f"PM >= {c['pm_deg']:g} deg and GM >= {c['gm_db']:g} dB in every condition with no "
        f"stiff-wall limit cycle on **{p['within']} of {p['joints']}** (margins alone "
        f"{p['margins_met']}, no wall cycle {p['no_wall_cycle']}); bandwidth at 0.5 rad/s median "
        f"{bw['median']:.0f} Hz, 10th percentile {bw['tail']:.0f} Hz; on the default joint as "
        f"flashed (no friction compensation) {_bw(still)} Hz at a standstill", src)] \
        + _autotune_row(d, src)


def _autotune_row(d: dict, src: str) -> list[tuple[str, str, str]]:
    a = d["summary"].get(cr.AUTOTUNED)
    if not a:
        return []
    bw = a["speeds"]["0.5"]["bandwidth"]
    return [(
        "The same joints, the tuning method run on each in the simulation from what a test "
        "on the joint measures at a standstill (no moving dynamometer, no true torque; on a "
        "joint: `hdsense control identify` and `hdsense tune`, step 4 by hand)",
        f"within on **{a['within']} of {a['joints']}** (margins alone {a['margins_met']}, no "
        f"wall cycle {a['no_wall_cycle']}); bandwidth at 0.5 rad/s median {bw['median']:.0f} Hz, "
        f"10th percentile {bw['tail']:.0f} Hz", src)]
