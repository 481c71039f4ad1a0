"""The add-and-verify loop.

Each round: replay with the current model -> detect candidates -> try the
strongest untried one (re-run the same C filter with it) -> keep it only if
it helps -> repeat.

"Helps" (no ground truth is used for any decision):
  * a new oscillator block (line effects): the line's least-squares
    amplitude in the filtered torque falls by at least LINE_DROP, the
    innovation RMS does not rise by more than INNOV_TOL, and the change of
    the filtered torque is essentially the line (rms change <= CHANGE_FACTOR
    x the line's rms), i.e. the block did not eat real torque;
  * a retuned block (q x 10: ripple whose amplitude or phase moves): the
    same line test;
  * a load coefficient (ripple amplitude x (1 + k |T|), when the residue's
    envelope follows the load): the innovation RMS falls by at least
    LOAD_GAIN and the residue band around the line falls;
  * an expected-torque term (velocity, acceleration): the innovation RMS
    falls by at least INNOV_GAIN and the slow model residual falls;
  * offset drift (offset state as a slowly moving sensor-zero error): only
    when the trend dominates what the expected torque leaves (the rest of
    the slow residual is below a quarter of the trend's excursion), since a
    sensor drift cannot otherwise be told from real slow torque, and the
    model residual then falls by at least a quarter.  (The innovation is no
    guide here: a slower offset state always predicts worse.)
Stopping rule: stop when no candidate passes detection (peak >= 30x local
floor and >= 0.2 % of residual variance for lines; >= 2 % partial variance
for slow terms), when every candidate has been tried once, when the filter
has 8 blocks, or after MAX_ROUNDS rounds.
"""
from __future__ import annotations

import math

import numpy as np

from . import detect, replay as rp, spectra
from .model import NOISE_FLOOR_NM, SENSOR_DRIFT_SETTLE_S, Block, Model

LINE_DROP = 0.5
INNOV_TOL = 0.01
INNOV_GAIN = 0.002
CHANGE_FACTOR = 2.0
MAX_ROUNDS = 8
MAX_BLOCKS = 8
RETUNE_FACTOR = 10.0
LOAD_GAIN = 0.05


def apply(model: Model, c: detect.Candidate) -> Model | None:
    m = model.copy()
    q = Model.q_for_settle(m.r_nm2, m.ts_s, 0.05)
    if c.action == "add_block":
        if len(m.blocks) >= MAX_BLOCKS:
            return None
        lock = {"motor_order": "motor", "output_order": "output", "fixed_frequency": "fixed"}[c.kind]
        m.blocks.append(Block(lock, round(c.order, 2), q))
    elif c.action == "retune_block":
        b = m.blocks[c.evidence["existing_block"]]
        b.q_nm2 = b.q_nm2 * RETUNE_FACTOR
    elif c.action == "load_scale":
        m.ripple_load_coeff_per_nm = c.params["ripple_load_coeff_per_nm"]
    elif c.action == "expected_torque":
        for k, v in c.params.items():
            if getattr(m, k) + v < 0:
                # The firmware's model has J, b, Fc >= 0: a negative total
                # is not a physical friction/inertia (wrong torque sign, or
                # real load torque correlated with the motion).
                c.evidence["rejected_because"] = (
                    f"{k} would be negative ({getattr(m, k) + v:.4g}): not physical")
                return None
            setattr(m, k, getattr(m, k) + v)
    elif c.action == "offset_sensor_error":
        if m.offset_is_sensor_error:
            c.evidence["rejected_because"] = "the offset is already treated as a sensor drift"
            return None
        m.offset_enabled = True
        m.offset_is_sensor_error = True
        m.offset_q_nm2 = Model.q_for_settle(m.r_nm2, m.ts_s, SENSOR_DRIFT_SETTLE_S)
    return m


def line_amplitude(runs, kind, order, raw=False):
    """Least-squares amplitude of the line in the filtered (or raw) torque
    (slow torque removed first, see spectra.highpass_for_line)."""
    sig = [(np.asarray(r.torque_nm, float) if raw else r.filtered)[r.warm:] for r in runs]
    if kind == "motor_order":
        ph = [order * r.motor_angle_rad[r.warm:] for r in runs]
    elif kind == "output_order":
        ph = [order * r.output_angle_rad[r.warm:] for r in runs]
    else:
        ph = [2 * math.pi * order * np.asarray(r.t_s[r.warm:], float) for r in runs]
    ts = float(np.median(np.diff(runs[0].t_s))) if len(runs[0].t_s) > 1 else 1e-3
    sig = spectra.highpass_for_line(sig, ph, ts)
    amp, _, _ = spectra.fit_line(detect._decimated(sig), detect._decimated(ph))
    return amp


