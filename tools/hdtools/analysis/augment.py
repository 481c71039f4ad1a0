"""The add-and-verify loop, with decisions that hold out of sample.

The log is split into fold A (detect and fit) and fold B (judge): time
blocks that alternate A, B (replay.folds).  Each round: replay with the
current model -> detect candidates in fold A -> fit each one's parameters
in fold A -> re-run the same C filter over the whole log with the candidate
-> keep it only if it helps in fold B, which it never saw.  No ground truth
is used for any decision.

Every change (a line, a retune, a load coefficient, friction, inertia,
drift, the angle profile, R, nyquist_fraction) must pass two tests in fold B:
  * the held-out innovation RMS does not grow (INNOV_EPS: float noise only);
  * the change does what it is for, measured in fold B:
      - a new or retuned block: the line's amplitude in the filtered torque
        falls by at least LINE_DROP, and the filtered torque changes by no
        more than CHANGE_FACTOR x the line's rms (the block did not eat real
        torque);
      - a load coefficient (loadcoef.py; tried with the output profile
        refitted under it): the innovation falls by loadcoef.INNOV_GAIN, or
        fold B's own fit of the coefficient agrees with it;
      - friction / inertia: the innovation falls by INNOV_GAIN and the model
        residual falls; J, b, Fc stay >= 0 (the firmware's model);
      - the angle profile (output-locked lines, geometry.py): with the
        profile subtracted, fold B's slow residual minus a smoother of the
        same time constant falls (the profile predicts angle-locked torque
        it was not fitted on);
      - drift (the offset state read as a sensor error; same q, so the
        innovation is unchanged): the line fitted in fold A leaves less
        than DRIFT_REST_FRACTION of its excursion in fold B;
      - R and nyquist_fraction: fold B keeps no more of the model's own
        motor-locked and fixed lines than before.
Stopping rule: stop when no candidate passes detection, every candidate has
been tried, the filter has 8 blocks, or after MAX_ROUNDS rounds.
"""
from __future__ import annotations

import math

import numpy as np

from .. import canproto, protocol
from . import detect, detect_slow, geometry, loadcoef, replay as rp
from .cfilter import MAX_BLOCKS   # the filter's capacity, read from filter/hd_kf.h
from .lineamp import (LINE_FIT_MAX_SAMPLES, line_amplitude, lines_left,  # noqa: F401
                      spectral_line_amplitude)
from .loadlevel import load_of
from .model import NOISE_FLOOR_NM, Block, Model, ProfileLine

LINE_DROP = 0.5
INNOV_EPS = 1e-6
INNOV_GAIN = 0.002
CHANGE_FACTOR = 2.0
MAX_ROUNDS = 8
RETUNE_FACTOR = 10.0
PROFILE_GAIN = 0.01
LINES_LEFT_TOL = 0.02
def apply(model: Model, c: detect.Candidate) -> Model | None:
    m = model.copy()
    q = Model.q_for_settle(m.r_nm2, m.ts_s, 0.05)
    if c.action == "add_block":
        if len(m.blocks) >= MAX_BLOCKS:
            c.evidence["rejected_because"] = f"the filter has {MAX_BLOCKS} blocks"
            return None
        if not canproto.order_representable(c.order):
            c.evidence["rejected_because"] = (
                f"order {c.order:g} is not representable on CAN "
                f"({canproto.ORDER_MIN:g}..{canproto.ORDER_MAX:g})")
            return None
        lock = {"motor_order": "motor", "fixed_frequency": "fixed"}[c.kind]
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
    elif c.action == "set_profile":
        m = with_profile(m, c.params["profile"])
        if m is None:
            c.evidence["rejected_because"] = f"the filter has {MAX_BLOCKS} blocks"
            return None
    elif c.action == "set_tuning":
        for k, v in c.params.items():
            if k == "noise_nm":
                m = m.with_noise(v)
            else:
                setattr(m, k, v)
    else:
        return None
    return m


