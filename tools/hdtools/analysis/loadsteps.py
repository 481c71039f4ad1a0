"""The load's steps in a decimated stretch of the slow residual (a payload
put down, a contact): where they are, and the nuisance columns that let a
smoother's fit and its held-out check carry them (geometry.series;
docs/decisions/geometry-step-split.md)."""
from __future__ import annotations

import numpy as np

STEP_HALF = 5        # decimated samples (0.1 s) either side of a candidate step
STEP_K = 10.0
STEP_ISOLATION = 3.0 # and this many times the difference 2-4 STEP_HALF before and after
STEP_SPEED_CHANGE = 0.1   # a step only where the speed changes less than this share
STEP_GAP = 2         # decimated samples either side of a step left out


def with_steps(parts, vel_col, vel_eps, steps=None):
    """parts with one more nuisance column per step of the load (a payload
    put down, a contact, a reversal's friction step) found in any stretch:
    0 before the step, 1 after, in its own stretch; 0 in the others.  The
    smoother cannot follow a step; fitted as a column, the step is
    predicted in a held-out block from the samples either side, and the
    stretch stays whole (a cut at each step left an operating log's holds
    too short for a profile: docs/decisions/geometry-step-split.md).  Only
    steps at a steady speed (column vel_col of A): where the speed changes,
    the torque that steps is the motion's (inertia, friction's sign), which
    the motion columns carry.  vel_eps: the speed below which a change is
    measured against it instead.  steps: per part, the indices to use
    instead of finding them."""
    if steps is None:
        steps = [steps_of(z, A[:, vel_col], vel_eps) for z, _, A in parts]
    total = sum(len(s) for s in steps)
    if total == 0:
        return parts
    out, j = [], 0
    for (z, t, A), st in zip(parts, steps):
        S = np.zeros((len(z), total))
        z = z.copy()
        for i in st:
            S[i:, j] = 1.0
            z[max(0, i - STEP_GAP):i + STEP_GAP] = np.nan   # the transition: not fitted, not scored
            j += 1
        out.append((z, t, np.column_stack([A, S])))
    return out


def steps_of(z, v, vel_eps):
    """Indices where the load steps: where the mean of STEP_HALF samples
    after a point differs from the mean of STEP_HALF before by more than
    STEP_K robust standard deviations of that difference over the stretch
    (a slow line or a slow load moves it a little everywhere, a step a lot
    at one place), and by STEP_ISOLATION times that difference 2, 3 and 4
    STEP_HALF samples either side (a ramp, or a line fast enough to pass the
    first test, moves it there as well: at one of the three offsets by at
    least 0.6 of its largest for any line of 0.5-3 Hz), where the speed v
    changes by less than STEP_SPEED_CHANGE of itself over 2 STEP_HALF
    samples either side; one index per run of such points, at its largest
    difference."""
    h, n = STEP_HALF, len(z)
    if n < 4 * h:
        return []
    c = np.concatenate([[0.0], np.cumsum(z)])
    i = np.arange(h, n - h + 1)
    d = np.abs((c[i + h] - c[i]) - (c[i] - c[i - h])) / h
    med = np.median(d)
    over = d > med + STEP_K * np.median(np.abs(d - med)) / 0.6745 + 1e-12
    out, k = [], 0
    while k < len(i):
        if not over[k]:
            k += 1
            continue
        e = k
        while e + 1 < len(i) and over[e + 1]:
            e += 1
        m = k + int(np.argmax(d[k:e + 1]))
        # a step is flat either side: the same difference one window pair
        # earlier and later is small (a ramp or a line moves it there too)
        beside = max([d[m + o] for pairs in (2, 3, 4) for o in (-pairs * h, pairs * h)
                      if 0 <= m + o < len(d)] or [0.0])
        c0 = int(i[m])
        dv = abs(float(np.mean(v[c0:c0 + 2 * h])) - float(np.mean(v[max(0, c0 - 2 * h):c0])))
        steady = dv <= STEP_SPEED_CHANGE * (abs(float(v[c0])) + vel_eps)
        if d[m] > STEP_ISOLATION * beside and steady:
            out.append(c0)
        k = e + 1
    return out
