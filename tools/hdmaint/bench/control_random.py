"""Random-joint control robustness (docs/results/control-random.md): is the
torque loop's default tuning general, or tuned to one joint?

The control benchmark (control.py) tunes every feedback on ONE simulated
40 N m class joint, the runner's default plant.  Here joints are drawn
around that class (SPACE: every physical parameter hdctrl-bench takes as a
plant option, each with its range and the reason for it), and on each the
firmware's torque loop runs as flashed, with no retuning: the product row is
`hdctrl-bench --defaults` (hd_ctrl_config_default: the feedback, gains,
integral bound and friction compensation at rest the law ships with); the
comparison row is the filtered feedback with the fixed bench's tuned gains
(docs/results/control.json), everything else the same defaults; the
autotuned row is the tuning method run on the joint itself from what a test
on it measures (control_autotune).  Per
joint and row, with the control benchmark's own measurements (nothing
copied): the phase and gain margins by breaking the loop in every condition
of the tuning (control.CONDITIONS: 0, 0.5 and 3 rad/s on the dynamometer,
the stiff wall, the free output), the -3 dB bandwidth of the true torque
(control.chirp_response) and the 5 -> 10 N m step's overshoot
(control.step_response) at every benchmark speed, and the stiff-wall
contact (control.wall_contact, IMPEDANCE kp 500 at every kd of control.WALL,
its limit-cycle criterion).  A joint is within when every margin is at least
control_tune's (45 deg, 6 dB) and no wall contact cycles.

Seeds: a joint is drawn from its seed with numpy's PCG64 on the stream
[seed, STREAM].  TUNE_SEEDS are for developing any change this bench
motivates (a retuning of the defaults, a new feedback); the report is on
REPORT_SEEDS, disjoint.  The defaults come from the one default joint
(control.py); the autotuned row's method (its fallback) was developed on
TUNE_SEEDS[:24], and its gains come from each joint's own measurements.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import math
import subprocess
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from . import control
from . import control_autotune
from . import control_loop as cl
from . import control_tune as ct

ROOT = Path(__file__).resolve().parents[3]
CONTROL_JSON = ROOT / "docs" / "results" / "control.json"

TUNE_SEEDS = range(0, 1000)
REPORT_SEEDS = range(200_000, 201_000)
STREAM = 31
N_REPORT = 100          # tools/bench --only control_random (--control-joints)
JOBS = 2                # worker processes (the runner is one process per run)
PRODUCT = "product"
COMPARE = "filtered"
AUTOTUNED = control_autotune.AUTOTUNED
AUTOTUNE_CONDITIONS = control_autotune.CONDITIONS


@dataclass(frozen=True)
class Param:
    key: str            # hd_sim_joint_params_t's / the drive's / the gauge's name
    option: str         # hdctrl-bench's plant option
    draw: str           # log: the default times a log-uniform factor in [lo, hi];
                        # add: the default plus a uniform [lo, hi]; phase: uniform [lo, hi]
    lo: float
    hi: float
    why: str


PI = math.pi
# The space of joints around the 40 N m class (size-20 strain-wave gear, N = 100,
# the firmware's gear ratio; docs/reference/sim.md).  One place: the doc's range
# table is rendered from it.
SPACE = (
    Param("motor_inertia_kgm2", "--motor-inertia-kgm2", "log", 0.5, 2.0,
          "rotor and wave generator of the motors that drive a size-20 gear; the "
          "flexspline mode's frequency goes as its square root"),
    Param("motor_viscous_nm_s_rad", "--motor-viscous-nm-s-rad", "log", 0.5, 2.0,
          "grease viscosity over the operating temperature"),
    Param("motor_coulomb_nm", "--motor-coulomb-nm", "log", 0.5, 2.0,
          "no-load running torque: temperature, lubricant and unit to unit"),
    Param("motor_stribeck_nm", "--motor-stribeck-nm", "log", 0.5, 2.0,
          "break-away above it, as the running torque"),
    Param("motor_stribeck_velocity_rad_s", "--motor-stribeck-velocity-rad-s", "log", 0.5, 2.0,
          "where the break-away fades"),
    Param("stiffness_nm_rad", "--stiffness-nm-rad", "log", 0.5, 2.0,
          "the catalogue's stiffness segments of one size and the neighbouring sizes"),
    Param("damping_nm_s_rad", "--damping-nm-s-rad", "log", 0.5, 2.0,
          "the flexspline mode's damping, drawn apart from the stiffness"),
    Param("output_inertia_kgm2", "--output-inertia-kgm2", "log", 0.5, 4.0,
          "the link and what it carries: the default joint's own payload (2 kg at "
          "0.4 m, left off by the runner) is 1.6 times its link"),
    Param("output_viscous_nm_s_rad", "--output-viscous-nm-s-rad", "log", 0.5, 2.0,
          "the output bearing"),
    Param("mesh_ripple_nm", "--mesh-ripple-nm", "log", 0.5, 2.0,
          "gear quality: the real meshing ripple"),
    Param("mesh_ripple_phase_rad", "--mesh-ripple-phase-rad", "phase", -PI, PI,
          "assembly"),
    Param("gauge_ripple_nm", "--gauge-ripple-nm", "log", 0.5, 2.0,
          "the gauges' placement: the sensing artifact"),
    Param("gauge_ripple_phase_rad", "--gauge-ripple-phase-rad", "phase", -PI, PI,
          "assembly"),
    Param("kt_error", "--kt-error", "add", -0.1, 0.1,
          "the motor's torque constant against its datasheet: tolerance and magnet "
          "temperature"),
    Param("current_bandwidth_hz", "--current-bandwidth-hz", "log", 0.5, 2.0,
          "the drive's current loop as tuned"),
    Param("noise_nm", "--noise-nm", "log", 0.5, 2.0,
          "the gauge's amplifier and converter"),
)


@functools.lru_cache(maxsize=1)
def defaults() -> dict[str, str]:
    """`hdctrl-bench --defaults`: {option: value as printed}, the firmware's
    torque loop and the plant's (one source of both: the C defaults)."""
    r = subprocess.run([str(cl.runner()), "--defaults"], capture_output=True, text=True)
    if r.returncode != 0:
        msg = (r.stderr.strip().splitlines() or ["no message"])[-1]
        raise cl.BenchError(f"hdctrl-bench --defaults: {msg}")
    return dict(line.split(" ", 1) for line in r.stdout.splitlines())


