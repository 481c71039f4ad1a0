"""Geometry versus load: which part of the slow torque is an artifact locked
to the output angle, and which is real load.

An artifact of the gear's geometry (misalignment, flexspline eccentricity,
any output order k) is a fixed function of the absolute output angle: it
repeats with the angle across revolutions, speeds and directions.  A load
(payload, contact, process torque) is a function of time that does not.
So the slow residual z (measured torque minus the motor-locked ripple the
C filter removes, minus the expected torque and the feed-forward) is fitted
jointly as

    z(t) = sum_k a_k cos(k theta(t)) + b_k sin(k theta(t)) + s(t) + noise

with s a smooth function of time per stretch (a Whittaker smoother: second
differences penalised with lambda, i.e. a low-pass of time constant tau)
and the profile (a_k, b_k) common to the whole record.  What decides:

  * tau and the orders are chosen by cross-validation over short time
    blocks (INNER_FOLDS folds, blocks of INNER_BLOCK_S): the smoother is
    fitted with the held-out block's weights at zero (it interpolates the
    load across it), the profile without the held-out block, and both
    predict the held-out samples;
  * an order joins the profile (forward selection) only if it lowers the
    held-out error in a paired test over blocks (t >= MIN_T on the per-block
    log ratio of the squared errors) and by at least MIN_GAIN in total;
  * only when the output angle covers whole revolutions (every bin of a
    turn visited, at least MIN_REVS turns of travel): over part of a turn a
    function of the angle cannot be told from gravity or any other
    posture-dependent load, so nothing is claimed.

Friction and inertia the expected torque may still miss are functions of
the motion, not of the angle or of time: velocity, its sign and the
acceleration are fitted alongside as free nuisance columns (never part of
the profile).  Everything runs on block averages of DEC_S (the motor-locked
lines are already removed by the filter; block-averaging the basis as well
keeps the model exact for the decimated samples).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_banded, solveh_banded

from . import loadsteps

DEC_S = 0.02
TAU_GRID_S = (1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
MAX_OUTPUT_ORDER = 12
INNER_FOLDS = 5
INNER_BLOCK_S = 0.5
MIN_T = 3.0
MIN_GAIN = 0.002            # and at least 0.2 % of the held-out error
COVERAGE_BINS = 36
MIN_COVERAGE = 0.9
MIN_REVS = 1.5


@dataclass
class Inputs:
    """Per stretch: the slow residual z (measured - motor-locked ripple -
    expected torque - feed-forward), the output angle, time and the output
    velocity (for the motion nuisance; None: no motion columns); gains, if
    given, the factor the profile's lines carry at each sample (a profile
    at a reference load whose lines grow with the load: the firmware's
    held output rows, augment.profile_inputs), else 1."""
    signals: list
    angles: list
    times: list
    velocities: list | None
    ts_s: float
    gains: list | None = None

    def gain(self, i: int):
        return 1.0 if self.gains is None else np.asarray(self.gains[i], float)

    def minus(self, lines):
        return Inputs([np.asarray(z, float) - self.gain(i) * profile_at(lines, th)
                       for i, (z, th) in enumerate(zip(self.signals, self.angles))],
                      self.angles, self.times, self.velocities, self.ts_s, self.gains)


N_MOTION = 3
VEL_EPS_RAD_S = 0.01


def _blockmean(x, w):
    m = (len(x) // w) * w
    return np.asarray(x[:m], float).reshape(-1, w).mean(axis=1)


def series(inp: Inputs, orders, steps=None):
    """Decimated stretches [(z, t, A)]: A's columns are cos, sin of each
    order (block-averaged like z), then N_MOTION motion columns (velocity,
    its smoothed sign, acceleration; zero without velocities), then the
    load's steps (loadsteps.with_steps: found in z, or `steps` as step_indices gave
    them for another signal of the same record).  Returns (parts, decimated
    step)."""
    w = max(1, int(round(DEC_S / inp.ts_s)))
    out = []
    vels = inp.velocities or [None] * len(inp.signals)
    for i, (z, th, t, v) in enumerate(zip(inp.signals, inp.angles, inp.times, vels)):
        if len(z) < 8 * w:
            continue
        cols = []
        g = inp.gain(i)
        for k in orders:
            cols += [_blockmean(g * np.cos(k * th), w), _blockmean(g * np.sin(k * th), w)]
        n = len(z) // w
        if v is not None:
            vb = _blockmean(v, w)
            cols += [vb, vb / (np.abs(vb) + VEL_EPS_RAD_S),
                     np.gradient(vb, w * inp.ts_s) if n > 1 else np.zeros(n)]
        else:
            cols += [np.zeros(n)] * N_MOTION
        out.append((_blockmean(z, w), _blockmean(t, w), np.column_stack(cols)))
    return loadsteps.with_steps(out, 2 * len(orders), VEL_EPS_RAD_S, steps), w * inp.ts_s


def step_indices(inp: Inputs, orders) -> list:
    """The load's steps series(inp, orders) finds: per stretch it keeps, the
    decimated indices (to give another signal of the same record the same
    step columns and left-out transitions)."""
    parts, _ = series(inp, orders, steps=[[]] * len(inp.signals))
    vel_col = 2 * len(orders)
    return [loadsteps.steps_of(z, A[:, vel_col], VEL_EPS_RAD_S) for z, _, A in parts]


def coverage(angles):
    """(fraction of the COVERAGE_BINS bins of a turn visited, revolutions of
    travel)."""
    th = np.concatenate([np.asarray(a, float) for a in angles]) if angles else np.zeros(0)
    if len(th) < 2:
        return 0.0, 0.0
    bins = np.unique(np.floor(np.mod(th, 2 * math.pi) / (2 * math.pi) * COVERAGE_BINS))
    travel = sum(float(np.sum(np.abs(np.diff(a)))) for a in angles) / (2 * math.pi)
    return len(bins) / COVERAGE_BINS, travel


def _banded(n, lam, w):
    """Upper banded form of diag(w) + lam D'D (D: second differences)."""
    ab = np.zeros((3, n))
    main = np.full(n, 6.0)
    main[[0, -1]] = 1.0
    if n > 2:
        main[[1, -2]] = 5.0
    off1 = np.full(n - 1, -4.0)
    off1[[0, -1]] = -2.0
    ab[2] = w + lam * main
    ab[1, 1:] = lam * off1
    ab[0, 2:] = lam
    return ab