def with_profile(model: Model, lines) -> Model | None:
    """The model with its output-locked lines as a fixed angle profile: one
    output block per line, output_learn_scale 0 (they predict and turn but
    never learn, so no load is ever taken), their state imported from the
    profile at the first sample (replay.py).  None if the blocks do not fit."""
    m = model.copy()
    q = Model.q_for_settle(m.r_nm2, m.ts_s, 0.05)
    keep = [b for b in m.blocks if b.lock != "output"]
    if len(keep) + len(lines) > MAX_BLOCKS:
        return None
    m.blocks = keep + [Block("output", float(o["order"]), q) for o in lines]
    m.profile = [ProfileLine("output", float(o["order"]), o["a_nm"], o["b_nm"]) for o in lines]
    m.output_learn_scale = 0.0 if lines else 1.0
    return m


# --- the angle profile ------------------------------------------------------------

GEOMETRY_MAX_SAMPLES = 300_000


def profile_gains(runs, view, model):
    """Per stretch of the view, the factor the firmware's held output rows
    carry with a model load coefficient c (hd_kf_rows.c): (1 + c |T_ref|) /
    (1 + c T_c), T_ref the filter's slow torque (expected + offset), T_c the
    record's load (what the replay imports the profile at), within the row's
    envelope; None without c (rows at 1)."""
    c = model.ripple_load_coeff_per_nm
    if not c > 0 or not view:
        return None
    ts = float(np.median(np.diff(view[0].t_s[:100])))
    load_c = load_of(((r.torque_nm, r.feedforward_nm, r.motor_angle_rad) for r in runs), ts)
    hi = protocol.param_by_key("output_row_max").default
    return [np.clip((1.0 + c * np.abs(r.out["torque_expected_nm"] + r.out["offset_nm"]))
                    / (1.0 + c * (load_c or 0.0)), 1.0 / hi, hi) for r in view]


def profile_inputs(runs, model, which) -> geometry.Inputs:
    """Signals for the geometry fit from a replay whose output-locked lines
    are a fixed profile (or absent): the model residual plus that profile,
    i.e. measured - motor-locked ripple - expected torque - feed-forward
    (at most GEOMETRY_MAX_SAMPLES samples of the fold, evenly spread); with
    a model load coefficient the profile's lines carry the held rows'
    growth (profile_gains), in what is added back and in the fit."""
    view = rp.analysis_view(runs, which, max_total=GEOMETRY_MAX_SAMPLES)
    gains = profile_gains(runs, view, model)
    has_out = any(p.lock == "output" for p in model.profile)
    sig = [r.residual + (rp.profile_torque(model, r.motor_angle_rad, r.output_angle_rad)
                         * (1.0 if gains is None else gains[i]) if has_out else 0.0)
           for i, r in enumerate(view)]
    ts = float(np.median(np.diff(view[0].t_s[:100]))) if view else 1e-3
    return geometry.Inputs(sig, [r.output_angle_rad for r in view],
                           [np.asarray(r.t_s, float) for r in view],
                           [r.out["output_velocity_rad_s"].astype(float) for r in view], ts,
                           gains)


def profile_candidate(runs, model, generation):
    """The geometry-vs-load fit over fold A as a candidate profile; None if
    it selects the model's current profile again."""
    g = geometry.fit(profile_inputs(runs, model, rp.TRAIN))
    now = sorted(p.order for p in model.profile if p.lock == "output")
    new = [o["order"] for o in g["orders"]]
    if not g.get("verifiable") or not new:
        return None, g
    if new == now and generation == 0:
        return None, g
    ev = {k: v for k, v in g.items() if k != "orders"}
    ev["orders_before"] = now
    fresh = [o for o in g["orders"] if o["order"] not in now]
    lead = max(fresh or g["orders"], key=lambda o: o["amplitude_nm"])
    c = detect.Candidate("output_order", float(lead["order"]), lead["amplitude_nm"],
                         score=1e9, action="set_profile", evidence=ev,
                         params={"profile": g["orders"], "tau_s": g["tau_s"]})
    c.key_override = ("profile", tuple(new), generation)
    return c, g


def profile_held_out(c, runs0, model0):
    """Fold B: slow residual after a smoother (tau of the fit) and the motion
    nuisance, with the current and with the candidate's output profile
    subtracted."""
    inp = profile_inputs(runs0, model0, rp.HELD_OUT)
    tau = c.params["tau_s"]
    cur = [{"order": p.order, "a_nm": p.a_nm, "b_nm": p.b_nm}
           for p in model0.profile if p.lock == "output"]
    _, rms_cur = geometry.check(inp, cur, tau)
    _, rms_new = geometry.check(inp, c.params["profile"], tau)
    return rms_cur, rms_new