@dataclass
class Joint:
    seed: int | None            # None: not drawn (the default joint, an end of a range)
    values: dict                # {key: value} of every SPACE parameter
    factors: dict               # {key: factor (log) or value (add, phase)}
    label: str = "default"      # of a joint not drawn

    @property
    def name(self) -> str:
        return self.label if self.seed is None else f"c{self.seed}"

    def plant(self) -> tuple:
        """hdctrl-bench's plant options (none for the default joint: the
        runner's own defaults, byte for byte)."""
        if self.seed is None and self.label == "default":
            return ()
        return tuple((p.option, f"{self.values[p.key]:.9g}") for p in SPACE)


def nominal() -> Joint:
    d = defaults()
    return Joint(None, {p.key: float(d[p.option]) for p in SPACE},
                 {p.key: (1.0 if p.draw == "log" else 0.0 if p.draw == "add"
                          else float(d[p.option])) for p in SPACE})


def range_ends() -> list[Joint]:
    """The default joint with one parameter at an end of its range, for every
    parameter but the phases (lo, then hi): what each alone does."""
    base, out = nominal(), []
    for p in SPACE:
        if p.draw == "phase":
            continue
        for end in (p.lo, p.hi):
            f = dict(base.factors, **{p.key: end})
            v = dict(base.values, **{p.key: value_of(p, base.values[p.key], end)})
            out.append(Joint(None, v, f, f"{p.key} {_factor_text(p, end)}"))
    return out


def _factor_text(p: Param, x: float) -> str:
    return f"x{x:g}" if p.draw == "log" else f"{x:+g}"


