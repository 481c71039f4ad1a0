"""Find structure the model lacks in the residual and trace it to an effect
by its signature.

Lines (spectra of the model residual r = filtered - expected):
  * a line locked to the motor angle is sharp in the motor-angle order
    spectrum; locked to the output angle, sharp in the output-angle order
    spectrum (the two are one spectrum rescaled by the gear ratio when only
    one encoder exists: then the physically plausible reading wins, integer
    motor orders >= 1 for the wave generator, integer output orders for the
    output side);
  * a fixed-frequency line (electrical pickup) is sharp in the time spectrum
    and smeared in the order spectra when the speed varies.
  At (nearly) constant speed the two readings cannot be told apart: the
  finding says so (`ambiguous`) and the integer-order reading is preferred.

Slow terms (the low-passed residual): hdtools.analysis.detect_slow.

Every candidate carries its evidence: peak-over-floor power ratios in each
domain, the least-squares amplitude and explained fraction, the speed
variation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import loadcoef, spectra

LINE_MIN_RATIO = 30.0       # peak power over the local floor (~15 dB)
MIN_EXPLAINED = 0.002       # line must explain >= 0.2 % of residual variance
# A weaker peak (>= LINE_WEAK_RATIO) still counts when one sinusoid explains
# >= WEAK_EXPLAINED of the residual variance: at the lowest orders the local
# floor is raised by leakage of slow torque, which hides strong lines.
LINE_WEAK_RATIO = 8.0
WEAK_EXPLAINED = 0.05
# Lock of a line (classify_line): windows of LOCK_WINDOW_S in which a
# reading's line has LOCK_PRESENT of the larger reading's 90th-percentile
# window amplitude; the reading present in LOCK_MARGIN more of the windows
# wins (if one holds in LOCK_HOLDS of them).  Windows where a reading's line
# makes fewer than LOCK_MIN_CYCLES cycles do not count (slow torque).
LOCK_WINDOW_S = 1.0
LOCK_PRESENT = 0.3
LOCK_MARGIN = 0.2
LOCK_HOLDS = 0.5            # a reading must hold in this share of the windows to win
LOCK_MIN_CYCLES = 4.0
SLOW_MIN_PARTIAL = 0.02     # slow term must explain >= 2 % of slow residual variance
INTEGER_TOL = 0.03
# Below this a fixed-frequency line may well be real periodic load torque
# (a repeated motion, a vibration): it is reported but not removed.
FIXED_MIN_HZ = 20.0
BAND_BINS = 4               # half-width of the band around an existing block


@dataclass
class Candidate:
    kind: str                     # motor_order | output_order | fixed_frequency | velocity | acceleration | offset_drift
    order: float = float("nan")   # cycles per rev of its lock (order kinds) or Hz (fixed)
    amplitude_nm: float = 0.0
    score: float = 0.0
    action: str = "add_block"     # add_block | retune_block | load_scale | expected_torque | offset_sensor_error
    evidence: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)

    def key(self):
        if self.action == "load_scale":
            # One coefficient for every line: tried once, whichever line
            # showed it.
            return (self.action,)
        if self.kind in ("motor_order", "output_order", "fixed_frequency"):
            return (self.kind, round(self.order, 2), self.action)
        # Slow terms may be refined once the model has changed: the key
        # includes the proposed values (to 2 significant digits).
        return (self.kind, self.action) + tuple(
            float(f"{v:.2g}") for _, v in sorted(self.params.items()))


def _near_int(x, tol=INTEGER_TOL):
    return x >= 0.5 and abs(x - round(x)) <= tol


@dataclass
class Context:
    ts_s: float
    gear_ratio: float
    signals: list          # residual per piece (after warm-up)
    motor_angle: list
    output_angle: list
    time: list             # t per piece
    velocity: list         # output velocity per piece (tracker)
    torque: list           # measured torque per piece
    motor_speed_median: float
    motor_speed_spread: float
    spec_motor: object = None
    spec_output: object = None
    spec_time: object = None
    slow: list = field(default_factory=list)


def build_context(runs, ts_s, gear_ratio) -> Context:
    sig, thm, tho, tt, vel, tq = [], [], [], [], [], []
    for r in runs:
        w = r.warm
        sig.append(r.residual[w:])
        thm.append(r.motor_angle_rad[w:])
        tho.append(r.output_angle_rad[w:])
        tt.append(np.asarray(r.t_s[w:], float))
        vel.append(r.out["output_velocity_rad_s"][w:].astype(float))
        tq.append(np.asarray(r.torque_nm[w:], float))
    speeds = np.concatenate([np.abs(np.diff(m)) / ts_s for m in thm if len(m) > 1])
    moving = speeds[speeds > 0.05 * (np.max(speeds) if len(speeds) else 0)]
    med = float(np.median(moving)) if len(moving) else 0.0
    spread = float((np.percentile(moving, 90) - np.percentile(moving, 10)) / med) if med else 0.0
    ctx = Context(ts_s, gear_ratio, sig, thm, tho, tt, vel, tq, med, spread)
    ctx.spec_motor = spectra.order_spectrum(sig, thm)
    ctx.spec_output = spectra.order_spectrum(sig, tho)
    ctx.spec_time = spectra.time_spectrum(sig, ts_s)
    ctx.slow = slow_series(runs)
    return ctx


def phases(ctx: Context, kind: str, order: float):
    if kind == "motor_order":
        return [order * m for m in ctx.motor_angle]
    if kind == "output_order":
        return [order * o for o in ctx.output_angle]
    return [2 * math.pi * order * t for t in ctx.time]


def _refine(ctx, kind, order, step):
    """Order/frequency that maximises the least-squares line amplitude
    within +-1 spectral bin."""
    best = (-1.0, order)
    sig = _decimated(spectra.highpass_for_line(ctx.signals, phases(ctx, kind, order), ctx.ts_s),
                     100_000)
    for o in order + step * np.linspace(-1, 1, 9):
        if o <= 0:
            continue
        amp, _, _ = spectra.fit_line(sig, _decimated(phases(ctx, kind, o), 100_000))
        if amp > best[0]:
            best = (amp, o)
    return best[1]


def _step(ctx, kind):
    """One spectral bin of this kind's spectrum, in its unit."""
    if kind == "fixed_frequency":
        return ctx.spec_time.resolution
    return ctx.spec_motor.resolution * (ctx.gear_ratio if kind == "output_order" else 1.0)