def _lam(tau_s, dt_s):
    # Half-power period of the Whittaker smoother: 2 pi lam^(1/4) samples.
    return (tau_s / (2 * math.pi * dt_s)) ** 4


def _smooth_solve(n, lam, w, rhs):
    """(diag(w) + lam D'D)^-1 rhs; Cholesky, or LU if rounding defeats it."""
    ab = _banded(n, lam, w)
    try:
        return solveh_banded(ab, rhs, check_finite=False)
    except np.linalg.LinAlgError:
        full = np.zeros((5, n))
        full[0], full[1], full[2] = ab[0], ab[1], ab[2]
        full[3, :-1], full[4, :-2] = ab[1, 1:], ab[0, 2:]
        return solve_banded((2, 2), full, rhs, check_finite=False)


class _Fit:
    """Per stretch and weight vector: the smoother's solve of [z, A], and
    the normal equations of the profile with the smoother profiled out
    (G = A' M A, h = A' M z over every column, M = W - W S^-1 W), so any
    column subset is a small solve.  A stretch with fewer than 3 weighted
    samples cannot anchor the smoother: it is left out (its residuals are
    NaN)."""

    def __init__(self, parts, lam, weights):
        self.parts = parts
        self.rows = []
        k = parts[0][2].shape[1] if parts else 0
        self.G = np.zeros((k, k))
        self.h = np.zeros(k)
        for (z, t, A), w in zip(parts, weights):
            n = len(z)
            seen = np.isfinite(z)               # a step's transition is NaN (loadsteps.with_steps)
            w = w * seen
            z = np.where(seen, z, 0.0)
            if n <= 3 or np.count_nonzero(w) < 3:
                self.rows.append((np.zeros(n), None))
                continue
            rhs = np.column_stack([z, A]) * w[:, None]
            sol = _smooth_solve(n, lam, w, rhs)
            self.rows.append((w, sol))
            MA = w[:, None] * (A - sol[:, 1:])
            self.G += A.T @ MA
            self.h += MA.T @ z

    def coef(self, cols):
        """Profile coefficients for the column subset (indices into A)."""
        k = len(cols)
        if k == 0:
            return np.zeros(0)
        G = self.G[np.ix_(cols, cols)]
        try:
            return np.linalg.solve(G + 1e-12 * np.trace(G) * np.eye(k), self.h[cols])
        except np.linalg.LinAlgError:
            return np.zeros(k)

    def residuals(self, cols, beta, rows=None):
        """z - (A beta + s) per stretch (at `rows`, a boolean mask per
        stretch, if given), s the smoother of z - A beta."""
        out = []
        for i, ((z, t, A), (w, sol)) in enumerate(zip(self.parts, self.rows)):
            sel = slice(None) if rows is None else rows[i]
            if sol is None:
                out.append(np.full(len(z[sel]), np.nan))
                continue
            r = z[sel] - sol[sel, 0]
            if len(cols):
                r = r + (sol[sel][:, 1:][:, cols] - A[sel][:, cols]) @ beta
            out.append(r)
        return out