def draw_factors(seed: int) -> dict:
    """The draw of this seed, every SPACE parameter in order from one stream:
    {key: factor (log) or value (add: the offset, phase: the phase)}."""
    rng = np.random.Generator(np.random.PCG64([seed, STREAM]))
    out = {}
    for p in SPACE:
        if p.draw == "log":
            out[p.key] = float(math.exp(rng.uniform(math.log(p.lo), math.log(p.hi))))
        else:
            out[p.key] = float(rng.uniform(p.lo, p.hi))
    return out


def value_of(p: Param, default: float, factor: float) -> float:
    return default * factor if p.draw == "log" else default + factor if p.draw == "add" \
        else factor


def draw(seed: int) -> Joint:
    """The joint of this seed (its parameters from the runner's defaults)."""
    base, factors = nominal().values, draw_factors(seed)
    return Joint(seed, {p.key: value_of(p, base[p.key], factors[p.key]) for p in SPACE},
                 factors)


def product_variant() -> cl.Variant:
    """The torque loop as flashed: every option of the law at the firmware's
    default (hdctrl-bench --defaults)."""
    d = defaults()
    return cl.Variant(PRODUCT, d["--feedback"], kp=float(d["--kp"]), ki=float(d["--ki"]),
                      kd=float(d["--kd"]), ff=float(d["--ff"]), ilim=float(d["--ilim"]),
                      lowpass_hz=float(d["--lowpass-hz"]),
                      lowpass_order=int(d["--lowpass-order"]),
                      notch_mask=int(d["--notch-mask"]),
                      notch_width_hz=float(d["--notch-width-hz"]),
                      artifact_hz=float(d["--artifact-hz"]),
                      friction_rest_nm=float(d["--friction-rest-nm"]))


def compare_variant(control_json: Path = CONTROL_JSON) -> cl.Variant | None:
    """The filtered feedback with the fixed bench's tuned gains (its row of
    control.json), everything else as flashed; None without that file."""
    try:
        t = json.loads(control_json.read_text())["tuning"][COMPARE]
    except (OSError, KeyError, ValueError):
        return None
    v = product_variant()
    v.key, v.feedback = COMPARE, COMPARE
    v.kp, v.ki, v.kd = float(t["kp"]), float(t["ki_per_s"]), float(t["kd_s"])
    return v


def autotune_summary(joints: list[dict]) -> dict:
    """What the method left on the joints: how often it found gains that
    hold in its own conditions (met), how often only from the conservative
    end of its list (fallback), how often it kept the defaults; the spread
    of the gains chosen."""
    a = [j["autotune"] for j in joints]
    names = [j["name"] for j in joints]
    out = {"joints": len(a), "met": sum(x["met"] for x in a),
           "fallback": sum(x["met"] and x["fallback"] for x in a),
           "kept_defaults": sum(not x["met"] for x in a),
           # the prediction's best (steps 1-3: what `hdsense tune` prints) held
           "first_held": sum(x["met"] and x.get("rank") == 1 for x in a)}
    for k in ("kp", "ki_per_s", "kd_s"):
        v = [x[k] for x in a]
        out[k] = {"min": min(v), "median": _q(v, 0.5), "max": max(v),
                  "at_max": names[int(np.argmax(v))]}
    return out


def config(v: cl.Variant) -> dict:
    return {k: getattr(v, k) for k in ("feedback", "kp", "ki", "kd", "ff", "ilim",
                                         "artifact_hz", "friction_rest_nm")}


def _r(x, digits: int = 4):
    """Rounded to `digits` significant digits (None and inf kept)."""
    if x is None or not math.isfinite(x):
        return x
    return float(f"{x:.{digits}g}")