# --- judging -------------------------------------------------------------------

def _fold_metrics(met):
    keys = ("innovation_rms_nm", "model_residual_rms_nm", "error_rms_nm")
    out = {}
    for name in rp.FOLD_NAMES.values():
        for k in keys:
            if f"{name}_{k}" in met:
                out[f"{name}_{k}"] = met[f"{name}_{k}"]
    return out


NLL_EPS = 1e-3


def judged_by(c) -> str:
    """The held-out innovation measure a change is kept on: the likelihood
    for R (the innovation's predicted variance), the RMS for the rest."""
    return ("innovation_nll" if c.action == "set_tuning" and "noise_nm" in c.params
            else "innovation_rms_nm")


def judge(c, runs0, m0, runs1, m1, model0):
    """Returns (keep, evidence); every number that decides is from fold B."""
    B = "out_of_sample_"
    ev = {"before": _fold_metrics(m0), "after": _fold_metrics(m1)}
    i0, i1 = m0[B + "innovation_rms_nm"], m1[B + "innovation_rms_nm"]
    innov_change = i1 / i0 - 1.0 if i0 > 0 else 0.0
    ev["held_out_innovation_change"] = innov_change
    if m1.get("filter_resets", 0) > m0.get("filter_resets", 0):
        ev["rejected_because"] = "the filter reset itself with this change"
        return False, ev
    if judged_by(c) == "innovation_nll":
        # R is the innovation's predicted variance: judged by the held-out
        # likelihood of the innovation (its RMS alone falls with any R the
        # blocks may chase the load with)
        n0, n1 = m0.get(B + "innovation_nll"), m1.get(B + "innovation_nll")
        ev.update({"held_out_innovation_nll_before": n0, "held_out_innovation_nll_after": n1})
        if n0 is not None and n1 is not None and n1 > n0 + NLL_EPS:
            ev["rejected_because"] = (f"the held-out innovation likelihood fell (NLL {n0:.4g} -> "
                                      f"{n1:.4g})")
            return False, ev
    elif innov_change > INNOV_EPS:
        ev["rejected_because"] = (f"the held-out innovation grew ({i0:.4g} -> {i1:.4g} N m)")
        return False, ev
    vb0, vb1 = rp.analysis_view(runs0, rp.HELD_OUT), rp.analysis_view(runs1, rp.HELD_OUT)
    if c.action == "load_scale":
        ok, more = loadcoef.judge(c.params["ripple_load_coeff_per_nm"], innov_change, vb0,
                                  loadcoef.motor_orders(model0))
        ev.update(more)
        return ok, ev
    if c.action == "set_profile":
        cur, new = profile_held_out(c, runs0, model0)
        ev.update({"held_out_slow_rms_current_profile_nm": cur,
                   "held_out_slow_rms_new_profile_nm": new})
        if not new < (1 - PROFILE_GAIN) * cur:
            ev["rejected_because"] = ("the profile does not predict the held-out angle-locked "
                                      "torque better than the current one")
            return False, ev
        return True, ev
    if c.action == "set_tuning":
        a0, a1 = lines_left(vb0, model0), lines_left(vb1, apply(model0, c))
        ev.update({"held_out_lines_left_before_nm": a0, "held_out_lines_left_after_nm": a1})
        if a1 > a0 * (1 + LINES_LEFT_TOL) + 1e-12:
            ev["rejected_because"] = "the held-out fold keeps more of the modelled lines"
            return False, ev
        return True, ev
    if c.kind in ("motor_order", "fixed_frequency"):
        if c.evidence.get("phase_coherent_over_record") is False:
            # No common phase over the record: measure in the averaged
            # spectrum (per-window phase) instead of one global fit.
            a0 = spectral_line_amplitude(vb0, c.kind, c.order)
            a1 = spectral_line_amplitude(vb1, c.kind, c.order)
            ev["amplitude_measure"] = "averaged spectrum"
        else:
            a0 = line_amplitude(vb0, c.kind, c.order)
            a1 = line_amplitude(vb1, c.kind, c.order)
        d = np.concatenate([(r1.filtered - r0.filtered)[r0.fold == rp.HELD_OUT]
                            for r0, r1 in zip(runs0, runs1)])
        change_rms = float(np.sqrt(np.mean(d ** 2))) if len(d) else 0.0
        line_rms = a0 / math.sqrt(2)
        ev.update({"line_amplitude_before_nm": a0, "line_amplitude_after_nm": a1,
                   "output_change_rms_nm": change_rms})
        if not a1 <= (1 - LINE_DROP) * a0:
            ev["rejected_because"] = ("the line did not drop by half in the held-out filtered "
                                      "torque")
            return False, ev
        if change_rms > CHANGE_FACTOR * line_rms + 1e-9:
            ev["rejected_because"] = "the filtered torque changed by more than the line"
            return False, ev
        return True, ev
    if c.kind in ("velocity", "acceleration"):
        if innov_change > -INNOV_GAIN:
            ev["rejected_because"] = "the held-out innovation did not fall"
            return False, ev
        if m1[B + "model_residual_rms_nm"] >= m0[B + "model_residual_rms_nm"]:
            ev["rejected_because"] = "the held-out model residual did not fall"
            return False, ev
        return True, ev
    if c.kind == "offset_drift":
        h = detect_slow.drift_held_out(c, vb0)
        ev.update(h)
        if not h.get("held_out_samples"):
            ev["rejected_because"] = "no held-out samples on the drift's time base"
            return False, ev
        if not (h["held_out_rest_after_line_rms_nm"]
                <= detect_slow.DRIFT_REST_FRACTION * max(h["held_out_line_excursion_nm"], 1e-12)):
            ev["rejected_because"] = ("the line fitted in fold A does not explain fold B's slow "
                                      "residual: not a drift")
            return False, ev
        return True, ev
    ev["rejected_because"] = f"no held-out test for a {c.kind} {c.action}"
    return False, ev


