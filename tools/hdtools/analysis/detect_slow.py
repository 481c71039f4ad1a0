"""Slow terms the model lacks, from the low-passed model residual (the
candidates of hdtools.analysis.detect, for the slow band):

  velocity (viscous + Coulomb), acceleration (inertia error), and a linear
  trend in time (offset drift) by regression; a polynomial in the output
  angle is fitted alongside as a nuisance when the joint moves back and
  forth (gravity);
  sensor drift: the slow residual a straight line in each segment's time,
  checked on the held-out fold.
"""
from __future__ import annotations

import math

import numpy as np

from .detect import SLOW_MIN_PARTIAL, Candidate, Context, slow_series


def slow_candidates(ctx: Context, model) -> list[Candidate]:
    """Regression of the low-passed residual on velocity terms, acceleration
    and time (plus nuisances)."""
    dec = max(1, int(round(0.02 / ctx.ts_s)))
    ys, cols, groups = [], [], []
    eps = model.coulomb_vel_eps_rad_s
    for k, (r, v, t, tho) in enumerate(zip(ctx.signals, ctx.velocity, ctx.time, ctx.output_angle)):
        m = (len(r) // dec) * dec
        if m < 4 * dec:
            continue
        blk = lambda x: np.asarray(x[:m], float).reshape(-1, dec).mean(axis=1)
        rb, vb, tb, ob = blk(r), blk(v), blk(t), blk(tho)
        ab = np.gradient(vb, dec * ctx.ts_s)
        ys.append(rb)
        cols.append({"velocity_viscous": vb, "velocity_coulomb": vb / (np.abs(vb) + eps),
                     "acceleration": ab, "time": tb, "angle": ob})
        groups.append(k)
    if not ys:
        return []
    y = np.concatenate(ys)
    n = len(y)
    X = {name: np.concatenate([c[name] for c in cols]) for name in cols[0]}
    # Nuisance: a constant per piece; a cubic in output angle when the
    # joint moves back and forth over less than a turn (gravity).
    nuis = []
    offs = np.cumsum([0] + [len(a) for a in ys])
    for a, b in zip(offs[:-1], offs[1:]):
        c = np.zeros(n)
        c[a:b] = 1
        nuis.append(c)
    th = X["angle"]
    reciprocating = np.ptp(th) < 2 * math.pi
    if reciprocating:
        thn = (th - th.mean()) / (np.ptp(th) / 2 + 1e-12)
        nuis += [thn, thn ** 2, thn ** 3]
    terms = {}
    vv = X["velocity_viscous"]
    both_ways = min(np.mean(vv > 0), np.mean(vv < 0)) > 0.05
    if np.std(vv) > 1e-6:
        # Coulomb friction is a step at reversals: without both directions
        # it is indistinguishable from a constant.
        terms["velocity"] = [vv, X["velocity_coulomb"]] if both_ways else [vv]
    if np.std(X["acceleration"]) > 1e-6:
        terms["acceleration"] = [X["acceleration"]]
    tvals = X["time"]
    if np.ptp(tvals) > 0:
        # A trend in time is a nuisance here (drift: drift_candidate).
        nuis.append(tvals - tvals.mean())
    if not terms:
        return []
    names = list(terms)

    def rss(include):
        A = np.vstack(nuis + [c for nm in include for c in terms[nm]]).T
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        res = y - A @ coef
        return float(res @ res), coef
    rss_nuis, _ = rss([])
    rss_full, coef_full = rss(names)
    if rss_nuis <= 0:
        return []
    cands = []
    base = len(nuis)
    idx = base
    coef_of = {}
    for nm in names:
        coef_of[nm] = coef_full[idx:idx + len(terms[nm])]
        idx += len(terms[nm])
    for nm in names:
        others = [o for o in names if o != nm]
        rss_wo, _ = rss(others)
        partial = (rss_wo - rss_full) / rss_nuis
        contrib = sum(c * x for c, x in zip(coef_of[nm], terms[nm]))
        amp = float(np.std(contrib))
        ev = {"partial_explained_fraction": round(partial, 4),
              "slow_residual_rms_nm": round(math.sqrt(rss_nuis / n), 5),
              "gravity_nuisance": bool(reciprocating)}
        if partial < SLOW_MIN_PARTIAL:
            continue
        c = Candidate(nm, amplitude_nm=amp, score=partial * 100, evidence=ev)
        if nm == "velocity":
            co = [float(x) for x in coef_of[nm]]
            c.params = {"viscous_nm_s_rad": co[0]}
            if len(co) > 1:
                c.params["coulomb_nm"] = co[1]
            c.action = "expected_torque"
        elif nm == "acceleration":
            c.params = {"inertia_kgm2": float(coef_of[nm][0])}
            c.action = "expected_torque"
        cands.append(c)
    return cands


DRIFT_REST_FRACTION = 0.25   # what the line leaves, over its excursion
DRIFT_MIN_PARTIAL = 0.5      # the line explains >= 50 % of the slow residual's variance


def drift_candidate(ctx: Context, has_feedforward: bool,
                    segment_t0: dict) -> Candidate | None:
    """Sensor drift: the slow residual is a straight line in each segment's
    time (a common slope, an intercept per time base), continuing across
    gaps.  The firmware form is the offset state read as a sensor error,
    which removes *all* the slow torque the expected torque misses: so it
    is a candidate only if the line explains the slow residual (the rest is
    below DRIFT_REST_FRACTION of the line's excursion) and, without a
    feed-forward column, the line starts near zero (else the level is real
    torque the model misses, which the sensor-error offset would remove)."""
    ser = ctx.slow
    if not ser:
        return None
    y = np.concatenate([s[0] for s in ser])
    t = np.concatenate([s[1] for s in ser])
    segs = sorted({s[2] for s in ser})
    cols = [np.concatenate([np.full(len(s[0]), float(s[2] == g)) for s in ser]) for g in segs]
    # The slope is fitted beside what the expected torque may still miss
    # (velocity, acceleration): those bias it, but stay in the "rest".
    vel = np.concatenate([s[3] for s in ser])
    acc = np.concatenate([np.gradient(s[3], s[4]) if len(s[3]) > 1 else np.zeros(len(s[3]))
                          for s in ser])
    nuis = [x - x.mean() for x in (vel, acc) if np.std(x) > 0]
    A = np.column_stack(cols + [t] + nuis)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    slope = float(coef[len(segs)])
    A = A[:, :len(segs) + 1]
    coef = coef[:len(segs) + 1]
    pred = A @ coef
    rest = float(np.sqrt(np.mean((y - pred) ** 2)))
    var = float(np.var(y))
    partial = 1.0 - rest ** 2 / var if var > 0 else 0.0
    exc = abs(slope) * float(np.ptp(t))
    start = {g: float(coef[i] + slope * segment_t0.get(g, min(s[1][0] for s in ser if s[2] == g)))
             for i, g in enumerate(segs)}
    ev = {"drift_nm_per_s": slope, "trend_excursion_nm": round(exc, 5),
          "residual_after_trend_rms_nm": round(rest, 5), "explained_fraction": round(partial, 4),
          "level_at_segment_start_nm": {g: round(v, 4) for g, v in start.items()},
          "intercepts_nm": {g: float(coef[i]) for i, g in enumerate(segs)}}
    if partial < DRIFT_MIN_PARTIAL or rest > DRIFT_REST_FRACTION * exc:
        return None
    c = Candidate("offset_drift", amplitude_nm=exc / 2, score=partial * 100,
                  action="offset_sensor_error", evidence=ev, params={"drift_nm_per_s": slope})
    if not has_feedforward and max(abs(v) for v in start.values()) > DRIFT_REST_FRACTION * exc:
        ev["not_added_because"] = (
            "the slow residual does not start near zero: its level is torque the expected torque "
            "misses, which the offset as a sensor error would remove (give the controller's "
            "torque as torque_feedforward_nm)")
        c.action = "report_only"
    return c


def drift_held_out(candidate: Candidate, runs_held_out) -> dict:
    """The drift line fitted on fold A, applied to fold B's slow residual."""
    ser = slow_series(runs_held_out)
    ic = candidate.evidence["intercepts_nm"]
    ys, ps = [], []
    for y, t, g, _, _ in ser:
        if g in ic:
            ys.append(y)
            ps.append(ic[g] + candidate.params["drift_nm_per_s"] * t)
    if not ys:
        return {"held_out_samples": 0}
    y, p = np.concatenate(ys), np.concatenate(ps)
    return {"held_out_samples": int(len(y)),
            "held_out_slow_rms_nm": float(np.sqrt(np.mean((y - y.mean()) ** 2))),
            "held_out_rest_after_line_rms_nm": float(np.sqrt(np.mean((y - p) ** 2))),
            "held_out_line_excursion_nm": float(abs(candidate.params["drift_nm_per_s"])
                                                * np.ptp(np.concatenate([s[1] for s in ser])))}