def measure(v: cl.Variant) -> dict:
    """The control benchmark's measurements of v on its plant (v.plant)."""
    margins = {}
    for c in control.CONDITIONS:
        r = cl.measure_loop(v, cl.scene_of(c))
        m = cl.margins(r.freq_hz, r.loop)
        margins[c] = {"pm_deg": _r(m["pm_deg"]), "gm_db": _r(m["gm_db"]),
                      "crossover_hz": _r(m["crossover_hz"])}
    speeds = {}
    for s in control.SPEEDS_RAD_S:
        ch, st = control.chirp_response(v, s), control.step_response(v, s)
        speeds[str(s)] = {"bandwidth_hz": _r(ch["bandwidth_hz"]), "above_band": ch["above_band"],
                          "peak_db": _r(ch["peak_db"]), "overshoot_pct": _r(st["overshoot_pct"]),
                          "settle_ms": st["settle_ms"], "final_error_nm": _r(st["final_error_nm"])}
    wall = []
    for kd in control.WALL["kds"]:
        w = control.wall_contact(v, kd)
        wall.append({"kd_nm_s_rad": kd, "p2p_nm": _r(w["p2p_nm"]), "mean_nm": _r(w["mean_nm"]),
                     "filtered_error_nm": _r(w["filtered_error_nm"]),
                     "contact_losses": w["contact_losses"], "limit_cycle": w["limit_cycle"]})
    met = all(_meets(m) for m in margins.values())
    cycle = any(w["limit_cycle"] for w in wall)
    return {"margins": margins, "speeds": speeds, "wall": wall, "margins_met": met,
            "wall_cycle": cycle, "within": met and not cycle}


def _meets(m: dict) -> bool:
    """control_tune's margins (a margin stored as None, no crossover, meets them)."""
    return cl.meets({k: _inf(m[k]) for k in ("pm_deg", "gm_db")}, ct.PM_DEG, ct.GM_DB)


def run_joint(joint: Joint, variants: list[cl.Variant]) -> dict:
    out = {"seed": joint.seed, "name": joint.name,
           "factors": {k: _r(x, 6) for k, x in joint.factors.items()}, "rows": {}}
    for v in variants:
        v = dataclasses.replace(v, plant=joint.plant())
        if v.key == AUTOTUNED:
            v, out["autotune"] = control_autotune.autotune(v)
        out["rows"][v.key] = measure(v)
    return out


def _job(args) -> dict:
    joint, variants = args
    return run_joint(draw(joint) if isinstance(joint, int) else joint, variants)


# ------------------------------------------------------------- distributions

def _q(x, p: float) -> float:
    """The p quantile as an order statistic (no interpolation: an inf, no
    crossover, stays one)."""
    return float(np.quantile(np.asarray(x, dtype=float), p, method="lower"))


def _dist(x, names, low_is_bad: bool = True) -> dict:
    """Median, the tail (the 10th percentile where low is bad, the 90th where
    high is bad), the worst and whose."""
    a = np.asarray(x, dtype=float)
    i = int(np.argmin(a) if low_is_bad else np.argmax(a))
    return {"median": _q(a, 0.5), "tail": _q(a, 0.1 if low_is_bad else 0.9),
            "worst": float(a[i]), "worst_joint": names[i]}


def _bw(s: dict) -> float:
    """A bandwidth below the lowest line (None) counts as 0 Hz."""
    return 0.0 if s["bandwidth_hz"] is None else s["bandwidth_hz"]


def _inf(x) -> float:
    """A margin as stored (None: no crossover) as a number."""
    return math.inf if x is None else x