# --- the loop ------------------------------------------------------------------

class Session:
    """The current model, its replay and metrics, and what was tried."""

    def __init__(self, data, model, log=print, noise_estimate_nm=None, output_orders=()):
        self.data, self.log = data, log
        self.fold = rp.folds(data)
        self.noise_estimate_nm = noise_estimate_nm
        self.output_orders = list(output_orders)
        self.model = model
        self.runs = rp.replay(data, model, self.fold)
        self.met = rp.metrics(self.runs)
        self.history = [{"step": 0, "change": "starting model", **self.met}]
        self.effects = []
        self.tuning = []        # R / nyquist_fraction trials (not effects)
        self.tried = set()
        self.generation = 0     # expected-torque changes so far (profile refits)
        self.segment_t0 = {}
        for p in data.pieces:
            self.segment_t0[p.segment] = min(self.segment_t0.get(p.segment, p.t_s[0]), p.t_s[0])

    def replay(self, model):
        return rp.replay(self.data, model, self.fold)

    def try_candidate(self, c, trials=None):
        trials = trials or [apply(self.model, c)]
        if trials[0] is None:
            c.evidence.setdefault("rejected_because", "cannot be expressed in the firmware model")
            self.effects.append(_finding(c, False, None, None, self.model.gear_ratio))
            return False
        best, nlls = None, []
        for t in trials:
            r1 = self.replay(t)
            nll = rp.metrics(r1, rp.TRAIN)["innovation_nll"]
            nlls.append(nll)
            if best is None or nll < best[0]:
                best = (nll, t, r1)
            del r1            # only the best replay is kept (memory)
        if len(nlls) > 1:
            # R is a noise parameter: the in-sample likelihood picks the
            # variant; fold B then judges it like any change.
            c.evidence["r_variants_in_sample_innovation_nll"] = [round(x, 4) for x in nlls]
            c.evidence["r_back_to_noise_estimate"] = bool(nlls[1] < nlls[0])
        _, trial, runs1 = best
        best = None
        met1 = rp.metrics(runs1)
        keep, ev = judge(c, self.runs, self.met, runs1, met1, self.model)
        c.evidence.update(ev)
        (self.tuning if c.action == "set_tuning" else self.effects).append(
            _finding(c, keep, self.met, met1, self.model.gear_ratio))
        self.log(f"{_describe(c)} -> {'kept' if keep else 'rejected'}"
                 + (f": {ev['rejected_because']}" if not keep else ""))
        if keep:
            self.model, self.runs, self.met = trial, runs1, met1
            self.history.append({"step": len(self.history), "change": _describe(c),
                                 "judged_by": judged_by(c), **met1})
            if c.action in ("expected_torque", "load_scale"):
                self.generation += 1
        return keep

    def _trials(self, c):
        """A load coefficient removes what made the starting R large (ripple
        lines that move with the load and that the blocks then chased): it
        is also tried with R back at the noise estimate.  It comes with the
        output profile refitted under it: the held rows grow the profile
        from its load T_c once the model has c, so a profile fitted without
        that growth is off by it."""
        first = apply(self.model, c)
        nz = self.noise_estimate_nm
        if first is None or c.action != "load_scale":
            return [first]
        trials = [first]
        if nz and self.model.r_nm2 > 1.5 * max(nz, NOISE_FLOOR_NM) ** 2:
            trials.append(apply(self.model.with_noise(nz), c))
        return [self._refit_profile(t) for t in trials]

    def _refit_profile(self, model):
        if not any(p.lock == "output" for p in model.profile):
            return model
        g = geometry.fit(profile_inputs(self.replay(model), model, rp.TRAIN))
        if not g.get("verifiable") or not g["orders"]:
            return model
        return with_profile(model, g["orders"]) or model

    def loop(self):
        for rnd in range(1, MAX_ROUNDS + 1):
            view = rp.analysis_view(self.runs, rp.TRAIN)
            if not view:
                break
            ctx = detect.build_context(view, self.data.ts_s, self.model.gear_ratio)
            lines = (detect.line_candidates(ctx, self.model)
                     + detect.block_residue_candidates(ctx, self.model)
                     + detect.load_candidate(view, self.data.ts_s, self.model))
            for c in lines:
                if c.action == "load_scale":
                    # tried again once the expected torque changed: T_ref with it
                    c.key_override = ("load_scale", self.generation)
            prof, _ = profile_candidate(self.runs, self.model, self.generation)
            # Output-order readings of spectral peaks are evidence for the
            # profile fit, not blocks of their own.
            for c in lines:
                if c.action == "profile" and c.key() not in self.tried:
                    self.tried.add(c.key())
            lines = [c for c in lines if c.action != "profile"]
            slow = detect_slow.slow_candidates(ctx, self.model)
            drift = detect_slow.drift_candidate(ctx, self.data.has_feedforward,
                                           self.segment_t0)
            # Order of trial: the profile, lines (strongest first), then
            # expected-torque terms, and drift last: a drift is only judged
            # once everything else that could explain slow torque has been
            # tried.
            cands = ([prof] if prof else []) + sorted(
                lines, key=lambda c: (c.action != "load_scale", -c.score)) + sorted(
                slow, key=lambda c: -c.score) + ([drift] if drift else [])
            for c in cands:
                if c.action == "report_only" and _key(c) not in self.tried:
                    self.tried.add(_key(c))
                    self.effects.append(_finding(c, False, None, None, self.model.gear_ratio))
            cands = [c for c in cands if c.action != "report_only" and _key(c) not in self.tried]
            if not cands:
                self.log(f"round {rnd}: nothing significant left")
                break
            progressed = False
            for c in cands:
                if _key(c) in self.tried:
                    continue
                self.tried.add(_key(c))
                if self.try_candidate(c, self._trials(c)):
                    progressed = True
                    break
            if not progressed:
                break


def _key(c):
    return getattr(c, "key_override", None) or c.key()


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
    if c.action == "set_profile":
        return "output-angle profile: " + ", ".join(
            f"order {o['order']:g} {o['amplitude_nm']:.3g} N m" for o in c.params["profile"])
    if c.action == "set_tuning":
        return "tuning: " + ", ".join(f"{k} {v:.4g}" for k, v in c.params.items())
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
        f["parameters"] = {k: v for k, v in c.params.items() if k != "profile"}
        if "profile" in c.params:
            f["profile"] = c.params["profile"]
    if m0 is not None:
        f["in_sample_before"] = {k: m0.get("in_sample_" + k) for k in _MET_KEYS}
        f["in_sample_after"] = {k: m1.get("in_sample_" + k) for k in _MET_KEYS}
        f["out_of_sample_before"] = {k: m0.get("out_of_sample_" + k) for k in _MET_KEYS}
        f["out_of_sample_after"] = {k: m1.get("out_of_sample_" + k) for k in _MET_KEYS}
    return f


_MET_KEYS = ("innovation_rms_nm", "model_residual_rms_nm", "error_rms_nm")
