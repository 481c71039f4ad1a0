#!/usr/bin/env python3
"""The measured tables of docs/results/reliability.md, written from what the
reliability tests measure (nothing typed):

  rel_doc.py --build BUILD            run the tests of BUILD, rewrite the blocks
  rel_doc.py --build BUILD --check    exit 1 if a block differs (CTest rel_doc)
  rel_doc.py --soak-long BUILD        run the 10^8-step soak of BUILD (a release
                                      build, ~1 min) and write its block

The tests (rel_fault_sensors, rel_fault_can, rel_fault_calib,
rel_fault_filter_input, fw_control) print one `measured: NAME key=value ...` line per
case (rel_measured.h) and hd_soak prints `key = value` lines; they run with
the command lines CTest has for them.  Blocks:

  reliability-faults        the fault-injection table (firmware on the rig)
  reliability-filter-input  bad input straight into hd_pipeline
  reliability-control       the control stage's fault reactions (fw_control)
  reliability-soak          hd_soak as rel_soak_1e6 runs it (no timing)
  reliability-soak-long     the 10^8 soak with its timing, date and machine:
                            written by --soak-long only, never checked

The first three are deterministic (fixed seeds, simulated time) and
checked; the texts of the rows are here, every number comes from a run.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from gendoc import (ROOT, GenDocError, build_info, command_of, ctest_commands, machine,  # noqa: E402
                    run, update_doc)

sys.path.insert(0, str(ROOT / "tools"))
from hdtools import protocol, summary  # noqa: E402  (fault and result names from the .def files)

DOC = ROOT / "docs" / "results" / "reliability.md"
FAULT_TESTS = ("rel_fault_sensors", "rel_fault_can", "rel_fault_calib", "rel_fault_filter_input",
               "fw_control")
SOAK_TEST = "rel_soak_1e6"
SOAK_LONG_ARGS = ["100000000", "--check-every", "10000"]
REGENERATE = "tests/reliability/rel_doc.py --build build/host-debug"


# ------------------------------------------------------------- measuring

def parse_measured(text: str) -> dict[str, dict[str, str]]:
    """{case: {key: value}} from `measured: NAME k=v ...` lines (a case may
    print several lines; their keys are merged)."""
    out: dict[str, dict[str, str]] = {}
    for line in text.splitlines():
        if not line.startswith("measured: "):
            continue
        name, *pairs = line[len("measured: "):].split()
        case = out.setdefault(name, {})
        for p in pairs:
            key, sep, value = p.partition("=")
            if not sep:
                raise GenDocError(f"malformed measured line: {line!r}")
            case[key] = value
    return out


def measure(build: Path) -> tuple[dict[str, dict[str, str]], dict[str, str]]:
    cmds = ctest_commands(build)
    measured: dict[str, dict[str, str]] = {}
    for test in FAULT_TESTS:
        for name, kv in parse_measured(run(command_of(cmds, test, build), 600)).items():
            if name in measured:
                raise GenDocError(f"{test}: case {name} measured twice")
            measured[name] = kv
    soak = summary.parse(run(command_of(cmds, SOAK_TEST, build), 600))
    if soak.get("result") != "PASS":
        raise GenDocError(f"{SOAK_TEST}: no PASS result")
    return measured, soak


# ------------------------------------------------------------- rendering

def faults(bits: str, none: str = "none") -> str:
    names = {f.name: f.code for f in protocol.faults()}
    found = protocol.fault_names(int(bits, 16))
    return ", ".join(f"{n} ({names[n]})" for n in found) or none


def results(codes: str) -> str:
    names = {e.code: e.name for e in protocol.results()}
    return ", ".join(f"{names[int(c)]} ({c})" for c in codes.split(",") if c != "none")


def calib_status(code: str) -> str:
    names = {e.code: e.name for e in protocol.record_statuses()}
    return f"heartbeat CalibStatus {code} ({names[int(code)]})"


def nm(value: str) -> str:
    return f"{float(value):.3f}"


def rec(m: dict[str, str], after: str = "", note: str = "") -> str:
    return f"**{m['recovery_ticks']}**{after} ({note}limit {m['limit_ticks']})"


def in_band(m: dict[str, str]) -> str:
    """Cases whose test asserts the error never leaves the band."""
    return f"**{m['recovery_ticks']}** (asserted: never leaves the band)"


def sci(value: str) -> str:
    return f"{float(value):.2g}".replace("e+", "e")


def ticks(n: str) -> str:
    return f"{n} tick" + ("" if n == "1" else "s")


# One row per case: (case, fault injected, what the firmware does, flag,
# recovery, worst |filtered - truth| over the fault and the 1 s after it).
# Each text is a function of the case's measured values `m`.
ROWS = [
    ("adc_read_error",
     lambda m: f"ADC read error, {m['window_ms']} ms",
     lambda m: "sample invalid, filter predicts only (oscillators keep turning with the "
               "encoder), torque sent as \"not available\"",
     None, None, lambda m: f"{nm(m['max_err_nm'])} (valid samples only)"),
    ("adc_stuck_at_rail", lambda m: f"ADC stuck at the rail (saturated), {m['window_ms']} ms",
     lambda m: "as above", None, None, None),
    ("open_bridge", lambda m: f"open bridge (`HAL_ERR_FAULT`), {m['window_ms']} ms",
     lambda m: "as above", None, None, None),
    ("out_of_range_sample",
     lambda m: f"sample above the torque limit ({m['sample_nm']} N m > {m['torque_limit_nm']} N m), "
               f"{m['window_ms']} ms",
     lambda m: "as above", None, None, lambda m: "-"),
    ("wild_sample_in_range",
     lambda m: f"one wild sample inside the range (+{m['sample_nm']} N m, 1 tick)",
     lambda m: "cannot be told from torque: filtered; the offset-jump gate takes it, the "
               "next sample undoes it",
     lambda m: faults(m["faults"], "none (by design)"), None, None),
    ("calibration_gain",
     lambda m: f"calibration gain {sci(m['refused_gain'])} N m/V over CAN (would "
               "overflow to +inf)",
     lambda m: f"refused: {results(m['result'])} (gain limit {float(m['gain_limit']):g} N m/V), "
               "calibration unchanged; the largest accepted gain drives every sample over "
               "the torque limit",
     None, lambda m: rec(m, " after the gain is restored"), lambda m: "-"),
    ("encoder_fault",
     lambda m: f"encoder reports a fault, {m['window_ms']} ms (garbage counts)",
     lambda m: "previous good delta used (dead reckoning); the first good read corrects "
               "the angle", None, None, None),
    ("encoder_glitch", lambda m: f"encoder glitch, +{m['counts']} counts for 1 tick",
     lambda m: "both jumps (out and back) replaced by the previous delta; angle unaffected",
     lambda m: f"{faults(m['faults'])}, {ticks(m['flagged_ticks'])}", None, None),
    ("encoder_jump", lambda m: f"encoder counter jumps by {m['counts']} counts for good",
     lambda m: "delta replaced once; only deltas are used, so the angle is unaffected",
     lambda m: f"{faults(m['faults'])}, {ticks(m['flagged_ticks'])}", None, None),
    ("encoder_lost_counts",
     lambda m: f"{m['counts']} encoder counts lost ({m['motor_deg']} deg of motor angle)",
     lambda m: "**not detectable** per tick (looks like a speed change): the ripple blocks "
               "re-estimate their phase", None, None, None),
    ("direction_reversal", lambda m: "direction reversal +156 -> -156 rad/s in 0.4 s",
     lambda m: "nothing to do (not a fault)", None,
     lambda m: rec(m, " from the end of the reversal"), None),
    ("standstill", lambda m: f"standstill for {m['standstill_s']} s, then restart",
     lambda m: "covariance stays bounded (motion-scaled q), no reset", None,
     lambda m: rec(m, " after the restart"),
     lambda m: f"{nm(m['max_err_nm'])} during the standstill"),
    ("order_over_nyquist",
     lambda m: f"{m['speed_rad_s']} rad/s for {int(m['window_ms']) / 1000:g} s: motor order 4 "
               "over Nyquist",
     lambda m: "block frozen (dropped from the model, held and turned with the encoder, "
               "resumed when back under the limit)", None,
     lambda m: rec(m, " after returning to 156 rad/s"),
     lambda m: f"{nm(m['max_err_nm'])} while frozen (its line is not removed)"),
    ("load_step_up", lambda m: "load step +10 N m in 5 ms",
     lambda m: "offset-jump gate sends the step to the offset state", None, None, None),
    ("load_step_down", lambda m: "load step -10 N m in 5 ms", lambda m: "same", None, None, None),
    ("ripple_amplitude_step",
     lambda m: f"ripple amplitude change (an extra {m['extra_line_nm']} N m motor order-2 "
               "line appears)",
     lambda m: "the order-2 block re-estimates", None, None, None),
    ("can_tx_queue_full", lambda m: f"CAN transmit queue full, {m['window_ms']} ms",
     lambda m: "frames dropped and counted; the first frame through carries the flag; the "
               f"sequence shows the loss modulo 256 (a gap of {m['seq_gap']})",
     None, lambda m: rec(m, note="telemetry resumes; "), None),
    ("can_bus_off", lambda m: f"CAN bus-off, {m['window_ms']} ms", lambda m: "same", None,
     lambda m: rec(m, note="telemetry resumes; "), None),
    ("can_error_frames",
     lambda m: f"error frames, frames for other ids ({m['frames']} frames)",
     lambda m: "ignored: no ACK, no counter, no change", None, in_band, None),
    ("can_malformed_commands",
     lambda m: "malformed / unknown command frames (DLC 0 and 3, RTR, FD, unknown opcodes, "
               f"unknown / read-only parameter, bad block index; {m['frames']} frames)",
     lambda m: f"error ACK with the documented result ({results(m['results'])}), "
               "configuration and calibration byte-identical", None, in_band, None),
    ("can_out_of_range_config",
     lambda m: f"out-of-range configuration ({m['frames']} cases)",
     lambda m: f"rejected ({results(m['results'])}), configuration byte-identical",
     None, in_band, None),
    ("can_command_flood", lambda m: f"{m['frames']} command frames at once",
     lambda m: f"{m['acks_per_tick']} answered per tick, all in order",
     lambda m: "(per command)", lambda m: f"{m['drain_ticks']} ticks to drain", lambda m: "-"),
    ("calib_missing", lambda m: "calibration record missing",
     lambda m: f"defaults ({m['gain_nm_per_v']} N m/V, {m['offset_v']} V) used, the joint runs",
     lambda m: f"{faults(m['faults'])} every tick, {calib_status(m['calib_status'])}",
     lambda m: "cleared on the tick after a good CALIB_SAVE", lambda m: "-"),
    ("calib_crc_corrupt", lambda m: "calibration record CRC-corrupt (both copies)",
     lambda m: "defaults", lambda m: f"{faults(m['faults'])}, {calib_status(m['calib_status'])}",
     lambda m: "same", lambda m: "-"),
    ("calib_implausible_gain",
     lambda m: "calibration record with an intact CRC and a gain no bridge chain has",
     lambda m: "counted as corrupt: defaults",
     lambda m: f"{faults(m['faults'])}, {calib_status(m['calib_status'])}",
     lambda m: "same", lambda m: "-"),
    ("calib_one_copy", lambda m: "one copy corrupt",
     lambda m: f"the good copy is used ({m['gain_nm_per_v']} N m/V, {m['offset_v']} V)",
     lambda m: f"{faults(m['faults'])}, {calib_status(m['calib_status'])}",
     lambda m: "-", lambda m: "-"),
    ("calib_wrong_version", lambda m: "wrong record version (intact CRC)", lambda m: "defaults",
     lambda m: f"{faults(m['faults'])}, {calib_status(m['calib_status'])}",
     lambda m: "after a save", lambda m: "-"),
    ("calib_nvm_error", lambda m: "NVM I/O error", lambda m: "defaults",
     lambda m: f"{faults(m['faults'])}, {calib_status(m['calib_status'])}",
     lambda m: "after a save", lambda m: "-"),
    ("calib_power_loss",
     lambda m: f"power loss at each of the {m['cut_points']} byte positions of a CALIB_SAVE "
               "(erase + write)",
     lambda m: f"at the next boot: the old record ({m['old']} cut points) or the new one "
               f"({m['new']}: the complete write), never defaults, never the old one after "
               "the new one", lambda m: "at most CALIB_ONE_COPY", lambda m: "-", lambda m: "-"),
    ("profile_power_loss",
     lambda m: f"power loss at each of the {m['cut_points']} byte positions of a PROFILE_SAVE",
     lambda m: f"at the next boot: the old profile ({m['old']} cut points) or the new one "
               f"({m['new']}), never none, never the old one after the new one",
     lambda m: "never PROFILE_UNUSABLE", lambda m: "-", lambda m: "-"),
]

# The filter pipeline table: (cases, input, what the filter does).
FILTER_ROWS = [
    (("filter_nan_torque", "filter_nan_torque_100", "filter_pos_inf_torque",
      "filter_neg_inf_torque"),
     "NaN torque (1 and 100 samples), +inf, -inf", "prediction only"),
    (("filter_1e30_torque", "filter_3e38_torque"),
     "1e30 or 3e38 N m (finite, beyond `HD_KF_MAX_ABS_Y_NM`)",
     "correction skipped, prediction continues"),
    (("filter_nan_angle", "filter_inf_angle"), "NaN or inf angle increment",
     "the increment is taken as 0 (the blocks fall one step of phase behind and "
     "re-estimate it)"),
    (("filter_1e6_rad_angle_step",), "1e6 rad angle increment in one step",
     "phase lost (beyond four turns): every block restarted from zero; the output-locked "
     "block relearns over output revolutions"),
]


def _cell(v: str) -> str:
    return v.replace("|", "\\|")


def table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(_cell(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def _used(measured: dict, name: str, used: set) -> dict[str, str]:
    if name not in measured:
        raise GenDocError(f"no measured line for case {name} (test renamed or removed?)")
    used.add(name)
    return measured[name]


def faults_block(measured: dict, used: set) -> str:
    rig = _used(measured, "rig", used)
    base = _used(measured, "no_fault", used)
    rows = []
    for name, fault, does, flag, recovery, err in ROWS:
        m = _used(measured, name, used)
        rows.append([fault(m), does(m), flag(m) if flag else faults(m["faults"]),
                     recovery(m) if recovery else rec(m),
                     err(m) if err else nm(m["max_err_nm"])])
    head = (f"Recovery band {rig['band_nm']} N m held for {rig['hold_ticks']} ticks; faults "
            f"start at {rig['fault_start_s']} s.  Without a fault the error over "
            f"{base['from_s']}-{base['to_s']} s is {nm(base['rms_err_nm'])} N m RMS, "
            f"{nm(base['max_err_nm'])} N m peak.  Recovery limits are the ones the tests "
            "assert.")
    return head + "\n\n" + table(
        ["fault (injected)", "what the firmware does", "flag (bit)",
         "recovery [ticks = ms] (limit)", "worst error meanwhile [N m]"], rows)


def filter_block(measured: dict, used: set) -> str:
    rows = []
    for names, what, does in FILTER_ROWS:
        ms = [_used(measured, n, used) for n in names]
        status = sorted({m["status"].replace("|", " + ") for m in ms})
        recs = [m["recovery_ticks"] for m in ms]
        limits = sorted({m["limit_ticks"] for m in ms})
        rows.append([what, f"{' / '.join(status)}: {does}",
                     f"{' / '.join(dict.fromkeys(recs))} (limit {' / '.join(limits)})"])
    return table(["input", "filter status: what happens", "recovery [ticks] (limit)"], rows)


def reaction(m: dict[str, str], note: str = "") -> str:
    return f"**{m['reaction_ticks']}**{note} (limit {m['limit_ticks']})"


def resume(m: dict[str, str], what: str) -> str:
    return f"{ticks(m['resume_ticks'])} {what}"


# The control stage (fw_control): (case, fault, reaction, reaction time,
# back to the asked mode).  The flag column is the case's `faults`.
CONTROL_ROWS = [
    ("ctrl_watchdog",
     lambda m: f"no new setpoint for `ctrl_watchdog_ms` ({m['timeout_ms']} ms; a repeated "
               "sequence number is not new)",
     lambda m: f"DAMP, STOP `ctrl_damp_ms` ({m['damp_ms']} ms) later",
     lambda m: f"DAMP **{m['damp_ticks']}**, STOP **{m['stop_ticks']}** after the last new "
               "setpoint (limit +1)",
     lambda m: "at the next new setpoint"),
    ("ctrl_encoder_lost", lambda m: "motor encoder reports a fault",
     lambda m: "STOP (drive disabled), latched", reaction,
     lambda m: f"latched while the encoder is back ({m['latched_ticks']} ticks checked); "
               f"{resume(m, 'after a STOP setpoint')}"),
    ("ctrl_gauge_adc_error", lambda m: "gauge: ADC read error",
     lambda m: "DAMP (open loop: the torque loop needs the gauge)", reaction,
     lambda m: resume(m, "after the first good sample")),
    ("ctrl_gauge_saturated", lambda m: "gauge saturated", lambda m: "same", reaction,
     lambda m: resume(m, "after the first good sample")),
    ("ctrl_gauge_open_bridge", lambda m: "gauge: open bridge", lambda m: "same", reaction,
     lambda m: resume(m, "after the first good sample")),
    ("ctrl_gauge_out_of_range", lambda m: "gauge beyond `torque_limit_nm`", lambda m: "same",
     reaction, lambda m: resume(m, "after the first good sample")),
    ("ctrl_filter_reset",
     lambda m: "filter restart (its correction held at a tiny `correction_max_nm`)",
     lambda m: "DAMP for the tick of the restart", reaction,
     lambda m: resume(m, "after the restart")),
    ("ctrl_filter_frozen",
     lambda m: f"filter block frozen ({m['speed_rad_s']} rad/s: motor order 4 over Nyquist)",
     lambda m: "none by design: the frozen block holds its estimate, TORQUE runs on",
     lambda m: f"- ({m['frozen_ticks']} frozen ticks, {m['other_mode_ticks']} not in TORQUE)",
     lambda m: "-"),
    ("ctrl_drive_fault", lambda m: "the drive reports a fault",
     lambda m: "STOP (drive disabled), latched", reaction,
     lambda m: resume(m, "after a STOP setpoint")),
    ("ctrl_drive_call_failed", lambda m: "a drive call fails",
     lambda m: "same (the drive disabled in that tick)", reaction,
     lambda m: resume(m, "after a STOP setpoint")),
    ("ctrl_bus_off", lambda m: "CAN bus-off",
     lambda m: "DAMP until a send period passes without a failed send",
     lambda m: reaction(m, " (a failed send is seen by the next tick)"),
     lambda m: f"{ticks(m['resume_ticks'])} after the bus is back (send period "
               f"{m['send_period_ticks']} ticks)"),
    ("ctrl_deadline_misses", lambda m: "repeated deadline misses (one alone: nothing)",
     lambda m: "DAMP", lambda m: reaction(m, f" from miss {m['misses']}"),
     lambda m: resume(m, "after the last miss")),
    ("ctrl_setpoint_refused",
     lambda m: f"setpoint out of range ({m['cases']} kinds: unknown mode, torque, position "
               "window, not a number)",
     lambda m: f"refused: ACK {results(','.join(dict.fromkeys(m['results'].split(','))))}, "
               "the last good setpoint stays",
     lambda m: f"never reaches the drive ({m['commands']} commands)", lambda m: "-"),
    ("ctrl_current_limit",
     lambda m: f"TORQUE {m['setpoint_nm']} N m against a gauge stuck at 0 (the loop winds up)",
     lambda m: f"current held at the limit: largest {m['max_abs_a']} A, limit {m['limit_a']} A",
     lambda m: "-", lambda m: "-"),
    ("ctrl_any_input",
     lambda m: f"{m['ticks']} ticks of random SETPOINT / GAINS frames ({m['frames']}), gauge "
               "readings, sensor faults, deadline misses and speeds",
     lambda m: f"largest command {m['max_abs_a']} A, limit {m['limit_a']} A, "
               f"{m['non_finite']} non-finite",
     lambda m: "-", lambda m: "-"),
]


def control_block(measured: dict, used: set) -> str:
    rows = []
    for name, fault, does, react, back in CONTROL_ROWS:
        m = _used(measured, name, used)
        rows.append([fault(m), does(m), faults(m["faults"]) if "faults" in m else "-",
                     react(m), back(m)])
    return table(["fault (injected)", "reaction (asserted)", "flag (bit)",
                  "reaction [ticks = ms] (limit)", "back to the asked mode"], rows)


SOAK_ROWS = [
    ("non-finite values", lambda s: s["non_finite"]),
    ("P asymmetric entries / not-PSD checks",
     lambda s: f"{s['p_asymmetric_entries']} / {s['p_not_psd_checks']} ({s['checks']} checks)"),
    ("smallest eigenvalue of P / Frobenius norm",
     lambda s: f"{s['p_min_eig_over_frobenius']} (limit -{s['p_psd_tolerance_over_frobenius']})"),
    ("filter resets; P clamps (ceiling, negative); frozen steps",
     lambda s: f"{s['filter_resets']}; {s['p_ceiling_clamps']}, {s['p_negative_clamps']}; "
               f"{s['steps_frozen']}"),
    ("window", lambda s: f"{s['window_s']} s"),
    ("RMS error first / last window",
     lambda s: f"{s['rms_err_first_nm']} / {s['rms_err_last_nm']} N m "
               f"({100 * float(s['rms_rel_diff_last_vs_first']):.1f} %, "
               f"limit {100 * float(s['rms_rel_diff_limit']):g} %)"),
    ("mean error first / last",
     lambda s: f"{s['mean_err_first_nm']} / {s['mean_err_last_nm']} N m (difference limit "
               f"{s['mean_diff_limit_nm']} N m)"),
    ("RMS error of a fresh filter on the last window",
     lambda s: f"{s['rms_err_last_fresh_filter_nm']} N m (long run "
               f"{100 * float(s['rms_excess_long_vs_fresh']):+.2f} %, "
               f"limit +{100 * float(s['rms_excess_limit']):g} %)"),
    ("largest error after the warm-up", lambda s: f"{s['max_abs_err_after_warmup_nm']} N m"),
]


def soak_block(soak: dict[str, str], timing: bool) -> str:
    rows = [[what, f(soak)] for what, f in SOAK_ROWS]
    if timing:
        rows.append(["time", f"{float(soak['ns_per_step']) / 1000:.2f} us/step, "
                             f"{float(soak['wall_s']):.0f} s"])
    steps = int(soak["steps"])
    return table(["", f"{steps:.0e} steps = {float(soak['hours']):.3g} h, {soak['states']} states"
                  .replace("e+0", "e")], rows)


def render(measured: dict, soak: dict) -> dict[str, str]:
    used: set[str] = set()
    blocks = {"reliability-faults": faults_block(measured, used),
              "reliability-filter-input": filter_block(measured, used),
              "reliability-control": control_block(measured, used),
              "reliability-soak": soak_block(soak, timing=False)}
    unused = sorted(set(measured) - used)
    if unused:
        raise GenDocError(f"measured cases without a row in rel_doc.py: {', '.join(unused)}")
    return blocks


def soak_long(build: Path) -> dict[str, str]:
    where = machine()
    cmd = [command_of(ctest_commands(build), SOAK_TEST, build)[0]] + SOAK_LONG_ARGS
    soak = summary.parse(run(cmd, 3600))
    if soak.get("result") != "PASS":
        raise GenDocError("hd_soak 10^8: no PASS result")
    head = (f"_`hd_soak {' '.join(SOAK_LONG_ARGS)}`, {build_info(build)}, {where}; written by "
            "`tests/reliability/rel_doc.py --soak-long`, not checked_")
    return {"reliability-soak-long": head + "\n\n" + soak_block(soak, timing=True)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", type=Path, help="build folder whose tests are run")
    ap.add_argument("--check", action="store_true", help="compare, do not write")
    ap.add_argument("--soak-long", type=Path, metavar="BUILD",
                    help="run the 10^8 soak of this (release) build and write its block")
    ap.add_argument("--doc", type=Path, default=DOC)
    a = ap.parse_args(argv)
    if not a.build and not a.soak_long:
        ap.error("give --build, --soak-long or both")
    try:
        if a.build:
            measured, soak = measure(a.build.resolve())
            print(update_doc(a.doc, render(measured, soak), a.check, REGENERATE))
        if a.soak_long:
            if a.check:
                raise GenDocError("--soak-long is a benchmark: it is written, never checked")
            print(update_doc(a.doc, soak_long(a.soak_long.resolve()), False, ""))
    except GenDocError as exc:
        print(f"rel_doc: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