def summary(joints: list[dict], key: str) -> dict:
    """The distributions over the joints (a function of the joints alone, as
    measured or as read back from the JSON)."""
    rows = [j["rows"][key] for j in joints]
    names = [j["name"] for j in joints]
    n = len(rows)
    out = {"joints": n, "within": sum(r["within"] for r in rows),
           "margins_met": sum(r["margins_met"] for r in rows),
           "no_wall_cycle": sum(not r["wall_cycle"] for r in rows), "conditions": {},
           "speeds": {}, "wall": {}}
    for c in control.CONDITIONS:
        pm = [r["margins"][c]["pm_deg"] for r in rows]
        gm = [r["margins"][c]["gm_db"] for r in rows]
        out["conditions"][c] = {
            "pm": _dist([_inf(x) for x in pm], names), "gm": _dist([_inf(x) for x in gm], names),
            "met": sum(_meets(r["margins"][c]) for r in rows)}
    worst_pm = [min(_inf(r["margins"][c]["pm_deg"]) for c in control.CONDITIONS) for r in rows]
    worst_gm = [min(_inf(r["margins"][c]["gm_db"]) for c in control.CONDITIONS) for r in rows]
    out["worst_condition"] = {"pm": _dist(worst_pm, names), "gm": _dist(worst_gm, names)}
    for s in control.SPEEDS_RAD_S:
        sp = [r["speeds"][str(s)] for r in rows]
        out["speeds"][str(s)] = {"bandwidth": _dist([_bw(x) for x in sp], names),
                                 "overshoot": _dist([x["overshoot_pct"] for x in sp], names,
                                                    low_is_bad=False)}
    for i, kd in enumerate(control.WALL["kds"]):
        w = [r["wall"][i] for r in rows]
        out["wall"][str(kd)] = {"p2p": _dist([x["p2p_nm"] for x in w], names, low_is_bad=False),
                                "filtered_error": _dist([abs(x["filtered_error_nm"]) for x in w],
                                                        names, low_is_bad=False),
                                "cycles": sum(x["limit_cycle"] for x in w)}
    return out


def sensitivity(joints: list[dict], key: str) -> list[dict]:
    """Spearman's rank correlation of every drawn parameter (its log factor,
    or its value) with the joint's least phase margin, least gain margin and
    bandwidth at the slowest moving speed, over the joints; strongest first."""
    rows = [j["rows"][key] for j in joints]
    slow = str(min(s for s in control.SPEEDS_RAD_S if s > 0))
    outcomes = {"pm": [min(_inf(r["margins"][c]["pm_deg"]) for c in control.CONDITIONS)
                       for r in rows],
                "gm": [min(_inf(r["margins"][c]["gm_db"]) for c in control.CONDITIONS)
                       for r in rows],
                "bandwidth": [_bw(r["speeds"][slow]) for r in rows]}
    out = []
    for p in (p for p in SPACE if p.draw != "phase"):   # a phase has no direction
        x = [j["factors"][p.key] for j in joints]
        x = np.log(x) if p.draw == "log" else np.asarray(x)
        rho = {}
        for k, y in outcomes.items():
            y = np.asarray(y, dtype=float)
            r = stats.spearmanr(x, y).statistic if np.ptp(y) > 0 and np.ptp(x) > 0 else 0.0
            rho[k] = 0.0 if not math.isfinite(r) else float(r)
        out.append({"key": p.key, **{f"rho_{k}": v for k, v in rho.items()}})
    out.sort(key=lambda r: -max(abs(r["rho_pm"]), abs(r["rho_gm"])))
    return out


BINS = 3        # by_range: the drawn range cut into this many equal (log) parts
BY_RANGE_TOP = 3   # for this many parameters, the strongest of `sensitivity`


def by_range(joints: list[dict], key: str, params: list[str]) -> list[dict]:
    """For each of params, the joints within and in all per part of its drawn
    range (BINS equal parts, in log for a log-uniform draw): where in the
    space the joints outside are."""
    out = []
    space = {p.key: p for p in SPACE}
    for k in params:
        p = space[k]
        log = p.draw == "log"
        edges = np.linspace(*(np.log([p.lo, p.hi]) if log else (p.lo, p.hi)), BINS + 1)
        x = [math.log(j["factors"][k]) if log else j["factors"][k] for j in joints]
        part = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, BINS - 1)
        within = [j["rows"][key]["within"] for j in joints]
        out.append({"key": k, "draw": p.draw,
                    "edges": [float(math.exp(e)) if log else float(e) for e in edges],
                    "within": [int(sum(w for w, b in zip(within, part) if b == i))
                               for i in range(BINS)],
                    "joints": [int(sum(part == i)) for i in range(BINS)]})
    return out