def judge(c, runs0, m0, runs1, m1, view0=None, view1=None):
    """Returns (keep, evidence).  view0/view1: analysis views of the two
    replays (line amplitudes are measured on them)."""
    view0 = runs0 if view0 is None else view0
    view1 = runs1 if view1 is None else view1
    ev = {"innovation_rms_before_nm": m0["innovation_rms_nm"],
          "innovation_rms_after_nm": m1["innovation_rms_nm"],
          "model_residual_rms_before_nm": m0["model_residual_rms_nm"],
          "model_residual_rms_after_nm": m1["model_residual_rms_nm"]}
    innov_change = m1["innovation_rms_nm"] / m0["innovation_rms_nm"] - 1.0
    if m1.get("filter_resets", 0) > m0.get("filter_resets", 0):
        ev["rejected_because"] = "the filter reset itself with this change"
        return False, ev
    if c.action == "load_scale":
        if innov_change > -LOAD_GAIN:
            ev["rejected_because"] = "the innovation did not fall by 5 %"
            return False, ev
        return True, ev
    if c.kind in ("motor_order", "output_order", "fixed_frequency"):
        if c.evidence.get("phase_coherent_over_record") is False:
            # No common phase over the record: measure in the averaged
            # spectrum (per-window phase) instead of one global fit.
            a0 = spectral_line_amplitude(view0, c.kind, c.order)
            a1 = spectral_line_amplitude(view1, c.kind, c.order)
            ev["amplitude_measure"] = "averaged spectrum"
        else:
            a0 = line_amplitude(view0, c.kind, c.order)
            a1 = line_amplitude(view1, c.kind, c.order)
        d = np.concatenate([(r1.filtered - r0.filtered)[r0.warm:] for r0, r1 in zip(runs0, runs1)])
        change_rms = float(np.sqrt(np.mean(d ** 2)))
        line_rms = a0 / math.sqrt(2)
        ev.update({"line_amplitude_before_nm": a0, "line_amplitude_after_nm": a1,
                   "output_change_rms_nm": change_rms})
        if a1 > (1 - LINE_DROP) * a0:
            ev["rejected_because"] = "the line did not drop by half in the filtered torque"
            return False, ev
        if innov_change > INNOV_TOL:
            ev["rejected_because"] = "the innovation grew"
            return False, ev
        if change_rms > CHANGE_FACTOR * line_rms + 1e-9:
            ev["rejected_because"] = "the filtered torque changed by more than the line"
            return False, ev
        return True, ev
    if c.kind in ("velocity", "acceleration"):
        if innov_change > -INNOV_GAIN:
            ev["rejected_because"] = "the innovation did not fall"
            return False, ev
        if m1["model_residual_rms_nm"] >= m0["model_residual_rms_nm"]:
            ev["rejected_because"] = "the model residual did not fall"
            return False, ev
        return True, ev
    if c.kind == "offset_drift":
        exc = c.evidence.get("trend_excursion_nm", 0.0)
        rest = c.evidence.get("residual_after_trend_rms_nm", float("inf"))
        if rest > 0.25 * exc:
            ev["rejected_because"] = ("the expected torque does not explain the rest of the "
                                      "slow torque: a drift cannot be told from real torque")
            return False, ev
        if m1["model_residual_rms_nm"] > 0.75 * m0["model_residual_rms_nm"]:
            ev["rejected_because"] = ("with the offset as a slow sensor error the slow residual "
                                      "did not fall by a quarter")
            return False, ev
        return True, ev
    return False, ev


def _trials(model, c, noise_estimate_nm):
    """The models to try for candidate c.  A load coefficient removes what
    made the starting R large (ripple lines that move with the load and that
    the blocks then chased): it is also tried with R back at the noise
    estimate, and the trial with the better innovation likelihood is judged
    (R is a noise parameter: likelihood is its criterion)."""
    first = apply(model, c)
    if first is None or c.action != "load_scale" or not noise_estimate_nm:
        return [first]
    if model.r_nm2 <= 1.5 * max(noise_estimate_nm, NOISE_FLOOR_NM) ** 2:
        return [first]
    return [first, apply(model.with_noise(noise_estimate_nm), c)]