def window_demod(ctx, phases_, win):
    """Per window of win samples of every piece: the line's amplitude at
    these phases (2 |mean((x - mean) e^-i phase)|), the line's mean
    frequency there [Hz] and the motor's mean turning rate [rev/s]."""
    amp, hz, rate = [], [], []
    for x, p_, th in zip(ctx.signals, phases_, ctx.motor_angle):
        m = (len(x) // win) * win
        if m < win:
            continue
        xs = np.asarray(x[:m], float).reshape(-1, win)
        ps = np.asarray(p_[:m], float).reshape(-1, win)
        ms = np.asarray(th[:m], float).reshape(-1, win)
        xc = xs - xs.mean(1, keepdims=True)
        amp.append(2 * np.hypot((xc * np.cos(ps)).mean(1), (xc * np.sin(ps)).mean(1)))
        span = (win - 1) * ctx.ts_s * 2 * math.pi
        hz.append(np.abs(ps[:, -1] - ps[:, 0]) / span)
        rate.append(np.abs(ms[:, -1] - ms[:, 0]) / span)
    if not amp:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    return np.concatenate(amp), np.concatenate(hz), np.concatenate(rate)


def classify_line(ctx, kind, order):
    """Which lock a spectral peak is: (kind, order, the peak's own reading,
    evidence).  Both readings of the line are tried window by window (1 s
    windows of fold A): the peak's own one (the spectrum it was found in)
    and the other (a fixed line at the frequency the angle-locked reading
    has where it is present; an angle-locked line at the order the fixed
    reading has at the motor's rate where it is present).  The true reading
    holds in every window whatever the speed; the false one only in windows
    at the speed where the two coincide (a fixed line shows as a sharp order
    peak from each constant-speed stretch, a motor-locked one as a time peak
    from each).  The reading present in clearly more windows wins; where
    both hold about equally (one |speed|: the log cannot tell), the finding
    says so and the integer-order reading (harmonic-drive lines are at
    integer orders) is preferred, else the fixed line."""
    ratio = ctx.gear_ratio
    win = max(16, int(round(LOCK_WINDOW_S / ctx.ts_s)))
    if ctx.spec_time is None or ctx.spec_motor is None:
        return kind, order, order, {}
    own = (kind, _refine(ctx, kind, order, _step(ctx, kind)))
    a_own, hz_own, rate = window_demod(ctx, phases(ctx, *own), win)
    if not len(a_own) or not np.any(a_own > 0):
        return own + (order, {})
    present = a_own >= LOCK_PRESENT * np.percentile(a_own, 90)
    # The other reading where the own one is present, known to the window's
    # resolution (the speed may vary within a stretch): the one with the
    # most line in the windows within that, then refined.
    if kind == "fixed_frequency":
        r = float(np.median(rate[present]))
        if not r > 0:
            return own + (order, {})
        alt_kind, alt_order = _angle_kind(own[1] / r, ratio)
        half = 1.0 / (LOCK_WINDOW_S * r) * (ratio if alt_kind == "output_order" else 1.0)
    else:
        alt_kind, alt_order = "fixed_frequency", float(np.median(hz_own[present]))
        half = 1.0 / LOCK_WINDOW_S
    grid = [o for o in alt_order + max(half, _step(ctx, alt_kind)) * np.linspace(-1, 1, 9)
            if o > 0]
    alt_order = max(grid, key=lambda o: float(np.mean(
        window_demod(ctx, phases(ctx, alt_kind, o), win)[0])))
    alt = (alt_kind, _refine(ctx, alt_kind, alt_order, _step(ctx, alt_kind)))
    a_alt, hz_alt, _ = window_demod(ctx, phases(ctx, *alt), win)
    lo = LOCK_MIN_CYCLES / (win * ctx.ts_s)
    valid = (hz_own >= lo) & (hz_alt >= lo)
    if np.sum(valid) < 2:
        return own + (order, {})
    ref = max(np.percentile(a_own[valid], 90), np.percentile(a_alt[valid], 90))
    s_own = float(np.mean(a_own[valid] >= LOCK_PRESENT * ref))
    s_alt = float(np.mean(a_alt[valid] >= LOCK_PRESENT * ref))
    ev = {"windows_present": {own[0]: round(s_own, 3), alt[0]: round(s_alt, 3)},
          "windows": int(np.sum(valid))}
    if max(s_own, s_alt) < LOCK_HOLDS:
        return own + (order, ev)       # no steady line under either lock: as found
    if s_own >= s_alt + LOCK_MARGIN:
        return own + (order, ev)
    if s_alt >= s_own + LOCK_MARGIN:
        return alt + (alt_order, ev)
    ev["ambiguous"] = ("the line holds as well at one lock as at the other (one |speed| in "
                       "the analysed part)")
    angle, fixed = (alt, own) if kind == "fixed_frequency" else (own, alt)
    if _near_int(angle[1], max(0.5 * _step(ctx, angle[0]), INTEGER_TOL)):
        return angle + (order if angle is own else alt_order, ev)
    return fixed + (order if fixed is own else alt_order, ev)


def _decimated(lst, max_total=400_000):
    total = sum(len(x) for x in lst)
    k = max(1, int(math.ceil(total / max_total)))
    return [x[::k] for x in lst]


def line_candidates(ctx: Context, model) -> list[Candidate]:
    fs = 1.0 / ctx.ts_s
    nyq_hz = 0.45 * fs
    speed_hz = ctx.motor_speed_median / (2 * math.pi)   # motor revs per second
    ratio = ctx.gear_ratio
    raw = []
    if ctx.spec_motor is not None and speed_hz > 0:
        lo = 3 * ctx.spec_motor.resolution
        for p in spectra.find_peaks(ctx.spec_motor, LINE_WEAK_RATIO, lo, nyq_hz / speed_hz,
                                    max_peaks=8):
            raw.append(("angle", p["at"], p))
    if ctx.spec_time is not None:
        lo = 3 * ctx.spec_time.resolution
        for p in spectra.find_peaks(ctx.spec_time, LINE_WEAK_RATIO, lo, nyq_hz, max_peaks=8):
            raw.append(("time", p["at"], p))
    cands = []
    seen = set()
    for domain, at, peak in raw:
        own = (("fixed_frequency", at) if domain == "time" else _angle_kind(at, ratio))
        kind, order, peak_order, lock_ev = classify_line(ctx, *own)
        step = _step(ctx, kind)
        if kind != "fixed_frequency" and _near_int(order, max(0.5 * step, INTEGER_TOL)):
            order = float(round(order))
        if any(k == kind and abs(o - order) <= max(step, 0.01 * order) for k, o in seen):
            continue
        seen.add((kind, order))
        # The reading's sharpness in both spectra (the other one's at the
        # median speed: evidence, not the decision).
        motor_order = (order / speed_hz if speed_hz else float("nan")) if (
            kind == "fixed_frequency") else (order / ratio if kind == "output_order" else order)
        f_equiv = order if kind == "fixed_frequency" else motor_order * speed_hz
        r_angle, x_m = spectra.peak_ratio_at(ctx.spec_motor, motor_order)
        r_out, x_o = spectra.peak_ratio_at(ctx.spec_output, motor_order * ratio)
        r_time, x_t = spectra.peak_ratio_at(ctx.spec_time, f_equiv)
        r_angle = max(r_angle, r_out)
        ev = {"peak_ratio_order_spectrum": round(r_angle, 1),
              "peak_ratio_time_spectrum": round(r_time, 1),
              "speed_spread": round(ctx.motor_speed_spread, 3),
              "found_in": "order spectrum" if domain == "angle" else "time spectrum", **lock_ev}
        spec_amp = peak["amplitude_nm"]
        if (kind == "fixed_frequency") != (domain == "time"):
            # Read in the other domain than found: its amplitude is that
            # domain's, and the found peak's strength counts.
            spec, x = ((ctx.spec_time, x_t) if kind == "fixed_frequency" else
                       (ctx.spec_output, x_o) if kind == "output_order" else (ctx.spec_motor, x_m))
            if spec is not None and x:
                spec_amp = float(np.sqrt(np.interp(x, spec.axis, spec.amp2)))
            r_time, r_angle = ((max(r_time, peak["ratio"]), r_angle) if kind == "fixed_frequency"
                               else (r_time, max(r_angle, peak["ratio"])))
        ph_all = phases(ctx, kind, order)
        amp, ph, expl = spectra.fit_line(
            _decimated(spectra.highpass_for_line(ctx.signals, ph_all, ctx.ts_s)),
            _decimated(ph_all))
        strong = max(r_angle, r_time) >= LINE_MIN_RATIO
        # The global fit is trusted when it agrees with the spectral peak and
        # explains a measurable share; otherwise it is noise projection.
        coherent = 0.5 * spec_amp <= amp <= 2.0 * spec_amp and expl >= MIN_EXPLAINED
        if not coherent and strong:
            # Sharp in the averaged spectrum but no single phase over the
            # whole record: the lock drifts slowly (inexact gear ratio, real
            # logs).  The Kalman block tracks phase, so it is still a
            # candidate; the spectral amplitude and position stand.
            ev["phase_coherent_over_record"] = False
            amp = spec_amp
            if domain == "angle" and kind != "fixed_frequency":
                order = (peak_order if not _near_int(peak_order, max(0.5 * step, INTEGER_TOL))
                         else float(round(peak_order)))
        elif not strong and expl < WEAK_EXPLAINED:
            continue
        ev.update({"fit_amplitude_nm": round(amp, 5), "fit_explained_fraction": round(expl, 4)})
        action = "add_block" if kind != "output_order" else "profile"
        lock = {"motor_order": "motor", "output_order": "output", "fixed_frequency": "fixed"}[kind]
        for i, b in enumerate(model.blocks):
            tol = max(step, 0.01 * b.order)
            if kind != "output_order" and b.lock == lock and abs(b.order - order) <= tol:
                action = "retune_block"
                order = b.order
                ev["existing_block"] = i
        if kind == "fixed_frequency" and order >= 0.5 * fs * model.nyquist_fraction:
            continue
        if kind == "fixed_frequency" and order < FIXED_MIN_HZ:
            action = "report_only"
            ev["not_added_because"] = (f"below {FIXED_MIN_HZ:g} Hz a fixed-frequency line may "
                                       "be real periodic torque (repeated motion, vibration)")
        cands.append(Candidate(kind, float(order), amp, score=r_angle if kind != "fixed_frequency"
                               else r_time, action=action, evidence=ev))
    return cands


def block_residue_candidates(ctx: Context, model) -> list[Candidate]:
    """Residue around an existing block: power in a band of +-BAND_BINS
    bins around its order over the floor just outside.  A block that lags a
    ripple whose amplitude moves (e.g. with load) leaves sidebands here."""
    out = []
    for i, b in enumerate(model.blocks):
        if b.lock == "output" and model.output_learn_scale == 0:
            continue     # a fixed profile: the geometry fit's business
        if b.lock == "fixed":
            spec, at = ctx.spec_time, b.order
        elif b.lock == "motor":
            spec, at = ctx.spec_motor, b.order
        else:
            spec, at = ctx.spec_output, b.order
        if spec is None:
            continue
        df = spec.axis[1] - spec.axis[0]
        j = int(round((at - spec.axis[0]) / df))
        if j - 3 * BAND_BINS < 1 or j + 3 * BAND_BINS >= len(spec.axis):
            continue
        band = spec.amp2[j - BAND_BINS:j + BAND_BINS + 1].sum()
        a, z = max(j - spectra.FLOOR_HALF_WIDTH * 2, 0), min(j + spectra.FLOOR_HALF_WIDTH * 2 + 1,
                                                              len(spec.axis))
        outside = np.r_[spec.amp2[a:j - 2 * BAND_BINS], spec.amp2[j + 2 * BAND_BINS + 1:z]]
        floor = np.median(outside) * (2 * BAND_BINS + 1)
        ratio = float(band / max(floor, 1e-30))
        if ratio < LINE_MIN_RATIO:
            continue
        kind = {"motor": "motor_order", "output": "output_order", "fixed": "fixed_frequency"}[b.lock]
        amp = math.sqrt(band)
        ev = {"band_ratio": round(ratio, 1), "band_rms_nm": round(amp / math.sqrt(2), 5),
              "existing_block": i,
              "note": "residue around a modelled line: its amplitude or phase moves faster "
                      "than the block follows"}
        # Evidence only: whether the residue's envelope follows |torque|.  A
        # line that grows with the load is load_candidate's to find.
        win = max(8, int(round(0.1 / ctx.ts_s)))
        env = window_line_amplitude(ctx.signals, phases(ctx, kind, b.order), win)
        load = window_means([np.abs(t) for t in ctx.torque], win)
        if env is not None and np.std(env) > 0 and np.std(load) > 0:
            ev["envelope_load_correlation"] = round(float(np.corrcoef(env, load)[0, 1]), 3)
        out.append(Candidate(kind, b.order, amp, score=ratio, action="retune_block",
                             evidence=ev))
    return out


def _windows(x, win):
    """x cut into windows of win samples (n x win), or None under two."""
    m = (len(x) // win) * win
    return x[:m].reshape(-1, win) if m >= 2 * win else None


def window_line_amplitude(signals, phases_, win):
    """The amplitude of the line with the given phase (2 |mean(x e^-i
    phase)|) in each window of win samples, over all pieces with at least
    two windows; None if none has."""
    out = []
    for x, p_ in zip(signals, phases_):
        xs, ps = _windows(x, win), _windows(p_, win)
        if xs is not None:
            out.append(2 * np.hypot((xs * np.cos(ps)).mean(1), (xs * np.sin(ps)).mean(1)))
    return np.concatenate(out) if out else None


def window_means(signals, win):
    """Each window's mean, over the same windows as window_line_amplitude."""
    out = [xs.mean(1) for xs in (_windows(x, win) for x in signals) if xs is not None]
    return np.concatenate(out) if out else None


def load_candidate(view, ts_s: float, model) -> list[Candidate]:
    """A load coefficient fitted on the measured torque against the
    filter's own slow torque (loadcoef.py), proposed whether or not a block
    leaves a residue: the firmware's blocks follow a line whose amplitude
    moves slowly, and what the coefficient buys there is the fixed output
    profile's growth with the load (the held rows follow the motor lines).
    Proposed while the model has none and the estimate is significant (the
    session tries it again after each change of the expected torque)."""
    if model.ripple_load_coeff_per_nm > 0:
        return []
    f = loadcoef.fit_view(view, ts_s, loadcoef.motor_orders(model))
    if f is None or not f.significant():
        return []
    ev = {"load_coefficient_t": round(f.t_stat, 1),
          "load_coefficient_std_err_per_nm": float(f"{f.std_err_per_nm:.2g}"),
          "load_ref_spread_nm": round(f.load_spread_nm, 3),
          "per_order": [{"order": o, "amplitude_nm": round(a, 4), "coeff_per_nm": round(c, 4),
                         "std_err_per_nm": float(f"{e:.2g}")} for o, a, c, e in f.per_order],
          "note": "the motor lines' amplitude grows with the filter's slow torque: "
                  "load-dependent ripple amplitude"}
    lead = max(f.per_order, key=lambda p: p[1])
    return [Candidate("motor_order", lead[0], lead[1], score=f.t_stat, action="load_scale",
                      evidence=ev, params={"ripple_load_coeff_per_nm":
                                           float(f"{f.coeff_per_nm:.3g}")})]


def _angle_kind(motor_order, ratio):
    """Motor or output reading of an angle-locked line."""
    out_order = motor_order * ratio
    if motor_order >= 0.75:
        return "motor_order", motor_order
    return "output_order", out_order


def slow_series(runs, dec_s=0.02):
    """20 ms means of the model residual and of time, per run, with each
    run's time base (its segment: pieces of one segment share a clock)."""
    out = []
    for r in runs:
        if len(r.t_s) - r.warm < 8:
            continue
        w = max(1, int(round(dec_s / float(np.median(np.diff(r.t_s[r.warm:r.warm + 100]))))))
        m = ((len(r.t_s) - r.warm) // w) * w
        if m < 4 * w:
            continue
        blk = lambda x: np.asarray(x[r.warm:r.warm + m], float).reshape(-1, w).mean(axis=1)
        out.append((blk(r.residual), blk(r.t_s), r.segment,
                    blk(r.out["output_velocity_rad_s"]), w * float(np.median(np.diff(r.t_s[:100])))))
    return out
