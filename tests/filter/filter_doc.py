#!/usr/bin/env python3
"""The measured tables of docs/results/filter-tests.md, written from what the filter
tests measure (nothing typed):

  filter_doc.py --build BUILD           run the filter tests of BUILD, rewrite the blocks
  filter_doc.py --build BUILD --check   exit 1 if a block differs (CTest filter_doc)

The tests (filter_kf_reference, filter_kf_behaviour, filter_kf_profile,
filter_kf_numerics, filter_trig, filter_track) print one `measured: NAME
key=value ...` line per measured case (tests/reliability/rel_measured.h),
bounds included where the test asserts one; they run with the command lines
CTest has for them.  Every run is deterministic (fixed seeds, no timing), and
the same in Debug, Release and sanitizer builds (-ffp-contract=off).  Blocks:

  filter-reference  the float32 filter against the dense double reference
  filter-shift      the step against the old order fed the next increment
  filter-behaviour  behaviour against closed forms and simulation truth
  filter-numerics   the long runs (P symmetric, PSD, bounded)
  filter-trig-track hd_sincosf and hd_track

The texts of the rows are here; every number comes from a run.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "reliability"))
from gendoc import GenDocError, ROOT, command_of, ctest_commands, run, update_doc  # noqa: E402
from rel_doc import parse_measured, table  # noqa: E402

DOC = ROOT / "docs" / "results" / "filter-tests.md"
TESTS = ("filter_kf_reference", "filter_kf_behaviour", "filter_kf_profile", "filter_kf_numerics",
         "filter_trig", "filter_track")
REGENERATE = "tests/filter/filter_doc.py --build build/host-debug"


def measure(build: Path) -> dict[str, dict[str, str]]:
    cmds = ctest_commands(build)
    measured: dict[str, dict[str, str]] = {}
    for test in TESTS:
        for name, kv in parse_measured(run(command_of(cmds, test, build), 900)).items():
            if name in measured:
                raise GenDocError(f"{test}: case {name} measured in two tests")
            measured[name] = kv
    return measured


class Cases:
    """The measured cases, each taken at most once per row; render() fails
    when a case has no row (a test added a case) or a row no case."""

    def __init__(self, measured: dict[str, dict[str, str]]):
        self.measured = measured
        self.used: set[str] = set()

    def __call__(self, name: str) -> dict[str, str]:
        if name not in self.measured:
            raise GenDocError(f"no measured line for case {name} (test renamed or removed?)")
        self.used.add(name)
        return self.measured[name]


# ---------------------------------------------------------------- blocks

REFERENCE_ROWS = [
    ("ref_paper4", "paper 4th order"),
    ("ref_paper6", "paper 6th order"),
    ("ref_narrow8", "narrow-band (motor 2, 4, 6 + output 1)"),
    ("ref_max", "8 blocks of every lock kind + sensor-error offset"),
    ("ref_recommended", "recommended (jump gate, motion-scaled q and gain)"),
    ("ref_texp_var", "recommended, T_exp with its own variance (0-4 N m^2, NaN, -1, 1e15)"),
    ("ref_load_recommended", "load k = 0.3, recommended + motor 8"),
    ("ref_load_max", "load k = 0.3, 8 blocks + sensor-error offset"),
    ("ref_load_paper", "load k = 0.3, paper 6th order (no offset)"),
    ("ref_load_k0", "load run, k = 0, recommended + motor 8"),
    ("ref_toggles", "20 block toggles, recommended + motor 8 configured off"),
]


def reference_block(c: Cases) -> str:
    rows = []
    for key, label in REFERENCE_ROWS:
        m = c(key)
        notes = []
        for field, text in (("clamped", "P-clamped steps"), ("frozen", "frozen steps"),
                            ("jumps", "offset jumps")):
            if m[field] != "0":
                notes.append(f"{m[field]} {text}")
        if "k0_dev" in m:
            notes.append(f"k = 0 reference {m['k0_dev']} N m away ({m['k0_x_tol']} x tol)")
        if "v0_dev" in m:
            notes.append(f"reference told no T_exp variance {m['v0_dev']} N m away "
                         f"({m['v0_x_tol']} x tol)")
        rows.append([label, m["states"], m["filtered"], m["innovation"], m["state"], m["s_rel"],
                     m["p_rel"], m["tol"], "; ".join(notes)])
    base = c("ref_paper4")
    head = (f"Tolerance: {base['tol_rel']} x the signal scale (max \\|T_meas\\| + max "
            f"\\|T_exp\\|) for the torques and states, {base['sp_bound']} relative for S and P "
            "(P against its largest diagonal entry).")
    return head + "\n\n" + table(["model", "states", "filtered [N m]", "innovation [N m]",
                                  "state [N m]", "S rel", "P rel", "tol [N m]", "notes"], rows)


SHIFT_ROWS = [("shift_recommended", "recommended + motor 8, k 0.3, motion scaling off"),
              ("shift_max", "8 blocks + sensor-error offset, k 0.3")]


def shift_block(c: Cases) -> str:
    rows = []
    for key, label in SHIFT_ROWS:
        m = c(key)
        rows.append([label, m["dev"], m["tol"], m["dev_ref"],
                     f"{m['old_own']} ({m['old_own_x_tol']} x tol)", m["jumps"]])
    return table(["run (30 s, speed steps up to 400 rad/s in a sample)",
                  "filter fed d_k vs old order fed d_k+1 [N m]", "tol [N m]",
                  "new reference vs the same [N m]", "old order fed d_k [N m]", "offset jumps"],
                 rows)


def _x(v: str) -> str:
    return f"{v} x noise"


def behaviour_rows(c: Cases) -> list[list[str]]:
    m = c("constant_speed")
    rows = [["156 rad/s, noise 0.05 N m: error RMS vs truth",
             f"{m['err']} N m = {_x(m['err_x'])} ({m['raw']} N m before filtering)",
             f"<= {_x(m['err_bound'])}"],
            ["156 rad/s: ripple estimate residual", _x(m["res_x"]), f"<= {_x(m['res_bound'])}"]]
    m = c("ramps")
    rows.append(["speed ramps 20-300 rad/s",
                 f"error {_x(m['err_x'])}, ripple residual {_x(m['res_x'])}",
                 f"<= {_x(m['err_bound'])}, <= {_x(m['res_bound'])}"])
    m = c("paper_lines")
    rows.append(["paper tuning (Q = 1e3 I, R = 1), 156 rad/s: 312 / 624 rad/s lines",
                 f"{m['in2']} -> {m['out2']} N m: **{m['db2']} dB**; {m['in4']} -> {m['out4']} "
                 f"N m: **{m['db4']} dB**", f">= {m['bound_db']} dB"])
    m = c("narrow_lines")
    rows.append(["narrow-band, 156 rad/s: 312 / 624 rad/s lines", f"{m['db2']} dB / {m['db4']} dB",
                 f">= {m['bound_db']} dB"])
    m = c("misalignment")
    rows.append(["misalignment line 1.56 rad/s (gear 100), 1 N m",
                 f"6th order {m['db6']} dB, 4th order {m['db4']} dB",
                 f">= {m['bound6_db']} dB / <= {m['bound4_db']} dB"])
    m = c("standstill_then_motion")
    rows.append(["20 s standstill then 156 rad/s", f"ripple residual {_x(m['res_x'])}",
                 f"<= {_x(m['res_bound'])}"])
    m = c("reversal")
    rows.append(["reversal +-156 rad/s", f"ripple residual {_x(m['res_x'])}, max {m['max']} N m",
                 f"<= {_x(m['res_bound'])}, <= {m['max_bound_x']} x noise"])
    m = c("over_nyquist")
    rows.append(["900 rad/s (motor order 4 over 0.9 pi a step)",
                 f"{m['frozen_steps']} frozen steps, the block held at {m['held']} N m (truth "
                 f"0.4): norm and covariance trace kept; ripple residual {_x(m['resume_x'])} in "
                 f"the first 0.1 s after resuming, {_x(m['end_x'])} after 1 s",
                 f"mask/status/ripple exact; norm and trace within {m['held_rel_bound']}; "
                 f"<= {_x(m['resume_bound'])}; <= {_x(m['end_bound'])}"])
    m = c("phase_lost")
    rows.append(["phase advance beyond four turns in one step (encoder fault)",
                 f"the block restarts: state 0, P = p0, decorrelated; just over Nyquist (8 rad) it "
                 f"is held ({m['held']} N m kept)", "exact"])
    m = c("paper_texp")
    rows.append(["paper tuning, T_exp = 0.5 T_true",
                 f"filtered - T_exp = {m['ratio']} (T_true - T_exp); DC innovation gain from the "
                 f"Riccati fixed point {m['g0']}", f"within {m['bound']} of the closed form"])
    m = c("narrow_texp")
    rows.append(["narrow-band, T_exp = 0.5 T_true",
                 f"the output carries {m['ratio']} of the missed torque (closed form {m['g0']})",
                 f"within {m['bound']}"])
    m = c("forced_bounds")
    rows.append(["forced covariance bounds",
                 f"an indefinite block zeroed (p_negative_count {m['negative']}), a block at "
                 f"5 N m^2 under p_max {m['p_max']} brought to lambda_max = {m['lmax']}",
                 f"exact counts; {m['rel_bound']} relative"])
    m = c("block_disabled")
    rows.append(["block disabled at run time", f"max deviation from a 4-state filter {m['dev']} N m",
                 f"<= {m['bound']} N m"])
    m = c("load_step_gate")
    rows.append(["10 N m load step, recommended tuning",
                 f"error after the step {m['on']} N m with the jump gate, {m['off']} N m without",
                 f"< {m['on_bound']} N m; without > {m['off_bound_x']} x with"])
    m = c("unmodelled_line")
    rows.append(["an undeclared 0.7 N m motor order 3 line (above the 0.5 N m jump gate), "
                 "0.3-0.8 rad/s with reversals",
                 f"filtered error {m['err']} N m, raw {m['raw']} N m, the line's own RMS "
                 f"{m['own']} N m; {m['held']} steps beyond the held gate",
                 f"< raw and < {m['cost_bound_x']} x its own RMS"])
    m = c("load_coeff_step")
    rows.append(["load step 0 -> 10 N m, order-2 line 0.5 -> 2 N m (x (1 + 0.3 T)), no offset",
                 f"ripple error 20-200 ms after the step {m['with_k']} N m with k = 0.3, "
                 f"{m['without_k']} N m with k = 0", f"< {m['bound_x']} x (k = 0)"])
    m = c("load_coeff_step_offset")
    rows.append(["same, with the offset state (T_ref = T_exp + offset)",
                 f"{m['with_k']} vs {m['without_k']} N m", f"< {m['bound_x']} x (k = 0)"])
    m, a = c("load_coeff_rows"), c("load_coeff_amplitude")
    o = c("load_coeff_rows_offset")
    rows.append(["amplitude_nm with k",
                 f"motor blocks (1 + k T_ref) x state amplitude within {m['motor_rel']} / "
                 f"{o['motor_rel']} relative (without / with offset); output-locked and fixed "
                 f"blocks unscaled ({m['unscaled']} / {o['unscaled']} N m); zero-load state "
                 f"{a['zero_load']} N m (truth 0.5), 50 Hz block {a['fixed']} N m (truth 0.2)",
                 f"{m['motor_bound']} / {m['unscaled_bound']}"])
    m = c("load_coeff_standstill")
    rows.append(["60 s standstill at 10 N m (unknown to T_exp), unmodelled 0.3 N m 50 Hz line",
                 f"the estimate's drift since the stop {m['drift_k']} N m with k = 0.3, "
                 f"{m['drift_0']} N m with k = 0 (the estimate holds the share of the 50 Hz line "
                 f"it had at the stop: {m['end_k']} / {m['end_0']} N m)",
                 f"< {m['bound']} N m"])
    m = c("short_plans")
    rows.append(["short plans against the full rules",
                 f"the motor short plan on {m['motor_steps']} of {m['of']} steps: every output, "
                 "state and covariance bit-identical", "exact"])
    return rows


def profile_rows(c: Cases) -> list[list[str]]:
    m = c("profile_export")
    rows = [["profile export at 156 rad/s (20-30 s)",
             f"motor order 2: {m['motor2']} N m from the truth (one sample of phase would be "
             f"0.31 N m); output order 1: {m['output1']} N m", f"{m['bound2']} / {m['bound1']} N m"]]
    m = c("profile_round_trip")
    rows.append(["profile round trip, the next 20 predictions",
                 f"importing filter within {m['dev']} N m of the exporting one; imported one "
                 f"sample off: {m['wrong']} N m away", f"{m['bound']} N m; > 1000 x that"])
    m = c("profile_import_running")
    rows.append(["import into a running filter, then a speed step 230 -> 70 rad/s",
                 f"prediction within {m['dev']} N m of the truth at the sample's angles (at the "
                 f"old speed's angles: {m['lagged']} N m off)", f"{m['bound']} N m"])
    m = c("speed_step_profile")
    rows.append(["speed step 30 -> 90 rad/s, exact profile and T_exp",
                 f"worst ripple error in the 200 ms after it {m['worst']} N m, filtered RMS error "
                 f"{m['before']} / {m['after']} N m before / after (noise {m['noise']}); the old "
                 f"order (turned by the last increment): {m['worst_old']} N m, {m['after_old']} "
                 "N m", f"< {m['worst_bound_x']} x noise, < {m['after_bound_x']} x noise; old "
                 f"> {m['old_bound_x']} x noise"])
    m = c("profile_reference")
    rows.append(["profiles vs the reference (learn scale 0.01, varying speed)",
                 f"exported (a, b) within {m['export']} N m; filtered torque after both imported "
                 f"a profile mid-run {m['after_import']} N m", f"{m['bound']} N m"])
    m = c("learn_scale_gravity")
    rms, moved = m["rms"].split("/"), m["moved"].split("/")
    rows.append(["output_learn_scale, +-120 deg gravity swing, 12 N m, profile imported",
                 f"RMS error {' / '.join(rms)} N m for scale 1 / 1e-2 / 1e-3 / 0; the output "
                 f"line's profile moved {' / '.join(moved)} N m",
                 f"scale 0: profile within {m['moved0_bound']} N m, error below scale 1's"])
    m = c("learn_scale_long")
    rows.append(["output_learn_scale 0, 2e6 steps at 1.56 rad/s",
                 f"the output line's profile moved {m['moved']} N m", f"{m['bound']} N m"])
    ms = [c(k) for k in ("learn_ref_0", "learn_ref_1e-3", "learn_ref_0.3")]
    rows.append(["output_learn_scale 0 / 1e-3 / 0.3 vs the reference",
                 f"filtered {' / '.join(x['filtered'] for x in ms)} N m; output-block variance "
                 f"{' / '.join(x['var_rel'] for x in ms)} relative",
                 f"{ms[0]['bound']} N m; {ms[0]['var_bound']}"])
    m = c("follow_output_grown")
    rows.append(["lines growing as 1 + 0.1 |T| under +-4.5 N m, output line held, profile "
                 "at zero load",
                 f"filtered RMS error {m['follow']} N m with output_row_follow, {m['off']} N m "
                 f"without; the same joint's lines not growing: {m['still']} N m",
                 f"< {m['bound']} the still joint's; without > 2x"])
    m = c("follow_drift")
    rows.append(["the same, motor lines also 1.3x their profile at every load (wear), "
                 "profile at zero load",
                 f"filtered RMS error {m['known']} N m with the profile's load known, "
                 f"{m['unknown']} N m unknown (no follow); without the drift {m['still']} N m",
                 f"known < {m['bound']} the drift-free joint's; unknown > 2x"])
    m = c("follow_modelled")
    rows.append(["lines growing as 1 + 0.1 |T|, the model's load coefficient 0.1 (motor rows "
                 "scaled, held output row from the profile's load)",
                 f"filtered RMS error {m['grown']} N m; lines not growing, no coefficient: "
                 f"{m['plain']} N m", f"< {m['bound']} the latter's"])
    m = c("follow_modelled_output_only")
    rows.append(["the same with a profile of output lines only (no motor line to measure a "
                 "growth against: the modelled factor alone)",
                 f"filtered RMS error {m['grown']} N m; row held at 1: {m['held']} N m; lines "
                 f"not growing: {m['plain']} N m", f"< {m['bound']} the latter's; held > 2x"])
    return rows


def behaviour_block(c: Cases) -> str:
    return table(["case", "result", "bound"], behaviour_rows(c) + profile_rows(c))


NUMERICS_ROWS = [("numerics_paper6", "paper 6th order"),
                 ("numerics_narrow", "narrow-band 6th order + offset"),
                 ("numerics_max", "8 blocks + offset")]


def numerics_block(c: Cases) -> str:
    rows = []
    for key, label in NUMERICS_ROWS:
        m = c(key)
        rows.append([label, m["steps"], m["still"], f"{m['clamped']} ({m['blocks_counted']})",
                     m["frozen"], m["max_diag"], m["pivot"]])
    return table(["run", "steps", "at standstill", "P-clamped steps (blocks counted)",
                  "with a frozen block", "max diag [N m^2]",
                  "smallest Cholesky pivot / max diag"], rows)


def trig_track_block(c: Cases) -> str:
    rows = []
    for key, label in (("trig_pi", "hd_sincosf on [-pi, pi], 2e6 points"),
                       ("trig_1e4", "hd_sincosf on [-1e4, 1e4] rad, 4e6 points")):
        m = c(key)
        rows.append([label, f"sin {m['sin']}, cos {m['cos']}", m["bound"]])
    for key, label in (("trig_boundaries", "hd_sincosf, 40000 floats around each quadrant "
                                           "boundary"),
                       ("trig_near_1e4", "hd_sincosf, 100000 floats just below 1e4 rad")):
        m = c(key)
        rows.append([label, m["err"], m["bound"]])
    m = c("track_constant_velocity")
    rows.append([f"hd_track (ts 1 ms), constant {m['v']} rad/s", f"velocity error {m['err']} rad/s",
                 f"{m['rel_bound']} relative"])
    m = c("track_constant_acceleration")
    rows.append(["hd_track, constant 50 rad/s^2", f"velocity {m['vel']} rad/s, acceleration "
                 f"{m['acc']} rad/s^2", f"{m['vel_bound']} / {m['acc_bound']}"])
    for hz in ("5", "20"):
        m = c(f"track_step_{hz}_hz")
        rows.append([f"hd_track, velocity step at {hz} Hz bandwidth",
                     f"max deviation from the continuous closed form {m['dev']} of the step, "
                     f"overshoot {m['overshoot']} % (closed form 24.9 %), 2 % settling "
                     f"{m['settle']}/w (closed form 7.9)",
                     f"{m['dev_bound']} (2 w ts); settling <= {m['settle_bound']}/w"])
    return table(["case", "max abs error", "bound"], rows)


def render(measured: dict[str, dict[str, str]]) -> dict[str, str]:
    c = Cases(measured)
    blocks = {"filter-reference": reference_block(c), "filter-shift": shift_block(c),
              "filter-behaviour": behaviour_block(c), "filter-numerics": numerics_block(c),
              "filter-trig-track": trig_track_block(c)}
    unused = sorted(set(measured) - c.used)
    if unused:
        raise GenDocError(f"measured cases without a row in filter_doc.py: {', '.join(unused)}")
    return blocks


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", type=Path, required=True, help="build folder whose tests are run")
    ap.add_argument("--check", action="store_true", help="compare, do not write")
    ap.add_argument("--doc", type=Path, default=DOC)
    a = ap.parse_args(argv)
    try:
        print(update_doc(a.doc, render(measure(a.build.resolve())), a.check, REGENERATE))
    except GenDocError as exc:
        print(f"filter_doc: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