def run_loop(data, model0: Model, log=print, feedforward=None, noise_estimate_nm=None):
    runs = rp.replay(data, model0, feedforward)
    met = rp.metrics(runs)
    model = model0
    history = [{"step": 0, "change": "starting model", **met}]
    effects = []
    tried = set()
    first_runs, first_met = runs, met
    for rnd in range(1, MAX_ROUNDS + 1):
        ctx = detect.build_context(rp.analysis_view(runs), data.ts_s, model.gear_ratio)
        lines = detect.line_candidates(ctx, model) + detect.block_residue_candidates(ctx, model)
        slow = detect.slow_candidates(ctx, model)
        # Order of trial: lines (strongest first), then expected-torque
        # terms, and drift last: a drift is only judged once everything
        # else that could explain slow torque has been tried.
        drift = [c for c in slow if c.kind == "offset_drift"]
        slow = [c for c in slow if c.kind != "offset_drift"]
        # A residue whose envelope follows the load is tried before a
        # plain retune of the same line: it is the more specific reading.
        cands = (sorted(lines, key=lambda c: (c.action != "load_scale", -c.score))
                 + sorted(slow, key=lambda c: -c.score) + drift)
        for c in cands:
            if c.action == "report_only" and c.key() not in tried:
                tried.add(c.key())
                effects.append(_finding(c, False, None, None, model.gear_ratio))
        cands = [c for c in cands if c.key() not in tried]
        if not cands:
            log(f"round {rnd}: nothing significant left")
            break
        progressed = False
        for c in cands:
            tried.add(c.key())
            trials = _trials(model, c, noise_estimate_nm)
            if trials[0] is None:
                c.evidence.setdefault("rejected_because",
                                      "cannot be expressed in the firmware model")
                effects.append(_finding(c, False, None, None, model.gear_ratio))
                continue
            scored = []
            for t in trials:
                r1 = rp.replay(data, t, feedforward)
                scored.append((rp.metrics(r1)["innovation_nll"], t, r1))
            if len(scored) > 1:
                c.evidence["r_variants_innovation_nll"] = [round(s[0], 4) for s in scored]
                c.evidence["r_back_to_noise_estimate"] = bool(scored[1][0] < scored[0][0])
            _, trial, runs1 = min(scored, key=lambda s: s[0])
            met1 = rp.metrics(runs1)
            keep, ev = judge(c, runs, met, runs1, met1, rp.analysis_view(runs),
                             rp.analysis_view(runs1))
            c.evidence.update(ev)
            effects.append(_finding(c, keep, met, met1, model.gear_ratio))
            log(f"round {rnd}: {c.kind} {c.order:.4g} ({c.action}) -> "
                f"{'kept' if keep else 'rejected'}: {ev.get('rejected_because', '')}")
            if keep:
                model, runs, met = trial, runs1, met1
                history.append({"step": len(history), "change": _describe(c), **met})
                progressed = True
                break
        if not progressed:
            break
    return {"model": model, "runs_before": first_runs, "runs_after": runs,
            "metrics_before": first_met, "metrics_after": met, "history": history,
            "effects": effects}


def _describe(c):
    if c.action == "add_block":
        return f"add {c.kind} block {c.order:.4g}"
    if c.action == "retune_block":
        return f"raise q of the {c.kind} {c.order:.4g} block x{RETUNE_FACTOR:g}"
    if c.action == "load_scale":
        return (f"ripple amplitude x (1 + {c.params['ripple_load_coeff_per_nm']:.3g} |T|) "
                f"(seen on the {c.kind} {c.order:.4g} line)")
    if c.action == "expected_torque":
        return "expected torque += " + ", ".join(f"{k} {v:+.4g}" for k, v in c.params.items())
    return "offset state as sensor error (slow drift)"


def _finding(c, added, m0, m1, gear_ratio):
    f = {"kind": c.kind, "action": c.action, "amplitude_nm": c.amplitude_nm, "added": bool(added),
         "evidence": c.evidence}
    if c.kind == "motor_order":
        f["order_per_motor_rev"] = c.order
        f["order_per_output_rev"] = c.order * gear_ratio
    elif c.kind == "output_order":
        f["order_per_output_rev"] = c.order
        f["order_per_motor_rev"] = c.order / gear_ratio
    elif c.kind == "fixed_frequency":
        f["frequency_hz"] = c.order
    if c.params:
        f["parameters"] = c.params
    if m0 is not None:
        f["metrics_before"] = m0
        f["metrics_after"] = m1
    return f


def spectral_line_amplitude(runs, kind, order, raw=False):
    """Line amplitude from the averaged order (or time) spectrum: the peak
    within +-2 bins of the line.  Each spectral window has its own phase,
    so this survives a slowly drifting phase (inexact gear ratio, real
    logs) where one global least-squares fit does not; it includes the
    noise floor in that bin."""
    sig = [(np.asarray(r.torque_nm, float) if raw else r.filtered)[r.warm:] for r in runs]
    ts = float(np.median(np.diff(runs[0].t_s))) if len(runs[0].t_s) > 1 else 1e-3
    if kind == "fixed_frequency":
        spec = spectra.time_spectrum(sig, ts)
    else:
        ang = [(r.motor_angle_rad if kind == "motor_order" else r.output_angle_rad)[r.warm:]
               for r in runs]
        spec = spectra.order_spectrum(sig, ang)
    if spec is None:
        return float("nan")
    i = int(round((order - spec.axis[0]) / (spec.axis[1] - spec.axis[0])))
    if i < 1 or i >= len(spec.axis) - 2:
        return float("nan")
    return float(np.sqrt(np.max(spec.amp2[max(i - 2, 0):i + 3])))