def _inner_blocks(parts, dt_s):
    """Per stretch, each sample's inner block id (global numbering)."""
    L = max(4, int(round(INNER_BLOCK_S / dt_s)))
    ids, base = [], 0
    for z, _, _ in parts:
        b = np.arange(len(z)) // L + base
        ids.append(b)
        base = int(b[-1]) + 1 if len(b) else base
    return ids, base


_FITS: dict = {}


def _fold_fits(parts, lam, ids):
    """The INNER_FOLDS fits (held-out fold's weights at zero) for this
    smoother, cached while the same parts are being selected on."""
    key = (id(parts), lam)
    if key not in _FITS:
        if len(_FITS) > 2 * len(TAU_GRID_S):
            _FITS.clear()
        fits = []
        for f in range(INNER_FOLDS):
            weights = [(b % INNER_FOLDS != f).astype(float) for b in ids]
            fits.append((_Fit(parts, lam, weights), [w == 0 for w in weights]))
        _FITS[key] = (parts, fits)        # parts kept alive with its id
    return _FITS[key][1]


def _cv_block_sse(parts, lam, ids, nblocks, cols_sets):
    """Held-out SSE per block for each column set (list of index lists)."""
    sse = np.zeros((len(cols_sets), nblocks))
    for fit, held in _fold_fits(parts, lam, ids):
        bids = [b[h] for b, h in zip(ids, held)]
        for j, cols in enumerate(cols_sets):
            beta = fit.coef(cols)
            for res, b in zip(fit.residuals(cols, beta, held), bids):
                ok = np.isfinite(res)
                np.add.at(sse[j], b[ok], res[ok] ** 2)
    return sse


def _forward(parts, lam, ids, nblocks, no, chosen, base, orders, pool=None, min_t=None):
    """Forward selection from `chosen`: the next order is the one with the
    largest paired t over blocks (on the per-block log ratio of the held-out
    squared errors, so blocks at a stretch's ends, where the smoother
    extrapolates, do not dominate); it joins if t >= min_t (MIN_T) and the
    geometric mean of the blocks' held-out errors falls by MIN_GAIN.  Returns (chosen, steps, the
    per-block errors of the final set)."""
    chosen = list(chosen)
    min_t = MIN_T if min_t is None else min_t
    pool = list(range(no)) if pool is None else list(pool)
    steps = []
    while True:
        rest = [i for i in pool if i not in chosen]
        if not rest:
            break
        sse = _cv_block_sse(parts, lam, ids, nblocks, [_cols_of(chosen + [i], no, _ncols(parts)) for i in rest])
        used = base > 0
        nb = max(int(used.sum()), 2)
        ratio = np.log((base[None, used] + 1e-30) / (sse[:, used] + 1e-30))
        se = ratio.std(axis=1, ddof=1) / math.sqrt(nb) + 1e-300
        tstat = ratio.mean(axis=1) / se
        j = int(np.argmax(tstat))
        # the gain by the same per-block statistic as t (the geometric mean
        # of the blocks' error ratios): a total is decided by the few blocks
        # the motion columns model worst (a reversal), as the smoother's tau
        gain = 1.0 - math.exp(-float(ratio[j].mean()))
        if not (tstat[j] >= min_t and gain >= MIN_GAIN):
            break
        chosen.append(rest[j])
        steps.append({"order": orders[rest[j]], "t": round(float(tstat[j]), 2),
                      "held_out_gain_fraction": round(float(gain), 4)})
        base = sse[j]
    return chosen, steps, base