def failures(joints: list[dict], key: str) -> list[dict]:
    """Every joint not within, with what it misses."""
    out = []
    for j in joints:
        r = j["rows"][key]
        if r["within"]:
            continue
        miss = [f"{c}: PM {_fmt(m['pm_deg'])} / GM {_fmt(m['gm_db'])}"
                for c, m in r["margins"].items() if not _meets(m)]
        miss += [f"wall kd {w['kd_nm_s_rad']:g}: cycle ({w['contact_losses']} contact losses, "
                 f"{w['p2p_nm']:.2f} N m p-p)" for w in r["wall"] if w["limit_cycle"]]
        out.append({"name": j["name"], "misses": miss})
    return out


def _fmt(x) -> str:
    return "none" if x is None or not math.isfinite(x) else f"{x:.1f}"


def run(n_joints: int = N_REPORT, jobs: int = JOBS, log=lambda s: None,
        seeds=None, with_ends: bool = True, autotuned: bool = True) -> dict:
    """The bench over REPORT_SEEDS[:n_joints] (or `seeds`), the default joint
    and (with_ends) the ends of every range one at a time (the product row
    only): {"joints": [...], "summary": {row: ...}, ...}."""
    t0 = time.monotonic()
    seeds = list(REPORT_SEEDS[:n_joints]) if seeds is None else [int(s) for s in seeds]
    variants = [product_variant()]
    cmp_ = compare_variant()
    if cmp_ is not None:
        variants.append(cmp_)
    if autotuned:
        variants.append(dataclasses.replace(product_variant(), key=AUTOTUNED))
    ends = range_ends() if with_ends else []
    jobs_ = ([(nominal(), variants)] + [(e, variants[:1]) for e in ends]
             + [(s, variants) for s in seeds])
    done = []
    with ProcessPoolExecutor(max_workers=max(1, min(jobs, JOBS))) as pool:
        for j in pool.map(_job, jobs_):
            done.append(j)
            log(f"{j['name']}: " + ", ".join(
                f"{k} {'within' if r['within'] else 'OUT'}" for k, r in j["rows"].items()))
    ref, ends_done, joints = done[0], done[1:1 + len(ends)], done[1 + len(ends):]
    base = nominal().values
    keys = [v.key for v in variants]
    named = seeds == list(REPORT_SEEDS[:len(seeds)])
    return {"seeds": (f"REPORT_SEEDS[:{len(seeds)}] = {seeds[0]}..{seeds[-1]}" if named
                      else "given: " + ", ".join(map(str, seeds))),
            "tune_seeds": f"TUNE_SEEDS = {TUNE_SEEDS.start}..{TUNE_SEEDS.stop - 1}",
            "stream": STREAM,
            "criteria": {"pm_deg": ct.PM_DEG, "gm_db": ct.GM_DB,
                         "wall_kds": list(control.WALL["kds"])},
            "space": [{"key": p.key, "option": p.option, "draw": p.draw, "lo": p.lo,
                       "hi": p.hi, "default": base[p.key], "why": p.why}
                      for p in SPACE],
            "rows": {v.key: config(v) for v in variants},
            "default_joint": ref, "range_ends": ends_done, "joints": joints,
            "summary": {k: summary(joints, k) for k in keys},
            "sensitivity": sensitivity(joints, PRODUCT),
            "by_range": {k: by_range(joints, k, [r["key"] for r in
                                                 sensitivity(joints, PRODUCT)[:BY_RANGE_TOP]])
                         for k in keys},
            "failures": {k: failures(joints, k) for k in keys},
            "autotune": autotune_summary(joints) if autotuned else None,
            "elapsed_s": round(time.monotonic() - t0, 1), "workers": min(jobs, JOBS)}


JOINT_LISTS = ("joints", "range_ends")   # to_json: one joint a line


def to_json(res: dict) -> str:
    """The results as JSON (inf as null), a joint of JOINT_LISTS a line."""
    from .control_report import clean
    c = clean(res)
    lines = {}
    for key in JOINT_LISTS:
        for i, j in enumerate(c.get(key, [])):
            mark = f"@joint {key} {i}@"
            lines[json.dumps(mark)] = json.dumps(j)
            c[key][i] = mark
    text = json.dumps(c, indent=1)
    for mark, line in lines.items():
        text = text.replace(mark, line, 1)
    return text + "\n"
