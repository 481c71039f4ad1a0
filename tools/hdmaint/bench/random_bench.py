"""The random-joint benchmark (issue 21, docs/results/random-joints.md): the
firmware and the analysis on joints drawn by hdmaint.bench.randjoint, each
run scored against the simulator's ripple-free truth.

Paths (nothing is handed the drawn joint's parameters: the firmware gets
the data-sheet constants hdjoint-host takes from the scenario, i.e. ratio
and encoder counts, and the nominal calibration; everything else it learns
or is told by the project's own tools from the commissioning log):
  self        learning_mode 2 on the commissioning run, PROFILE_SAVE, then
              the operating run booted from that NVM (operating mode);
  self_nofollow the same with output_row_follow = 0 (the held output rows
              do not follow the motor lines' load growth; the default before
              2026-12-06; loaded set only, for comparison);
  analyze     `hdsense analyze` of the commissioning log -> model.cfg +
              profile.json -> `hdsense profile record` -> the operating run;
  analyze_op  the same from the operating log of another day of the joint
              (its own speed plan and loads): a fixed-frequency line can be
              told from a motor-locked one only where the speed varies;
  adaptive    learning_mode 0 on the operating run, no profile;
  commission  learning_mode 2 on the operating run, no profile;
  operating   learning_mode 1 (the default) on the operating run, no profile.

Per run: RMS error after the first second, the raw measurement's, the
noise floor (measured - true ripple - truth: the sensor's noise and ADC
steps), their ratio, and filtered <= raw.
"""
from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import randjoint
from . import metrics
from .goals import LOAD_KEPT_MIN
from .metrics import rms
from .joint import (HDSENSE, compose_config, firmware_commissioning, load_csv, nominal,
                    run_firmware, run_tool, simulate)

PATHS = ("self", "analyze", "analyze_op", "adaptive", "commission", "operating")
REPORT_ORDER = ("self", "self_nofollow") + PATHS[1:]
NO_FOLLOW = "output_row_follow = 0\n"
MODES = {"adaptive": "0", "commission": "2", "operating": "1"}
GOAL_RATIO = 1.5
SKIP_S = 1.0
# T_exp from the slow-torque source only (as the slow-torque benchmark's rows):
# no friction/inertia terms from the commissioning log.
NO_DYNAMICS = {"inertia_kgm2": "0", "viscous_nm_s_rad": "0", "coulomb_nm": "0"}


@dataclass
class Score:
    error_nm: float
    raw_nm: float
    floor_nm: float
    load_kept: float | None = None   # metrics.slow_load_kept; None: no slow load

    @property
    def ratio(self) -> float:
        return self.error_nm / self.floor_nm

    def to_dict(self) -> dict:
        return {"error_rms_nm": self.error_nm, "raw_rms_nm": self.raw_nm,
                "floor_rms_nm": self.floor_nm, "ratio_to_floor": self.ratio,
                "worse_than_raw": bool(self.error_nm > self.raw_nm),
                "load_kept": self.load_kept}


def score(filtered, sim: dict) -> Score:
    """filtered against the truth of the simulated run, after SKIP_S."""
    t = sim["t_s"]
    keep = t >= SKIP_S
    truth = sim["torque_true_nm"][keep]
    meas = sim["torque_nm"][keep]
    floor = meas - sim["ripple_true_nm"][keep] - truth
    err = np.asarray(filtered) - sim["torque_true_nm"]
    return Score(rms(err[keep]), rms(meas - truth), rms(floor),
                 metrics.slow_load_kept(err, sim, keep))


def _analyze(com_csv: Path, wd: Path, nom: dict, tag: str = "analyze"
             ) -> tuple[str, Path | None, str]:
    """model.cfg and a profile record from `hdsense analyze` of a log:
    (config text, record or None, note)."""
    an = wd / tag
    run_tool([HDSENSE, "analyze", com_csv, "--gear-ratio", f"{nom['gear_ratio']:.9g}",
              "--out", an, "--json", an / "report.json", "--quiet"], "hdsense analyze")
    rep = json.loads((an / "report.json").read_text())
    note = rep.get("starting_profile_fit", {})
    kept = [o["order"] for o in note.get("orders", [])]
    rec = wd / f"{tag}.hdprofile"
    try:
        run_tool([HDSENSE, "profile", "record", an / "profile.json", "-o", rec,
                  "--gear-ratio", f"{nom['gear_ratio']:.9g}", "--motor-cpr",
                  int(nom["motor_cpr"]), "--output-cpr", int(nom["output_cpr"])],
                 "hdsense profile record")
    except RuntimeError:
        rec = None
    return (an / "model.cfg").read_text(), rec, f"starting profile orders {kept}"