def _block_log_score(sse):
    """Mean log of the held-out error over the blocks that hold samples."""
    used = sse > 0
    return float(np.mean(np.log(sse[used]))) if used.any() else 0.0


def _cols_of(order_idx, n_orders, n_cols):
    """Columns of these orders plus the nuisance (motion, steps: always in)
    up to n_cols."""
    return [c for i in order_idx for c in (2 * i, 2 * i + 1)] + list(range(2 * n_orders, n_cols))


def _ncols(parts):
    return parts[0][2].shape[1]


def fit(inp: Inputs, orders=None):
    """The geometry-vs-load fit over the candidate output orders (default
    1..MAX_OUTPUT_ORDER).  Returns a dict: verifiable (bool), why (if not),
    orders (the selected ones, with a_nm, b_nm), tau_s, selection (each
    order's held-out gain and paired t), the held-out error with and
    without the profile."""
    cov, revs = coverage(inp.angles)
    res = {"angle_coverage": round(cov, 3), "revolutions": round(revs, 2), "orders": []}
    if cov < MIN_COVERAGE or revs < MIN_REVS:
        res["verifiable"] = False
        res["why"] = (f"the output angle covers {100 * cov:.0f} % of a turn and {revs:.2g} "
                      f"revolutions (needs {100 * MIN_COVERAGE:.0f} % and {MIN_REVS:g}): over part "
                      "of a turn a function of the angle cannot be told from gravity or any other "
                      "posture-dependent load")
        return res
    orders = list(orders or range(1, MAX_OUTPUT_ORDER + 1))
    no = len(orders)
    parts, dt = series(inp, orders)
    if not parts or sum(len(p[0]) for p in parts) < 20 * INNER_FOLDS:
        res["verifiable"] = False
        res["why"] = "too few samples for the cross-validated fit"
        return res
    ids, nblocks = _inner_blocks(parts, dt)
    per_tau = []
    for tau in TAU_GRID_S:
        lam = _lam(tau, dt)
        base = _cv_block_sse(parts, lam, ids, nblocks, [_cols_of([], no, _ncols(parts))])[0]
        chosen, steps, sse_end = _forward(parts, lam, ids, nblocks, no, [], base, orders)
        per_tau.append({"tau": tau, "chosen": chosen, "steps": steps, "total": float(sse_end.sum()),
                        "base": float(base.sum()), "sse": sse_end})
    # The smoother's time constant by the mean log of the per-block held-out
    # errors, as the selection's paired test: a few blocks the motion
    # columns model badly (a reversal's friction step, a start) would
    # otherwise choose the most flexible smoother for the whole record, and
    # a smoother that follows the load there also absorbs every slow line.
    best = min(per_tau, key=lambda p: _block_log_score(p["sse"]))
    tau, chosen, steps = best["tau"], list(best["chosen"]), list(best["steps"])
    # The best tau is the one that interpolates the load best across the
    # held-out blocks, and there a slow line is partly interpolated too: an
    # order that a stiffer smoother (a larger tau) shows significantly also
    # joins, if it lowers the held-out error at the best tau as well.
    stiffer = [i for p in per_tau if p["tau"] > tau for i in p["chosen"] if i not in chosen]
    if stiffer:
        lam = _lam(tau, dt)
        chosen, more, sse_end = _forward(parts, lam, ids, nblocks, no, chosen, best["sse"], orders,
                                         pool=sorted(set(stiffer)), min_t=0.0)
        for st in more:
            st["from_stiffer_smoother"] = True
        steps += more
        best["total"] = float(sse_end.sum())
    total, base0 = best["total"], best["base"]
    beta = _Fit(parts, _lam(tau, dt), [np.ones(len(p[0])) for p in parts]).coef(
        _cols_of(chosen, no, _ncols(parts)))
    n_dec = sum(len(p[0]) for p in parts)
    res.update({"verifiable": True, "tau_s": tau, "decimation_s": dt,
                "held_out_rms_without_nm": math.sqrt(base0 / n_dec),
                "held_out_rms_with_nm": math.sqrt(total / n_dec),
                "selection": steps})
    for n, i in enumerate(chosen):
        a, b = float(beta[2 * n]), float(beta[2 * n + 1])
        res["orders"].append({"order": float(orders[i]), "a_nm": a, "b_nm": b,
                              "amplitude_nm": math.hypot(a, b)})
    res["orders"].sort(key=lambda o: o["order"])
    return res