def run_joint(joint: randjoint.Joint, wd: Path, paths=PATHS) -> dict:
    """Every path on one joint: {path: Score dict} plus the joint and notes."""
    com_ini, op_ini = randjoint.write(joint, wd)
    nom = nominal(op_ini)
    op_sim = simulate(op_ini, wd / "operate_sim.csv")
    out = {"joint": joint.describe(), "name": joint.name, "paths": {}, "notes": {}}
    selfs = [p for p in ("self", "self_nofollow") if p in paths]
    if selfs:
        nvm, note = firmware_commissioning(com_ini, wd, nom, None, "")
        out["notes"]["self"] = note
        for p in selfs if nvm is not None else ():
            extra = NO_FOLLOW if p == "self_nofollow" else ""
            filt, _ = run_firmware(op_ini, "learning_mode = 1\n" + extra, wd, p, nvm=nvm)
            out["paths"][p] = score(filt, op_sim).to_dict()
    if "analyze" in paths:
        com_csv = wd / "commission_sim.csv"
        simulate(com_ini, com_csv)
        cfg, rec, note = _analyze(com_csv, wd, nom)
        out["notes"]["analyze"] = note
        filt, _ = run_firmware(op_ini, compose_config(cfg, NO_DYNAMICS), wd, "analyze",
                               profile=rec)
        out["paths"]["analyze"] = score(filt, op_sim).to_dict()
    if "analyze_op" in paths:
        day = joint.another_day(1)
        day_ini = wd / f"{joint.name}_day1.ini"
        day_ini.write_text(day.operating_ini())
        day_csv = wd / "day1_sim.csv"
        simulate(day_ini, day_csv)
        cfg, rec, note = _analyze(day_csv, wd, nom, "analyze_op")
        out["notes"]["analyze_op"] = note
        filt, _ = run_firmware(op_ini, compose_config(cfg, NO_DYNAMICS), wd, "analyze_op",
                               profile=rec)
        out["paths"]["analyze_op"] = score(filt, op_sim).to_dict()
    for p, mode in MODES.items():
        if p in paths:
            filt, _ = run_firmware(op_ini, f"learning_mode = {mode}\n", wd, p)
            out["paths"][p] = score(filt, op_sim).to_dict()
    return out


def distribution(runs: list[dict], path: str) -> dict:
    """Median, 90th percentile, worst ratio, the fraction within GOAL_RATIO
    and the number worse than raw, over the runs that have this path."""
    r = [x["paths"][path] for x in runs if path in x["paths"]]
    if not r:
        return {"runs": 0}
    ratio = np.array([x["ratio_to_floor"] for x in r])
    worst = int(np.argmax(ratio))
    names = [x["name"] for x in runs if path in x["paths"]]
    return {"runs": len(r), "median": float(np.median(ratio)),
            "p90": float(np.percentile(ratio, 90)), "worst": float(ratio[worst]),
            "worst_joint": names[worst],
            "within_goal": int(np.sum(ratio <= GOAL_RATIO)),
            "fraction_within_goal": float(np.mean(ratio <= GOAL_RATIO)),
            "worse_than_raw": int(sum(x["worse_than_raw"] for x in r)),
            "worst_error_over_raw": float(max(x["error_rms_nm"] / x["raw_rms_nm"] for x in r)),
            **_kept(r)}


def _kept(r: list[dict]) -> dict:
    """The least slow load kept over the runs that have one, and how many
    keep at least LOAD_KEPT_MIN of it."""
    kept = [x["load_kept"] for x in r if x.get("load_kept") is not None]
    if not kept:
        return {}
    return {"load_kept_min": float(min(kept)), "load_kept_runs": len(kept),
            "load_kept_within": int(sum(k >= LOAD_KEPT_MIN for k in kept))}


def run(seeds, undeclared: bool, paths=PATHS, log=None, loaded: bool = False) -> dict:
    """The benchmark over these seeds; {"runs": [...], "paths": {path: distribution}}."""
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for s in seeds:
            j = randjoint.draw(int(s), undeclared, loaded)
            runs.append(run_joint(j, Path(tmp) / j.name, paths))
            if log:
                log(j.name + ": " + ", ".join(f"{p} {v['ratio_to_floor']:.2f}x"
                                              for p, v in runs[-1]["paths"].items()))
    return {"seeds": [int(s) for s in seeds], "undeclared": bool(undeclared),
            "loaded": bool(loaded), "runs": runs, "paths": {p: distribution(runs, p) for p in paths}}


def ci_record(seeds, paths=("self", "adaptive", "commission", "operating")) -> dict:
    """What tests/tools/test_random_joints.py holds the CI sample to: its
    seeds, the self-commissioned share within GOAL_RATIO and median."""
    r = run(seeds, False, paths)
    d = r["paths"]["self"]
    return {"seeds": [int(s) for s in seeds], "self_within_goal": d["within_goal"],
            "self_median": d["median"], "paths": r["paths"]}


QUICK_PATHS = ("self", "adaptive")     # tools/bench --quick: a smoke run
# Load-modulated lines: the product path and the analysis loops.
LOADED_PATHS = ("self", "self_nofollow", "analyze", "analyze_op")


def bench(n_joints: int, log=None, paths=PATHS, ci_sample=True) -> dict:
    """The benchmark: n_joints report seeds, declared effects only and with
    one undeclared effect each, on these paths, and with load-modulated
    lines on LOADED_PATHS; plus the CI sample's record."""
    seeds = list(randjoint.REPORT_SEEDS[:n_joints])
    out = {"seeds": f"REPORT_SEEDS[:{n_joints}] = {seeds[0]}..{seeds[-1]}",
           "tuned_on": f"TUNE_SEEDS ({randjoint.TUNE_SEEDS.start}..{randjoint.TUNE_SEEDS.stop - 1})",
           "goal_ratio": GOAL_RATIO}
    for key, und in (("declared", False), ("undeclared", True)):
        out[key] = run(seeds, und, paths, log)
    out["loaded"] = run(seeds, False, [p for p in REPORT_ORDER
                                       if p in LOADED_PATHS and (p in paths or (p == "self_nofollow" and "self" in paths))],
                        log, loaded=True)
    if ci_sample:
        out["ci_sample"] = ci_record(randjoint.REPORT_SEEDS[:4])
    return out