def refit(inp: Inputs, orders, tau_s, nuisance_orders=()):
    """The profile of exactly these orders at time constant tau_s, fitted on
    all the given samples (nuisance_orders fitted alongside and dropped):
    [{order, a_nm, b_nm, amplitude_nm}]."""
    allo = list(orders) + [o for o in nuisance_orders if o not in orders]
    parts, dt = series(inp, allo)
    if not parts or not orders:
        return []
    beta = _Fit(parts, _lam(tau_s, dt), [np.ones(len(p[0])) for p in parts]).coef(
        _cols_of(range(len(allo)), len(allo), _ncols(parts)))
    return [{"order": float(o), "a_nm": float(beta[2 * i]), "b_nm": float(beta[2 * i + 1]),
             "amplitude_nm": float(math.hypot(beta[2 * i], beta[2 * i + 1]))}
            for i, o in enumerate(orders)]


def profile_at(lines, th):
    """sum a cos(order th) + b sin(order th) over the lines (dicts)."""
    x = np.zeros(len(th))
    for ln in lines:
        x += ln["a_nm"] * np.cos(ln["order"] * th) + ln["b_nm"] * np.sin(ln["order"] * th)
    return x


def check(inp: Inputs, lines, tau_s, nuisance_orders=()):
    """Out-of-sample check of a fitted profile on data it was not fitted on,
    with the fit's own cross-validation: the held-out error of a smoother of
    time constant tau_s (the load), the nuisance (motion, the load's steps)
    and any nuisance_orders (other lines, refitted freely), interpolated
    across INNER_BLOCK_S blocks, with and without the profile (fixed, not
    refitted) subtracted first.  Returns (rms_without, rms_with): the
    held-out RMS without the profile, and that times the square root of the
    geometric mean over the blocks of their error ratio with / without (the
    selection's per-block statistic: the few blocks a load step's transient
    or a reversal leaves unpredictable count as one block each, not by their
    size).  The load's steps are found once, without the profile: both
    errors are of the same samples and the same nuisance."""
    nuis = [o for o in nuisance_orders if o not in [ln["order"] for ln in lines]]
    sses, scored = [], []
    steps = step_indices(inp, nuis)     # one set of steps: the same samples scored both ways
    for x in (inp, inp.minus(lines)):
        parts, dt = series(x, nuis, steps)
        if not parts:
            return float("nan"), float("nan")
        ids, nblocks = _inner_blocks(parts, dt)
        sses.append(_cv_block_sse(parts, _lam(tau_s, dt), ids, nblocks,
                                  [_cols_of(range(len(nuis)), len(nuis), _ncols(parts))])[0])
        scored.append(sum(int(np.isfinite(p[0]).sum()) for p in parts))
    without, with_ = sses
    used = (without > 0) & (with_ > 0)
    rms_without = math.sqrt(float(without.sum()) / max(scored[0], 1))
    if not used.any():
        return rms_without, rms_without
    ratio = math.exp(float(np.mean(np.log(with_[used] / without[used]))))
    return rms_without, rms_without * math.sqrt(ratio)
